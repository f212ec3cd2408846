"""Render, or check, the Mitsuba truth of the validation scenes in this folder.

Each scene is a booth folder ``<scene>/booth.yaml`` whose inputs are all declared (lamp
luminance known, no fit) and whose ``effects:`` lists exactly the physics the truth includes.
This script renders its illuminance on the validation grids (``a3``: the 55-point A3 sheet,
``floor``: 9 × 7 over the floor; receivers facing +z, ideal cosine response) with Mitsuba 3
(:class:`lbscene.engine.truth.mitsuba.MitsubaTruth`, ``scalar_spectral``, ``path`` integrator
of unbounded depth) and writes ``truth-<grid>.csv`` beside the booth
(:func:`lbscene.engine.truth.validation.write_truth_csv`), with the booth folder's sha256 so that
a test notices an edited booth.

Sampling: passes of ``--spp`` samples (65536: Mitsuba accumulates a film in float32), each with
its own seed; a receiver gets passes until the standard error of their mean (spread of the
passes, σ/√k) is at most ``--target-rel-error`` of its value, with at least ``--min-passes``
(enough passes for the spread to be a usable estimate) and at most ``--max-passes``.

``--variant llvm_ad_spectral`` renders with Mitsuba's vectorised CPU variant (the same path tracer;
for the volumetric opal scenes).  ``--check`` re-renders ``--points`` receivers of every grid with
fresh seeds (disjoint from those of the committed render), always in the scalar variant, and
compares them with the committed values: they agree when

.. math:: |E_\\text{new} - E_\\text{csv}| \\le 4 \\sqrt{σ_\\text{new}^2 + σ_\\text{csv}^2} .

Exit status 0 when every checked receiver agrees, 1 when one does not, 2 for a missing truth
or a booth edited since its truth was rendered.

Run (tens of minutes for all scenes; two processes at most on a small machine)::

    nice -n 10 .venv/bin/python tests/data/validation/render_truth.py [SCENE ...] [--grids a3 floor]
    .venv/bin/python tests/data/validation/render_truth.py --check [--points 2]
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: the validation scenes, in the order they are rendered and reported
SCENES = ("direct-shapes", "walls-05", "walls-45", "cavity-aperture", "cavity-white", "mesh-cavity",
          "rough-diffuser-r030",
          "rough-diffuser-r010",
          # bright luminaire ceilings and mirrors
          "ceiling-85", "ceiling-85-spaced", "mirror-strip", "mirror-behind", "mirror-prism",
          # the three mirror shapes in a bright room (their images of the surfaces)
          "mirror-room-45",
          # plates: the declared total transmittance, opal plates, the plate in the inter-reflection
          "rough-cavity-45",
          # a glass plate reflecting the tubes into a white cavity
          "glass-cavity-45",
          # opal plates (faces matched to the air: the scattering layer alone)
          "opal-black", "opal-grey", "opal-cavity-45",
          # a diffuser inside a cavity closed by an aperture plate
          "aperture-diffuser")
#: the forward model's RMS deviation from the truth allowed per scene (percent, the truth's noise
#: removed in quadrature): tests/engine/test_model_vs_truth.py and benchmarks/bench_truth.py
THRESHOLDS_PERCENT = {"direct-shapes": 0.5, "walls-05": 1.0, "walls-45": 1.0, "cavity-aperture": 1.5,
                      "cavity-white": 1.5, "mesh-cavity": 1.5,
                      "rough-diffuser-r030": 2.0, "rough-diffuser-r010": 2.0,
                      # bright luminaire ceilings and mirrors
                      "ceiling-85": 1.0, "ceiling-85-spaced": 1.0, "mirror-strip": 1.0, "mirror-behind": 1.0,
                      "mirror-prism": 1.0, "mirror-room-45": 1.0,
                      # plates
                      "rough-cavity-45": 1.0, "glass-cavity-45": 1.0,
                      "opal-black": 1.0, "opal-grey": 1.0, "opal-cavity-45": 1.0,
                      "aperture-diffuser": 1.0}
#: scenes whose truth covers some grids only (the others: every grid of
#: ``engine.truth.validation.GRIDS``)
SCENE_GRIDS: dict[str, tuple[str, ...]] = {}
LIGHTING = "L"
SPP_PER_PASS = 65536
TARGET_REL_ERROR = 0.0015
MIN_PASSES = 8
MAX_PASSES = 1024
#: seeds of a --check run start here: beyond every seed of a committed render
#: (MitsubaTruth uses seed + 7919·pass + receiver, pass < MAX_PASSES, receiver < 997)
CHECK_SEED = 7919 * (MAX_PASSES + 1)
CHECK_K_SIGMA = 4.0

__all__ = ["SCENES", "THRESHOLDS_PERCENT", "SCENE_GRIDS", "grids_of", "render_scene", "check_scene", "truth_path",
           "main"]


def grids_of(scene: str) -> tuple[str, ...]:
    """The grids ``scene``'s truth covers (:data:`SCENE_GRIDS`, default every grid)."""
    from lbscene.engine.truth.validation import GRIDS

    return tuple(SCENE_GRIDS.get(scene, GRIDS))


def truth_path(scene: str, grid: str) -> Path:
    return HERE / scene / f"truth-{grid}.csv"


def _receivers(ir, grid: str):
    from lbscene.engine.truth.validation import validation_grid

    P = validation_grid(ir, grid)
    return P, np.tile([0.0, 0.0, 1.0], (len(P), 1))


def _render_chunk(args):
    """One process's share of a grid: receivers ``start …`` with the seeds they get in one run
    (MitsubaTruth seeds receiver ``i`` of a call with ``seed + 7919·pass + i``)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth

    scene, P, N, start, spp, min_passes, seed, target_rel_error, max_passes, variant = args
    truth = MitsubaTruth(compile_booth(HERE / scene), LIGHTING, spp=spp, passes=min_passes, seed=seed + start,
                         variant=variant)
    r = truth.illuminance_with_error_lx(P, N, target_rel_error=target_rel_error, max_passes=max_passes)
    return r.illuminance_lx, r.std_error_lx, r.passes


def _render_grid(scene, truth, P, N, *, jobs, spp, min_passes, seed, target_rel_error, max_passes):
    """(illuminance, standard error, passes) of the receivers ``P``, in ``jobs`` processes (the same
    values as one process: each receiver keeps its seeds)."""
    if jobs <= 1:
        r = truth.illuminance_with_error_lx(P, N, target_rel_error=target_rel_error, max_passes=max_passes)
        return r.illuminance_lx, r.std_error_lx, r.passes
    import multiprocessing as mp

    bounds = np.linspace(0, len(P), jobs + 1).round().astype(int)
    work = [(scene, P[a:b], N[a:b], int(a), spp, min_passes, seed, target_rel_error, max_passes, truth.variant)
            for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
    with mp.get_context("spawn").Pool(len(work)) as pool:
        parts = pool.map(_render_chunk, work)
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))


def render_scene(scene: str, grids=None, *, spp: int = SPP_PER_PASS, target_rel_error: float = TARGET_REL_ERROR,
                 min_passes: int = MIN_PASSES, max_passes: int = MAX_PASSES, seed: int = 0, jobs: int = 1,
                 variant: str | None = None, log=print) -> None:
    """Render ``scene`` on ``grids`` (default all) and write ``truth-<grid>.csv`` beside its booth
    (``jobs`` processes per grid; the values do not depend on it; ``variant``: the Mitsuba
    variant, default ``MitsubaTruth``'s scalar one)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth, mitsuba_version
    from lbscene.engine.truth.validation import GRIDS, TruthData, booth_files_sha256, write_truth_csv

    folder = HERE / scene
    ir = compile_booth(folder)
    truth = MitsubaTruth(ir, LIGHTING, spp=spp, passes=min_passes, seed=seed, variant=variant)
    for grid in grids or GRIDS:
        P, N = _receivers(ir, grid)
        t0 = time.perf_counter()
        E, se, used = _render_grid(scene, truth, P, N, jobs=jobs, spp=spp, min_passes=min_passes, seed=seed,
                                   target_rel_error=target_rel_error, max_passes=max_passes)
        wall_s = time.perf_counter() - t0
        meta = {
            "scene": scene,
            "grid": grid,
            "renderer": "Mitsuba 3 (lbscene.engine.truth.mitsuba.MitsubaTruth, path integrator, max_depth -1)",
            "mitsuba_version": mitsuba_version(),
            "variant": truth.variant,
            "spp_per_pass": spp,
            "passes": f"min {min_passes}, max {max_passes}, until std_error <= {target_rel_error:g} x value",
            "seed": seed,
            "lighting": LIGHTING,
            "effects": json.dumps(truth.effects, sort_keys=True),
            "receivers": "facing +z, ideal cosine response",
            "booth_sha256": booth_files_sha256(folder),
            "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        }
        write_truth_csv(truth_path(scene, grid),
                        TruthData(P, N, E, se, used, meta))
        rel = se / E
        log(f"{scene:16s} {grid:5s} {len(P):3d} points  {wall_s:7.0f} s  passes {used.min()}-"
            f"{used.max()}  std error max {100 * rel.max():.3f} %  RMS {100 * np.sqrt(np.mean(rel ** 2)):.3f} %")


def _spread_indices(n: int, k: int) -> np.ndarray:
    """``k`` receivers spread over a grid of ``n`` (first, last, evenly between)."""
    return np.unique(np.round(np.linspace(0, n - 1, k)).astype(int))


def check_scene(scene: str, grids=None, *, points: int = 2, spp: int = SPP_PER_PASS,
                target_rel_error: float = 0.005, min_passes: int = MIN_PASSES, max_passes: int = 256,
                seed: int = CHECK_SEED) -> list[dict]:
    """Re-render ``points`` receivers of each grid with fresh seeds; one row per receiver:
    ``scene, grid, index, csv_lx, csv_se_lx, new_lx, new_se_lx, z`` (the difference in combined
    standard errors) and ``agree`` (``|z| <= 4``).

    Raises ``FileNotFoundError`` for a missing truth and ``ValueError`` for a booth edited
    since its truth was rendered."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth
    from lbscene.engine.truth.validation import GRIDS, booth_files_sha256, read_truth_csv

    folder = HERE / scene
    sha = booth_files_sha256(folder)
    ir = compile_booth(folder)
    rows = []
    for g, grid in enumerate(grids or grids_of(scene)):
        if grid not in grids_of(scene):
            continue
        path = truth_path(scene, grid)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no truth rendered; run render_truth.py {scene}")
        t = read_truth_csv(path)
        # own seeds per grid: the grids share receivers (the floor's centre is the sheet's); always
        # the scalar variant, whichever variant rendered the CSV (a check across variants)
        truth = MitsubaTruth(ir, LIGHTING, spp=spp, passes=min_passes, seed=seed + 997 * g)
        if t.meta.get("booth_sha256") != sha:
            raise ValueError(f"{path}: the booth changed after its truth was rendered; "
                             f"run render_truth.py {scene}")
        idx = _spread_indices(len(t.points_mm), points)
        res = truth.illuminance_with_error_lx(t.points_mm[idx], t.normals[idx],
                                              target_rel_error=target_rel_error, max_passes=max_passes)
        for j, i in enumerate(idx):
            se = float(np.hypot(res.std_error_lx[j], t.std_error_lx[i]))
            z = float((res.illuminance_lx[j] - t.illuminance_lx[i]) / se)
            rows.append({"scene": scene, "grid": grid, "index": int(i),
                         "csv_lx": float(t.illuminance_lx[i]), "csv_se_lx": float(t.std_error_lx[i]),
                         "new_lx": float(res.illuminance_lx[j]), "new_se_lx": float(res.std_error_lx[j]),
                         "z": z, "agree": abs(z) <= CHECK_K_SIGMA})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", metavar="SCENE", help=f"scenes (default all: {', '.join(SCENES)})")
    ap.add_argument("--grids", nargs="+", choices=("a3", "floor"), default=None, help="grids (default both)")
    ap.add_argument("--spp", type=int, default=SPP_PER_PASS, help="samples per pass (at most 65536)")
    ap.add_argument("--target-rel-error", type=float, default=None,
                    help=f"standard error per receiver, fraction of its value (default {TARGET_REL_ERROR}; "
                         "--check: 0.005)")
    ap.add_argument("--min-passes", type=int, default=MIN_PASSES)
    ap.add_argument("--max-passes", type=int, default=None,
                    help=f"default {MAX_PASSES} (--check: 256)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="processes per grid (the rendered values do not depend on it)")
    ap.add_argument("--variant", choices=("scalar_spectral", "llvm_ad_spectral"), default=None,
                    help="Mitsuba variant (default scalar_spectral; llvm_ad_spectral: the same path tracer "
                         "vectorised, for the opal scenes; needs libLLVM, DRJIT_LIBLLVM_PATH)")
    ap.add_argument("--check", action="store_true",
                    help="re-render a few receivers per grid with fresh seeds and compare with the CSVs")
    ap.add_argument("--points", type=int, default=2, help="--check: receivers per grid")
    ap.add_argument("--json", action="store_true", help="--check: print the rows as JSON")
    args = ap.parse_args(argv)
    unknown = [s for s in args.scenes if s not in SCENES]
    if unknown:
        ap.error(f"unknown scene(s) {unknown}; known: {list(SCENES)}")
    scenes = args.scenes or list(SCENES)
    if not args.check:
        for s in scenes:
            render_scene(s, args.grids, spp=args.spp,
                         target_rel_error=args.target_rel_error or TARGET_REL_ERROR,
                         min_passes=args.min_passes, max_passes=args.max_passes or MAX_PASSES,
                         jobs=args.jobs, variant=args.variant)
        return 0
    rows = []
    try:
        for s in scenes:
            rows += check_scene(s, args.grids, points=args.points, spp=args.spp,
                                target_rel_error=args.target_rel_error or 0.005, min_passes=args.min_passes,
                                max_passes=args.max_passes or 256)
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(f"{'scene':16s} {'grid':5s} {'point':>5s} {'csv lx':>10s} {'± lx':>7s} {'new lx':>10s} {'± lx':>7s} "
              f"{'z':>6s}  agree (|z| <= {CHECK_K_SIGMA:g})")
        for r in rows:
            print(f"{r['scene']:16s} {r['grid']:5s} {r['index']:5d} {r['csv_lx']:10.2f} {r['csv_se_lx']:7.2f} "
                  f"{r['new_lx']:10.2f} {r['new_se_lx']:7.2f} {r['z']:6.2f}  {'yes' if r['agree'] else 'NO'}")
    return 0 if all(r["agree"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
