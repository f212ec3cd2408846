"""Make the pictures of the "Effect coatings" documentation page (docs/images/coating-*.png).

    .venv/bin/python scripts/make_coating_images.py        # a few minutes (BYK forward model, renders)

* ``coating-flop.png``: L* of the three example coatings at the six geometries, the fitted flop
  model (curve over the aspecular angle) and each geometry predicted from the other five;
* ``coating-instrument.png``: lbscene's simulated instrument images of the coarse silver
  (sparkle at 15°, 45°, 75°; the diffuse image for graininess), crops of 2 mm;
* ``coating-mitsuba.png``: the glint flux distributions of Mitsuba 3's explicit flakes and of
  lbscene's flake model at 15°, 45°, 75° (the committed reference, tests/data/coatings);
* ``coating-byk.png``: the three coatings rendered in the byko-spectra effect booth at its six
  geometries (realtime runtime, tablet display), cropped to the sample.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "images"
EXAMPLES = REPO / "examples" / "render"
NAMES = ["fine-silver", "coarse-silver", "blue-pearl"]
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def _sample(name):
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    return SampleSpec.from_document(load_document(EXAMPLES / f"sample-coating-{name}.yaml", Sample))


def flop_figure(plt) -> None:
    from lbscene.engine.coatings.colorimetry import lab_bands
    from lbscene.engine.coatings.flop import MeasuredGeometry, fit_flop
    from lbscene.engine.spectra.bands import DEFAULT_GRID

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), sharey=True)
    for ax, name in zip(axes, NAMES):
        sp = _sample(name)
        meas = [MeasuredGeometry(45.0, a, DEFAULT_GRID.integrate(r)) for a, _, r in sp.geometries]
        asp = np.array([m.aspecular_deg for m in meas])
        lab = lab_bands(np.stack([m.bands for m in meas]))
        model = fit_flop(meas, lobes=sp.coating.flop.lobes, distribution=sp.coating.flop.distribution)
        grid = np.linspace(-20, 115, 136)
        curve = lab_bands(model.at_geometry(45.0, grid))
        loo = []
        for j in range(len(meas)):
            m = fit_flop(meas[:j] + meas[j + 1:], lobes=sp.coating.flop.lobes,
                         distribution=sp.coating.flop.distribution)
            loo.append(lab_bands(m.at_geometry(45.0, meas[j].aspecular_deg)).reshape(3))
        ax.plot(grid, curve[:, 0], "-", color="0.3", label="fitted flop model")
        ax.plot(asp, lab[:, 0], "o", color="C0", label="measured (synthetic)")
        ax.plot(asp, np.array(loo)[:, 0], "x", color="C3", label="predicted from the other five")
        ax.set_title(sp.name)
        ax.set_xlabel("aspecular angle (°), illumination 45°")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("L* (D65, 10°)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "coating-flop.png", dpi=90)
    plt.close(fig)


def instrument_figure(plt) -> None:
    from lbscene.engine.coatings.colorimetry import luminance_weights
    from lbscene.engine.coatings.instrument import (FlakePool, GlintPool, dense_sparkle_image, diffuse_image)
    from lbscene.engine.coatings.model import coating_appearance

    sp = _sample("coarse-silver")
    app = coating_appearance(sp)
    rho = float(app.flakes.flake_reflectance @ luminance_weights())
    fig, axes = plt.subplots(1, 4, figsize=(12, 3.3))
    for ax, a in zip(axes[:3], (15.0, 45.0, 75.0)):
        img = dense_sparkle_image(app.flakes, app.base_diffuse_luminance, a, GlintPool(1), rho, field_mm=6.0)
        ax.imshow(np.clip(img[:200, :200] / 50.0, 0, 1), cmap="gray", vmin=0, vmax=1)
        s = app.predicted.sparkle[a]
        ax.set_title(f"directional {a:g}°: S_a {s[0]:.2f}, S_i {s[1]:.1f}", fontsize=9)
        ax.axis("off")
    img = diffuse_image(app.flakes, app.base_diffuse_luminance, FlakePool(1), rho)
    axes[3].imshow(img[:200, :200], cmap="gray")
    axes[3].set_title(f"diffuse: G {app.predicted.graininess:.1f}", fontsize=9)
    axes[3].axis("off")
    fig.suptitle("lbscene's texture instrument, coarse silver (fitted flakes), 2 mm × 2 mm crops", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "coating-instrument.png", dpi=90)
    plt.close(fig)


def mitsuba_figure(plt) -> None:
    from lbscene.engine.coatings.instrument import GlintPool, dense_sparkle_image
    from lbscene.engine.coatings.mitsuba_flakes import glint_statistics, truth_flake_model

    truth = json.loads((REPO / "tests" / "data" / "coatings" / "flake-truth.json").read_text())
    c = truth["config"]
    model = truth_flake_model(c)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, a in zip(axes, c["angles_deg"]):
        mi = np.asarray(truth["sparkle"][f"{a:g}"]["flux"])
        lb = np.concatenate([glint_statistics(dense_sparkle_image(model, 0.0, a, GlintPool(s), c["flake_reflectance"],
                                                                  c["field_mm"], c["half_angle_deg"]))["flux"]
                             for s in (1, 2, 3)])
        bins = np.logspace(1, 4, 31)
        ax.hist(mi, bins=bins, histtype="step", lw=1.5, label=f"Mitsuba 3 ({len(mi)} glints)")
        ax.hist(lb, bins=bins, histtype="step", lw=1.5, weights=np.full(len(lb), 1 / 3),
                label=f"lbscene model ({len(lb) / 3:.0f} per field)")
        ax.set_xscale("log")
        ax.set_xlabel("glint flux (reflectance factor × pixels)")
        ax.set_title(f"illumination {a:g}°, source half-angle {c['half_angle_deg']:g}°", fontsize=9)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("glints per 14 × 14 mm field")
    fig.tight_layout()
    fig.savefig(OUT / "coating-mitsuba.png", dpi=90)
    plt.close(fig)


def byk_figure() -> None:
    from PIL import Image, ImageDraw

    from lbscene.runtimes.render import prepare_from_config

    size = (512, 384)
    rows = []
    for name in NAMES:
        job = prepare_from_config(EXAMPLES / f"byko-coating-{name}.yaml", all_geometries=True, size=size)
        r = job.renderer()
        try:
            tiles = []
            for v in job.views:
                f = r.render(v, size)
                x, y = (int(t) for t in r.sample_pixel(v, size))
                tile = Image.fromarray(f.rgba8[..., :3]).crop((x - 70, y - 52, x + 70, y + 52)).resize((280, 208),
                                                                                                    Image.NEAREST)
                ImageDraw.Draw(tile).text((4, 3), v, fill=(255, 255, 255))
                tiles.append(tile)
        finally:
            r.close()
        rows.append((job.sample.name, tiles))
    out = Image.new("RGB", (6 * 280, 3 * 208 + 3 * 18), (255, 255, 255))
    d = ImageDraw.Draw(out)
    for i, (label, tiles) in enumerate(rows):
        y0 = i * (208 + 18)
        d.text((4, y0 + 3), label, fill=(0, 0, 0))
        for j, t in enumerate(tiles):
            out.paste(t, (j * 280, y0 + 18))
    out.save(OUT / "coating-byk.png", optimize=True)


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    OUT.mkdir(parents=True, exist_ok=True)
    for step in (lambda: flop_figure(plt), lambda: instrument_figure(plt), lambda: mitsuba_figure(plt), byk_figure):
        step()
    for name in ("coating-flop.png", "coating-instrument.png", "coating-mitsuba.png", "coating-byk.png"):
        print("wrote", (OUT / name).relative_to(REPO))
    return 0


if __name__ == "__main__":
    sys.exit(main())
