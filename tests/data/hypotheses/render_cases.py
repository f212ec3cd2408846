"""Render, or check, the Mitsuba truth of the hypothesis scenes in this folder (committed as data).

Each scene is a booth folder whose ``booth.yaml`` declares the hardware the diagnosis will be
handed *without* (a luminaire cavity, a ceiling of another reflectance, walls lighter than
declared, a rough plate, an opal plate, mirrors above the lamps or behind them) and whose
``effects:`` lists exactly the physics its truth includes.  The tests
(``tests/engine/test_hypotheses_on_truth.py``) and the table
(``benchmarks/hypothesis_truth_table.py``) read ``truth-a3.csv`` (the 55-point A3 sheet) and
``truth-floor.csv`` (9 × 7 over the floor), receivers facing +z with an ideal cosine response,
rendered by Mitsuba 3 (:class:`lbscene.engine.truth.mitsuba.MitsubaTruth`) to a Monte Carlo
standard error of :data:`TARGET_REL_ERROR` per receiver (passes of :data:`SPP_PER_PASS` samples,
at least :data:`MIN_PASSES`), with the booth folder's sha256.

``--check`` re-renders ``--points`` receivers per grid with seeds disjoint from the committed
render's and compares: they agree when
:math:`|E_\\text{new} - E_\\text{csv}| \\le 4 \\sqrt{σ_\\text{new}^2 + σ_\\text{csv}^2}`
(exit 1 otherwise, 2 for a booth edited since its truth was rendered).

Run (minutes per scene on 2 cores)::

    nice -n 10 .venv/bin/python tests/data/hypotheses/render_cases.py [SCENE ...] [--grids a3 floor]
    .venv/bin/python tests/data/hypotheses/render_cases.py --check [--points 2]

``--variant llvm_ad_spectral`` renders with Mitsuba's vectorised CPU variant (the same spectral
path tracer, several times faster; needs libLLVM 16 or later, e.g.
``DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so``); ``--check`` always re-renders in
the scalar variant, so a committed truth is checked by the other variant where it was made by the
vectorised one.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENES = ("cavity-wide", "ceiling-dark", "rough-plate", "mirror-above", "walls-light", "opal-plate", "mirror-sides")
GRIDS = ("a3", "floor")
#: grids rendered per scene (all of them unless listed)
SCENE_GRIDS: dict[str, tuple[str, ...]] = {}
LIGHTING = "L"
SPP_PER_PASS = 65536
#: the truth's noise (0.3 %) is well below the 1 % meter noise the tests add
TARGET_REL_ERROR = 0.003
MIN_PASSES = 4
MAX_PASSES = 256
#: seeds of a --check run: beyond every seed of a committed render
CHECK_SEED = 7919 * (MAX_PASSES + 1)


def _truth(folder: Path, seed: int, variant: str | None = None):
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth

    ir = compile_booth(folder / "booth.yaml")
    return ir, MitsubaTruth(ir, LIGHTING, spp=SPP_PER_PASS, passes=MIN_PASSES, seed=seed, variant=variant)


def render_scene(scene: str, grids=GRIDS, variant: str | None = None) -> None:
    from lbscene.engine.truth.mitsuba import mitsuba_version
    from lbscene.engine.truth.validation import booth_files_sha256, render_truth_grid

    folder = HERE / scene
    ir, truth = _truth(folder, 1, variant)
    meta = {"scene": scene, "renderer": "Mitsuba 3 (lbscene.engine.truth.mitsuba.MitsubaTruth)",
            "mitsuba_version": mitsuba_version(), "variant": truth.variant, "lighting": LIGHTING,
            "effects": ",".join(sorted(ir.effects)), "booth_sha256": booth_files_sha256(folder)}
    for grid in (g for g in grids if g in SCENE_GRIDS.get(scene, GRIDS)):
        t0 = time.perf_counter()
        t = render_truth_grid(truth, ir, grid, folder / f"truth-{grid}.csv", meta,
                              target_rel_error=TARGET_REL_ERROR, max_passes=MAX_PASSES)
        print(f"{scene} {grid}: {time.perf_counter() - t0:.0f} s, max rel. error "
              f"{100 * np.max(t.std_error_lx / t.illuminance_lx):.2f} %", flush=True)


def check_scene(scene: str, points: int) -> int:
    """0 when ``points`` re-rendered receivers per grid agree with the committed truth."""
    from lbscene.engine.truth.validation import booth_files_sha256, read_truth_csv

    folder = HERE / scene
    bad = 0
    ir, truth = _truth(folder, CHECK_SEED)
    for grid in SCENE_GRIDS.get(scene, GRIDS):
        t = read_truth_csv(folder / f"truth-{grid}.csv")
        if t.meta.get("booth_sha256") != booth_files_sha256(folder):
            print(f"{scene}: booth edited since its truth was rendered", flush=True)
            return 2
        idx = np.linspace(0, len(t.illuminance_lx) - 1, points).round().astype(int)
        res = truth.illuminance_with_error_lx(t.points_mm[idx], t.normals[idx],
                                              target_rel_error=TARGET_REL_ERROR, max_passes=MAX_PASSES)
        d = np.abs(res.illuminance_lx - t.illuminance_lx[idx])
        lim = 4.0 * np.hypot(res.std_error_lx, t.std_error_lx[idx])
        bad |= int(np.any(d > lim))
        print(f"{scene} {grid}: max |Δ|/limit {np.max(d / lim):.2f}", flush=True)
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--grids", nargs="+", default=list(GRIDS), choices=GRIDS)
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--points", type=int, default=2)
    ap.add_argument("--variant", choices=("scalar_spectral", "llvm_ad_spectral"),
                    help="Mitsuba variant of a render (default: the scalar one); --check always uses it")
    a = ap.parse_args(argv)
    if a.check:
        return max(check_scene(s, a.points) for s in a.scenes)
    for s in a.scenes:
        render_scene(s, a.grids, a.variant)
    return 0


if __name__ == "__main__":
    sys.exit(main())
