"""Tables of the effect-coating models against their references.

Run:  .venv/bin/python benchmarks/coating_table.py [--json]

1. Colour flop: each geometry of the three example coatings predicted from the other five (the
   flop BRDF refitted without it), ΔE00 (CIE 2000, D65, 10°) against the reading; Beckmann
   (Cook–Torrance) and GGX lobes; and the repository's older gonio-apparent example, whose
   reflectances come from a made-up curve rather than flakes.
2. Texture fit: the readings lbscene's instrument model gives for the fitted flakes (another seed
   than the fit's) against the sample file's readings, relative difference.
3. Flakes against Mitsuba 3's explicit flakes (the committed reference,
   ``tests/data/coatings/flake-truth.json``): S_a, S_i, total glint flux, glints above a flux of
   200, upper quartile of the glint flux, per illumination angle; the lamp-size test; graininess.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
EXAMPLES = REPO / "examples" / "render"


def _sample(path):
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    return SampleSpec.from_document(load_document(path, Sample))


def flop_rows() -> list[dict]:
    from lbscene.engine.coatings.flop import MeasuredGeometry, leave_one_out
    from lbscene.engine.spectra.bands import DEFAULT_GRID

    rows = []
    files = [EXAMPLES / f"sample-coating-{n}.yaml" for n in ("fine-silver", "coarse-silver", "blue-pearl")]
    files.append(EXAMPLES / "sample-gonio-blue-metallic.yaml")
    for f in files:
        sp = _sample(f)
        meas = [MeasuredGeometry(45.0, a, DEFAULT_GRID.integrate(r)) for a, _, r in sp.geometries]
        for dist in ("beckmann", "ggx"):
            loo = leave_one_out(meas, lobes=2, distribution=dist)
            rows.append({"sample": sp.name, "lobes": f"2 {dist}",
                         "delta_e00": {f"{r['aspecular_deg']:g}": round(r["delta_e00"], 2) for r in loo},
                         "mean": round(float(np.mean([r["delta_e00"] for r in loo])), 2),
                         "max": round(float(np.max([r["delta_e00"] for r in loo])), 2)})
    return rows


def texture_rows() -> list[dict]:
    from lbscene.engine.coatings.model import coating_appearance

    out = []
    for n in ("fine-silver", "coarse-silver"):
        sp = _sample(EXAMPLES / f"sample-coating-{n}.yaml")
        c = coating_appearance(sp)
        for a in sorted(c.readings.sparkle):
            for k, what in ((0, "S_a"), (1, "S_i")):
                t, r = c.readings.sparkle[a][k], c.predicted.sparkle[a][k]
                out.append({"sample": sp.name, "reading": f"{what}({a:g}°)", "input": t, "recovered": round(r, 4),
                            "relative": round(r / t - 1, 4)})
        out.append({"sample": sp.name, "reading": "G", "input": c.readings.graininess,
                    "recovered": round(c.predicted.graininess, 4),
                    "relative": round(c.predicted.graininess / c.readings.graininess - 1, 4)})
        f = c.flakes
        out.append({"sample": sp.name, "reading": "flakes", "input": None,
                    "recovered": f"{f.density_per_mm2:.0f}/mm², d50 {f.median_diameter_um:.1f} µm, "
                                 f"spread {f.orientation_spread_deg:.1f}°", "relative": None})
    return out


def mitsuba_rows() -> dict:
    from lbscene.engine.coatings.instrument import (FlakePool, GlintPool, analyse_graininess,
                                                    dense_sparkle_image, diffuse_image)
    from lbscene.engine.coatings.mitsuba_flakes import glint_statistics, truth_flake_model

    truth = json.loads((REPO / "tests" / "data" / "coatings" / "flake-truth.json").read_text())
    c = truth["config"]
    m = truth_flake_model(c)

    def lb(a, half):
        return [glint_statistics(dense_sparkle_image(m, 0.0, a, GlintPool(s), c["flake_reflectance"], c["field_mm"],
                                                     half)) for s in (1, 2, 3)]

    rows = []
    for a in c["angles_deg"]:
        mi, st = truth["sparkle"][f"{a:g}"], lb(a, c["half_angle_deg"])
        fl = np.concatenate([s["flux"] for s in st])
        mif = np.asarray(mi["flux"])
        rows.append({"angle_deg": a,
                     "S_a": (mi["S_a"], round(float(np.mean([s["S_a"] for s in st])), 4)),
                     "S_i": (mi["S_i"], round(float(np.mean([s["S_i"] for s in st])), 3)),
                     "total_flux": (mi["total_flux"], round(float(fl.sum() / 3), 1)),
                     "glints_above_200": (int((mif > 200).sum()), round(float((fl > 200).sum() / 3), 1)),
                     "flux_p75": (round(float(np.percentile(mif, 75)), 1), round(float(np.percentile(fl, 75)), 1))})
    ext, comp = truth["sparkle"][f"{c['compact_angle_deg']:g}"], truth["compact"]
    d_e, d_c = np.radians(c["half_angle_deg"]), np.radians(c["compact_half_angle_deg"])
    mie, mic = np.asarray(ext["flux"]), np.asarray(comp["flux"])
    lamp = {"count_ratio": (round(float((mie > 0.3 * np.median(mie)).sum() / (mic > 0.3 * np.median(mic)).sum()), 2),
                            round(float((1 - np.cos(d_e)) / (1 - np.cos(d_c))), 2)),
            "flux_p75_ratio": (round(float(np.percentile(mic, 75) / np.percentile(mie, 75)), 2),
                               round(float(np.sin(d_e) ** 2 / np.sin(d_c) ** 2), 2))}
    g = float(np.mean([analyse_graininess(diffuse_image(m, c["base_reflectance"], FlakePool(s), c["flake_reflectance"],
                                                        c["diffuse_field_mm"], 0.0)) for s in (1, 2, 3)]))
    mean = float(diffuse_image(m, c["base_reflectance"], FlakePool(1), c["flake_reflectance"], c["diffuse_field_mm"],
                               0.0).mean())
    return {"mitsuba": truth["mitsuba"], "sparkle": rows, "lamp_size": lamp,
            "graininess": (truth["diffuse"]["graininess"], round(g, 2)),
            "diffuse_mean": (truth["diffuse"]["mean"], round(mean, 4))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    out = {"flop_leave_one_out": flop_rows(), "texture_fit": texture_rows(), "mitsuba": mitsuba_rows()}
    if a.json:
        print(json.dumps(out, indent=1, ensure_ascii=False))
        return 0
    print("1. Flop: leave-one-geometry-out ΔE00 (D65, 10°)")
    print(f"{'sample':<42} {'lobes':<12} " + " ".join(f"{g:>6}" for g in ("-15", "15", "25", "45", "75", "110"))
          + "   mean    max")
    for r in out["flop_leave_one_out"]:
        print(f"{r['sample']:<42} {r['lobes']:<12} " + " ".join(f"{v:>6.2f}" for v in r["delta_e00"].values())
              + f" {r['mean']:>6.2f} {r['max']:>6.2f}")
    print("\n2. Texture fit: readings of the fitted flakes (instrument model, another seed) vs the file's")
    for r in out["texture_fit"]:
        if r["input"] is None:
            print(f"   {r['sample']:<40} fitted flakes: {r['recovered']}")
        else:
            print(f"   {r['sample']:<40} {r['reading']:<10} input {r['input']:>8g}  recovered {r['recovered']:>9.4g}"
                  f"  {100 * r['relative']:+6.1f} %")
    m = out["mitsuba"]
    print(f"\n3. Flake model vs Mitsuba {m['mitsuba']} explicit flakes (Mitsuba, lbscene mean of 3 fields)")
    for r in m["sparkle"]:
        print(f"   {r['angle_deg']:>4g}°  " + "  ".join(f"{k} {v[0]:g} / {v[1]:g}" for k, v in r.items()
                                                     if k != "angle_deg"))
    print(f"   lamp 2.5° vs 1.0° at 45°: glint count ratio {m['lamp_size']['count_ratio'][0]} (closed form "
          f"{m['lamp_size']['count_ratio'][1]}), flux ratio {m['lamp_size']['flux_p75_ratio'][0]} (closed form "
          f"{m['lamp_size']['flux_p75_ratio'][1]})")
    print(f"   graininess G {m['graininess'][0]} / {m['graininess'][1]}; diffuse mean {m['diffuse_mean'][0]} / "
          f"{m['diffuse_mean'][1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
