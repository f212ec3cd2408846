"""
The ``lbscene`` command line: thin Typer commands over library code.

Each command lives in ``lbscene/commands/<name>.py`` and exposes
``register(app)``; commands import their heavy dependencies (colour, pxr, bpy,
moderngl) inside the command function so ``lbscene --help`` stays fast.

User mistakes raise :class:`~lbscene.engine.files.diagnostics.LbsceneUserError`; they
are printed as located diagnostics and the process exits with code 2.  SIGTERM,
SIGINT and SIGHUP stop a command through its clean-up code (temporaries removed,
child processes stopped: :mod:`lbscene.engine.files.processes`); the exit code is then
``128 + signal number``.
"""

from __future__ import annotations

import importlib
import sys

import typer

from lbscene.engine.files.diagnostics import LbsceneUserError

__all__ = ["app", "main", "COMMAND_MODULES", "print_diagnostics"]

app = typer.Typer(
    name="lbscene",
    help="Declarative spectral scene engine for light booths.",
    no_args_is_help=True,
    add_completion=True,       # --install-completion / --show-completion for bash, zsh, fish
    pretty_exceptions_enable=False,
)



def _version(value: bool) -> None:
    if value:
        from lbscene._version import __version__

        typer.echo(f"lbscene {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")) -> None:
    """Declarative spectral scene engine for light booths."""


#: Command modules, in help order.  A module that is not present is skipped.
COMMAND_MODULES = (
    "validate", "build", "compare", "plan", "history", "effects", "accuracy", "bake", "render",
    "web", "visual_report", "conformance", "export_mitsuba", "export_blender",
)

for _name in COMMAND_MODULES:
    try:
        _mod = importlib.import_module(f"lbscene.commands.{_name}")
    except ModuleNotFoundError as _exc:
        if _exc.name != f"lbscene.commands.{_name}":
            raise
        continue
    _mod.register(app)


def print_diagnostics(diags, *, stream=None) -> None:
    """Print diagnostics, one per line (plain text: they are meant to be grepped)."""
    stream = stream or sys.stderr
    for d in diags:
        print(d.format(), file=stream)   # Diagnostic.format shows control characters as escapes


def _wants_json(argv: list[str]) -> bool:
    """``--format json`` (or ``--format=json``) on the command line."""
    for i, a in enumerate(argv):
        if a == "--format=json" or (a == "--format" and i + 1 < len(argv) and argv[i + 1] == "json"):
            return True
    return False


def _json_errors(diags, code: int = 2) -> None:
    """Errors under ``--format json``: one JSON object on stdout (nothing else to parse)."""
    from lbscene.engine.files.textsafe import json_text

    print(json_text({"ok": False, "exit_code": code, "errors": [d.to_json() for d in diags]}, indent=2))


def _tolerant_streams() -> None:
    """Characters the console's encoding cannot show are written as escapes (``\\u0394``)
    instead of raising: ``PYTHONIOENCODING=ascii`` or a C locale must not crash a command."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is None or (getattr(stream, "errors", None) or "strict") != "strict":
            continue
        try:
            reconfigure(errors="backslashreplace")
        except (ValueError, OSError):   # a detached or closed stream: leave it
            pass


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, turning user errors into exit code 2.

    With ``--format json`` a user error is a JSON object on stdout,
    ``{"ok": false, "exit_code": 2, "errors": [{code, message, location, …}]}``, instead of text on
    stderr.
    """
    _tolerant_streams()
    argv = list(sys.argv[1:] if argv is None else argv)
    from lbscene.engine.files.processes import Stopped, stop_on_signals

    try:
        with stop_on_signals():
            return _main(argv)
    except Stopped as exc:
        print(f"lbscene: stopped by {exc}; its temporary files were removed", file=sys.stderr)
        return exc.exit_code


def _main(argv: list[str]) -> int:
    as_json = _wants_json(argv)
    from lbscene.engine.files.outputs import INPUTS

    INPUTS.clear()   # the inputs of this run only (tests call main() many times in one process)
    try:
        from lbscene.engine.files.limits import check_environment

        check_environment()
        # with standalone_mode=False click *returns* the code of typer.Exit instead of exiting
        rc = app(args=argv, standalone_mode=False)
    except LbsceneUserError as exc:
        if as_json:
            _json_errors(exc.diagnostics)
            return 2
        print_diagnostics(exc.diagnostics)
        n = len(exc.diagnostics)
        print(f"{n} error{'s' if n != 1 else ''}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # typer.Exit inside commands
        return int(exc.code or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        # the last net under the commands' own checks: a path the system refuses (a name too long,
        # a loop of symbolic links, a full disk) is a located error, never a traceback
        if exc.filename is None:
            raise
        from lbscene.engine.files.diagnostics import Diagnostic, SourceLocation

        shown = str(exc.filename)
        shown = shown if len(shown) <= 120 else shown[:60] + "…" + shown[-40:]
        d = Diagnostic("LB013", f"cannot use the path: {exc.strerror or exc}", SourceLocation(shown))
        if as_json:
            _json_errors([d])
        else:
            print_diagnostics([d])
            print("1 error", file=sys.stderr)
        return 2
    except Exception as exc:  # click usage errors
        import click

        if isinstance(exc, click.exceptions.Exit):
            return exc.exit_code
        if isinstance(exc, click.exceptions.Abort):
            print("aborted", file=sys.stderr)
            return 1
        if isinstance(exc, click.ClickException):
            if as_json:
                from lbscene.engine.files.diagnostics import Diagnostic

                _json_errors([Diagnostic("LB500", exc.format_message())])
                return 2
            exc.show()
            return 2
        from lbscene.engine.files.outputs import NO_SPACE_ERRNOS, no_space_error

        if isinstance(exc, OSError) and exc.errno in NO_SPACE_ERRNOS:
            # a full disk in a writer that does not say which output: still a located error, no traceback
            diags = no_space_error(exc.filename or "(output)", None, exc).diagnostics
            if as_json:
                _json_errors(diags)
            else:
                print_diagnostics(diags)
                print("1 error", file=sys.stderr)
            return 2
        raise
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def run() -> None:
    """Console-script entry point."""
    sys.exit(main())
