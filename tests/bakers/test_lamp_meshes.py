"""Bake jobs emit from the lamps' real surfaces: emissive meshes of the right area, facing out,
with radiance = reference intensity / projected area (no Blender needed)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lbscene.bakers.from_ir import lighting_job
from lbscene.bakers.job import AreaEmitter, PointEmitters
from lbscene.engine.scene.compile import compile_booth

LAMPS = """\
  - id: T
    type: tube
    position_mm: [0, -100, 700]
    axis: [1, 0, 0]
    length_mm: 590
    radius_mm: 13
    end_caps: true
    spd: {type: cie_illuminant, name: A}
    output: {type: luminance_cd_m2, value_cd_m2: 10000}
  - id: P
    type: panel
    position_mm: [0, 100, 700]
    length_mm: 400
    width_mm: 200
    spd: {type: cie_illuminant, name: A}
    output: {type: luminance_cd_m2, value_cd_m2: 5000}
  - id: B
    type: bulb
    position_mm: [300, 0, 600]
    radius_mm: 30
    spd: {type: cie_illuminant, name: A}
    output: {type: luminance_cd_m2, value_cd_m2: 20000}
  - id: X
    type: point
    position_mm: [-300, 0, 600]
    spd: {type: cie_illuminant, name: A}
    output: {type: peak_intensity_cd, value_cd: 100}
"""


@pytest.fixture
def job(minimal_booth):
    f = minimal_booth / "booth.yaml"
    s = f.read_text()
    a, b = s.index("lamps:\n") + len("lamps:\n"), s.index("lighting:")
    s = s[:a] + LAMPS + s[b:].replace("A: {lamps: [bulb]}", "A: {lamps: [T, P, B, X]}")
    f.write_text(s)
    ir = compile_booth(minimal_booth)
    return ir, lighting_job(ir, "A", environment=False, maps=False)


def _mesh(em):
    v = np.asarray(em.vertices_mm, float)
    t = np.asarray(em.triangles)
    cr = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    return v, t, cr


@pytest.mark.parametrize("lamp,area_mm2,proj_m2,lv", [
    ("T", 2 * math.pi * 13 * 590 + 2 * math.pi * 13 ** 2, 2 * 0.013 * 0.59, 10000),
    ("P", 400 * 200, 0.4 * 0.2, 5000),
    ("B", 4 * math.pi * 30 ** 2, math.pi * 0.03 ** 2, 20000),
])
def test_lamps_are_emissive_surfaces(job, lamp, area_mm2, proj_m2, lv):
    ir, jb = job
    (em,) = [e for e in jb.emitters if e.id == f"lamp.{lamp}"]
    assert isinstance(em, AreaEmitter) and not em.two_sided and not em.visible_to_camera
    v, t, cr = _mesh(em)
    assert 0.5 * np.linalg.norm(cr, axis=1).sum() == pytest.approx(area_mm2, rel=1e-9)
    # every facet faces away from the lamp's inside
    c = np.asarray(ir.lamp(lamp).position_mm, float)
    centroids = v[t].mean(axis=1)
    if lamp == "P":
        assert np.all(cr @ np.array([0, 0, -1.0]) > 0)          # toward aim only
    else:
        assert np.all(np.einsum("ij,ij->i", centroids - c, cr) > 0)
    # radiance: the declared luminance (band radiance × 683·V summed ≈ L_v through I_ref = L·A)
    lamp_ir = ir.lamp(lamp)
    bands = np.asarray(em.radiance_W_sr_m2_nm)
    want = ir.grid.integrate(lamp_ir.peak_intensity_1nm) / proj_m2
    assert bands == pytest.approx(want, rel=1e-9)
    assert lamp_ir.peak_luminous_intensity_cd / proj_m2 == pytest.approx(lv, rel=1e-6)


def test_point_lamps_stay_points(job):
    _, jb = job
    (em,) = [e for e in jb.emitters if e.id == "lamp.X"]
    assert isinstance(em, PointEmitters) and len(em.positions_mm) == 1


def test_effects_without_a_cycles_backend_are_named_in_the_job(job):
    ir, _ = job
    jb = lighting_job(ir, "A", effects={"detector_cosine_error": {}}, environment=False, maps=False)
    assert "not modelled by the bake" in jb.source["notes"]
    assert "detector_cosine_error" in jb.source["notes"]


def test_a_mirror_on_a_turning_luminaire_is_named_in_the_job(tmp_path):
    """The mirror image's window is placed at platform rotation 0: a job for a luminaire that
    turns with the platform says so rather than approximating silently."""
    import shutil

    src = Path(__file__).resolve().parents[2] / "booths" / "byk-byko-spectra-effect"
    dst = tmp_path / "byk"
    shutil.copytree(src, dst)
    y = (dst / "booth.yaml").read_text()
    y = y.replace("    mount: platform\n    provenance:\n      status: estimate\n      source: \"seed: PL-L 55W/950, N = 100;",
                  "    mount: platform\n    reflector: mirror\n    provenance:\n      status: estimate\n"
                  "      source: \"seed: PL-L 55W/950, N = 100;", 1)
    y = y.replace("occluders:\n", "reflectors:\n  mirror: {type: plane, reflectance: {type: constant, value: 0.9},"
                  " distance_mm: 30, normal: [0, -0.70710678, -0.70710678], width_mm: 100}\n\noccluders:\n", 1)
    y = y.replace("effects:\n", "effects:\n  reflector: {}\n", 1)
    (dst / "booth.yaml").write_text(y)
    ir = compile_booth(dst / "booth.yaml")
    assert ir.lamps[0].reflector == "mirror"
    job = lighting_job(ir, "FL950", environment=False, maps=False)
    assert "lamp PL-L_leg_a: its mirror image shines through the mirror as it lies at platform rotation 0" \
        in job.source["notes"]
    # a booth whose luminaire does not turn gets no such note
    plain = lighting_job(compile_booth(Path(__file__).resolve().parents[2] / "booths" / "xrite-spectralight-qc"),
                         "D65", environment=False, maps=False)
    assert "platform rotation 0" not in plain.source.get("notes", "")
