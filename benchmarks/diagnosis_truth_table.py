"""The diagnosis on Mitsuba 3 truth: verdict, RMSE before and after the suggested edit, time.

Run: .venv/bin/python benchmarks/diagnosis_truth_table.py [--cases a,b,...]   (~1.5 min on 2 cores)

The cases, their truth and their helpers are those of ``tests/engine/test_diagnosis_on_truth.py``
(imported, not copied): validation and diagnosis scenes rendered by Mitsuba 3, physics removed
from the booth file handed to the tool (an effect switched off, or the hardware deleted), 1 %
seeded meter noise.  Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _testcases import case_rows, load_test_module  # noqa: E402  (benchmarks/ is the script's folder)


def _cases():
    return load_test_module("tests/engine/test_diagnosis_on_truth.py", "diagnosis_on_truth")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", help="comma-separated subset of case ids")
    a = ap.parse_args()
    T = _cases()
    print("| case | removed from the booth file | output | verdict | allowed | RMSE before % | "
          "RMSE after edit % | recurrence | diagnosis s | compare s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for c, r in case_rows(T, a.cases):
        after = "—" if r["rmse_after"] is None else f"{r['rmse_after']:.2f} ({r['verdict_after']})"
        rec = "—" if r["recurrence"] is None else f"{r['recurrence']:.3f}"
        print(f"| {c.id} ({c.scene}, {c.grid}) | {', '.join(c.remove) or 'nothing'} | "
              f"{'known' if c.known else 'fitted'} | {r['verdict']} | {'yes' if r['allowed'] else 'NO'} | "
              f"{r['rmse_before']:.2f} | {after} | {rec} | {r['seconds']:.1f} | {r['total_seconds']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
