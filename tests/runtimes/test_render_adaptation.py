"""Chromatic adaptation in the display stage: a neutral grey under illuminant A renders neutral
with ``adaptation: cat16`` (the default: what a person in the booth sees) and orange with
``none`` (what a camera sees).  The expected 8-bit values come from colour-science's own sRGB
encoding and CAT16 (``XYZ_to_sRGB``, ``chromatic_adaptation_VonKries``), not from the shaders."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gl

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

GREY = 0.2
SIZE = (64, 48)
VIEW = "45as0"


@pytest.fixture(scope="module")
def a_booth(tmp_path_factory):
    """The tube test booth (neutral grey walls) with its lamp under CIE illuminant A."""
    d = tmp_path_factory.mktemp("a-booth")
    text = (DATA / "tube-booth" / "booth.yaml").read_text()
    text = text.replace("{type: cie_illuminant, name: D65}", "{type: cie_illuminant, name: A}")
    text = text.replace("  D65: {lamps: [tube]}", "  A: {lamps: [tube]}")
    (d / "tube-booth").mkdir()
    (d / "tube-booth" / "booth.yaml").write_text(text)
    return d


def _grey_pixel(a_booth, ctx, adaptation):
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.graph import build_render_graph
    from lbscene.runtimes.render import Renderer
    from lbscene.engine.scene.sample import SampleSpec

    ir = compile_booth(a_booth / "tube-booth")
    r = Renderer(ir, build_render_graph(ir, "A"), SampleSpec.flat(np.full(471, GREY)), srgb_display(),
                 dither=False, adaptation=adaptation, ctx=ctx)
    try:
        f = r.render(VIEW, SIZE, want_xyz=True)
        x, y = (int(v) for v in r.sample_pixel(VIEW, SIZE))
    finally:
        r.close()
    return f.rgba8[y, x, :3].astype(float), f.xyz[y, x].astype(float), f.info


def _expected_srgb8(xyz_display_units, adapt: bool) -> np.ndarray:
    import colour

    xyz = np.asarray(xyz_display_units, float)
    if adapt:
        w_a = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["A"])
        w_d65 = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
        xyz = colour.adaptation.chromatic_adaptation_VonKries(xyz, w_a, w_d65, transform="CAT16")
    rgb = colour.XYZ_to_sRGB(xyz, chromatic_adaptation_transform=None, apply_cctf_encoding=True)
    return np.clip(rgb, 0, 1) * 255


def test_grey_under_a_is_neutral_when_adapted(a_booth, gl_ctx):
    rgb, xyz, info = _grey_pixel(a_booth, gl_ctx, "cat16")
    # the lighting's white at the sample is illuminant A (neutral walls): x, y = 0.4476, 0.4074
    assert info["adaptation"]["white_xy"] == pytest.approx([0.44758, 0.40745], abs=2e-4)
    assert rgb.max() - rgb.min() <= 1.0, rgb
    want = _expected_srgb8(xyz * info["exposure"] / 80.0, adapt=True)
    assert np.abs(rgb - want).max() <= 1.0, (rgb, want)


def test_grey_under_a_is_orange_without_adaptation(a_booth, gl_ctx):
    rgb, xyz, info = _grey_pixel(a_booth, gl_ctx, "none")
    assert rgb[0] > rgb[1] > rgb[2] and rgb[0] - rgb[2] > 80, rgb
    want = _expected_srgb8(xyz * info["exposure"] / 80.0, adapt=False)
    assert np.abs(rgb - want).max() <= 1.0, (rgb, want)


def test_cli_adaptation_option_json_and_png_metadata(run_cli, a_booth, tmp_path):
    from PIL import Image

    shutil.copy(DATA / "sample-gonio.yaml", a_booth / "sample-gonio.yaml")
    cfg = a_booth / "grey-a.yaml"
    cfg.write_text("version: 1\nkind: render_config\nbooth: tube-booth\nlighting: A\ngeometry: 45as0\n"
                   "sample: sample-gonio.yaml\ndisplay: builtin:srgb\ndiffuse: analytic\n"
                   "output: {png: out.png, width_px: 32, height_px: 24}\n")
    for option, method in ((None, "cat16"), ("none", "none")):
        png = tmp_path / f"{method}.png"
        args = ["render", cfg, "-o", png, "--format", "json"] + (["--adaptation", option] if option else [])
        code, out, err = run_cli(*args)
        assert code == 0, err
        res = json.loads(out)
        assert res["adaptation"]["method"] == method
        assert res["adaptation"]["lighting_white_xy"] == pytest.approx([0.44758, 0.40745], abs=2e-4)
        text = Image.open(png).text["lbscene:adaptation"]
        assert text.startswith(f"{method}: ")
    code, out, err = run_cli("render", cfg, "-o", tmp_path / "x.png", "--adaptation", "vonkries")
    assert code == 2 and "Traceback" not in err
    code, out, err = run_cli("render", cfg, "-o", tmp_path / "t.png")
    assert code == 0 and "adaptation: cat16: CAT16 (von Kries, D = 1) from the lighting's white" in out
