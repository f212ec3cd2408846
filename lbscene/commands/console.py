"""Terminal conventions shared by the commands.

* On a terminal: rich tables and live progress bars (on stderr).
* Piped or redirected: tables as wide as they need (``$COLUMNS`` if set, else 200
  characters), and progress as plain lines,
  one per step, on stderr — a log keeps them, a pipe is not filled with escape codes.
* At any width, a table's cells wrap, and a word too long for its column is folded onto the
  next line, never cut with "…" (:func:`table`): a verdict such as ``DISAGREE`` or a sample's
  name is read whole on an 80-column terminal too.
* User text is shown as it is written: the consoles parse no rich markup and no emoji codes
  in strings (a sample named ``[/link]`` is printed, not parsed), and control characters are
  shown as escapes (:func:`lbscene.engine.files.textsafe.printable`); styles are given as ``style=``
  or :class:`rich.text.Text`.  :func:`echo` does the same for plain lines.
"""

from __future__ import annotations

import os
import sys
import time

__all__ = ["out_console", "err_console", "table", "progress", "PlainProgress", "echo", "styled"]

#: Width of tables written to a pipe or a file (no terminal to fit).
PIPED_WIDTH = 200


def _width(stream) -> int | None:
    if stream.isatty():
        return None
    try:
        return max(40, int(os.environ["COLUMNS"]))
    except (KeyError, ValueError):
        return PIPED_WIDTH


def _safe_console(**kw):
    """A rich console that renders strings literally: no markup, no emoji codes, control
    characters escaped (table cells, titles and status lines included)."""
    from rich.console import Console

    from lbscene.engine.files.textsafe import printable

    class _LiteralConsole(Console):
        def render_str(self, text, **options):
            options["markup"] = False
            options["emoji"] = False
            return super().render_str(printable(text), **options)

    return _LiteralConsole(markup=False, emoji=False, **kw)


def table(*args, **kw):
    """A :class:`rich.table.Table` whose columns fold a word too long for them instead of cutting
    it with "…" (a column's own ``overflow=`` still wins)."""
    from rich.table import Table

    class _FoldingTable(Table):
        def add_column(self, *a, **k):
            k.setdefault("overflow", "fold")
            return super().add_column(*a, **k)

    return _FoldingTable(*args, **kw)


def out_console():
    """Console for a command's result (stdout)."""
    return _safe_console(width=_width(sys.stdout))


def err_console():
    """Console for progress and notes (stderr)."""
    return _safe_console(stderr=True, width=_width(sys.stderr))


def styled(*parts):
    """A :class:`rich.text.Text` of ``(text, style)`` pairs and plain strings, user text escaped:
    ``styled(("verdict: ", ""), (str(v), "bold red"))``."""
    from rich.text import Text

    from lbscene.engine.files.textsafe import printable

    out = Text()
    for p in parts:
        text, style = (p, "") if isinstance(p, str) else p
        out.append(printable(text), style=style or None)
    return out


def echo(text: str = "", *, err: bool = False) -> None:
    """One line of plain text (``typer.echo``), control characters shown as escapes."""
    import typer

    from lbscene.engine.files.textsafe import printable

    typer.echo(printable(text), err=err)


class PlainProgress:
    """The part of :class:`rich.progress.Progress` the commands use, as plain lines."""

    def __init__(self, stream=None, prefix: str = "") -> None:
        self.stream = stream or sys.stderr
        self.tasks: dict[int, dict] = {}
        self.t0 = time.perf_counter()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def _say(self, tid: int) -> None:
        t = self.tasks[tid]
        count = f" ({t['completed']}/{t['total']})" if t["total"] else ""
        line = f"{t['description']}{count}"
        if line != t.get("said"):
            t["said"] = line
            from lbscene.engine.files.textsafe import printable

            print(f"[{time.perf_counter() - self.t0:6.1f} s] {printable(line, newlines=False)}", file=self.stream,
                  flush=True)

    def add_task(self, description: str, total=None, **_) -> int:
        tid = len(self.tasks)
        self.tasks[tid] = {"description": description, "total": total, "completed": 0}
        self._say(tid)
        return tid

    def update(self, tid: int, *, description: str | None = None, completed=None, total=None, **_) -> None:
        t = self.tasks[tid]
        if description is not None:
            t["description"] = description
        if completed is not None:
            t["completed"] = completed
        if total is not None:
            t["total"] = total
        self._say(tid)

    def advance(self, tid: int, amount: float = 1) -> None:
        self.tasks[tid]["completed"] += amount
        self._say(tid)


def progress(*columns, console=None, transient: bool = True, disable: bool = False):
    """A rich progress display on a terminal, plain lines otherwise, nothing when ``disable``.

    Descriptions often hold user text (a lighting, a file): text columns render them without
    markup, and control characters are shown as escapes either way.
    """
    from rich.progress import Progress, TextColumn

    from lbscene.engine.files.textsafe import printable

    console = console or err_console()
    if disable or console.is_terminal:
        for c in columns:
            if isinstance(c, TextColumn):
                c.markup = False

        class _LiteralProgress(Progress):
            def add_task(self, description, *a, **kw):
                return super().add_task(printable(description, newlines=False), *a, **kw)

            def update(self, task_id, *a, description=None, **kw):
                if description is not None:
                    description = printable(description, newlines=False)
                return super().update(task_id, *a, description=description, **kw)

        return _LiteralProgress(*columns, console=console, transient=transient, disable=disable)
    return PlainProgress(console.file)
