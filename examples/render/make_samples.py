"""Write the sample documents of examples/render/ (run from the repository root).

    .venv/bin/python examples/render/make_samples.py

* ColorChecker patches: reflectances of colour-science's "ColorChecker N Ohta" dataset
  (N. Ohta, 1997), every 10 nm from 380 to 780 nm, written inline.
* A gonio-apparent blue metallic: SYNTHETIC (made up here, for demonstrations): a reflectance
  factor per geometry of the six multi-angle geometries, bright and greenish-blue near the
  specular direction (45as-15 exceeds 1, as effect coatings do), dark and violet-blue at the flop
  (45as110).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
HEADER = "# yaml-language-server: $schema=../../schemas/json/sample.schema.json\n"
WL = np.arange(380.0, 781.0, 10.0)


def _spectrum(values) -> str:
    vals = ", ".join(f"{v:.4f}" for v in values)
    return (f"{{type: inline, wavelengths_nm: [{', '.join(f'{w:g}' for w in WL)}],\n"
            f"                values: [{vals}]}}")


def colorchecker(patch: str, file: str, gloss_GU: float = 0.0, roughness: float = 0.1,
                 note: str = "") -> None:
    import colour

    sd = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][patch]
    vals = np.interp(WL, sd.wavelengths, sd.values)
    text = HEADER + f"""# ColorChecker patch "{patch}" ({'glossy' if gloss_GU else 'matte'}); reflectance from
# colour-science's "ColorChecker N Ohta" dataset.{(' ' + note) if note else ''}
version: 1
kind: sample
name: ColorChecker {patch}{' (glossy)' if gloss_GU else ''}
provenance:
  status: published
  source: "N. Ohta (1997), ColorChecker spectral reflectances, via colour-science SDS_COLOURCHECKERS"
  notes: "gloss_GU and roughness are assumptions of this example"
size_mm: [100, 85]
reflectance: {_spectrum(vals)}
gloss_GU: {gloss_GU:g}
roughness: {roughness:g}
"""
    (HERE / file).write_text(text)


def gonio_blue(file: str) -> None:
    # lightness flop and a hue shift with the aspecular angle (synthetic, plausible magnitudes)
    geoms = {"45as-15": (2.10, 478.0), "45as15": (1.35, 472.0), "45as25": (0.95, 468.0),
             "45as45": (0.48, 462.0), "45as75": (0.24, 456.0), "45as110": (0.16, 452.0)}
    lines = []
    for g, (level, peak) in geoms.items():
        blue = np.exp(-0.5 * ((WL - peak) / 38.0) ** 2)
        vals = 0.02 + level * (0.08 + 0.55 * blue + 0.06 * (WL > 620) * (WL - 620) / 160)
        lines.append(f"  - geometry: {g}\n    reflectance: {_spectrum(vals)}")
    text = HEADER + """# A gonio-apparent blue metallic: SYNTHETIC reflectance factors at the six multi-angle
# geometries (made up for this example by make_samples.py, not a measurement). The renderer
# interpolates between them by the aspecular angle seen at each pixel.
version: 1
kind: sample
name: Blue metallic (synthetic, gonio-apparent)
provenance:
  status: synthetic
  source: "examples/render/make_samples.py"
instrument: "synthetic (BYK-mac i geometries)"
size_mm: [100, 85]
by_geometry:
""" + "\n".join(lines) + """
gloss_GU: 88
roughness: 0.08
"""
    (HERE / file).write_text(text)


if __name__ == "__main__":
    colorchecker("moderate red", "sample-colorchecker-moderate-red.yaml")
    colorchecker("moderate red", "sample-colorchecker-moderate-red-glossy.yaml", gloss_GU=90, roughness=0.08,
                 note="Glossy like the seed's 30 chromatic paints.")
    colorchecker("blue sky", "sample-colorchecker-blue-sky.yaml")
    colorchecker("neutral 5 (.70 D)", "sample-colorchecker-neutral-5.yaml")
    gonio_blue("sample-gonio-blue-metallic.yaml")
    print("wrote", *sorted(p.name for p in HERE.glob("sample-*.yaml")))
