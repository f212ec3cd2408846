"""A lamp in the bake is a body: its environment maps see it black, not what lies behind it.

The bake counts a lamp's straight light in its direct products, so the environment camera must
not see the lamp's emission; but the lamp's body is still in the way, as the real lamp is.  A
small lamp (radiance in band 1) hangs 500 mm above the map's centre in front of a large bright
panel (band 0) 1000 mm up.  Closed forms (view factors of parallel rectangles):

* band 0 of the map's irradiance: the panel less the part the lamp hides
  (the lamp's 200 mm square at 500 mm hides a 400 mm square of the panel at 1000 mm);
* band 1 of the map: 0 (the lamp is black to camera rays);
* a sensor at the same point (not a camera ray) receives the lamp's light, and the panel's less
  the lamp's shadow.

And the SpectraLight's mirror images of its D65 lamps: their light is tested against the booth's
blockers (filter masks, box walls, the lamp's own body), and what lies on or behind the mirror
(the mirror plate, the cavity top it sits on) does not block them.
"""

from __future__ import annotations

import pytest

import bake_closed_forms as cf
from conftest import only, rect
from lbscene.bakers.job import (AreaEmitter, BakeJob, EnvironmentMapProduct, IrradiancePointsProduct,
                                MeasurementPoint, Quality)

pytestmark = pytest.mark.bake

PANEL_HALF_MM, PANEL_H_MM = 400.0, 1000.0
LAMP_HALF_MM, LAMP_H_MM = 100.0, 500.0
L_PANEL, L_LAMP = 1.0, 3.0


def _square_E(L, half, h):
    return cf.rect_E(L, -half, half, -half, half, h)


@pytest.fixture(scope="module")
def lamp_bake(tmp_path_factory):
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.products import read_product

    pv, pt = rect(0, 0, PANEL_H_MM, 2 * PANEL_HALF_MM, 2 * PANEL_HALF_MM)
    lv, lt = rect(0, 0, LAMP_H_MM, 2 * LAMP_HALF_MM, 2 * LAMP_HALF_MM)
    job = BakeJob(name="lamp-body", emitters=[
        AreaEmitter(id="panel", vertices_mm=pv, triangles=pt, radiance_W_sr_m2_nm=only({0: L_PANEL})),
        AreaEmitter(id="lamp", vertices_mm=lv, triangles=lt, radiance_W_sr_m2_nm=only({1: L_LAMP}),
                    visible_to_camera=False)],
        products=[EnvironmentMapProduct(id="env", position_mm=(0, 0, 0), projection="cube",
                                        width_px=128, samples=16),
                  IrradiancePointsProduct(id="sensor", light_paths="direct", samples=64, offset_mm=0.0,
                                          points=[MeasurementPoint(position_mm=(0, 0, 0))])],
        quality=Quality(noise_estimate=False))
    out = tmp_path_factory.mktemp("lamp-body") / "bake"
    [r] = run_tasks([BakeTask(job, out)], progress=False)
    assert r.status == "baked", (r.error, r.log_tail)
    env, _ = read_product(out / "env.exr")
    sensor, _ = read_product(out / "sensor.exr")
    return env, sensor.reshape(-1, sensor.shape[-1])[0]


def test_the_map_sees_the_lamp_black_and_not_what_is_behind_it(lamp_bake):
    from lbscene.bakers.products import environment_irradiance

    env, _ = lamp_bake
    E = environment_irradiance(env, "cube", (0, 1, 0), (0, 0, 1), (0, 0, 1))
    hidden = _square_E(L_PANEL, 2 * LAMP_HALF_MM, PANEL_H_MM)
    expected = _square_E(L_PANEL, PANEL_HALF_MM, PANEL_H_MM) - hidden
    # seeing through the lamp would give the whole panel: 1 + hidden/expected ≈ 1.3 × expected
    assert E[0] == pytest.approx(expected, rel=0.02)
    assert E[1] == 0.0


def test_the_lamp_still_shines_on_a_sensor(lamp_bake):
    _, e = lamp_bake
    assert e[1] == pytest.approx(_square_E(L_LAMP, LAMP_HALF_MM, LAMP_H_MM), rel=0.02)
    hidden = _square_E(L_PANEL, 2 * LAMP_HALF_MM, PANEL_H_MM)
    assert e[0] == pytest.approx(_square_E(L_PANEL, PANEL_HALF_MM, PANEL_H_MM) - hidden, rel=0.02)


#: run in its own process (as every bake is): the SpectraLight's D65 scene, what Blender holds
_SCENE_PROBE = r"""
import json, sys
import bpy
from lbscene.bakers.blender_scene import BlenderScene
from lbscene.bakers.from_ir import lighting_job
from lbscene.engine.scene.compile import compile_booth
ir = compile_booth(sys.argv[1])
job = lighting_job(ir, "D65", environment=False, maps=False, grid=False, points=[(0.0, 0.0, 0.0)])
BlenderScene.build(job)
out = {}
for e in job.emitters:
    o = bpy.data.objects[e.id]
    nodes = o.data.materials[0].node_tree.nodes
    lp = [n for n in nodes if n.bl_idname == "ShaderNodeLightPath"]
    coll = o.light_linking.blocker_collection
    out[e.id] = {"image": e.window is not None, "camera": o.visible_camera,
                 "diffuse": o.visible_diffuse, "shadow": o.visible_shadow,
                 "camera_ray_switch": bool(lp and lp[0].outputs["Is Camera Ray"].is_linked),
                 "blockers": sorted(x.name for x in coll.objects) if coll is not None else None}
print("SCENE " + json.dumps(out))
"""


@pytest.fixture(scope="module")
def spectralight_d65_scene():
    import json
    import subprocess
    import sys
    from pathlib import Path

    pytest.importorskip("bpy")
    booth = Path(__file__).resolve().parents[2] / "booths" / "xrite-spectralight-qc"
    r = subprocess.run([sys.executable, "-c", _SCENE_PROBE, str(booth)], capture_output=True,
                       text=True, timeout=600)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("SCENE ")]
    assert lines, r.stdout[-2000:] + r.stderr[-2000:]
    return json.loads(lines[0][len("SCENE "):])


def test_lamps_are_camera_black_bodies_and_mirror_images_pass_camera_rays(spectralight_d65_scene):
    """Every lamp surface stops camera rays, its emission switched off for them (Light Path: Is
    Camera Ray) and on for every other ray; its mirror image is hidden from camera rays."""
    lamps = {k: v for k, v in spectralight_d65_scene.items() if not v["image"]}
    images = {k: v for k, v in spectralight_d65_scene.items() if v["image"]}
    # a prism mirror behind each D65 lamp: one image per facet
    assert sorted(lamps) == ["lamp.D65_left", "lamp.D65_right"]
    assert sorted(images) == [f"lamp.D65_{s}.mirror{k}" for s in ("left", "right") for k in (0, 1)]
    for v in lamps.values():
        assert v["camera"] and v["diffuse"] and v["shadow"] and v["camera_ray_switch"]
    for v in images.values():
        assert not v["camera"]


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("facet", [0, 1])
def test_mirror_images_are_blocked_by_masks_boxes_and_the_lamp_not_by_the_mirror(
        spectralight_d65_scene, side, facet):
    names = set(spectralight_d65_scene[f"lamp.D65_{side}.mirror{facet}"]["blockers"])
    assert {f"occluder.D65_{side}_mask", f"occluder.D65_{side}_box_inner",
            f"occluder.D65_{side}_box_outer", f"lamp.D65_{side}", "diffuser"} <= names
    # on or behind the facet's plane: its mirror plate and its image (the cavity top the apex
    # touches reaches in front of a tilted facet's plane, so it stays a blocker: Cycles links
    # shadows per object, and cannot exempt the part of it behind the plane)
    assert not names & {f"mirror.D65_{side}.facet{facet}", f"lamp.D65_{side}.mirror{facet}"}


@pytest.mark.slow
def test_spectralight_mirror_images_send_no_direct_light_to_the_sample(tmp_path):
    """The D65 mirror images alone (the lamps' own emission off, their bodies kept): at the
    sample, straight lines from the images to it cross a mask or a lamp, so their direct light
    there is nil (< 0.1 % of the lamps' own)."""
    from lbscene.bakers.bake import bake_job
    from lbscene.bakers.from_ir import lighting_job
    from lbscene.engine.scene.compile import compile_booth

    ir = compile_booth("booths/xrite-spectralight-qc")
    job = lighting_job(ir, "D65", environment=False, maps=False, grid=False,
                       points=[ir.sample_position_mm], samples=256)
    dark = tuple(e.model_copy(update={"radiance_W_sr_m2_nm": (0.0,) * len(e.radiance_W_sr_m2_nm)})
                 if e.window is None else e for e in job.emitters)
    both = bake_job(job, tmp_path / "both", save_blend=False)
    images = bake_job(job.model_copy(update={"emitters": dark}), tmp_path / "images", save_blend=False)
    e_both = both["products"]["points"]["illuminance_lx"]["mean"]
    e_img = images["products"]["points"]["illuminance_lx"]["mean"]
    assert e_both > 500.0
    assert e_img < 1e-3 * e_both


def test_the_sample_estimate_carries_its_two_half_noise(tmp_path):
    """The map + direct estimate at the sample says how noisy it is: the lamp's straight light
    (a 200 mm square at 500 mm, next-event estimated) is the whole estimate here (the map sees
    the lamp black), exactly the closed form within the noise the manifest states."""
    from lbscene.bakers.executor import BakeTask, run_tasks

    lv, lt = rect(0, 0, LAMP_H_MM, 2 * LAMP_HALF_MM, 2 * LAMP_HALF_MM)
    job = BakeJob(name="sample-noise", emitters=[
        AreaEmitter(id="lamp", vertices_mm=lv, triangles=lt, radiance_W_sr_m2_nm=only({1: L_LAMP}),
                    visible_to_camera=False)],
        products=[EnvironmentMapProduct(id="env", position_mm=(0, 0, 0), width_px=32, samples=4,
                                        direct_product="direct"),
                  IrradiancePointsProduct(id="direct", light_paths="direct", samples=16, offset_mm=0.0,
                                          points=[MeasurementPoint(position_mm=(0, 0, 0))])])
    [r] = run_tasks([BakeTask(job, tmp_path / "bake")], progress=False)
    assert r.status == "baked", (r.error, r.log_tail)
    si = r.manifest["products"]["env"]["sample_irradiance"]
    rel = si["illuminance_noise_relative"]
    assert 0.0 <= rel < 0.02
    e_band1 = si["irradiance_W_m2_nm"][1]
    assert e_band1 == pytest.approx(_square_E(L_LAMP, LAMP_HALF_MM, LAMP_H_MM), rel=0.02 + 4 * rel)
    assert si["from_map_W_m2_nm"][1] == 0.0
