"""
Watch the error fall: every ``compare`` run appends one entry to a history
next to the measurements (``<measurement set>.history.jsonl``, one JSON
object per line) — booth hash, enabled effects, fitted parameters, errors,
verdict — labelled with what changed since the previous entry.

The file is rewritten atomically (temp file + ``os.replace``), so an
interrupted run never leaves a half-written history.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

__all__ = ["append_history", "check_history_path", "read_history", "change_label", "plot_history"]

MAX_ENTRIES = 10_000


def change_label(prev: dict | None, cur: dict) -> str:
    """Human label of what changed between two history entries."""
    if prev is None:
        return "first run"
    parts = []
    pe, ce = prev.get("effects", {}), cur.get("effects", {})
    added = sorted(set(ce) - set(pe))
    removed = sorted(set(pe) - set(ce))
    if added:
        parts.append("+" + ", +".join(added))
    if removed:
        parts.append("−" + ", −".join(removed))
    changed = sorted(k for k in set(ce) & set(pe) if ce[k] != pe[k])
    if changed:
        parts.append("changed " + ", ".join(changed))
    if prev.get("n_points") != cur.get("n_points"):
        parts.append(f"{prev.get('n_points')}→{cur.get('n_points')} points")
    if prev.get("fitted") != cur.get("fitted"):
        parts.append("fit on" if cur.get("fitted") else "fit off")
    if not parts and prev.get("booth_hash") != cur.get("booth_hash"):
        parts.append("booth edited")
    return "; ".join(parts) if parts else "no change"


#: Bound on a history file's size (about 10 000 entries).
MAX_HISTORY_BYTES = 32 * 1024 * 1024


#: Fields of a history entry that are numbers (or null), and those that are text.
_NUMBER_FIELDS = ("rmse_percent", "mean_abs_percent", "max_percent", "spectral_rmse_percent",
                  "noise_percent_estimate")
_WHOLE_FIELDS = ("step", "n_points", "outliers")
_TEXT_FIELDS = ("label", "verdict", "time", "booth", "booth_hash", "lighting")


def _entry_problem(d) -> tuple[str, str, str] | None:
    """(field, got, expected) of the first field of a history line with the wrong type, else None."""
    import math

    if not isinstance(d, dict):
        return "<line>", type(d).__name__, "a JSON object (one history entry)"
    for k in _NUMBER_FIELDS + _WHOLE_FIELDS:
        v = d.get(k)
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return k, repr(v)[:40], "a finite number or null"
        if k in _WHOLE_FIELDS and (v != int(v) or v < 0):
            return k, repr(v)[:40], "a whole number ≥ 0"
    for k in _TEXT_FIELDS:
        if k in d and not isinstance(d[k], str):
            return k, repr(d[k])[:40], "text"
    if "effects" in d and not isinstance(d["effects"], dict):
        return "effects", repr(d["effects"])[:40], "an object of effect parameters"
    return None


def read_history(path: Path) -> list[dict]:
    """Entries of a history file (missing file: none).

    A path that exists but cannot be read (not a regular file, no permission, too large) is a
    located error, not an empty history; so is a line that is not an entry (not JSON, nested
    too deeply, a field of the wrong type such as ``"rmse_percent": "abc"``), at its line: the
    next ``compare`` rewrites the history from what was read, and must not drop a line silently.

    Raises
    ------
    LbsceneUserError
        ``LB0xx`` reading the file, ``LB015`` a line that is not JSON, ``LB101`` a field of the
        wrong type.
    """
    return _parse_history(_history_bytes(Path(path)), Path(path))


def _history_bytes(path: Path) -> bytes | None:
    """The history file's bytes (None when there is none), read with the usual bounds."""
    from lbscene.engine.files.yamlio import read_bytes_bounded

    if not os.path.lexists(path):
        return None
    return read_bytes_bounded(path, str(path), MAX_HISTORY_BYTES, is_input=False)


def _parse_history(raw: bytes | None, path: Path) -> list[dict]:
    out = []
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.yamlio import parse_json_text

    for no, line in enumerate((raw or b"").decode("utf-8", errors="replace").splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        d = parse_json_text(line, str(path), line=no)
        bad = _entry_problem(d)
        if bad is not None:
            field, got, expected = bad
            raise LbsceneUserError.single(
                "LB101", f"history line: {field!r} has the wrong type" if field != "<line>"
                else "history line is not an entry", str(path), no, 1, value=got, expected=expected,
                hint="the file is lbscene's history of this measurement set: fix or delete the line "
                     "(or the file) and run again")
        out.append(d)
    return out[-MAX_ENTRIES:]


def _is_history(path: Path, entries: list[dict]) -> bool:
    """An existing file lbscene may rewrite: in the ledger, or every line a history entry."""
    from lbscene.engine.files.outputs import made_by_lbscene

    if made_by_lbscene(path):
        return True
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = [x for x in text.splitlines() if x.strip()]
    return len(lines) == len(entries) and all("step" in e and "label" in e for e in entries)


def _own_history(path: Path, raw: bytes | None = None) -> list[dict]:
    """The entries of the history lbscene may rewrite at ``path`` (none when it does not exist).

    A file of that name that is not lbscene's (not in the folder's ledger, and a line that is not
    an entry) is ``LB611`` and left alone; a history lbscene wrote whose line was damaged since
    is the located error of :func:`read_history`.
    """
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import made_by_lbscene

    not_ours = LbsceneUserError.single(
        "LB611", "history file exists and is not an lbscene history; it is left as it is", str(path),
        expected="an lbscene history (JSON lines)", hint="move it away, or run with --no-history")
    try:
        old = _parse_history(raw if raw is not None else _history_bytes(path), path)
    except LbsceneUserError as exc:
        if any(d.code in ("LB015", "LB101") for d in exc.diagnostics) and not made_by_lbscene(path):
            raise not_ours from None
        raise
    if os.path.lexists(path) and not _is_history(path, old):
        raise not_ours
    return old


def check_history_path(path: Path) -> None:
    """Before a run's work: the history next to the measurements can be (re)written.

    Raises ``LB611`` for a file of that name that is not an lbscene history, ``LB610`` where
    nothing can be written, ``LB012``/``LB013`` for an unreadable one.
    """
    from lbscene.engine.files.outputs import _probe_parent

    path = Path(path)
    _own_history(path)
    _probe_parent(path, "history", None)


def append_history(path: Path, entry: dict) -> dict:
    """Append ``entry`` (adds ``step``, ``time`` and ``label``); atomic rewrite.

    The history file is lbscene's own; a file of that name that is not a history is never
    replaced (``LB611``).
    """
    from lbscene.engine.files.outputs import write_output

    path = Path(path)
    raw = _history_bytes(path)
    old = _own_history(path, raw)
    entry = dict(entry)
    entry.setdefault("time", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    entry["step"] = (old[-1].get("step", len(old)) + 1) if old else 1
    entry["label"] = change_label(old[-1] if old else None, entry)
    lines = [json.dumps(e, sort_keys=True, ensure_ascii=False) for e in old + [entry]]
    # rewritten only if it still holds what was read here (a line appended meanwhile is not lost)
    write_output(path, "\n".join(lines) + "\n",
                 replace_if_sha256=hashlib.sha256(raw).hexdigest() if raw is not None else None)
    return entry


def plot_history(entries: list[dict], ax=None, title: str = ""):
    """Error per step (RMSE %, and the noise level), each step labelled with what changed.

    Linear axis from 0 so the fall reads as it is; what changed is written under each step
    (wrapped), the RMSE above each point.
    """
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lbscene.engine.files.textsafe import plain_text_plots

    # labels and title are user text (effect ids, file names): drawn as written, never as
    # mathtext; save the figure inside plain_text_plots() too (tick labels are made then)
    with plain_text_plots():
        fig = _plot_history(plt, textwrap, entries, ax, title)
    for t in fig.findobj(matplotlib.text.Text):
        t.set_parse_math(False)
    return fig


def _plot_history(plt, textwrap, entries, ax, title):
    from lbscene.engine.files.textsafe import printable

    if ax is None:
        fig, ax = plt.subplots(figsize=(max(5.0, 1.9 * len(entries) + 2.0), 4.2), dpi=110)
    else:
        fig = ax.figure
    steps = [e.get("step", i + 1) for i, e in enumerate(entries)]
    rmse = [float("nan") if e.get("rmse_percent") is None else e["rmse_percent"] for e in entries]
    noise = [e.get("noise_percent_estimate") for e in entries]
    ax.plot(steps, rmse, "o-", color="#1f5fa8", label="illuminance RMSE %")
    if any(n is not None for n in noise):
        ax.plot(steps, [n if n is not None else float("nan") for n in noise], "--", color="0.5",
                label="noise % (estimate)")
    for s_, r, n in zip(steps, rmse, noise):
        if r == r:
            below = n is not None and r < 1.15 * n       # keep the value off the noise line
            ax.annotate(f"{r:.2f} %", (s_, r), textcoords="offset points", xytext=(0, -13 if below else 7),
                        ha="center", fontsize=8)
    top = max([v for v in rmse + [n for n in noise if n is not None] if v == v] or [1.0])
    ax.set_ylim(0, 1.2 * top)
    ax.set_xlim(min(steps) - 0.5, max(steps) + 0.5)
    ax.set_xticks(steps)
    ax.set_xticklabels([f"{s_}\n" + textwrap.fill(printable(e.get("label", ""), newlines=False), 24)
                        for s_, e in zip(steps, entries)],
                       fontsize=7)
    ax.set_ylabel("RMSE (%)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(printable(title or "error per step", newlines=False), fontsize=10)
    fig.tight_layout()
    return fig
