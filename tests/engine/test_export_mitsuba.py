"""``lbscene export-mitsuba``: the exported scene is the provider's, and Mitsuba renders it to the
provider's own figures (and, without inter-reflection, to the inverse-square law)."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")

BOOTH = """version: 1
kind: booth
name: grey box
provenance: {status: synthetic}
interior: {type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}
materials:
  grey: {type: diffuse, reflectance: {type: constant, value: 0.5}}
surfaces: {floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}
lamps:
  - id: panel
    type: panel
    position_mm: [0, 0, 700]
    axis: [1, 0, 0]
    aim: [0, 0, -1]
    length_mm: 300
    width_mm: 200
    spd: {type: cie_illuminant, name: D65}
    output: {type: luminous_flux_lm, value_lm: 1000}
lighting:
  D65: {lamps: [panel]}
observer: {type: eye_point, position_mm: [0, -900, 500]}
effects:
  interreflection: {patch_size_mm: 100}
"""

SPP = 4096


@pytest.fixture
def booth(tmp_path):
    d = tmp_path / "box"
    d.mkdir()
    (d / "booth.yaml").write_text(BOOTH)
    return d


def _render(scene, sensors, spp=SPP, passes=2):
    """Mean and standard error (lx) of the chosen sensors over ``passes`` seeds."""
    out = []
    for i in sensors:
        v = [683.0 * np.pi * float(np.asarray(mi.render(scene, sensor=i, spp=spp, seed=1000 * k + i)).ravel()[0])
             for k in range(passes)]
        out.append((np.mean(v), np.std(v, ddof=1) / np.sqrt(passes)))
    return np.array(out)


def _provider(booth, points):
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.mitsuba import MitsubaTruth

    r = MitsubaTruth(compile_booth(booth), "D65", spp=SPP, passes=2).illuminance_with_error_lx(points)
    return r.illuminance_lx, r.std_error_lx


def test_exported_xml_renders_the_providers_figures(booth, tmp_path, run_cli):
    out = tmp_path / "x" / "scene.xml"
    code, stdout, err = run_cli("export-mitsuba", booth, "--out", out, "--format", "json")
    assert code == 0, err
    j = json.loads(stdout)
    assert j["readings"] == 55 and j["lighting"] == "D65" and j["effects"] == ["interreflection"]
    assert (tmp_path / "x" / "scene_meshes" / "surface_floor.ply").is_file()
    mi.set_variant("scalar_spectral")
    scene = mi.load_file(str(out))
    sensors = scene.sensors()
    assert len(sensors) == 55
    pick = [0, 27, 54]
    got = _render(scene, pick)
    from lbscene.engine.truth.synthetic import a3_grid

    ref, se = _provider(booth, a3_grid()[pick])
    tol = 4 * np.hypot(got[:, 1], se) + 0.005 * ref
    assert np.all(np.abs(got[:, 0] - ref) <= tol), (got, ref, se)


def test_exported_python_module_is_the_same_scene(booth, tmp_path, run_cli):
    out = tmp_path / "scene.py"
    m = tmp_path / "m"
    m.mkdir()
    (m / "g.csv").write_text("x_mm,y_mm,illuminance_lx\n0,0,900\n150,100,800\n-200,0,800\n")
    (m / "s.yaml").write_text(f"version: 1\nkind: measurement_set\nname: two\nbooth: {booth}\nlighting: D65\n"
                              "illuminance:\n  - path: g.csv\n")
    code, _, err = run_cli("export-mitsuba", booth, "--measurements", m / "s.yaml", "--out", out)
    assert code == 0, err
    spec = importlib.util.spec_from_file_location("exported_scene", out)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.RECEIVERS_MM == [[0.0, 0.0, 0.0], [150.0, 100.0, 0.0], [-200.0, 0.0, 0.0]]
    scene = mi.load_dict(mod.scene_dict())
    got = _render(scene, [0, 1, 2])
    ref, se = _provider(booth, mod.RECEIVERS_MM)
    assert np.all(np.abs(got[:, 0] - ref) <= 4 * np.hypot(got[:, 1], se) + 0.005 * ref), (got, ref)


def test_without_interreflection_the_scene_gives_the_closed_form(booth, tmp_path, run_cli):
    """A point lamp in a black box: E = I/h² at the sample, independent of both engines."""
    f = booth / "booth.yaml"
    f.write_text(BOOTH.replace("value: 0.5", "value: 0.0").replace(
        "    type: panel\n", "    type: point\n").replace("luminous_flux_lm, value_lm: 1000",
                                                         "peak_intensity_cd, value_cd: 490"))
    out = tmp_path / "p.xml"
    assert run_cli("export-mitsuba", booth, "--out", out)[0] == 0
    mi.set_variant("scalar_spectral")
    got = _render(mi.load_file(str(out)), [27], spp=64)            # the grid's centre point
    assert got[0, 0] == pytest.approx(490 / 0.7 ** 2, rel=0.01)


def test_refusals_are_located_and_pinned(booth, tmp_path, run_cli):
    f = booth / "booth.yaml"
    f.write_text(BOOTH.replace("  interreflection: {patch_size_mm: 100}\n",
                               "  interreflection: {patch_size_mm: 100}\n  tube_end_falloff: {}\n"))
    code, _, err = run_cli("export-mitsuba", booth, "--out", tmp_path / "s.xml")
    assert code == 2
    assert (f"{f}:24:3: error LB603: export-mitsuba: Mitsuba cannot represent this: effect 'tube_end_falloff' "
            "has no Mitsuba representation (expected a booth the Mitsuba truth provider represents)") in err
    assert not (tmp_path / "s.xml").exists()


def test_bad_targets(booth, tmp_path, run_cli):
    code, _, err = run_cli("export-mitsuba", booth, "--out", tmp_path / "s.json")
    assert code == 2 and "error LB500: --out must name a .xml or .py file" in err
    mine = tmp_path / "mine.xml"
    mine.write_text("<scene/>")
    code, _, err = run_cli("export-mitsuba", booth, "--out", mine)
    assert code == 2 and "LB611" in err and mine.read_text() == "<scene/>"
    code, _, err = run_cli("export-mitsuba", booth, "--lighting", "A", "--out", tmp_path / "a.xml")
    assert code == 2 and "error LB202: --lighting: booth 'grey box' has no lighting configuration 'A'" in err
