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


def read_history(path: Path) -> list[dict]:
    """Entries of a history file (missing file: none; unreadable lines are skipped).

    A path that exists but cannot be read (not a regular file, no permission, too large) is a
    located error, not an empty history.
    """
    return _parse_history(_history_bytes(Path(path)))


def _history_bytes(path: Path) -> bytes | None:
    """The history file's bytes (None when there is none), read with the usual bounds."""
    from .yamlio import read_bytes_bounded

    if not os.path.lexists(path):
        return None
    return read_bytes_bounded(path, str(path), MAX_HISTORY_BYTES, is_input=False)


def _parse_history(raw: bytes | None) -> list[dict]:
    out = []
    for line in (raw or b"").decode("utf-8", errors="replace").splitlines():
        line = line.strip()
        if not line:
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(d, dict):
            out.append(d)
    return out[-MAX_ENTRIES:]


def _is_history(path: Path, entries: list[dict]) -> bool:
    """An existing file lbscene may rewrite: in the ledger, or every line a history entry."""
    from .outputs import made_by_lbscene

    if made_by_lbscene(path):
        return True
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = [x for x in text.splitlines() if x.strip()]
    return len(lines) == len(entries) and all("step" in e and "label" in e for e in entries)


def check_history_path(path: Path) -> None:
    """Before a run's work: the history next to the measurements can be (re)written.

    Raises ``LB611`` for a file of that name that is not an lbscene history, ``LB610`` where
    nothing can be written, ``LB012``/``LB013`` for an unreadable one.
    """
    from .diagnostics import LbsceneUserError
    from .outputs import _probe_parent

    path = Path(path)
    if os.path.lexists(path):
        old = read_history(path)
        if not _is_history(path, old):
            raise LbsceneUserError.single(
                "LB611", "history file exists and is not an lbscene history; it is left as it is", str(path),
                expected="an lbscene history (JSON lines)", hint="move it away, or run with --no-history")
    _probe_parent(path, "history", None)


def append_history(path: Path, entry: dict) -> dict:
    """Append ``entry`` (adds ``step``, ``time`` and ``label``); atomic rewrite.

    The history file is lbscene's own; a file of that name that is not a history is never
    replaced (``LB611``).
    """
    from .diagnostics import LbsceneUserError
    from .outputs import write_output

    path = Path(path)
    raw = _history_bytes(path)
    old = _parse_history(raw)
    if raw is not None and not _is_history(path, old):
        raise LbsceneUserError.single(
            "LB611", "history file exists and is not an lbscene history; it is left as it is", str(path),
            expected="an lbscene history (JSON lines)", hint="move it away, or run with --no-history")
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
    ax.set_xticklabels([f"{s_}\n" + textwrap.fill(e.get("label", ""), 24) for s_, e in zip(steps, entries)],
                       fontsize=7)
    ax.set_ylabel("RMSE (%)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(title or "error per step", fontsize=10)
    fig.tight_layout()
    return fig
