"""Render the Mitsuba truth of the diagnosis scenes in this folder (committed as data).

The diagnosis tests (``tests/engine/test_diagnosis_on_truth.py``) read the illuminance of the
validation scenes (``tests/data/validation``) and of the scenes here, add seeded meter noise,
and hand the tool a booth file from which the hidden physics was removed.  A scene here is a
booth folder whose ``effects:`` lists exactly the physics its truth includes; this script writes

* ``truth-a3.csv``: illuminance on the 55-point A3 sheet with its Monte Carlo standard error
  (:func:`lbscene.engine.truth.validation.write_truth_csv`, with the booth's sha256), and
  ``truth-floor.csv`` on the 9 × 7 floor grid for the scenes of :data:`FLOOR_SCENES`;
* ``truth-tile.csv``: the radiance of an ideal white Lambertian tile (reflectance 1) at the
  sample position, as 5 nm bin means over 380–780 nm (a spectroradiometer's output), with its
  standard error: :math:`L_b = \\frac{1}{π}\\,\\overline{E}_b`.

Run (a few minutes per scene on 2 cores)::

    nice -n 10 .venv/bin/python tests/data/diagnosis/render_cases.py [SCENE ...]

``--variant llvm_ad_spectral`` renders with Mitsuba's vectorised CPU variant (the same spectral
path tracer, several times faster; needs libLLVM 16 or later, e.g.
``DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENES = ("filter-dip", "lamp-shift", "filter-narrow", "filter-broad", "lamp-aged")
#: scenes whose truth includes the floor grid too
FLOOR_SCENES = ("filter-narrow", "filter-broad", "lamp-aged")
LIGHTING = "L"
SPP_PER_PASS = 65536
TARGET_REL_ERROR = 0.002
TILE_TARGET_REL_ERROR = 0.003
MIN_PASSES = 4
MAX_PASSES = 256
TILE_BIN_NM = 5.0


def render_tile(truth, ir) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """White-tile radiance (W·sr⁻¹·m⁻²·nm⁻¹) in 5 nm bins: centres, means, standard errors."""
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    edges = np.arange(380.0, 780.0 + TILE_BIN_NM, TILE_BIN_NM)
    bands = {}
    for k in range(len(edges) - 1):
        w = ((WL > edges[k]) & (WL < edges[k + 1])).astype(float)
        w[(WL == edges[k]) | (WL == edges[k + 1])] = 0.5
        bands[f"b{k:03d}"] = w
    P = np.asarray([ir.sample_position_mm], float)
    N = np.array([[0.0, 0.0, 1.0]])
    # E_b = π ∫ L dλ / Δλ on the white disc; the tile's radiance is E_b / π
    m, s, _ = truth._render(P, N, bands, 1.0 / TILE_BIN_NM, TILE_TARGET_REL_ERROR, MAX_PASSES)
    return 0.5 * (edges[:-1] + edges[1:]), m[0], s[0]


def render_scene(scene: str, variant: str | None = None) -> None:
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth, mitsuba_version
    from lbscene.engine.truth.validation import booth_files_sha256, render_truth_grid

    folder = HERE / scene
    ir = compile_booth(folder / "booth.yaml")
    truth = MitsubaTruth(ir, LIGHTING, spp=SPP_PER_PASS, passes=MIN_PASSES, seed=1, variant=variant)
    meta = {"scene": scene, "renderer": "Mitsuba 3 (lbscene.engine.truth.mitsuba.MitsubaTruth)",
            "mitsuba_version": mitsuba_version(), "variant": truth.variant, "lighting": LIGHTING,
            "effects": ",".join(sorted(ir.effects)), "booth_sha256": booth_files_sha256(folder)}
    for grid in ("a3", "floor") if scene in FLOOR_SCENES else ("a3",):
        t0 = time.perf_counter()
        render_truth_grid(truth, ir, grid, folder / f"truth-{grid}.csv", meta,
                          target_rel_error=TARGET_REL_ERROR, max_passes=MAX_PASSES)
        print(f"{scene} {grid}: {time.perf_counter() - t0:.0f} s", flush=True)
    t0 = time.perf_counter()
    wl, L, se = render_tile(truth, ir)
    lines = [f"# {k}: {v}" for k, v in {**meta, "receiver": "white tile, reflectance 1"}.items()]
    lines.append("wavelength_nm,radiance_W_sr_m2_nm,std_error")
    lines += [f"{a:g},{b:.7g},{c:.3g}" for a, b, c in zip(wl, L, se)]
    tmp = folder / "truth-tile.csv.tmp"
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(folder / "truth-tile.csv")
    print(f"{scene} tile: {time.perf_counter() - t0:.0f} s, max rel. error "
          f"{100 * np.max(se / np.maximum(L, 1e-30)):.2f} %", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--variant", choices=("scalar_spectral", "llvm_ad_spectral"),
                    help="Mitsuba variant (default: the scalar one)")
    a = ap.parse_args(argv)
    for s in a.scenes:
        render_scene(s, a.variant)
    return 0


if __name__ == "__main__":
    sys.exit(main())
