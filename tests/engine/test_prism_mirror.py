"""Prism (V) mirrors: two plane facets meeting at an apex along the lamp's axis.

Expected values come from outside the code under test: the image of a point in a wedge of
apex angle α lies on the circle of radius d about the apex, α from the point (plane geometry,
written here as an angle, not as the model's reflection); a 2D ray trace written here finds the
apex angle below which a ray from the lamp meets both facets; Mitsuba 3's truth of the
validation scene ``mirror-prism`` is what a plane mirror of the same width must miss."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light.effects.builtin.reflector import mirror_facets
from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.truth.validation import compare_with_truth

VALIDATION = Path(__file__).resolve().parents[1] / "data" / "validation"
D_MM, W_MM, R_MM = 35.0, 130.0, 13.0

BOOTH = """\
version: 1
kind: booth
name: Prism mirror test
provenance: {{status: synthetic, source: "lbscene test suite (prism mirror)"}}
interior: {{type: box, width_mm: 900, depth_mm: 600, height_mm: 700, open_front: true}}
materials:
  black: {{type: diffuse, reflectance: {{type: constant, value: 0.0}}}}
surfaces: {{floor: black, left_wall: black, right_wall: black, rear_wall: black, ceiling: black}}
lamps:
  - {{id: tube, type: tube, position_mm: [0, 40, 560], axis: [1, 0, 0], length_mm: 600, radius_mm: {r},
     reflector: m, spd: {{type: constant, value: 1.0}}, output: {{type: luminance_cd_m2, value_cd_m2: 10000}}}}
reflectors:
  m: {{type: {type}, {apex}reflectance: {{type: constant, value: 0.9}}, distance_mm: {d}, normal: [0, 0, -1],
      width_mm: {w}}}
lighting:
  L: {{lamps: [tube]}}
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
effects:
  reflector: {{}}
"""


def _ir(tmp_path, name, type_="prism", apex=None):
    d = tmp_path / name
    d.mkdir()
    a = "" if apex is None else f"apex_angle_deg: {apex}, "
    (d / "booth.yaml").write_text(BOOTH.format(type=type_, apex=a, d=D_MM, w=W_MM, r=R_MM))
    return compile_booth(d / "booth.yaml")


@pytest.mark.parametrize("apex", [90.0, 120.0, 150.0])
def test_each_facet_images_the_lamp_on_the_circle_about_the_apex(tmp_path, apex):
    """Seen from the apex, the lamp's image in a facet lies at the lamp's distance and the apex
    angle away from it (two reflections' worth of angle: across the facet at α/2)."""
    ir = _ir(tmp_path, "b", apex=apex)
    lamp, refl = ir.lamps[0], ir.reflectors["m"]
    facets = mirror_facets(ir, lamp, refl)
    assert len(facets) == 2
    p = np.asarray(lamp.position_mm, float)
    apex_pt = p + np.array([0.0, 0.0, D_MM])
    a = np.radians(apex)
    expected = [apex_pt + D_MM * np.array([0.0, s * np.sin(a), -np.cos(a)]) for s in (-1, 1)]
    images = [p - 2.0 * ((p - f.centre) @ f.normal) * f.normal for f in facets]
    for img in images:
        assert min(np.linalg.norm(img - e) for e in expected) < 1e-9
    # the facets meet at the apex, (180° − α) apart, each width_mm / 2 wide, facing the lamp
    n0, n1 = (np.asarray(f.normal) for f in facets)
    assert np.degrees(np.arccos(np.clip(n0 @ n1, -1, 1))) == pytest.approx(180.0 - apex)
    for f in facets:
        assert f.half[1] == pytest.approx(W_MM / 4)
        assert (p - f.centre) @ f.normal > R_MM
        assert abs((apex_pt - f.centre) @ f.normal) < 1e-9


def test_a_prism_of_180_degrees_is_the_plane_mirror(tmp_path):
    """Two coplanar facets are the plane mirror: the same light everywhere (within 1e-4: a
    facet's image is seen through it by the footprints of its lines, a plane mirror's line by line)."""
    P = np.array([[x, y, 0.0] for x in (-300.0, 0.0, 250.0) for y in (-250.0, 40.0, 200.0)] + [[0, 300, 400.0]])
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    flat = ForwardModel(_ir(tmp_path, "p180", apex=180), "L").illuminance_lx(P, N, meter=False)
    plane = ForwardModel(_ir(tmp_path, "plane", type_="plane"), "L").illuminance_lx(P, N, meter=False)
    np.testing.assert_allclose(flat, plane, rtol=1e-4)


def _double_reflections(apex_deg, d=D_MM, facet=W_MM / 2, r=0.0, rays=20001):
    """Share of the rays (uniform in angle, 2D) from the points of a circle of radius ``r``
    about (0, d) — the apex at the origin, the facets leaving it downward-facing toward +y —
    that meet one facet and then the other (a ray trace written here)."""
    b = np.radians((180.0 - apex_deg) / 2.0)
    ends = [np.array([s * np.cos(b), np.sin(b)]) * facet for s in (-1.0, 1.0)]

    def hit(o, u, k):
        e = ends[k]                                        # segment from the origin to e
        M = np.array([[u[0], -e[0]], [u[1], -e[1]]])
        if abs(np.linalg.det(M)) < 1e-12:
            return None
        t, s = np.linalg.solve(M, -o)
        return (t, o + t * u) if t > 1e-9 and 0.0 <= s <= 1.0 else None

    starts = [np.array([0.0, d])] if r == 0 else [np.array([r * np.cos(q), d + r * np.sin(q)])
                                                 for q in np.linspace(0, 2 * np.pi, 36, endpoint=False)]
    twice = total = 0
    for o in starts:
        for ang in np.linspace(0, 2 * np.pi, rays // len(starts) + 1, endpoint=False):
            u = np.array([np.cos(ang), np.sin(ang)])
            if r > 0 and (u @ (o - np.array([0.0, d]))) <= 0:
                continue                                   # a surface point emits outward only
            total += 1
            hits = [(h, k) for k in (0, 1) if (h := hit(o, u, k)) is not None]
            if not hits:
                continue
            (t, x), k = min(hits, key=lambda z: z[0][0])
            e = ends[k] / np.linalg.norm(ends[k])
            n = np.array([-e[1], e[0]])
            u2 = u - 2 * (u @ n) * n
            twice += hit(x, u2, 1 - k) is not None
    return twice / total


def test_light_meets_both_facets_only_under_120_degrees():
    """The module's claim: from a lamp on the prism's axis no ray meets both facets at 120° or
    more; under it some do (the linter warns there, LB314)."""
    assert _double_reflections(120.5) == 0.0
    assert _double_reflections(150.0) == 0.0
    assert _double_reflections(110.0) > 0.01


def test_a_tube_under_a_120_degree_prism_sends_little_light_twice():
    """The fringe the module docstring bounds: the points of a tube off the prism's axis can meet
    both facets up to 120° + ⅔·arcsin(r/d) (radius 13 mm at 35 mm: 134.5°; 6 mm: 126.6°); at
    120° a few percent of the rays leaving the tube do (the validation scene's model, which
    leaves them out, is within 0.3 % of Mitsuba 3, which draws them)."""
    assert 0.0 < _double_reflections(120.0, r=R_MM, rays=40000) < 0.03
    assert 0.0 < _double_reflections(120.0, r=6.0, rays=40000) < 0.015
    assert _double_reflections(136.0, r=R_MM, rays=40000) == 0.0
    assert _double_reflections(128.0, r=6.0, rays=40000) == 0.0


@pytest.mark.parametrize("grid", ["a3", "floor"])
def test_a_plane_mirror_of_the_same_width_misses_the_prism_truth(tmp_path, grid):
    """The prism's truth is not a plane mirror's: the same booth with its mirror declared as one
    plane 130 mm wide is far off Mitsuba 3 (the image hides behind the tube: 49 % RMS on the A3
    sheet, 37 % over the floor); as the prism it is within the scene's threshold."""
    scene = VALIDATION / "mirror-prism"
    text = (scene / "booth.yaml").read_text()
    assert "type: prism" in text and "    apex_angle_deg: 120\n" in text
    plane_dir = tmp_path / "as-plane"
    plane_dir.mkdir()
    (plane_dir / "booth.yaml").write_text(text.replace("type: prism", "type: plane")
                                          .replace("    apex_angle_deg: 120\n", ""))
    (plane_dir / f"truth-{grid}.csv").write_text((scene / f"truth-{grid}.csv").read_text())
    prism = compare_with_truth(scene, grid)
    plane = compare_with_truth(plane_dir, grid)
    assert compile_booth(plane_dir).reflectors["prism"].type == "plane"
    assert prism.rms_noise_removed_percent <= 1.0
    assert plane.rms_percent > 20.0


def test_the_bake_job_has_an_image_and_a_plate_per_facet(tmp_path):
    """Cycles gets the prism as the model draws it: the tube mirrored in each facet, shining only
    through that facet, and each facet an absorbing plate."""
    from lbscene.bakers.from_ir import lighting_job

    ir = _ir(tmp_path, "b", apex=120)
    job = lighting_job(ir, "L", environment=False, maps=False)
    images = sorted((e for e in job.emitters if ".mirror" in e.id), key=lambda e: e.id)
    assert [e.id for e in images] == ["lamp.tube.mirror0", "lamp.tube.mirror1"]
    plates = sorted(m.id for m in job.meshes if m.role == "mirror")
    assert plates == ["mirror.tube.facet0", "mirror.tube.facet1"]
    centre = np.array([0.0, 40.0, 560.0 + D_MM])              # the apex line's middle
    seen = []
    for e in images:
        v = np.asarray(e.vertices_mm, float)
        axis_pt = v.mean(axis=0)                               # the image tube's centre
        seen.append(np.round(axis_pt - centre, 6))
        n = np.asarray(e.window.normal, float)
        assert np.degrees(np.arccos(-n[2])) == pytest.approx(30.0)   # facets 30° off the plane
    # the images lie 35 mm from the apex, 120° from the lamp: (±35 sin 120°, 35 cos 60°) mm
    got = np.array(sorted(tuple(s[1:]) for s in seen))
    side = D_MM * np.sin(np.radians(120))
    np.testing.assert_allclose(got, [[-side, D_MM * 0.5], [side, D_MM * 0.5]], atol=1e-6)


def test_the_mitsuba_truth_draws_two_conductor_facets(tmp_path):
    pytest.importorskip("mitsuba")
    from lbscene.engine.truth.mitsuba import MitsubaTruth

    ir = _ir(tmp_path, "b", apex=100)
    d = MitsubaTruth(ir, "L", effects={"reflector": {}})._mirrors()
    assert sorted(d) == ["mirror_tube_facet0", "mirror_tube_facet1"]
    normals = []
    for v in d.values():
        assert v["type"] == "rectangle" and v["bsdf"]["type"] == "conductor"
        T = np.array(v["to_world"].matrix, float)
        normals.append(T[:3, 2] / np.linalg.norm(T[:3, 2]))
    assert np.degrees(np.arccos(normals[0] @ normals[1])) == pytest.approx(80.0)


def test_the_linter_names_what_the_model_leaves_out(tmp_path):
    """LB314: a prism under 120° (facet-to-facet light left out), a parabolic trough (a plane)."""
    from lbscene.engine.conformance.validate import validate_paths

    for name, type_, apex, expected in [
        ("p100", "prism", 100, "reflector 'm': apex angle 100° is under 120°, where light meets both facets; "
                               "the model draws one reflection per facet and leaves the facet-to-facet "
                               "reflections out (Mitsuba and Cycles draw them)"),
        ("trough", "parabolic_trough", None, "reflector 'm' is a parabolic trough: the model and the Cycles "
                                             "bakes draw it as a plane mirror of the same width (its focusing "
                                             "is not modelled; the Mitsuba truth refuses it)"),
        ("p120", "prism", 120, None)]:
        _ir(tmp_path, name, type_=type_, apex=apex)
        rep = validate_paths([tmp_path / name / "booth.yaml"])
        found = [d for d in rep.diagnostics if d.code == "LB314"]
        assert rep.errors == 0
        if expected is None:
            assert found == []
        else:
            assert [(d.severity.value, d.message) for d in found] == [("warning", expected)]


def test_apex_angle_belongs_to_prisms_only(tmp_path):
    from lbscene.engine.conformance.validate import validate_paths

    d = tmp_path / "plane"
    d.mkdir()
    (d / "booth.yaml").write_text(BOOTH.format(type="plane", apex="apex_angle_deg: 120, ", d=D_MM, w=W_MM, r=R_MM))
    rep = validate_paths([d / "booth.yaml"])
    assert rep.exit_code(strict=False) == 2
    assert [x.message for x in rep.diagnostics if x.code == "LB104"] == [
        "reflectors.m: apex_angle_deg applies to prism reflectors only (this one is 'plane')"]


def test_the_usd_stage_holds_the_facets(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    from lbscene.engine.scene.usd_stage import stage_to_string

    ir = _ir(tmp_path, "b", apex=120)
    stage = Usd.Stage.CreateInMemory()
    stage.GetRootLayer().ImportFromString(stage_to_string(ir))
    prim = stage.GetPrimAtPath("/Booth/Optics/reflector_m")
    assert prim.GetAttribute("lbscene:reflector:apex_angle_deg").Get() == 120
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Booth/Optics/reflector_m/tube"))
    pts = np.asarray(mesh.GetPointsAttr().Get(), float)
    assert len(pts) == 8 and len(mesh.GetFaceVertexCountsAttr().Get()) == 4
    # two facets from the apex line (z 595) down to their edges, 65 mm wide at 30°: z 562.5
    np.testing.assert_allclose(sorted(set(np.round(pts[:, 2], 3))), [595.0 - 32.5, 595.0], atol=2e-3)
    np.testing.assert_allclose(sorted(set(np.round(pts[:, 1], 3))),
                               [40 - 65 * np.cos(np.radians(30)), 40.0, 40 + 65 * np.cos(np.radians(30))],
                               atol=2e-3)


def test_the_reference_engine_draws_the_facets_too():
    """The Monte Carlo reference (its own facet geometry: each half of the plane mirror turned
    about the apex line) against the Mitsuba truth of mirror-prism, down the floor's middle
    column and at its corners (measured within 0.6 %)."""
    from lbscene.engine.truth.reference import ReferenceEngine
    from lbscene.engine.truth.validation import read_truth_csv

    scene = VALIDATION / "mirror-prism"
    truth = read_truth_csv(scene / "truth-floor.csv")
    idx = [4, 13, 22, 31, 40, 49, 58, 0, 62]
    ref = ReferenceEngine(compile_booth(scene), "L", samples_per_lamp=40000, seed=1).illuminance_lx(
        truth.points_mm[idx], truth.normals[idx], meter=False)
    np.testing.assert_allclose(ref, truth.illuminance_lx[idx], rtol=0.015)
