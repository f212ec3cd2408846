"""Benchmark: validate-config + build of every shipped booth (wall time, best of N).

Run: .venv/bin/python benchmarks/bench_build.py [--repeat 3]
Prints a table; the baseline row is YAML parsing alone of the same file, measured in the same run,
so the ratios say how much of the time is validation/compilation rather than I/O.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _timing import best_of  # noqa: E402  (benchmarks/ is the script's folder)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from lbscene.engine.scene.build import build_booth
    from lbscene.engine.conformance.validate import validate_paths
    from lbscene.engine.files.yamlio import load_yaml_file

    import colour  # noqa: F401  (import cost is paid once, not per booth: measure steady state)
    import pxr.Usd  # noqa: F401

    booths = sorted(p.parent for p in (REPO / "booths").glob("*/booth.yaml"))
    print(f"{'booth':32s} {'parse ms':>9s} {'validate ms':>12s} {'build ms':>9s} "
          f"{'validate/parse':>15s} {'build/parse':>12s}")
    for b in booths:
        parse = best_of(lambda: load_yaml_file(b / "booth.yaml"), args.repeat)
        val = best_of(lambda: validate_paths([b]), args.repeat)
        with tempfile.TemporaryDirectory() as td:
            bld = best_of(lambda: build_booth(b, Path(td) / "out"), args.repeat)
        print(f"{b.name:32s} {parse * 1e3:9.1f} {val * 1e3:12.1f} {bld * 1e3:9.1f} "
              f"{val / parse:15.1f} {bld / parse:12.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
