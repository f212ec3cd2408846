"""Benchmark: colour accuracy and speed of the colour module (issue 4).

Run: .venv/bin/python benchmarks/bench_colour.py [--repeat 3] [--quick]

Prints five tables:

1. Band weighting vs the 1 nm reference (360–830 nm, CIE 1931 2°, ColorChecker N Ohta, 24
   patches): ΔE00 mean/max of point sampling, the naive box, illuminant×CMF weights and the
   projection, per lighting (CIE D65, A, F2, F7, F11, measured TL84, every shipped booth lighting).
2. The projection when the light reaching the sample is changed in band space afterwards
   (inter-reflection off coloured/grey walls, filters): worst mean/max ΔE00.
3. Display round trips: float, 8-bit nearest, 8-bit blue-noise dithered; out-of-gamut counts.
4. Banding on a smooth gradient: nearest rounding vs white-noise vs blue-noise dithering.
5. Timings, each with the baseline it is compared with, measured in the same run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _timing import best_of  # noqa: E402  (benchmarks/ is the script's folder)


def mm(a) -> str:
    a = np.asarray(a)
    return f"{a.mean():.3f}/{a.max():.3f}" if a.max() >= 1e-3 else f"{a.mean():.0e}/{a.max():.0e}"


def table_band(lightings, refl):
    from lbscene.engine.colour.accuracy import BAND_METHODS, band_delta_e00

    print("\n1. Band weighting vs 1 nm (ΔE00 mean/max over 24 patches); target projected <= 0.1/0.3")
    w = max(len(k) for k in lightings)
    print(f"{'lighting':{w}s} " + " ".join(f"{m:>15s}" for m in BAND_METHODS))
    for label, s in lightings.items():
        print(f"{label:{w}s} " + " ".join(f"{mm(band_delta_e00(m, refl, s)):>15s}"
                                          for m in BAND_METHODS))


def table_changed_light(lightings, refl):
    from lbscene.engine.colour.accuracy import delta_e00, xyz_to_lab
    from lbscene.engine.colour.band_weighting import BandWeighting, reference_xyz
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL, to_reference

    def csv(p):
        rows = [r.split(",") for r in Path(p).read_text().splitlines()[1:] if r.strip()]
        return to_reference([float(r[0]) for r in rows], [float(r[1]) for r in rows],
                            extrapolate="constant")

    def planck(t):
        x = WL * 1e-9
        return 1 / (x ** 5 * (np.exp(1.4388e-2 / (x * t)) - 1))

    spectra = REPO / "booths/xrite-spectralight-qc/spectra"
    grey = csv(spectra / "grey_n7.csv")
    ctb = planck(5500) / planck(3200)
    cases = {"walls k=0.3": [("wall", 0.3, refl[i]) for i in range(24)],
             "walls k=0.5": [("wall", 0.5, refl[i]) for i in range(24)],
             "walls k=0.7": [("wall", 0.7, refl[i]) for i in range(24)],
             "grey N7 k=0.9": [("wall", 0.9, grey)],
             "diffuser": [("filter", 0, csv(spectra / "glass_diffuser.csv"))],
             "1/2 CTB": [("filter", 0, np.sqrt(ctb) / np.sqrt(ctb).max())],
             "full CTB": [("filter", 0, ctb / ctb.max())],
             "full CTO": [("filter", 0, (1 / ctb) / (1 / ctb).max())]}
    print("\n2. Changed light applied in band space after projecting for the bare lamp "
          "(worst mean/max ΔE00 over the cases)")
    w = max(len(k) for k in lightings)
    print(f"{'lighting':{w}s} " + " ".join(f"{c:>13s}" for c in cases))
    for label, s in lightings.items():
        bw = BandWeighting.for_light(s)
        r = bw.project(refl)
        cells = []
        for case in cases.values():
            worst_mean = worst_max = 0.0
            for kind, k, spec in case:
                if kind == "wall":
                    e = bw.illuminant_bands / (1 - k * bw.project(spec))
                    true = s / (1 - k * spec)
                else:
                    e = bw.illuminant_bands * bw.project(spec)
                    true = s * spec
                ref = xyz_to_lab(reference_xyz(refl, true), reference_xyz(1.0, true))
                de = delta_e00(xyz_to_lab((e * r) @ bw.weights, e @ bw.weights), ref)
                worst_mean, worst_max = max(worst_mean, de.mean()), max(worst_max, de.max())
            cells.append(f"{worst_mean:.3f}/{worst_max:.3f}")
        print(f"{label:{w}s} " + " ".join(f"{c:>13s}" for c in cells))


def table_display(lightings, refl, displays):
    from lbscene.engine.colour.accuracy import display_round_trip
    from lbscene.engine.colour.band_weighting import reference_xyz

    print("\n3. Display round trip ΔE00 mean/max (in-gamut patches); out of gamut: count (max ΔE00)")
    w = max(len(k) for k in lightings)
    for d in displays:
        print(f"  {d.name}")
        print(f"{'lighting':{w}s} {'float':>15s} {'8-bit nearest':>15s} {'8-bit dithered':>15s} "
              f"{'out of gamut':>14s}")
        for label, s in lightings.items():
            rt = display_round_trip(d, reference_xyz(refl, s), reference_xyz(1.0, s))
            ins = ~rt.out_of_gamut
            cells = [mm(a[ins]) if ins.any() else "-" for a in
                     (rt.float_dE00, rt.nearest_8bit_dE00, rt.dithered_8bit_dE00)]
            print(f"{label:{w}s} {cells[0]:>15s} {cells[1]:>15s} {cells[2]:>15s} "
                  f"{int(rt.out_of_gamut.sum()):>4d} ({rt.gamut_dE00.max():5.2f})")


def table_banding():
    from lbscene.engine.colour.dither import (banding_metrics, blue_noise, dither_quantise,
                                              quantise_nearest, white_noise_mask)

    ramp = np.tile(np.linspace(0.2, 0.25, 1024), (256, 1))
    rows = {"nearest (no dither)": quantise_nearest(ramp),
            "white-noise dither": dither_quantise(ramp, white_noise_mask(64)),
            "blue-noise dither": dither_quantise(ramp, blue_noise(64))}
    print("\n4. Banding: 1024x256 ramp 0.20->0.25 (12.75 codes), errors in 8-bit codes")
    keys = ["strip_mean_error_std_codes", "strip_mean_error_max_codes", "blurred_rms_codes",
            "pixel_rms_codes", "mean_error_codes"]
    print(f"{'method':22s} {'strip-mean std':>15s} {'strip-mean max':>15s} {'blurred rms':>12s} "
          f"{'pixel rms':>10s} {'mean':>9s}")
    for name, codes in rows.items():
        m = banding_metrics(codes, ramp)
        print(f"{name:22s} " + " ".join(f"{m[k]:>{n}.4f}" for k, n in zip(keys, (15, 15, 12, 10, 9))))
    print("  (strip: 8 columns x all rows; blurred: Gaussian sigma 2 px; rounding's pixel rms "
          "is 1/sqrt(12) = 0.2887 in closed form)")


def table_timing(repeat, lights, refl, displays):
    from lbscene.engine.colour import band_weighting as bwm
    from lbscene.engine.colour.dither import _void_and_cluster, blue_noise, dither_quantise
    from lbscene.engine.spectra.bands import DEFAULT_GRID

    print(f"\n5. Timings (best of {repeat}); ratio = time / baseline measured in the same run")
    print(f"{'operation':58s} {'ms':>9s} {'baseline':>44s} {'ratio':>7s}")
    rng = np.random.default_rng(0)
    many = np.clip(refl[rng.integers(0, 24, 100_000)] + rng.normal(0, 0.01, (100_000, 1)), 0, 1)
    s = lights["CIE F11"]

    def fresh_matrix():
        bwm._projection_cached.cache_clear()
        bwm.projection_matrix(s)

    rows = []
    base = best_of(lambda: DEFAULT_GRID.integrate(many), repeat)
    rows.append(("project 100k reflectances (cached matrix)",
                 best_of(lambda: bwm.project_reflectance(many, s), repeat),
                 "band means of the same (grid.integrate)", base))
    base_w = best_of(lambda: bwm.band_xyz_weights(s), repeat)
    rows.append(("projection matrix for a new light (uncached)", best_of(fresh_matrix, repeat),
                 "band_xyz_weights of that light", base_w))
    img = rng.uniform(0.05, 1, (768, 1024, 3))
    for d in displays:
        xyz = d.drive_to_xyz(img)
        fwd = best_of(lambda: d.drive_to_xyz(img), repeat)
        rows.append((f"xyz_to_drive 1024x768 ({d.name[:22]})",
                     best_of(lambda: d.xyz_to_drive(xyz), repeat), "drive_to_xyz of the same", fwd))
    mask = blue_noise(64)
    near = best_of(lambda: dither_quantise(img, None), repeat)
    rows.append(("dither_quantise 1024x768x3 (blue noise 64)",
                 best_of(lambda: dither_quantise(img, mask), repeat), "plain rounding of the same", near))

    def gen(size):
        _void_and_cluster.cache_clear()
        blue_noise(size)

    g32 = best_of(lambda: gen(32), repeat)
    rows.append(("blue_noise(64) void-and-cluster", best_of(lambda: gen(64), repeat),
                 "blue_noise(32)", g32))
    rows.append(("blue_noise(128) void-and-cluster", best_of(lambda: gen(128), 1),
                 "blue_noise(32)", g32))
    for name, t, bname, b in rows:
        print(f"{name:58s} {t * 1e3:9.2f} {bname + f' {b * 1e3:.2f} ms':>44s} {t / b:7.1f}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="CIE lightings only, no booths")
    args = ap.parse_args()
    from lbscene.engine.colour.accuracy import (booth_lighting_spds, cie_lighting_spds,
                                                colorchecker_reflectances)
    from lbscene.engine.colour.display_model import load_display
    from lbscene.engine.scene.compile import compile_booth

    _, refl = colorchecker_reflectances()
    lights = cie_lighting_spds()
    lightings = dict(lights)
    if not args.quick:
        for b in sorted((REPO / "booths").glob("*/booth.yaml")):
            try:
                lightings.update(booth_lighting_spds(compile_booth(b)))
            except Exception as exc:  # a booth in progress must not stop the benchmark
                print(f"note: {b.parent.name} skipped: {exc}")
    displays = [load_display(p) for p in sorted((REPO / "displays").glob("*.yaml"))]
    table_band(lightings, refl)
    table_changed_light(lights, refl)
    table_display(lightings, refl, displays)
    table_banding()
    table_timing(args.repeat, lights, refl, displays)
    return 0


if __name__ == "__main__":
    sys.exit(main())
