"""
The ``lbscene`` command line: thin Typer commands over library code.

Each command lives in ``lbscene/commands/<name>.py`` and exposes
``register(app)``; commands import their heavy dependencies (colour, pxr, bpy,
moderngl) inside the command function so ``lbscene --help`` stays fast.

User mistakes raise :class:`~lbscene.engine.diagnostics.LbsceneUserError`; they
are printed as located diagnostics and the process exits with code 2.
"""

from __future__ import annotations

import importlib
import sys

import typer

from lbscene.engine.diagnostics import LbsceneUserError

__all__ = ["app", "main", "COMMAND_MODULES", "print_diagnostics"]

app = typer.Typer(
    name="lbscene",
    help="Declarative spectral scene engine for light booths.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)



def _version(value: bool) -> None:
    if value:
        from lbscene import __version__

        typer.echo(f"lbscene {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")) -> None:
    """Declarative spectral scene engine for light booths."""


#: Command modules, in help order.  A module that is not present is skipped.
COMMAND_MODULES = (
    "validate", "build", "compare", "plan", "history", "effects", "accuracy", "bake", "render",
    "web", "visual_report",
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
        print(d.format(), file=stream)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the app, turning user errors into exit code 2."""
    try:
        # with standalone_mode=False click *returns* the code of typer.Exit instead of exiting
        rc = app(args=argv, standalone_mode=False)
    except LbsceneUserError as exc:
        print_diagnostics(exc.diagnostics)
        n = len(exc.diagnostics)
        print(f"{n} error{'s' if n != 1 else ''}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # typer.Exit inside commands
        return int(exc.code or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # click usage errors
        import click

        if isinstance(exc, click.exceptions.Exit):
            return exc.exit_code
        if isinstance(exc, click.exceptions.Abort):
            print("aborted", file=sys.stderr)
            return 1
        if isinstance(exc, click.ClickException):
            exc.show()
            return 2
        raise
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def run() -> None:
    """Console-script entry point."""
    sys.exit(main())
