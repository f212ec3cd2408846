"""Cross-check: Cycles (path tracing) against the analytic forward model (radiosity), real bakes.

Two independent engines must agree within a tolerance set by the bake's own
noise: ``tolerance + 4 σ`` (σ: RMS relative noise of the bake at the points,
two-half estimate).  The cavity booth is the BYK's luminaire in miniature: a
white box around a tube with a rectangular aperture underneath, so most of
the light reaching the floor has bounced inside the cavity.  It checks that
the model includes a mesh in its inter-reflection (both faces reflect, the
mesh blocks light), and that Cycles does not z-fight the aperture plate
against the cavity's coplanar bottom face.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lbscene.bakers.crosscheck import cross_check

pytestmark = pytest.mark.bake

MINIMAL = Path(__file__).resolve().parents[1] / "data" / "minimal-booth"

#: 3 × 3 points on the floor under the lamp (mm)
POINTS = np.array([(x, y, 0.0) for y in (-80.0, 0.0, 80.0) for x in (-120.0, 0.0, 120.0)])

# Cavity (local frame: lamp at the origin, -z toward the floor): 260 × 100 × 60 mm, aperture
# 220 × 50 mm in the bottom face; faces wound so that their normals point into the cavity.
CAVITY_OBJ = """\
v -130 -50 -30
v 130 -50 -30
v 130 50 -30
v -130 50 -30
v -130 -50 30
v 130 -50 30
v 130 50 30
v -130 50 30
v -110 -25 -30
v 110 -25 -30
v 110 25 -30
v -110 25 -30
f 5 8 7 6
f 1 5 6 2
f 4 3 7 8
f 1 4 8 5
f 2 6 7 3
f 1 2 10 9
f 12 11 3 4
f 1 9 12 4
f 2 3 11 10
"""

CAVITY_BOOTH = """\
version: 1
kind: booth
name: Cavity test booth
provenance: {status: synthetic, source: "lbscene test suite"}
interior: {type: box, width_mm: 400, depth_mm: 300, height_mm: 320, open_front: true}
materials:
  dark: {type: diffuse, reflectance: {type: constant, value: 0.05}}
  white: {type: diffuse, reflectance: {type: constant, value: 0.8}}
surfaces: {floor: dark, left_wall: dark, right_wall: dark, rear_wall: dark, ceiling: dark}
geometry_files:
  - {type: obj, id: cavity, path: cavity.obj, material: white,
     transform: {translate_mm: [0, 0, 230]}}
lamps:
  - id: tube
    type: tube
    position_mm: [0, 0, 230]
    axis: [1, 0, 0]
    aim: [0, 0, -1]
    length_mm: 200
    radius_mm: 8
    spd: {type: cie_illuminant, name: D65}
    output: {type: peak_intensity_cd, value_cd: 100}
    point_sources: 20
lighting:
  D65: {lamps: [tube]}
occluders:
  # the cavity's bottom face again, as the aperture plate that shades the lamp (coplanar)
  - {id: aperture, type: aperture_plate, centre_mm: [0, 0, 200], normal: [0, 0, -1],
     size_mm: [260, 100], opening_mm: [220, 50], u_axis: [1, 0, 0], material: dark}
geometries: [{name: 45as45}]
observer: {type: eye_point, position_mm: [0, -600, 300]}
effects:
  aperture_occlusion: {}
  interreflection: {patch_size_mm: 25}
"""


@pytest.fixture(scope="module")
def cavity_ir(tmp_path_factory):
    from lbscene.engine.scene.compile import compile_booth

    folder = tmp_path_factory.mktemp("cavity-booth")
    (folder / "cavity.obj").write_text(CAVITY_OBJ)
    (folder / "booth.yaml").write_text(CAVITY_BOOTH)
    return compile_booth(folder / "booth.yaml")


def _within(check, tol_percent):
    d = 100.0 * (check.ratio - 1.0)
    limit = tol_percent + 4.0 * 100.0 * check.noise_rms
    return np.abs(d), limit


def test_direct_light_agrees_with_the_model_on_the_minimal_booth():
    """A point lamp over a grey box: inverse-square cosine law in both engines."""
    from lbscene.engine.scene.compile import compile_booth

    ir = compile_booth(MINIMAL / "booth.yaml")
    check = cross_check(ir, "A", mode="direct", points=POINTS, samples=16)
    d, limit = _within(check, 1.0)
    assert np.all(d <= limit), (d, limit)
    # the two engines compute the same closed form: far tighter than the tolerance
    assert np.all(d < 0.05), d
    s = check.summary()
    assert s["agrees"] and s["points"] == len(POINTS) and s["effects"] == []


@pytest.mark.slow
def test_white_cavity_lit_from_inside_agrees_with_the_model(cavity_ir):
    """~35 s: direct light and inter-reflection in the cavity booth, Cycles vs the model."""
    from lbscene.bakers.products import band_photopic_weights
    from lbscene.engine.light.forward import ForwardModel

    direct = cross_check(cavity_ir, "D65", mode="direct", points=POINTS, samples=512)
    d, limit = _within(direct, 2.0)
    assert np.all(d <= limit), ("direct", d, limit)

    inter = cross_check(cavity_ir, "D65", mode="interreflection", points=POINTS, samples=16384)
    assert inter.max_bounces == 64                      # converged paths, as the model's radiosity
    assert inter.noise_rms < 0.015, inter.noise_rms
    d, limit = _within(inter, 3.0)
    assert np.all(d <= limit), ("interreflection", d, limit, inter.summary())
    # the plate lies on the cavity's face: counting its shadow on top of the mesh's (the gather's
    # two visibilities multiplied) put the model 3 % under Cycles, outside the bake's noise
    assert inter.agrees, inter.summary()
    # the cavity is most of the light on the floor ...
    assert inter.cycles_lx.mean() > 1.5 * direct.cycles_lx.mean()
    # ... which the model missed when it left meshes out of its radiosity
    eff = dict(cavity_ir.effects)
    eff["interreflection"] = {**eff["interreflection"], "meshes": False}
    old = ForwardModel(cavity_ir, "D65", effects=eff).spectral_irradiance_bands(POINTS)
    assert np.all(inter.cycles_lx > 1.5 * (old @ band_photopic_weights(cavity_ir.grid)))


def test_a_closed_black_mesh_around_the_lamp_leaves_no_light_to_reflect(tmp_path):
    """Closed form: a lamp inside a closed, black mesh box lights nothing else, so the booth's
    (grey, 50 %) surfaces have nothing to inter-reflect; the radiosity must see the mesh block
    the lamp's light (before meshes took part, the walls were lit straight through it).
    The mesh's own inside, lit by the lamp, reflects nothing (ρ = 0)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.light.forward import ForwardModel

    obj = "\n".join(f"v {x} {y} {z}" for x in (-50, 50) for y in (-50, 50) for z in (-50, 50))
    # the 6 faces of the cube (vertex k = 4·[x>0] + 2·[y>0] + [z>0] + 1), wound outward
    obj += "\nf 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n"
    (tmp_path / "box.obj").write_text(obj)
    text = (MINIMAL / "booth.yaml").read_text()
    text = text.replace("  paint: {type: diffuse, reflectance: {type: csv, path: spectra/paint.csv}}",
                        "  paint: {type: diffuse, reflectance: {type: constant, value: 0.5}}\n"
                        "  black: {type: diffuse, reflectance: {type: constant, value: 0.0}}")
    text = text.replace("lamps:\n", "geometry_files:\n  - {type: obj, id: box, path: box.obj, material: black,"
                                     " transform: {translate_mm: [0, 0, 700]}}\nlamps:\n", 1)
    text += "effects:\n  interreflection: {patch_size_mm: 100}\n"
    (tmp_path / "booth.yaml").write_text(text)
    ir = compile_booth(tmp_path / "booth.yaml")
    pts = [(0, 0, 0), (300, 100, 0), (-400, -200, 0)]
    fm = ForwardModel(ir, "A")
    direct = ForwardModel(ir, "A", effects={}).illuminance_lx(pts, meter=False)
    total = fm.illuminance_lx(pts, meter=False)
    # the analytic model's direct light ignores meshes (occluders do that): only the
    # inter-reflected part is tested here, and it must be exactly zero
    np.testing.assert_allclose(total, direct, rtol=1e-12, atol=1e-9)
    # same booth, mesh left out of the radiosity: the lit walls reflect ~10 % more
    eff = {"interreflection": {"patch_size_mm": 100, "meshes": False}}
    assert np.all(ForwardModel(ir, "A", effects=eff).illuminance_lx(pts, meter=False) > 1.05 * direct)


def test_cli_cross_check_json(run_cli):
    code, out, err = run_cli("bake", MINIMAL, "--cross-check",
                             "--cross-check-mode", "direct", "--samples", "8", "--format", "json")
    assert code == 0, err
    d = json.loads(out)
    [row] = d["cross_check"]
    assert row["mode"] == "direct" and row["lighting"] == "A" and row["points"] == 55
    assert row["agrees"] and abs(row["mean_diff_percent"]) < 0.05


def test_cli_cross_check_unknown_lighting_is_a_user_error(run_cli):
    code, out, err = run_cli("bake", MINIMAL, "--cross-check", "-l", "D65")
    assert code == 2
    assert "LB500" in err and "'D65'" in err


def test_cli_cross_check_reports_a_failed_cycles_bake_without_a_traceback(run_cli, monkeypatch):
    # Cycles failing inside its process (an exception in the scene build) is said as a failed
    # bake is: LB600, the error and its log's last lines, exit status 1, in text and in JSON
    import lbscene.bakers.executor as executor

    def failing(tasks, **kw):
        return [executor.TaskResult(t, "failed", 0.0, error="AttributeError: no such socket",
                                    log_tail=["Traceback (most recent call last):", "  in _sheet",
                                              "AttributeError: no such socket"]) for t in tasks]

    monkeypatch.setattr(executor, "run_tasks", failing)
    code, out, err = run_cli("bake", MINIMAL, "--cross-check", "--cross-check-mode", "direct", "--samples", "8")
    assert code == 1, err
    assert "error LB600: Cycles bake A.points.black.all failed: AttributeError: no such socket" in err
    assert "    AttributeError: no such socket" in err
    assert "Traceback" not in err.replace("    Traceback (most recent call last):", "")
    code, out, err = run_cli("bake", MINIMAL, "--cross-check", "--cross-check-mode", "direct", "--samples", "8",
                             "--format", "json")
    assert code == 1
    d = json.loads(out)
    assert d["ok"] is False and d["error"]["code"] == "LB600"
    assert d["error"]["log_tail"][-1] == "AttributeError: no such socket"


SHIPPED = Path(__file__).resolve().parents[2] / "booths"
#: why the opal-plate booth's bake is not its model (measured: Cycles / model - 1 at final quality)
_OPAL_SLAB = ("the bake draws the opal plate as the Mitsuba truth does (a slab of a Henyey-Greenstein medium, "
              "its g from the plane-parallel layer).  At final quality opal-cavity-45's direct light agrees; "
              "with inter-reflection Cycles / model - 1 = -0.70 % (noise 1.00 %, -4.2 sigma), while Cycles is "
              "-0.78 % (0.14 %) off the Mitsuba truth and the model -0.08 %.  Not noise: on opal-grey Cycles is "
              "-0.84 +- 0.20 % off Mitsuba at 32768 samples and -0.67 +- 0.09 % at 131072 (the model +0.35 %).  "
              "Not the slab's optics: alone in Cycles it is the photon Monte Carlo's layer (a collimated beam at "
              "0 to 85 degrees; diffuse light with a floor of reflectance 0 and 0.8: +0.08 and +0.09 %, "
              "test_opal_bake.py).  Not the lamps' sampling: with their next-event estimation off, opal-grey "
              "is -0.48 +- 0.15 % off Mitsuba; nor its volume algorithm: ray-marched (volume_biased) -0.66 +- 0.11 % "
              "at 131072 samples.  Where Cycles loses the light in a booth is not traced")
VALIDATION = Path(__file__).resolve().parents[1] / "data" / "validation"
#: the SpectraLight's inter-reflected light, measured at final quality against two renderers
_SPECTRALIGHT = ("the model's light with inter-reflection is above Cycles in the SpectraLight at D65: Cycles / model "
                 "- 1 = -0.50 % at the final preset's 24377 samples (3.2 sigma); its direct light agrees (+0.02 %). "
                 "It was -0.74 % (4.8 sigma) while the lamps' images in the glass plate lit the luminaire cavity "
                 "through the D65 boxes' masks (receivers under the plate facing the cavity: the model 11 % high, "
                 "then within 1 %).  With the boxes' walls black and the cavity's ceiling black -0.24 % (1.8 sigma), "
                 "without the plate -0.26 % (2.2 sigma): a part of the rest is the bake's own (its mean rose "
                 "0.11 % from 24377 to 65536 samples), not yet traced further.  The lamps that shine into the open "
                 "cavity (TL84, A) agree since the patches' first-order light is integrated at Gauss points and "
                 "patches are cut finer at the bodies of the lamps that are off")


@pytest.mark.slow
@pytest.mark.parametrize("folder,lighting", [pytest.param("xrite-spectralight-qc", "D65", id="xrite-spectralight-qc-D65",
                                                          marks=pytest.mark.xfail(strict=True, reason=_SPECTRALIGHT)),
                                             ("xrite-spectralight-qc", "TL84"),
                                             ("xrite-spectralight-qc", "A"),
                                             ("iso3664-p1-d50", "P1"),
                                             ("byk-byko-spectra-effect", "FL950"),
                                             pytest.param(VALIDATION / "opal-cavity-45", "L", id="opal-cavity-45-L",
                                                          marks=pytest.mark.xfail(strict=True, reason=_OPAL_SLAB))])
def test_shipped_booths_agree_with_cycles_within_the_bake_noise(folder, lighting):
    """~20 s (X-Rite, ISO) to ~2 min (BYK): final-quality bakes of each shipped booth's lighting
    against the model, direct light and with inter-reflection.  Both must be the bake's noise
    alone: the white lamp boxes the model had left black (X-Rite, inter-reflection 1 % low),
    the tube legs it had let through the BYK's cavity (34 % high) and the aperture plate's
    shadow it counted twice there (3 % low) each failed this, and so did the SpectraLight's lamps in
    its open white cavity (TL84 0.6 % and A 1.2 % low: the patches' first-order light taken at
    their centres, the ceiling behind the dark UV tube cut coarsely).  With them an opal-plate booth
    (the validation scene ``opal-cavity-45``: three tubes in a white cavity over an opal plate,
    0.45 walls), whose plate Cycles renders as the Mitsuba truth does: a slab of a scattering
    medium (``lbscene.bakers.opal_slab``; about 4 min direct and 9 min with inter-reflection on
    two busy cores)."""
    from lbscene.bakers.crosscheck import cross_check_all
    from lbscene.engine.scene.compile import compile_booth, find_booth_file

    ir = compile_booth(find_booth_file(SHIPPED / folder))
    checks = cross_check_all(ir, lighting, quality="final")
    assert [c.mode for c in checks] == ["direct", "interreflection"]
    for c in checks:
        assert c.agrees, c.summary()
