"""Render the explicit-flake reference with Mitsuba 3 and write its glint statistics.

    .venv/bin/python tests/data/coatings/render_flake_truth.py        # several minutes

Writes ``flake-truth.json`` beside this script: the scene (``TRUTH_CONFIG`` of
``lbscene.engine.coatings.mitsuba_flakes``), Mitsuba's version and variant, and per lighting the
glints Mitsuba's image shows (count, density, every glint's flux, S_a, S_i) and the graininess of
the diffuse image.  ``tests/coatings/test_flakes_vs_mitsuba.py`` compares lbscene's flake model
with it; its slow test re-renders and checks that this file is current.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "flake-truth.json"


def main() -> int:
    from lbscene.engine.coatings.mitsuba_flakes import reference_statistics

    t0 = time.perf_counter()
    stats = reference_statistics(progress=lambda s: print(f"[{time.perf_counter() - t0:6.0f} s] {s}",
                                                          flush=True))
    OUT.write_text(json.dumps(stats, indent=1, sort_keys=True) + "\n")
    print(f"wrote {OUT.name} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
