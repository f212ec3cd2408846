"""Undeclared hardware on Mitsuba 3 truth: verdict, fitted hardware, RMSE before and after pasting.

Run: .venv/bin/python benchmarks/hypothesis_truth_table.py [--cases a,b,...]   (minutes per case)

The cases, their truth and their helpers are those of ``tests/engine/test_hypotheses_on_truth.py``
(imported, not copied): scenes rendered by Mitsuba 3 (``tests/data/hypotheses``), the hardware
deleted from the booth file handed to the tool (a black cavity, a dark ceiling, a rough plate),
1 % seeded meter noise.  "RMSE after" is the refit after merging the YAML of the truth's
explanation (the verdict's, or the tied alternative that is the truth) into the booth file.
Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _testcases import case_rows, load_test_module  # noqa: E402  (benchmarks/ is the script's folder)


def _fitted(row) -> str:
    if not row["fitted"]:
        return "—"
    out = []
    for k, (v, se) in sorted(row["fitted"].items()):
        name = k.split(".", 1)[1]
        out.append(f"{name} {v:.4g}" + (f" ± {se:.2g}" if se else " (not pinned)"))
    return "; ".join(out)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", help="comma-separated subset of case ids")
    a = ap.parse_args()
    T = load_test_module("tests/engine/test_hypotheses_on_truth.py", "hypotheses_on_truth")
    print("| case | scene, grid | hardware not declared | output | verdict | truth in verdict | fitted (± σ) | "
          "RMSE before % | RMSE after pasting % (verdict) | compare s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for c, r in case_rows(T, a.cases, ready=lambda c: (c.folder / f"truth-{c.grid}.csv").is_file()):
        if r is None:
            print(f"| {c.id} | {c.scene}, {c.grid} | — | — | no committed truth | — | — | — | — | — |", flush=True)
            continue
        after = "—" if r["rmse_after"] is None else f"{r['rmse_after']:.2f} ({r['verdict_after']})"
        print(f"| {c.id} | {c.scene}, {c.grid} | {', '.join(c.remove)} | {'known' if c.known else 'fitted'} | "
              f"{r['verdict']} | {'yes' if r['allowed'] else 'NO'} | {_fitted(r)} | {r['rmse_before']:.2f} | "
              f"{after} | {r['seconds']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
