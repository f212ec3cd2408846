"""Cycles bakes a lamp's effects on its real surface: a tube's end falloff, an IES file in two
dimensions, a mirror image.  Irradiance is compared with truths written here from the physics
(a weighted quadrature of the Lambertian cylinder, the file's own candela numbers, the image of
the cylinder seen through the mirror and past the lamp), not with the model's code."""

from __future__ import annotations

import math

import numpy as np
import pytest
from closed_forms import cylinder_quadrature_lx, mirror_image_visible

from lbscene.bakers.crosscheck import bake_points
from lbscene.bakers.from_ir import lighting_job
from lbscene.bakers.job import AreaEmitter, IesProfile
from lbscene.engine.scene.compile import compile_booth

H_MM = 700.0
LV = 10000.0
LENGTH, RADIUS = 590.0, 13.0
END, FALL = 0.3, 150.0
R_MIRROR, D_MIRROR, W_MIRROR = 0.9, 35.0, 130.0
I0_CD = 1000.0

BOOTH = f"""\
version: 1
kind: booth
name: Lamp effects bake test
provenance: {{status: synthetic, source: "lbscene test suite (lamp effects in the bake)"}}
interior: {{type: box, width_mm: 4000, depth_mm: 4000, height_mm: 900}}
materials:
  grey: {{type: diffuse, reflectance: {{type: constant, value: 0.5}}}}
surfaces: {{floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}}
reflectors:
  mirror:
    type: plane
    reflectance: {{type: constant, value: {R_MIRROR}}}
    distance_mm: {D_MIRROR}
    normal: [0, 0, -1]
    width_mm: {W_MIRROR}
lamps:
  - {{id: F, type: tube, position_mm: [0, 0, {H_MM}], axis: [1, 0, 0], length_mm: {LENGTH}, radius_mm: {RADIUS},
     spd: {{type: constant, value: 1.0}}, output: {{type: luminance_cd_m2, value_cd_m2: {LV}}}}}
  - {{id: M, type: tube, position_mm: [0, 0, {H_MM}], axis: [1, 0, 0], length_mm: {LENGTH}, radius_mm: {RADIUS},
     reflector: mirror, spd: {{type: constant, value: 1.0}}, output: {{type: luminance_cd_m2, value_cd_m2: {LV}}}}}
  - {{id: I, type: point, position_mm: [0, 0, {H_MM}], axis: [0, 1, 0], aim: [0, 0, -1],
     profile: {{type: ies, path: full.ies}}, spd: {{type: constant, value: 1.0}},
     output: {{type: peak_intensity_cd, value_cd: {I0_CD}}}}}
  - {{id: B, type: point, position_mm: [0, 0, {H_MM}], axis: [0, 1, 0], aim: [0, 0, -1],
     profile: {{type: ies, path: bilateral.ies}}, spd: {{type: constant, value: 1.0}},
     output: {{type: peak_intensity_cd, value_cd: {I0_CD}}}}}
lighting:
  F: {{lamps: [F]}}
  M: {{lamps: [M]}}
  I: {{lamps: [I]}}
  B: {{lamps: [B]}}
geometries: [{{name: 45as45}}]
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
effects:
  tube_end_falloff: {{lamps: [F], end_level: {END}, falloff_length_mm: {FALL}}}
  reflector: {{lamps: [M]}}
  angular_profile: {{lamps: [I, B]}}
  # the test's lamps share one place, one lighting each: no off lamp's body around the one on
  interreflection: {{lamp_bodies: false}}
"""

#: vertical angles (γ) and candela per C plane of the asymmetric full-set file
GAMMA = [0.0, 22.5, 45.0, 67.5, 90.0]
FULL = {0: [500, 450, 400, 200, 20], 90: [500, 420, 300, 150, 20], 180: [500, 380, 200, 100, 20],
        270: [500, 340, 100, 50, 20]}
#: bilateral file (C 0..180, mirrored about the C0–C180 plane by the reader)
BILATERAL = {0: [500, 450, 400, 200, 20], 90: [500, 300, 150, 60, 20], 180: [500, 200, 50, 30, 20]}


def _ies(planes: dict, full: bool) -> str:
    h = sorted(planes) + ([360] if full else [])
    rows = [planes[c % 360] for c in h]
    return ("IESNA:LM-63-2002\n[TEST] lbscene bake test\nTILT=NONE\n"
            f"1 1000 1 {len(GAMMA)} {len(h)} 1 2 0 0 0\n1 1 0\n"
            + " ".join(f"{g:g}" for g in GAMMA) + "\n" + " ".join(map(str, h)) + "\n"
            + "\n".join(" ".join(map(str, r)) for r in rows) + "\n")


@pytest.fixture(scope="module")
def ir(tmp_path_factory):
    d = tmp_path_factory.mktemp("lamp-effects-bake")
    (d / "booth.yaml").write_text(BOOTH)
    (d / "full.ies").write_text(_ies(FULL, True))
    (d / "bilateral.ies").write_text(_ies(BILATERAL, False))
    return compile_booth(d / "booth.yaml")


def _ratio_ok(lux, want, noise, tol):
    return np.all(np.abs(lux / want - 1) <= tol + 4 * noise)


def test_jobs_emit_every_lamp_from_its_surface(ir):
    for lighting in ("F", "M"):
        job = lighting_job(ir, lighting)
        assert all(isinstance(e, AreaEmitter) for e in job.emitters), lighting
        assert "not its Lambertian surface" not in job.source.get("notes", "")
    f = lighting_job(ir, "F").emitters[0]
    assert (f.axial_weight.end_level, f.axial_weight.falloff_length_mm) == (END, FALL)
    m = lighting_job(ir, "M").emitters
    assert [e.window is not None for e in m] == [False, True]
    # the image lies 2 × 35 mm beyond the lamp, across the mirror plane z = 735
    zs = np.asarray(m[1].vertices_mm)[:, 2]
    assert zs.mean() == pytest.approx(H_MM + 2 * D_MIRROR, abs=1e-6)
    i = lighting_job(ir, "I").emitters[0]
    assert isinstance(i.profile, IesProfile)
    # C0 along the lamp's axis (+y), C90 along axis × aim = −x
    assert np.allclose(i.profile.c0_axis, (0, 1, 0)) and np.allclose(i.profile.c90_axis, (-1, 0, 0))


FLOOR_POINTS = np.array([[0, 0, 0], [250, 0, 0], [-330, 120, 0], [0, 300, 0]], float)


def test_tube_end_falloff_on_the_tube_surface(ir):
    def w(x):
        d_end = LENGTH / 2 - np.abs(x)
        return END + (1 - END) * np.clip(d_end / FALL, 0, 1)

    _, lux, noise, _ = bake_points(ir, "F", FLOOR_POINTS, surfaces="black", light_paths="direct",
                                   samples=512)
    want = np.array([cylinder_quadrature_lx(LV, (0, 0, H_MM), LENGTH, RADIUS, p, (0, 0, 1), n_along=1200,
                                            n_around=360, weight=w) for p in FLOOR_POINTS])
    uniform = np.array([cylinder_quadrature_lx(LV, (0, 0, H_MM), LENGTH, RADIUS, p, (0, 0, 1), n_along=1200,
                                               n_around=360) for p in FLOOR_POINTS])
    assert np.all(want < 0.97 * uniform)           # the falloff matters at these points
    assert _ratio_ok(lux, want, noise, 0.01), (lux / want, noise)


_through_mirror_past_the_tube = mirror_image_visible(H_MM + D_MIRROR, LENGTH / 2, W_MIRROR / 2, H_MM, RADIUS)


MIRROR_POINTS = np.array([[0, 0, 0], [0, 150, 0], [200, -250, 0], [-100, 450, 0], [0, 700, 300]], float)


def _mirror_truth(p):
    direct = cylinder_quadrature_lx(LV, (0, 0, H_MM), LENGTH, RADIUS, p, (0, 0, 1), n_along=600, n_around=720)
    image = cylinder_quadrature_lx(LV, (0, 0, H_MM + 2 * D_MIRROR), LENGTH, RADIUS, p, (0, 0, 1),
                                   n_along=600, n_around=720, visible=_through_mirror_past_the_tube)
    return direct, R_MIRROR * image


def test_mirror_image_of_the_tube_surface(ir):
    _, lux, noise, _ = bake_points(ir, "M", MIRROR_POINTS, surfaces="black", light_paths="direct",
                                   samples=512)
    parts = np.array([_mirror_truth(p) for p in MIRROR_POINTS])
    want = parts.sum(axis=1)
    # the image adds a good part of the light where it is seen, and the tube hides it below itself
    assert parts[1, 1] > 0.2 * parts[1, 0] and parts[0, 1] < 0.2 * parts[1, 1]
    assert _ratio_ok(lux, want, noise, 0.015), (lux / want, parts, noise)


def _ies_truth(planes, gamma_deg, c_deg):
    """E on the floor from the file's numbers at a node (γ, C): I·cos γ / d²."""
    cd = planes[c_deg][GAMMA.index(gamma_deg)]
    i_cd = I0_CD * cd / 500.0
    d_m = H_MM / math.cos(math.radians(gamma_deg)) * 1e-3
    return i_cd * math.cos(math.radians(gamma_deg)) / d_m ** 2


def _floor_point(gamma_deg, c_deg):
    """Floor point in direction (γ, C) of the lamp: C0 = +y (its axis), C90 = −x (axis × aim)."""
    r = H_MM * math.tan(math.radians(gamma_deg))
    c = math.radians(c_deg)
    return (-r * math.sin(c), r * math.cos(c), 0.0)


@pytest.mark.parametrize("lighting,planes", [("I", FULL), ("B", {**BILATERAL, 270: BILATERAL[90]})])
def test_ies_planes_in_two_dimensions(ir, lighting, planes):
    nodes = [(g, c) for g in (22.5, 45.0, 67.5) for c in (0, 90, 180, 270)] + [(0.0, 0)]
    pts = np.array([_floor_point(g, c) for g, c in nodes])
    _, lux, noise, _ = bake_points(ir, lighting, pts, surfaces="black", light_paths="direct", samples=16)
    want = np.array([_ies_truth(planes, g, c) for g, c in nodes])
    assert np.allclose(lux, want, rtol=2e-3), np.c_[lux / want, pts]


def test_lamps_that_are_off_stand_in_the_bake_as_black_bodies(tmp_path):
    booth = BOOTH.replace("  interreflection: {lamp_bodies: false}\n", "")
    (tmp_path / "booth.yaml").write_text(booth)
    (tmp_path / "full.ies").write_text(_ies(FULL, True))
    (tmp_path / "bilateral.ies").write_text(_ies(BILATERAL, False))
    job = lighting_job(compile_booth(tmp_path / "booth.yaml"), "F")
    bodies = {m.id: m for m in job.meshes if m.role == "lamp_body"}
    # the other tube is there (black); point lamps have no body; the lamp that is on emits
    assert set(bodies) == {"lamp_body.M"} and bodies["lamp_body.M"].material == "lbscene_black"


@pytest.mark.slow
def test_prism_mirror_images_against_mitsuba():
    """~10 s: the validation scene mirror-prism (a tube under a 120° prism mirror, black box) baked
    by Cycles — the tube mirrored in each facet, shining through it, past the tube — against its
    committed Mitsuba 3 truth (which draws the facets as conductors, every reflection) along the
    floor's middle column, the far rows where each facet's edge cuts its image, and two corners."""
    from pathlib import Path

    from lbscene.engine.truth.validation import read_truth_csv

    scene = Path(__file__).resolve().parents[1] / "data" / "validation" / "mirror-prism"
    truth = read_truth_csv(scene / "truth-floor.csv")
    idx = [4, 13, 22, 31, 40, 49, 58, 0, 62]
    _, lux, noise, _ = bake_points(compile_booth(scene), "L", truth.points_mm[idx], surfaces="black",
                                   light_paths="direct", samples=4096)
    want = truth.illuminance_lx[idx]
    se = np.hypot(noise, truth.std_error_lx[idx] / want)
    assert np.all(np.abs(lux / want - 1) <= 0.01 + 4 * se), (lux / want, se)
