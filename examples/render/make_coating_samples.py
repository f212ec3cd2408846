"""Write the three example effect-coating samples (synthetic, not measurements).

    .venv/bin/python examples/render/make_coating_samples.py

Each coating is made from declared flake parameters (density, diameter, orientation spread,
flake reflectance) and a declared base reflectance, by physics that is *not* the flop model
lbscene fits to the result:

* reflectance factors at the six BYK-mac i geometries (45° illumination; aspecular −15°, 15°,
  25°, 45°, 75°, 110°), 400–700 nm in 10 nm steps: the base (Lambertian, under the clear coat,
  Fresnel in and out) plus the flakes' mean lobe with their Beckmann orientation distribution
  (``FlakeModel.mean_reflectance_factor``), plus a broader Beckmann lobe for the light the flakes
  scatter more than once (``MULTIPLE_SCATTER`` of the flake lobe, α = 0.45), plus seeded
  reading noise (0.3 % relative, 0.0005 absolute);
* sparkle area and intensity at 15°, 45°, 75° and graininess: the mean of 8 runs of lbscene's
  simulated texture instrument (``engine/coatings/instrument.py``) with other seeds than the
  fit's, rounded to 3 significant digits (fine and coarse silver: ``texture: {type: measured}``).
  The blue pearl declares its flakes directly (``texture: {type: flakes}``).

The flake parameters are plausible for the coating types (aluminium "silver dollar" flakes of
about 10–15 µm for a fine and 25–35 µm for a coarse silver; mica pearl flakes of about 15 µm
with a blue interference colour), chosen for this example; the numbers in the files are what
lbscene's instrument model gives for them, not readings of real panels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lbscene.engine.coatings.colorimetry import luminance_weights
from lbscene.engine.coatings.flakes import FlakeModel
from lbscene.engine.coatings.instrument import texture_metrics
from lbscene.engine.coatings.optics import BYK_ASPECULAR_DEG, fresnel_transmittance, geometry_directions
from lbscene.engine.spectra.bands import DEFAULT_GRID

HERE = Path(__file__).resolve().parent
WL_NM = np.arange(400.0, 701.0, 10.0)
N_COAT = 1.5
MULTIPLE_SCATTER = 0.15
SEEDS = range(101, 109)


def _gauss(wl, centre, width):
    return np.exp(-0.5 * ((wl - centre) / width) ** 2)


COATINGS = {
    "fine-silver": {
        "name": "Fine silver metallic (synthetic)",
        "flakes": dict(density_per_mm2=3000.0, median_diameter_um=12.0, diameter_spread=0.35,
                       spread_deg=10.0),
        "flake_reflectance": lambda wl: 0.88 + 0.02 * (wl - 400) / 300,
        "base": lambda wl: 0.045 + 0.004 * (wl - 400) / 300,
        "texture": "measured",
        "gloss_GU": 90,
    },
    "coarse-silver": {
        "name": "Coarse silver metallic (synthetic)",
        "flakes": dict(density_per_mm2=450.0, median_diameter_um=30.0, diameter_spread=0.35,
                       spread_deg=14.0),
        "flake_reflectance": lambda wl: 0.88 + 0.02 * (wl - 400) / 300,
        "base": lambda wl: 0.05 + 0.004 * (wl - 400) / 300,
        "texture": "measured",
        "gloss_GU": 88,
    },
    "blue-pearl": {
        "name": "Blue pearl (synthetic)",
        "flakes": dict(density_per_mm2=1500.0, median_diameter_um=15.0, diameter_spread=0.40,
                       spread_deg=12.0),
        # TiO2-on-mica interference blue: reflects blue, transmits (to the base) the rest
        "flake_reflectance": lambda wl: 0.08 + 0.45 * _gauss(wl, 455.0, 45.0),
        # blue base pigment
        "base": lambda wl: 0.03 + 0.30 * _gauss(wl, 460.0, 40.0) + 0.02 * _gauss(wl, 690.0, 40.0),
        "texture": "flakes",
        "gloss_GU": 92,
    },
}


def reflectance_factors(spec, rng) -> np.ndarray:
    """(6, len(WL_NM)) reflectance factors at the BYK geometries."""
    f = spec["flakes"]
    rho = spec["flake_reflectance"](WL_NM)
    model = FlakeModel.from_spread_deg(f["density_per_mm2"], f["median_diameter_um"],
                                       f["diameter_spread"], f["spread_deg"], rho, N_COAT)
    broad = FlakeModel(model.density_per_mm2, model.median_diameter_um, model.diameter_spread, 0.45,
                       rho * MULTIPLE_SCATTER, N_COAT)
    l, v = geometry_directions(45.0, np.asarray(BYK_ASPECULAR_DEG))
    t = fresnel_transmittance(l[:, 2], N_COAT) * fresnel_transmittance(v[:, 2], N_COAT) / N_COAT ** 2
    r = (t[:, None] * spec["base"](WL_NM)[None, :] + model.mean_reflectance_factor(l, v)
         + broad.mean_reflectance_factor(l, v))
    noise = 1.0 + 0.003 * rng.standard_normal(r.shape)
    return np.round(np.clip(r * noise + 0.0005 * rng.standard_normal(r.shape), 0.0, None), 4)


def texture_readings(spec) -> dict:
    f = spec["flakes"]
    grid_rho = np.interp(DEFAULT_GRID.centres_nm, WL_NM, spec["flake_reflectance"](WL_NM))
    grid_base = np.interp(DEFAULT_GRID.centres_nm, WL_NM, spec["base"](WL_NM))
    w = luminance_weights()
    model = FlakeModel.from_spread_deg(f["density_per_mm2"], f["median_diameter_um"],
                                       f["diameter_spread"], f["spread_deg"], grid_rho, N_COAT)
    runs = [texture_metrics(model, float(grid_base @ w), seed=s, flake_reflectance=float(grid_rho @ w))
            for s in SEEDS]
    sig = lambda x: float(f"{x:.3g}")  # noqa: E731
    return {"sparkle": [(a, sig(np.mean([r.sparkle[a][0] for r in runs])),
                         sig(np.mean([r.sparkle[a][1] for r in runs]))) for a in (15.0, 45.0, 75.0)],
            "graininess": sig(np.mean([r.graininess for r in runs]))}


def _inline(values) -> str:
    return ("{type: inline, wavelengths_nm: [" + ", ".join(f"{w:g}" for w in WL_NM) + "],\n"
            "                values: [" + ", ".join(f"{x:.4f}" for x in values) + "]}")


def _spec_line(values) -> str:
    return ("{type: inline, wavelengths_nm: [" + ", ".join(f"{w:g}" for w in WL_NM) + "], values: ["
            + ", ".join(f"{x:.4f}" for x in values) + "]}")


def write(key: str, spec: dict, rng) -> Path:
    r = reflectance_factors(spec, rng)
    f = spec["flakes"]
    rho = spec["flake_reflectance"](WL_NM)
    lines = [
        "# yaml-language-server: $schema=../../schemas/json/sample.schema.json",
        f"# {spec['name']}: SYNTHETIC data written by make_coating_samples.py (see its docstring for",
        "# how every number was made); an effect coating as a BYK-mac i style instrument reports it.",
        "version: 1",
        "kind: sample",
        f"name: {spec['name']}",
        "provenance:",
        "  status: synthetic",
        "  source: examples/render/make_coating_samples.py",
        "  notes: >-",
        f"    Made from flakes of density {f['density_per_mm2']:g}/mm², median diameter "
        f"{f['median_diameter_um']:g} µm (ln-σ {f['diameter_spread']:g}), orientation spread "
        f"{f['spread_deg']:g}°, under a clear coat n = {N_COAT:g}, over a Lambertian base. "
        "Reflectance factors: the flakes' mean Beckmann lobe, a broader lobe for multiply "
        "scattered light and the base, with 0.3 % reading noise. "
        + ("Sparkle and graininess: the mean of 8 runs of lbscene's texture instrument "
           "simulation (other seeds than the fit's), rounded to 3 significant digits."
           if spec["texture"] == "measured" else "The flakes are declared directly."),
        'instrument: "synthetic (BYK-mac i geometries and texture readings)"',
        "size_mm: [100, 85]",
        f"gloss_GU: {spec['gloss_GU']}",
        "roughness: 0.06",
        "by_geometry:",
    ]
    for asp, row in zip(BYK_ASPECULAR_DEG, r):
        lines.append(f"  - geometry: 45as{asp:g}")
        lines.append(f"    reflectance: {_inline(row)}")
    lines += ["effect_coating:", f"  clear_coat: {{refractive_index: {N_COAT:g}, thickness_um: 40}}",
              "  flop: {lobes: 2}", "  texture:"]
    if spec["texture"] == "measured":
        t = texture_readings(spec)
        lines += ["    type: measured", '    instrument: "lbscene texture instrument (simulated)"',
                  "    sparkle:"]
        for a, s_a, s_i in t["sparkle"]:
            lines.append(f"      - {{illumination_deg: {a:g}, area: {s_a:g}, intensity: {s_i:g}}}")
        lines.append(f"    graininess: {t['graininess']:g}")
        lines.append(f"    diameter_spread: {f['diameter_spread']:g}")
        lines.append(f"    flake_reflectance: {_spec_line(rho)}")
    else:
        lines += ["    type: flakes", f"    density_per_mm2: {f['density_per_mm2']:g}",
                  f"    diameter: {{median_um: {f['median_diameter_um']:g}, spread: {f['diameter_spread']:g}}}",
                  f"    orientation_spread_deg: {f['spread_deg']:g}",
                  f"    flake_reflectance: {_spec_line(rho)}"]
    path = HERE / f"sample-coating-{key}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def main() -> None:
    rng = np.random.default_rng(2025)
    for key, spec in COATINGS.items():
        print("wrote", write(key, spec, rng).relative_to(HERE.parents[1]))


if __name__ == "__main__":
    main()
