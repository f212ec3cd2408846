"""``lbscene render``: user errors (pinned messages, exit code 2, no traceback, no output
file), the contact sheet of ``--all-geometries`` and the XYZ output.  The example render
configurations are checked against their booths without rendering."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
DATA = HERE / "data"
TUBE_GONIO = DATA / "tube-gonio.yaml"
TUBE_BAKED = DATA / "tube-baked.yaml"
TUBE_VIEWS = ["45as-15", "45as0", "45as15", "45as45"]

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def _no_traceback(err: str) -> None:
    assert "Traceback" not in err and "Error:" not in err.replace("error LB", "")


@pytest.fixture
def tube_copy(tmp_path):
    """A writable copy of the tube test booth, its sample and the gonio configuration."""
    for name in ("tube-booth",):
        shutil.copytree(DATA / name, tmp_path / name)
    for name in ("sample-gonio.yaml", "tube-gonio.yaml"):
        shutil.copy(DATA / name, tmp_path / name)
    return tmp_path


# --------------------------------------------------------------------------- user errors

def test_unknown_geometry_option(run_cli, tmp_path):
    out = tmp_path / "x.png"
    code, _, err = run_cli("render", TUBE_GONIO, "--geometry", "45as99", "-o", out)
    assert code == 2
    assert ("error LB303: --geometry: unknown viewing geometry '45as99' for booth 'Tube test booth' "
            "(got '45as99'; expected one of 45as-15, 45as0, 45as15, 45as45)") in err
    _no_traceback(err)
    assert not out.exists()


def test_unknown_geometry_in_the_config_is_located(run_cli, tube_copy):
    cfg = tube_copy / "tube-gonio.yaml"
    text = cfg.read_text().replace("geometry: 45as0", "geometry: 45as25")
    cfg.write_text(text)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if s.startswith("geometry:"))
    code, _, err = run_cli("render", cfg, "-o", tube_copy / "x.png")
    assert code == 2
    assert f"tube-gonio.yaml:{line}:11: error LB303: unknown viewing geometry '45as25' for booth " \
           f"'Tube test booth' (got '45as25'; expected one of 45as-15, 45as0, 45as15, 45as45)" in err
    _no_traceback(err)


@pytest.mark.parametrize("size, message", [
    ("8x8", ("error LB500: --size: 8x8: each side must be 16..8192 px (got 8x8; "
             "expected WIDTHxHEIGHT with each side 16..8192)")),
    ("9000x600", "error LB500: --size: 9000x600: each side must be 16..8192 px"),
    ("100", "error LB500: --size: '100' is not a size like 1024x768 (got 100;"),
    ("axb", "error LB500: --size: 'axb' is not a size like 1024x768"),
])
def test_bad_size(run_cli, tmp_path, size, message):
    out = tmp_path / "x.png"
    code, _, err = run_cli("render", TUBE_GONIO, "--size", size, "-o", out)
    assert code == 2
    assert message in err
    _no_traceback(err)
    assert not out.exists()


def test_out_of_range_size_in_the_config_is_located(run_cli, tube_copy):
    cfg = tube_copy / "tube-gonio.yaml"
    cfg.write_text(cfg.read_text().replace("width_px: 96", "width_px: 9000"))
    code, _, err = run_cli("render", cfg, "-o", tube_copy / "x.png")
    assert code == 2
    assert "tube-gonio.yaml:11:" in err and "width_px" in err and "8192" in err
    _no_traceback(err)


def test_missing_bake_names_the_bake_and_offers_to_run_it(run_cli, tmp_path):
    out = tmp_path / "x.png"
    code, _, err = run_cli("render", TUBE_BAKED, "--no-input", "-o", out, cwd=tmp_path)
    assert code == 2
    assert ("tube-baked.yaml:9:10: error LB601: the configuration asks for baked lighting but no bake "
            "products found (looked in ") in err
    assert "(got diffuse: baked; expected bake products of lighting 'D65')" in err
    # the hint names the commands, and --bake runs them
    assert "hint: run `lbscene build " in err and "lbscene bake " in err and "--lighting D65`" in err
    assert "or pass --bake to run the bake now, or set `diffuse: analytic`" in err
    _no_traceback(err)
    assert not out.exists()


def test_geometry_and_all_geometries_exclude_each_other(run_cli, tmp_path):
    code, _, err = run_cli("render", TUBE_GONIO, "--geometry", "45as0", "--all-geometries",
                           "-o", tmp_path / "x.png")
    assert code == 2
    assert "error LB500: --geometry and --all-geometries exclude each other" in err


def test_bad_xyz_suffix(run_cli, tmp_path):
    code, _, err = run_cli("render", TUBE_GONIO, "--xyz", tmp_path / "x.tif", "-o", tmp_path / "x.png")
    assert code == 2
    assert "error LB500: --xyz must name a .npy or .exr file" in err


# --------------------------------------------------------------------------- rendering

def _tile(sheet: np.ndarray, i: int, size, columns: int = 3) -> np.ndarray:
    w, h = size
    r, c = divmod(i, columns)
    return sheet[r * h:(r + 1) * h, c * w:(c + 1) * w]


@pytest.mark.gl
def test_all_geometries_writes_a_contact_sheet(run_cli, tmp_path):
    from lbscene.runtimes.render import prepare_from_config
    from PIL import Image

    out, xyz = tmp_path / "sheet.png", tmp_path / "sheet.npy"
    code, stdout, err = run_cli("render", TUBE_GONIO, "--all-geometries", "--size", "64x48", "-o", out,
                                "--xyz", xyz, "--format", "json")
    assert code == 0, err
    res = json.loads(stdout)
    assert [v["view"] for v in res["views"]] == TUBE_VIEWS
    assert res["contact_sheet"] == {"views": 4, "columns": 3, "tile_px": [64, 48]}
    img = Image.open(out)
    assert img.size == (3 * 64, 2 * 48) and img.mode == "RGB"
    assert img.text["lbscene:views"] == ",".join(TUBE_VIEWS)
    sheet = np.asarray(img)
    # every tile is that view's own render (outside its label), the unused sixth tile is black
    job = prepare_from_config(TUBE_GONIO, all_geometries=True, size=(64, 48))
    r = job.renderer()
    try:
        for i, v in enumerate(TUBE_VIEWS):
            own = r.render(v, (64, 48), want_gamut=True).rgba8[..., :3]
            tile = _tile(sheet, i, (64, 48))
            label_w = 8 + 7 * len(v) + 1
            np.testing.assert_array_equal(tile[17:], own[17:])
            np.testing.assert_array_equal(tile[:17, label_w:], own[:17, label_w:])
    finally:
        r.close()
    assert not _tile(sheet, 4, (64, 48)).any() and not _tile(sheet, 5, (64, 48)).any()
    # the views differ (the platform turns; the gonio sample changes colour)
    assert len({_tile(sheet, i, (64, 48))[17:].tobytes() for i in range(4)}) == 4
    # one XYZ file per view
    assert sorted(res["xyz"]) == sorted(str(tmp_path / f"sheet.{v}.npy") for v in TUBE_VIEWS)
    for v in TUBE_VIEWS:
        a = np.load(tmp_path / f"sheet.{v}.npy")
        assert a.shape == (48, 64, 3) and a.dtype == np.float32 and a[24, 32, 1] > 0


@pytest.mark.gl
def test_all_geometries_of_a_booth_with_one_geometry(run_cli, tube_copy):
    booth = tube_copy / "tube-booth" / "booth.yaml"
    text = booth.read_text()
    start = text.index("\ngeometries:") + 1
    end = text.index("\nobserver:") + 1
    booth.write_text(text[:start] + "geometries:\n  - {name: 45as0, platform_rotation_deg: 15}\n" + text[end:])
    out = tube_copy / "sheet.png"
    code, _, err = run_cli("render", tube_copy / "tube-gonio.yaml", "--all-geometries", "--size", "48x32",
                           "-o", out)
    assert code == 0, err
    assert ("note: booth 'Tube test booth' declares one viewing geometry (45as0): the contact sheet has "
            "one view") in err
    from PIL import Image

    img = Image.open(out)
    assert img.size == (48, 32) and img.text["lbscene:views"] == "45as0"


@pytest.mark.gl
def test_single_view_png_and_xyz(run_cli, tmp_path):
    from PIL import Image

    out, xyz = tmp_path / "one.png", tmp_path / "one.npy"
    code, stdout, err = run_cli("render", TUBE_GONIO, "--size", "33x25", "-o", out, "--xyz", xyz,
                                "--format", "json")
    assert code == 0, err
    res = json.loads(stdout)
    assert res["contact_sheet"] is None and [v["view"] for v in res["views"]] == ["45as0"]
    assert set(res["timing_s"]) == {"config_and_booth", "scene_per_view", "frame_per_view"}
    assert Image.open(out).size == (33, 25)
    assert np.load(xyz).shape == (25, 33, 3)


@pytest.mark.gl
def test_baked_sample_light_agrees_with_the_analytic_model(run_cli, tube_copy):
    """A real Cycles bake of the tube booth, then the same view with baked and analytic diffuse
    light: the sample's illuminance must agree (Cycles vs the forward model: ~1 %; the preview
    bake's noise: ~1.5 %).  The map alone misses the light straight from the point lamps, which
    no camera ray can see, so the runtime adds the bake's direct product: without it the baked
    sample got a tenth of its light.  Cycles always has inter-reflection, so the model gets it too
    (the test booth has no effects: 2814 lx analytic against 3668 lx baked at 45as0).  The
    booth copy keeps the one geometry rendered: the bake's per-view products (environment map,
    the sample's direct light) of the other three were most of its time."""
    booth = tube_copy / "tube-booth" / "booth.yaml"
    text = booth.read_text()
    start = text.index("\ngeometries:") + 1
    end = text.index("\nobserver:") + 1
    booth.write_text(text[:start] + "geometries:\n  - {name: 45as-15, platform_rotation_deg: 0}\n" + text[end:]
                     + "effects: {interreflection: {}}\n")
    config = tube_copy / "tube-gonio.yaml"
    config.write_text(config.read_text().replace("geometry: 45as0\n", "geometry: 45as-15\n"))
    code, _, err = run_cli("bake", "tube-booth", "-l", "D65", cwd=tube_copy)
    assert code == 0, err
    lx = {}
    for diffuse in ("analytic", "baked"):
        # 45as-15: platform rotation 0 (at other rotations the analytic inter-reflection of a turning
        # luminaire is evaluated in the platform's frame, an approximation of a few %)
        code, out, err = run_cli("render", "tube-gonio.yaml", "--diffuse", diffuse, "--size", "32x24",
                                 "--geometry", "45as-15",
                                 "-o", f"{diffuse}.png", "--format", "json", cwd=tube_copy)
        assert code == 0, err
        (view,) = json.loads(out)["views"]
        lx[diffuse] = view["sample_illuminance_lx"]
    assert lx["baked"] == pytest.approx(lx["analytic"], rel=0.04)


@pytest.mark.gl
@pytest.mark.slow
def test_byko_all_geometries_contact_sheet(run_cli, tmp_path):
    """The issue's case: the six geometries of the byko-spectra effect as one 3 × 2 sheet."""
    from PIL import Image

    out = tmp_path / "byko.png"
    code, stdout, err = run_cli("render", REPO / "examples" / "render" / "byko-gonio-blue-45as15.yaml",
                                "--all-geometries", "--size", "64x48", "--diffuse", "analytic", "-o", out,
                                "--format", "json")
    assert code == 0, err
    res = json.loads(stdout)
    views = ["45as-15", "45as15", "45as25", "45as45", "45as75", "45as110"]
    assert [v["view"] for v in res["views"]] == views
    for v in res["views"]:
        assert v["realised"]["aspecular_deg"] == pytest.approx(float(v["view"].split("as")[1]), abs=0.5)
    img = Image.open(out)
    assert img.size == (192, 96) and img.text["lbscene:views"] == ",".join(views)


# --------------------------------------------------------------------------- examples

def _example_configs():
    return sorted((REPO / "examples" / "render").glob("*.yaml"))


def test_example_render_configs_match_their_booths():
    from lbscene.engine.files.load import load_document
    from lbscene.schemas.booth import Booth
    from lbscene.schemas.render_config import RenderConfig
    from lbscene.schemas.sample import Sample

    configs = [p for p in _example_configs() if "kind: render_config" in p.read_text()]
    booths, samples = set(), set()
    for p in configs:
        cfg = load_document(p, RenderConfig).model
        booth_dir = (p.parent / cfg.booth).resolve()
        booth = load_document(booth_dir / "booth.yaml", Booth).model
        assert cfg.lighting in booth.lighting, p.name
        if cfg.geometry is not None:
            assert cfg.geometry in [g.name for g in booth.geometries], p.name
        sample = load_document(p.parent / cfg.sample, Sample).model
        booths.add(booth_dir.name)
        samples.add(sample.name)
        if cfg.display != "builtin:srgb":
            assert (p.parent / cfg.display).is_file(), p.name
    # both seed booths, ColorChecker patches and a gonio-apparent sample
    assert {"xrite-spectralight-qc", "byk-byko-spectra-effect"} <= booths
    assert sum("ColorChecker" in s for s in samples) >= 3
    assert any("gonio" in s for s in samples)
