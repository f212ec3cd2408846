"""The hidden-effect table of issue 3: for every catalog effect (and a control), with the lamp
output fitted and declared known, the RMSE before, the verdict, the verdict after the planned
points (where tied) and the RMSE after pasting the diagnosis' snippet into the booth file.

Run: .venv/bin/python benchmarks/hidden_effect_table.py [--effects a,b,...]   (~3 min on 2 cores)

Same set-up as ``tests/engine/test_hidden_effects.py`` (its truths, booth, noise and helpers are
imported, not copied): truth from the brute-force Monte Carlo reference engine, 1 % noise,
55-point A3 grid.  Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _testcases import load_test_module  # noqa: E402  (benchmarks/ is the script's folder)


def _helpers():
    return load_test_module("tests/engine/test_hidden_effects.py", "hidden_effects")


def row(H, truth: str, known: bool) -> list[str]:
    from lbscene.engine.loop.compare import run_compare

    with tempfile.TemporaryDirectory() as td:
        td = Path(td)
        booth = td / "booth"
        shutil.copytree(H.BOOTH, booth)
        m = H.measure(booth, td / "m", truth, known=known)
        t0 = time.perf_counter()
        res = run_compare(m, do_plan=True)
        secs = time.perf_counter() - t0
        before = res.fit.rmse_percent
        verdict, after_plan = str(res.verdict), "—"
        if res.verdict.kind == "ambiguous":
            m, res = H.resolve_with_plan(booth, td / "m", truth, known, res)
            after_plan = str(res.verdict)
        after = "—"
        if res.diagnosis.snippet:
            H.add_to_booth(booth, res.diagnosis.snippet)
            fixed = run_compare(m)
            after = f"{fixed.fit.rmse_percent:.2f} ({fixed.verdict})"
    return [truth, "known" if known else "fitted", f"{before:.2f}", verdict, after_plan, after, f"{secs:.1f}"]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--effects", help="comma-separated subset of the truths")
    args = ap.parse_args()
    H = _helpers()
    truths = args.effects.split(",") if args.effects else list(H.TRUTHS)
    head = ["effect", "lamp output", "RMSE before %", "verdict", "after plan",
            "RMSE after adding the snippet % (verdict)", "compare s"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for known in (False, True):
        for truth in truths:
            print("| " + " | ".join(row(H, truth, known)) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
