"""``lbscene export-blender``: the booth as a ``.blend``, read back and rendered by Blender itself.

A test booth holds one lamp of each shape, each in its own lighting: a tube (1350 lm, a
catalogue T8's flux), a panel (800 cd peak) and a bulb (1500 lm), plus a black mask (an
occluder with a declared material).  Read back from the file (fast, default suite):

* each lamp is an emitter of its own shape and size: a cylinder of the tube's length and radius,
  a rectangle of the panel's size, a sphere of the bulb's radius;
* its watts are right in Blender's convention (683 lm/W × Rec. 709 luminance): the luminous flux
  of the emitting surface, π · 683 · Y(radiance) · area for a Lambertian emitter, is the datasheet's
  — 1350 lm, π × 800 cd (a Lambertian panel's flux is π I₀), 1500 lm;
* one collection per lighting, the first on; every mesh has a material, the mask its declared one;
* the camera's view holds the whole floor, the floor's corners within the margin of the frame.

Rendered: Cycles renders a white probe at the sample in the opened file, and its illuminance
(683 lm/W · π · Y) is ``lbscene bake``'s at the same point within 5 % for the tube, the panel and
the bulb, and the ratios between lightings are the bake's within 3 %.  The bake's values are
committed data (``tests/data/lamp-shapes-booth/bake-reference.json``, written by
``bake_reference.py`` beside it); the slow test bakes again and checks that they are current.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.bake
HERE = Path(__file__).resolve().parent
REC709_Y = np.array([0.2126729, 0.7151522, 0.0721750])

DATA = Path(__file__).resolve().parents[1] / "data" / "lamp-shapes-booth"
BOOTH = DATA / "booth.yaml"
#: ``lbscene bake``'s illuminance at the sample, written by ``bake_reference.py`` beside it
REFERENCE = json.loads((DATA / "bake-reference.json").read_text())

#: datasheet flux of each lamp (lm): the declared lumens, π × the panel's peak candela
FLUX_LM = {"tube": 1350.0, "panel": math.pi * 800.0, "bulb": 1500.0}


def _env() -> dict:
    return dict(os.environ, PYTHONPATH="")


def _run_probe(*args) -> list[dict]:
    res = subprocess.run([sys.executable, str(HERE / "blend_probe.py"), *map(str, args)],
                         capture_output=True, text=True, env=_env(), timeout=600)
    tag = "FILE " if args[0] == "inspect" else "PROBE "
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith(tag)]
    assert lines, res.stdout[-2000:] + res.stderr[-2000:]
    return [json.loads(ln[len(tag):]) for ln in lines]


def _probes(blend: Path, lightings, samples: int) -> list[dict]:
    """Illuminance at the sample rendered from the file, one entry per lighting."""
    return _run_probe("render", blend, ",".join(lightings), 0, 0, 0, samples)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    pytest.importorskip("bpy")
    import lbscene

    root = tmp_path_factory.mktemp("blend")
    out = root / "booth.blend"
    res = lbscene.export_blender(BOOTH, out)
    return root, out, res


@pytest.fixture(scope="module")
def contents(exported):
    return _run_probe("inspect", exported[1])[0]


def _lamp(contents, lighting):
    objs = [o for o in contents["objects"].values()
            if o["props"].get("lbscene_lighting") == lighting and o["props"].get("lbscene_role") == "lamp"]
    assert len(objs) == 1, [n for n in contents["objects"]]
    return objs[0]


def _flux_lm(obj) -> float:
    """Luminous flux of a Lambertian emitting mesh in Blender's watts: π · 683 · Y(L) · area, with
    L = colour × Strength its radiance."""
    return math.pi * 683.0 * float(REC709_Y @ np.asarray(obj["emission_rgb"])) * obj["area_m2"]


def test_lamps_are_emitters_of_their_shape_size_and_watts(contents):
    tube = _lamp(contents, "tube")
    v = np.asarray(tube["vertices_m"]) * 1e3 - [0, -150, 800]
    assert tube["type"] == "MESH" and tube["props"]["lbscene_lamp_kind"] == "tube"
    assert np.ptp(v[:, 0]) == pytest.approx(590, abs=0.01)            # length along the axis
    assert np.hypot(v[:, 1], v[:, 2]) == pytest.approx(13, rel=0.002)   # a cylinder of the radius
    panel = _lamp(contents, "panel")
    v = np.asarray(panel["vertices_m"]) * 1e3
    assert (np.ptp(v[:, 0]), np.ptp(v[:, 1]), np.ptp(v[:, 2])) == pytest.approx((300, 200, 0), abs=0.01)
    assert panel["area_m2"] == pytest.approx(0.06, rel=1e-4)
    bulb = _lamp(contents, "bulb")
    v = np.asarray(bulb["vertices_m"]) * 1e3 - [250, 0, 700]
    assert np.linalg.norm(v, axis=1) == pytest.approx(20, rel=0.01)     # a sphere of the radius
    assert np.ptp(v, axis=0) == pytest.approx([40, 40, 40], rel=0.01)
    for name, obj in (("tube", tube), ("panel", panel), ("bulb", bulb)):
        assert _flux_lm(obj) == pytest.approx(FLUX_LM[name], rel=0.01), name
        assert obj["visible_camera"]
        assert max(obj["emission_color"]) == pytest.approx(1.0)     # the colour, its Strength the level
    # the colours are the lamps' own: A warm, D65 near white, 3000 K between
    a, d65 = np.asarray(tube["emission_rgb"]), np.asarray(panel["emission_rgb"])
    assert a[0] / a[2] > 3 and 0.9 < d65[0] / d65[2] < 1.1


def test_one_collection_per_lighting_and_materials_bound(contents):
    assert contents["excluded"] == {"booth": False, "lighting tube": False, "lighting panel": True,
                                    "lighting bulb": True}
    meshes = {n: o for n, o in contents["objects"].items() if o["type"] == "MESH"}
    unbound = [n for n, o in meshes.items() if not o["materials"] or None in o["materials"]]
    assert unbound == []
    assert meshes["occluder.mask"]["materials"] == ["mat.mask_black"]
    assert meshes["surface.floor"]["materials"] == ["mat.white"]
    # the lamps that are off are in each lighting, black, in the light's way
    assert {o["props"].get("lbscene_lighting") for o in meshes.values()
            if o["props"].get("lbscene_role") == "lamp_body"} == {"tube", "panel", "bulb"}
    assert contents["props"]["lbscene_light_unit"].startswith("W (683 lm/W")


def test_the_camera_frames_the_floor_from_the_observer(contents):
    cam = contents["objects"][contents["camera"]]["camera"]
    eye = np.asarray(cam["location_m"]) * 1e3
    assert eye == pytest.approx([0, -900, 600], abs=0.01)
    f = np.asarray(cam["forward"])
    assert f == pytest.approx(-eye / np.linalg.norm(eye), abs=1e-5)     # looking at the sample
    w, h = contents["resolution"]
    tx = math.tan(cam["angle_x"] / 2)
    ty = tx * h / w
    right = np.cross(f, [0, 0, 1])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    corners = np.array([[x, y, 0] for x in (-600, 600) for y in (-400, 400)]) - eye
    u = np.abs(corners @ right) / (corners @ f) / tx
    t = np.abs(corners @ up) / (corners @ f) / ty
    assert u.max() < 1 and t.max() < 1                      # the whole floor is in the picture
    assert max(u.max(), t.max()) > 0.9                      # and fills it, within the margin


LIGHTINGS = ("tube", "panel", "bulb")


def test_cycles_renders_the_bakes_light_from_the_file(exported):
    """The file's light at the sample is the bake's (tube, panel, bulb), and so are the ratios."""
    assert REFERENCE["booth_sha256"] == hashlib.sha256(BOOTH.read_bytes()).hexdigest(), \
        "the booth changed: rerun tests/data/lamp-shapes-booth/bake_reference.py"
    e_bake = REFERENCE["sample_lx_from_env"]
    e_blend = {p["lighting"]: p["illuminance_lx"] for p in _probes(exported[1], LIGHTINGS, 512)}
    for lighting in LIGHTINGS:
        assert e_blend[lighting] == pytest.approx(e_bake[lighting], rel=0.05), lighting
    for a, b in (("tube", "panel"), ("bulb", "tube"), ("panel", "bulb")):
        assert e_blend[a] / e_blend[b] == pytest.approx(e_bake[a] / e_bake[b], rel=0.03), (a, b)


@pytest.mark.slow
def test_bake_reference_is_current(tmp_path):
    """Bake again (a few minutes) and compare with the committed illuminances (noise: < 1 %)."""
    sys.path.insert(0, str(DATA))
    try:
        import bake_reference
    finally:
        sys.path.remove(str(DATA))
    now = bake_reference.reference(tmp_path)
    assert now["samples"] == REFERENCE["samples"]
    for lighting in LIGHTINGS:
        assert now["sample_lx_from_env"][lighting] == pytest.approx(
            REFERENCE["sample_lx_from_env"][lighting], rel=0.02), lighting


@pytest.mark.slow
def test_spectralight_masks_boxes_and_mirrors(tmp_path):
    """The SpectraLight QC's D65 lighting: the filter masks and lamp boxes carry their declared
    materials, each prism mirror is two 65 × 118 mm facets meeting 35 mm above its lamp at 120°
    (the booth file's reflector: each 30° off the horizontal, 56.3 mm wide seen from below, its
    lower edge 32.5 mm under the apex) with a mirror material of the reflector's ~0.88
    reflectance, the lamps are tubes."""
    pytest.importorskip("bpy")
    import lbscene

    out = tmp_path / "splqc.blend"
    res = lbscene.export_blender("xrite-spectralight-qc", out, lightings=["D65"])
    assert res.lightings == ["D65"]
    objs = _run_probe("inspect", out)[0]["objects"]
    for side in ("left", "right"):
        assert objs[f"occluder.D65_{side}_mask"]["materials"] == ["mat.mask_black"]
        for wall in ("inner", "outer"):
            assert objs[f"occluder.D65_{side}_box_{wall}"]["materials"] == ["mat.luminaire_white"]
        x0 = -380 if side == "left" else 380
        centres = []
        for k in (0, 1):
            mirror = objs[f"D65/mirror.D65_{side}.facet{k}"]
            v = np.asarray(mirror["vertices_m"]) * 1e3
            assert np.ptp(v, axis=0) == pytest.approx([65 * math.cos(math.radians(30)), 118, 32.5], abs=0.01)
            assert v[:, 2].max() == pytest.approx(725 + 35, abs=0.01)
            centres.append(v[:, 0].mean() - x0)
            assert mirror["glossy_roughness"] == 0.0
            assert mirror["glossy_rgb"] == pytest.approx([0.88] * 3, abs=0.02)
        assert sorted(centres) == pytest.approx([-32.5 * math.cos(math.radians(30)),
                                                 32.5 * math.cos(math.radians(30))], abs=0.01)
        lamp = objs[f"D65/lamp.D65_{side}"]
        assert lamp["props"]["lbscene_lamp_kind"] == "tube"
        assert lamp["materials"][0].startswith("D65/emitter")
    unbound = [n for n, o in objs.items() if o["type"] == "MESH" and (not o["materials"] or None in o["materials"])]
    assert unbound == []


POINT_BOOTH = """\
version: 1
kind: booth
name: Point lamp test booth
provenance: {status: synthetic, source: "lbscene test suite"}
interior: {type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}
materials:
  grey: {type: diffuse, reflectance: {type: constant, value: 0.5}}
surfaces: {floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}
lamps:
  - {id: spot, type: point, position_mm: [0, 0, 700], spd: {type: cie_illuminant, name: D65},
     output: {type: peak_intensity_cd, value_cd: 250}}
lighting:
  D65: {lamps: [spot]}
geometries: [{name: 45as45}]
observer: {type: eye_point, position_mm: [0, -900, 500]}
"""


def test_point_lamp_is_a_point_light_of_its_watts(tmp_path):
    """A point lamp of 250 cd is a Blender point light of radius 0 whose Power P (W) and colour c
    (peak 1) give 683 · P · Y(c) / 4π = 250 cd, Blender's convention (683 lm/W)."""
    pytest.importorskip("bpy")
    import lbscene

    (tmp_path / "booth").mkdir()
    (tmp_path / "booth" / "booth.yaml").write_text(POINT_BOOTH)
    lbscene.export_blender(tmp_path / "booth", tmp_path / "p.blend")
    objs = _run_probe("inspect", tmp_path / "p.blend")[0]["objects"]
    lights = [o for o in objs.values() if o["type"] == "LIGHT"]
    assert len(lights) == 1
    light = lights[0]
    assert light["light"]["type"] == "POINT" and light["light"]["radius_m"] == 0.0
    assert np.asarray(light["location_m"]) * 1e3 == pytest.approx([0, 0, 700], abs=1e-3)
    c = np.asarray(light["emission_rgb"])
    assert c.max() == pytest.approx(1.0)
    intensity_cd = 683.0 * light["light"]["energy_W"] * float(REC709_Y @ c) / (4 * math.pi)
    assert intensity_cd == pytest.approx(250.0, rel=0.005)


@pytest.mark.slow
def test_spectralight_direct_light_is_the_forward_models(tmp_path):
    """The shipped SpectraLight QC's direct light at the sample, rendered from its file (Cycles,
    no bounce), is the analytic forward model's (its effects but inter-reflection) within 2 % for
    a filtered D65 pair with Gaussian beams, prism mirrors, masks and a glass plate, the A bulb
    and the three TL84 tubes: the shape, the watts and the occluders of every lighting."""
    pytest.importorskip("bpy")
    import lbscene
    from lbscene.engine.light.forward import ForwardModel

    out = tmp_path / "splqc.blend"
    lbscene.export_blender("xrite-spectralight-qc", out, lightings=["D65", "A", "TL84"])
    got = {p["lighting"]: p["illuminance_lx"] for p in _run_probe("render", out, "D65,A,TL84", 0, 0, 0, 1024, 0)}
    ir = lbscene.compile_booth("xrite-spectralight-qc")
    effects = {k: v for k, v in ir.effects.items() if k != "interreflection"}
    for lighting in ("D65", "A", "TL84"):
        model = float(ForwardModel(ir, lighting, effects=effects).illuminance_lx([[0.0, 0.0, 0.0]])[0])
        assert got[lighting] == pytest.approx(model, rel=0.02), lighting
