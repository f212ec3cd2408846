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

Rendered (slow): Cycles renders a white probe at the sample in the opened file, and its
illuminance (683 lm/W · π · Y) is ``lbscene bake``'s at the same point within 5 % for the tube,
the panel and the bulb, and the ratio between two lightings is the bake's within 3 %.
"""

from __future__ import annotations

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

BOOTH = """\
version: 1
kind: booth
name: Lamp shapes test booth
provenance: {status: synthetic, source: "lbscene test suite"}
interior: {type: box, width_mm: 1200, depth_mm: 800, height_mm: 900}
materials:
  white: {type: diffuse, reflectance: {type: constant, value: 0.8}}
  grey: {type: diffuse, reflectance: {type: constant, value: 0.4}}
  mask_black: {type: diffuse, reflectance: {type: constant, value: 0.03}}
surfaces: {floor: white, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}
lamps:
  - id: tube
    type: tube
    position_mm: [0, -150, 800]
    axis: [1, 0, 0]
    length_mm: 590
    radius_mm: 13
    spd: {type: cie_illuminant, name: A}
    output: {type: luminous_flux_lm, value_lm: 1350}
  - id: panel
    type: panel
    position_mm: [0, 150, 850]
    axis: [1, 0, 0]
    aim: [0, 0, -1]
    length_mm: 300
    width_mm: 200
    spd: {type: cie_illuminant, name: D65}
    output: {type: peak_intensity_cd, value_cd: 800}
  - id: bulb
    type: bulb
    position_mm: [250, 0, 700]
    radius_mm: 20
    spd: {type: blackbody, cct_K: 3000}
    output: {type: luminous_flux_lm, value_lm: 1500}
occluders:
  - {id: mask, type: panel, centre_mm: [-450, 0, 600], normal: [0, 0, -1], size_mm: [150, 300],
     u_axis: [1, 0, 0], material: mask_black}
lighting:
  tube: {lamps: [tube]}
  panel: {lamps: [panel]}
  bulb: {lamps: [bulb]}
geometries: [{name: 45as45}]
observer: {type: eye_point, position_mm: [0, -900, 600], look_at_mm: [0, 0, 0]}
sample_position_mm: [0, 0, 0]
effects:
  aperture_occlusion: {}
"""

#: datasheet flux of each lamp (lm): the declared lumens, π × the panel's peak candela
FLUX_LM = {"tube": 1350.0, "panel": math.pi * 800.0, "bulb": 1500.0}


def _env() -> dict:
    return dict(os.environ, PYTHONPATH="")


def _probe(*args) -> str:
    res = subprocess.run([sys.executable, str(HERE / "blend_probe.py"), *map(str, args)],
                         capture_output=True, text=True, env=_env(), timeout=600)
    tag = "FILE " if args[0] == "inspect" else "PROBE "
    line = next((ln for ln in res.stdout.splitlines() if ln.startswith(tag)), None)
    assert line, res.stdout[-2000:] + res.stderr[-2000:]
    return json.loads(line[len(tag):])


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    pytest.importorskip("bpy")
    import lbscene

    root = tmp_path_factory.mktemp("blend")
    (root / "booth").mkdir()
    (root / "booth" / "booth.yaml").write_text(BOOTH)
    out = root / "booth.blend"
    res = lbscene.export_blender(root / "booth", out)
    return root, out, res


@pytest.fixture(scope="module")
def contents(exported):
    return _probe("inspect", exported[1])


def _lamp(contents, lighting):
    objs = [o for o in contents["objects"].values()
            if o["props"].get("lbscene_lighting") == lighting and o["props"].get("lbscene_role") == "lamp"]
    assert len(objs) == 1, [n for n in contents["objects"]]
    return objs[0]


def _flux_lm(obj) -> float:
    """Luminous flux of a Lambertian emitting mesh in Blender's watts: π · 683 · Y(L) · area."""
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


#: bake samples: the sample's light comes from the bake's environment map, where a thin tube
#: covers a fraction of a pixel; the preview's 8 samples leave a few % of noise there, 128 under 1 %
BAKE_SAMPLES = 128


def _bake_lx(booth: Path, lighting: str, out: Path) -> float:
    r = subprocess.run([sys.executable, "-m", "lbscene", "bake", str(booth), "--lighting", lighting,
                        "--samples", str(BAKE_SAMPLES), "--out", str(out), "--format", "json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)["bakes"][0]["sample_lx_from_env"]


@pytest.mark.slow
def test_cycles_renders_the_bakes_light_from_the_file(exported):
    """The file's light at the sample is the bake's (tube, panel, bulb), and so are the ratios."""
    root, blend, _ = exported
    e_blend, e_bake = {}, {}
    for lighting in ("tube", "panel", "bulb"):
        e_blend[lighting] = _probe("render", blend, lighting, 0, 0, 0, 1024)["illuminance_lx"]
        e_bake[lighting] = _bake_lx(root / "booth", lighting, root / "bakes")
        assert e_blend[lighting] == pytest.approx(e_bake[lighting], rel=0.05), lighting
    for a, b in (("tube", "panel"), ("bulb", "tube")):
        assert e_blend[a] / e_blend[b] == pytest.approx(e_bake[a] / e_bake[b], rel=0.03)
