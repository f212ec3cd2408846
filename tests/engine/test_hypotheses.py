"""Hypotheses for undeclared hardware: their building blocks against closed forms, and the YAML
they write against the booth schema and compiler."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light.effects.builtin.lamp_spectrum_shift import shifted_spectrum_1nm
from lbscene.engine.loop.hypotheses import (HYPOTHESES, AperturePlateHypothesis, CeilingReflectanceHypothesis,
                                            DiffuserPlateHypothesis, GeometryParameter, MirrorHypothesis,
                                            applicable_hypotheses, filter_basis, paste_hardware,
                                            profile_geometry)

DATA = Path(__file__).resolve().parents[1] / "data"


class _ToyFit:
    """A refit at profile point ``x`` whose χ² is ``chi2(x)`` (60 degrees of freedom)."""

    def __init__(self, x, chi2):
        self.x, self.chi2, self.dof, self.values, self.stderr = x, chi2(x), 60, {}, {}


def _toy_hypothesis(*params):
    """A hypothesis ``toy`` profiling ``params`` (GeometryParameter); the profile point is the
    value itself for one parameter, the dict of values for several."""
    class H:
        id = "toy"

        @staticmethod
        def geometry(ir, lighting):
            return list(params)

        @staticmethod
        def regeometry(ir, lighting, values):
            return values[params[0].name] if len(params) == 1 else dict(values)

    return H


#: the two properties the joint-profile tests fit together
_PAIR = (GeometryParameter("opening_v_mm", (100.0, 150.0, 200.0, 250.0, 300.0), 150.0, (100.0, 300.0)),
         GeometryParameter("gap_mm", (5.0, 20.0, 45.0, 80.0, 130.0), 20.0, (1.0, 130.0)))


def _pair_profiled(chi2):
    """The toy pair profiled from (150, 20) on refits of χ² ``chi2``: ``(fit, joint entry)``."""
    v0 = {"opening_v_mm": 150.0, "gap_mm": 20.0}
    _, fit, _, _ = profile_geometry(_toy_hypothesis(*_PAIR), v0, "L", lambda v, start: (None, _ToyFit(v, chi2)),
                                    _ToyFit(v0, chi2), None)
    return fit, fit.hypothesis_data["joint"]["toy"]["opening_v_mm|gap_mm"]


def test_filter_basis_is_a_partition_of_unity_over_the_measured_range():
    B = filter_basis(12)
    assert B.shape == (471, 12)
    assert np.allclose(B.sum(axis=1), 1.0)
    assert (B >= 0).all()
    # a constant log-transmittance is exactly representable: T = e^c
    assert np.allclose(np.exp(B @ np.full(12, np.log(0.5))), 0.5)


def test_spectrum_shift_moves_a_line_and_keeps_its_area():
    s = np.zeros(471)
    s[200] = 1.0                                            # 560 nm
    out = shifted_spectrum_1nm(s, 2.5)
    assert out.sum() == pytest.approx(1.0)
    centroid = (np.arange(471) * out).sum() / out.sum()
    assert 360 + centroid == pytest.approx(562.5)
    # the tilt is a ramp through 1 at 555 nm
    flat = shifted_spectrum_1nm(np.ones(471), 0.0, 0.2)
    assert flat[195] == pytest.approx(1.0) and flat[395] == pytest.approx(1.2)


def test_hypotheses_apply_only_to_hardware_the_booth_lacks():
    from lbscene.engine.scene.compile import compile_booth

    hardware = {h for h, H in HYPOTHESES.items() if H.hardware}
    assert hardware == {"diffuser_plate", "aperture_plate", "smooth_filter", "mirror", "ceiling_reflectance",
                        "walls_reflectance"}
    full = compile_booth(DATA / "hidden-effect-booth" / "booth.yaml")
    todo, skipped = applicable_hypotheses(full, "FL")
    # an aged lamp spectrum is no hardware: it applies to every booth
    assert [h.id for h in todo] == ["lamp_ageing"] and set(skipped) == hardware
    # a surface's reflectance matters only where the surfaces inter-reflect
    assert skipped["ceiling_reflectance"] == "inter-reflection is off: the model's surfaces reflect nothing"
    bare = compile_booth(DATA / "validation" / "walls-05" / "booth.yaml")
    todo, _ = applicable_hypotheses(bare, "L")
    assert {h.id for h in todo} == set(HYPOTHESES)


def _fake_fit(values, stderr=None):
    class F:
        pass
    f = F()
    f.values, f.stderr = values, stderr or {}
    return f


@pytest.mark.parametrize("H,values", [
    (DiffuserPlateHypothesis, {"effect.diffuser.diffuse_fraction": 0.37,
                               "effect.diffuser.transmittance_scale": 0.8}),
    (AperturePlateHypothesis, {"effect.aperture_occlusion.opening_scale_u": 0.9,
                               "effect.aperture_occlusion.opening_scale_v": 1.3}),
    (MirrorHypothesis, {"effect.reflector.reflectance_scale": 0.72}),
    (CeilingReflectanceHypothesis, {"effect.surface_reflectance.ceiling_scale": 0.5}),
])
def test_plate_hypothesis_yaml_validates_and_compiles_to_the_fitted_hardware(H, values, tmp_path):
    from lbscene.engine.scene.compile import compile_booth

    src = DATA / "validation" / "walls-05"
    ir = compile_booth(src / "booth.yaml")
    aug, eff, free = H.augment(ir, "L", ["tube_front", "tube_rear"])
    assert {fp.target for fp in free} <= set(values)
    text = H.hardware_yaml(aug, _fake_fit(values))
    booth = tmp_path / "b"
    shutil.copytree(src, booth)
    f = booth / "booth.yaml"
    # merged as the user pastes it: sections the booth has gain keys or items by id
    f.write_text(paste_hardware(f.read_text(), text + "effects:\n  interreflection: {}\n  " + H.effect + ": {}\n"))
    out = compile_booth(f)
    if H is MirrorHypothesis:
        # merged by id: the lamps that are on carry the fitted mirror
        r = out.reflectors["fitted_mirror"]
        assert np.allclose(r.reflectance.array_1nm, 0.72) and r.normal == (0.0, 0.0, -1.0)
        assert {lp.id: lp.reflector for lp in out.lamps} == {"tube_front": "fitted_mirror",
                                                              "tube_rear": "fitted_mirror"}
    elif H is CeilingReflectanceHypothesis:
        ceiling = next(s for s in out.surfaces if s.role == "ceiling")
        assert ceiling.material == "fitted_ceiling"
        rho0 = ir.materials[next(s for s in ir.surfaces if s.role == "ceiling").material].reflectance.array_1nm
        assert np.allclose(out.materials["fitted_ceiling"].reflectance.array_1nm[40:341], 0.5 * rho0[40:341].mean(),
                           atol=5e-4)
    elif H is DiffuserPlateHypothesis:
        d = out.diffuser
        # an opal plate without a measured reflectance absorbs nothing (reflectance None: 1 - T)
        assert d.scattering == {"type": "lambertian", "diffuse_fraction": 0.37, "reflectance": None}
        assert d.z_mm == pytest.approx(620 - 13 - 20)
        assert np.allclose(d.transmittance.array_1nm, 0.8)
    else:
        plate = next(o for o in out.occluders if o.type == "aperture_plate")
        # the lamps' footprint (600 + 2·13 by 240 + 2·13) plus 20 mm each side, scaled
        assert plate.opening_mm == pytest.approx((666 * 0.9, 306 * 1.3))
        assert len(out.occluders) == 5      # plate + four black cavity sides


# slow: with the plate in the inter-reflection, every rough-glass refit lights the radiosity's
# patches through the plate's BTDF (minutes on 2 cores)
@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason=(
    "ambiguous:angular_profile,surface_reflectance,tube_end_falloff: every candidate reaches the "
    "noise on this level drop (χ² 117 to 121 on 55 readings), the plate too (χ² 118.8, rough glass "
    "0.35 at 27 mm, f_d 0.66, T 0.81), but with five parameters pinned it scores 20 BIC units "
    "under the one-parameter explanations, out of the tie's 10"))
def test_an_undeclared_diffusing_plate_is_among_the_explanations(tmp_path):
    """Truth: the 45 % walls scene with a Lambertian-scattering plate (flat transmittance 0.85,
    diffuse fraction 0.6) that the user's booth does not declare.  Mitsuba has no such plate, so
    the truth is the brute-force Monte Carlo reference engine (its own sampling and transport).
    With the output known, the A3 grid sees a level drop several shapes explain: the verdict
    must list the plate, and never a filter (a level is not a spectrum)."""
    from lbscene.engine.loop.compare import run_compare
    from lbscene.engine.truth.synthetic import synthesize

    src = DATA / "validation" / "walls-45"
    full, user = tmp_path / "full", tmp_path / "user"
    for d in (full, user):
        d.mkdir()
        shutil.copy(src / "booth.yaml", d / "booth.yaml")
    t = (full / "booth.yaml").read_text().replace("lighting:", (
        "diffuser:\n  z_mm: 570\n  size_mm: [880, 580]\n  transmittance: {type: constant, value: 0.85}\n"
        "  scattering: {type: lambertian, diffuse_fraction: 0.6}\nlighting:"), 1)
    (full / "booth.yaml").write_text(t.replace("effects:\n", "effects:\n  diffuser: {}\n"))
    m = synthesize(full, tmp_path / "m", lighting="L", truth_effects={"interreflection": {}, "diffuser": {}},
                   noise_percent=1.0, known_output_groups=["tube_front", "tube_rear"])
    y = m.read_text()
    m.write_text(re.sub(r"booth: .*", "booth: ../user", y))
    res = run_compare(m)
    v = res.verdict
    named = v.effects if v.kind == "missing" else tuple(v.tied)
    assert v.kind in ("missing", "ambiguous") and "diffuser" in named, str(v)
    assert "spectral_filter" not in named
    plate = next(s for s in res.diagnosis.suspects if "hypothesis:diffuser_plate" in s.items)
    assert plate.explains and "diffuser:" in plate.hardware["diffuser_plate"]


def test_profile_recovers_a_quadratic_minimum_and_its_curvature():
    """χ²(θ) = 4 (θ − 37)² + 50 with 60 degrees of freedom (reduced χ² below 1): the parabola
    through the grid's best three gives θ̂ = 37 and σ = 1/√4 = 0.5 (Δχ² = 1)."""
    def R(x):
        return _ToyFit(x, lambda x: 4 * (x - 37.0) ** 2 + 50.0)

    H = _toy_hypothesis(GeometryParameter("gap_mm", (5.0, 20.0, 45.0, 80.0), 20.0, (1.0, 80.0)))

    ir, fit, prob, n = profile_geometry(H, 20.0, "L", lambda x, start: (None, R(x)), R(20.0), None)
    assert n == 1 and ir == pytest.approx(37.0)
    assert fit.values["hypothesis.toy.gap_mm"] == pytest.approx(37.0)
    assert fit.stderr["hypothesis.toy.gap_mm"] == pytest.approx(0.5)
    assert fit.hypothesis_data["geometry"]["toy"]["gap_mm"][1] == pytest.approx(0.5)


def test_each_profile_point_starts_from_the_hypothesis_refit():
    """Every refit of the profile starts from the hypothesis' own refit (its parameter values)."""
    def R(x):
        return _ToyFit(x, lambda x: 4 * (x - 37.0) ** 2 + 50.0)

    H = _toy_hypothesis(GeometryParameter("gap_mm", (5.0, 20.0, 45.0, 80.0), 20.0, (1.0, 80.0)))

    starts = []

    def solve_on(x, start):
        starts.append((x, start.x))
        return None, R(x)

    profile_geometry(H, 20.0, "L", solve_on, R(20.0), None)
    assert starts == [(5.0, 20.0), (45.0, 20.0), (80.0, 20.0), (pytest.approx(37.0), 20.0)]


def test_a_flat_profile_is_not_pinned():
    def R(x):
        return _ToyFit(x, lambda x: 50.0)

    H = _toy_hypothesis(GeometryParameter("gap_mm", (5.0, 20.0, 45.0), 20.0, (1.0, 45.0)))

    _, fit, _, _ = profile_geometry(H, 20.0, "L", lambda x, start: (None, R(x)), R(20.0), None)
    assert "hypothesis.toy.gap_mm" not in fit.stderr
    assert fit.hypothesis_data["geometry"]["toy"]["gap_mm"][1] is None


def test_paste_hardware_merges_sections_and_items_by_id():
    booth = ("materials:\n  wall: {type: diffuse, reflectance: {type: constant, value: 0.5}}\n"
             "surfaces: {floor: wall, ceiling: wall}\n"
             "lamps:\n  - {id: a, type: tube}\n  - {id: b, type: tube}\n"
             "effects:\n  interreflection: {}\n")
    snippet = ("materials:\n  dark: {type: diffuse, reflectance: {type: constant, value: 0.1}}\n"
               "surfaces:\n  ceiling: dark\nlamps:\n  - {id: b, reflector: m}\n  - {id: c, type: bulb}\n"
               "effects:\n  interreflection: {}\n  reflector: {}\n")
    from ruamel.yaml import YAML

    out = YAML(typ="safe").load(paste_hardware(booth, snippet))
    assert set(out["materials"]) == {"wall", "dark"}
    assert out["surfaces"] == {"floor": "wall", "ceiling": "dark"}
    assert out["lamps"] == [{"id": "a", "type": "tube"}, {"id": "b", "type": "tube", "reflector": "m"},
                            {"id": "c", "type": "bulb"}]
    assert out["effects"] == {"interreflection": {}, "reflector": {}}


def test_surface_reflectance_scale_is_the_scaled_material(tmp_path):
    """The effect's ceiling_scale s and a ceiling declared with reflectance s·ρ give the same light."""
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.scene.compile import compile_booth

    src = DATA / "validation" / "walls-45"
    ir = compile_booth(src / "booth.yaml")
    P = np.array([[0.0, 0.0, 0.0], [200.0, 100.0, 0.0], [-300.0, -150.0, 0.0]])
    N = np.tile([0.0, 0.0, 1.0], (3, 1))
    eff = {**ir.effects, "surface_reflectance": {"ceiling_scale": 0.3}}
    a = ForwardModel(ir, "L", effects=eff).predict(P, N, np.ones(3, bool))
    b_ir = CeilingReflectanceHypothesis.augment(ir, "L", [])[0]
    text = CeilingReflectanceHypothesis.hardware_yaml(b_ir, _fake_fit({"effect.surface_reflectance.ceiling_scale": 0.3}))
    booth = tmp_path / "b"
    shutil.copytree(src, booth)
    f = booth / "booth.yaml"
    f.write_text(paste_hardware(f.read_text(), text))
    ir2 = compile_booth(f)
    b = ForwardModel(ir2, "L", effects=ir2.effects).predict(P, N, np.ones(3, bool))
    la, lb = sum(a.lux_by_group().values()), sum(b.lux_by_group().values())
    assert np.allclose(la, lb, rtol=2e-3)
    c = ForwardModel(ir, "L", effects=ir.effects).predict(P, N, np.ones(3, bool))
    assert (sum(c.lux_by_group().values()) > la * 1.01).all()


def test_a_rough_plate_at_a_profiled_height_is_written_as_rough_glass(tmp_path):
    from lbscene.engine.scene.compile import compile_booth

    src = DATA / "validation" / "walls-05"
    ir = compile_booth(src / "booth.yaml")
    aug = DiffuserPlateHypothesis.augment(ir, "L", [])[0]
    names = [g.name for g in DiffuserPlateHypothesis.geometry(aug, "L")]
    assert names == ["rough", "roughness", "matte_faces", "gap_mm"]
    values = {"rough": 1.0, "roughness": 0.3, "gap_mm": 45.0}
    rough = DiffuserPlateHypothesis.regeometry(aug, "L", values)
    fit = _fake_fit({"effect.diffuser.diffuse_fraction": 0.0})
    fit.hypothesis_data = {"geometry": {"diffuser_plate": {"rough": (1.0, None), "roughness": (0.3, 0.04),
                                                           "gap_mm": (45.0, 3.0)}},
                           "choices": {"diffuser_plate": {"rough": {0.0: 140.0, 1.0: 60.0}}}}
    text = DiffuserPlateHypothesis.hardware_yaml(rough, fit)
    assert "rough glass fits better by Δχ² = 80" in text and "# ± 0.04 (profiled)" in text
    assert DiffuserPlateHypothesis.effect_entry(fit) == {}
    booth = tmp_path / "b"
    shutil.copytree(src, booth)
    f = booth / "booth.yaml"
    f.write_text(paste_hardware(f.read_text(), text + "effects:\n  interreflection: {}\n  diffuser: {}\n"))
    d = compile_booth(f).diffuser
    assert d.scattering == {"type": "roughness", "roughness": 0.3}
    assert d.z_mm == pytest.approx(620 - 13 - 45)


def test_an_opal_plate_with_matte_faces_is_written_at_index_1(tmp_path):
    """An opal plate whose faces fit better without a Fresnel boundary is written with ior 1 and
    says by how much; rough glass keeps its own index, and its faces are not profiled."""
    from lbscene.engine.scene.compile import compile_booth

    src = DATA / "validation" / "walls-05"
    ir = compile_booth(src / "booth.yaml")
    aug = DiffuserPlateHypothesis.augment(ir, "L", ["tube_front", "tube_rear"])[0]
    assert aug.diffuser.ior == 1.49
    matte = DiffuserPlateHypothesis.regeometry(aug, "L", {"rough": 0.0, "matte_faces": 1.0, "gap_mm": 45.0})
    assert matte.diffuser.ior == 1.0 and matte.diffuser.scattering["type"] == "lambertian"
    polished = DiffuserPlateHypothesis.regeometry(aug, "L", {"rough": 0.0, "matte_faces": 0.0})
    assert polished.diffuser.ior == 1.49
    glass = DiffuserPlateHypothesis.regeometry(aug, "L", {"rough": 1.0, "matte_faces": 1.0})
    assert glass.diffuser.ior == 1.5
    assert not DiffuserPlateHypothesis.profiled("matte_faces", {"rough": 1.0})
    assert DiffuserPlateHypothesis.profiled("matte_faces", {"rough": 0.0})
    assert not DiffuserPlateHypothesis.profiled("roughness", {"rough": 0.0})
    fit = _fake_fit({"effect.diffuser.diffuse_fraction": 0.9, "effect.diffuser.transmittance_scale": 0.62})
    fit.hypothesis_data = {"geometry": {"diffuser_plate": {"rough": (0.0, None), "matte_faces": (1.0, None),
                                                           "gap_mm": (45.0, 3.0)}},
                           "choices": {"diffuser_plate": {"rough": {0.0: 60.0, 1.0: 140.0},
                                                          "matte_faces": {0.0: 110.0, 1.0: 60.0}}}}
    text = DiffuserPlateHypothesis.hardware_yaml(matte, fit)
    assert "  ior: 1   # matte faces fit better by Δχ² = 50" in text
    assert "opal fits better by Δχ² = 80" in text
    booth = tmp_path / "b"
    shutil.copytree(src, booth)
    f = booth / "booth.yaml"
    f.write_text(paste_hardware(f.read_text(), text + "effects:\n  interreflection: {}\n  diffuser: {}\n"))
    d = compile_booth(f).diffuser
    assert d.ior == 1.0 and d.scattering["diffuse_fraction"] == 0.9
    assert np.allclose(d.transmittance.array_1nm, 0.62)
    # the plate's transmittance is fitted with the lamps' output fitted too (an opal plate
    # declared to transmit everything neither scatters nor reflects as one does): the shape of
    # the light pins it, and the comment says so
    free = DiffuserPlateHypothesis.augment(ir, "L", [])[2]
    assert {fp.target for fp in free} == {"effect.diffuser.diffuse_fraction", "effect.diffuser.transmittance_scale"}
    fit.values["group.tube_front.intensity_scale"] = 1.1
    fit.stderr = {"effect.diffuser.transmittance_scale": 0.07}
    text = DiffuserPlateHypothesis.hardware_yaml(matte, fit)
    assert ("  transmittance: {type: constant, value: 0.62}   # ± 0.07, from the shape of the light "
            "(the lamps' output fitted): the datasheet's is better") in text


def test_the_rough_plate_hypothesis_grid_is_shipped():
    # every roughness the diffuser_plate hypothesis profiles is read from a table, not simulated
    from lbscene.engine.light.rough_slab import SHIPPED_PLATES
    from lbscene.engine.loop.hypotheses import PLATE_ROUGHNESSES, ROUGH_PLATE_IOR

    for r in PLATE_ROUGHNESSES:
        assert (r, ROUGH_PLATE_IOR) in SHIPPED_PLATES


def test_standard_errors_added_later_are_those_of_the_full_solve(tmp_path):
    """A fit solved without its standard errors (a profile point) gets, once kept, the same
    errors and correlations as the fit solved with them."""
    import shutil

    from lbscene.engine.loop.diagnose import noise_model
    from lbscene.engine.loop.fit import FitProblem, resolve_free_parameters
    from lbscene.engine.loop.measurements import load_measurements
    from lbscene.engine.truth.synthetic import synthesize

    booth = tmp_path / "booth"
    shutil.copytree(Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth", booth)
    m = synthesize(booth, tmp_path / "m", lighting="FL", truth_effects={"interreflection": {}},
                   noise_percent=1.0)
    meas = load_measurements(Path(m))
    noise = noise_model(meas)
    effects = {k: dict(v) for k, v in meas.ir.effects.items()}
    free = resolve_free_parameters(meas.ir, meas.lighting, effects, meas.known_output_groups,
                                   str(meas.booth_file))
    full = FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, {}).solve()
    prob = FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, {})
    lazy = prob.solve(errors=False)
    assert lazy.errors_pending and not lazy.stderr
    assert lazy.chi2 == pytest.approx(full.chi2, rel=1e-12)
    prob.add_errors(lazy)
    assert not lazy.errors_pending
    assert lazy.stderr.keys() == full.stderr.keys() and lazy.stderr
    for k, v in full.stderr.items():
        assert lazy.stderr[k] == pytest.approx(v, rel=1e-9)
    np.testing.assert_allclose(lazy.correlation, full.correlation, atol=1e-9)


def test_two_properties_that_trade_off_get_their_joint_uncertainty():
    """χ² = 10 + dᵀ C⁻¹ d with σ = (4, 20) and correlation −0.8 about (37, 200): the 1-D profiles'
    conditional uncertainties are σ √(1 − ρ²); the joint profile gives back the marginal σ and ρ."""
    C = np.array([[16.0, -0.8 * 4 * 20], [-0.8 * 4 * 20, 400.0]])
    Ci = np.linalg.inv(C)

    def chi2(v):
        d = np.array([v["gap_mm"] - 37.0, v["opening_v_mm"] - 200.0])
        return 10.0 + float(d @ Ci @ d)

    fit, j = _pair_profiled(chi2)
    assert j["rho"] == pytest.approx(-0.8, abs=1e-6)
    assert j["sigma"]["gap_mm"] == pytest.approx(4.0, rel=1e-6)
    assert j["sigma"]["opening_v_mm"] == pytest.approx(20.0, rel=1e-6)
    assert fit.stderr["hypothesis.toy.gap_mm"] == pytest.approx(4.0, rel=1e-6)


def test_a_minimum_sharper_than_the_refits_spacing_is_no_ridge():
    """χ² = 10 + dᵀ C⁻¹ d (σ = (30, 10) mm, correlation −0.5 about (150, 20)) up to Δχ² = 9, and
    40 times steeper beyond (a mirror's distance: a minimum narrower than the grid's steps).  The
    profile's nearest refits reach beyond that, so no quadratic goes through them; the 1-D
    profiles' curvature (their three best points lie inside) with the refits at both diagonals
    gives back the marginal σ and ρ, not "an unidentified combination"."""
    C = np.array([[900.0, -0.5 * 30 * 10], [-0.5 * 30 * 10, 100.0]])
    Ci = np.linalg.inv(C)

    def chi2(v):
        d = np.array([v["opening_v_mm"] - 150.0, v["gap_mm"] - 20.0])
        q = float(d @ Ci @ d)
        return 10.0 + (q if q <= 9.0 else 9.0 + 40.0 * (q - 9.0))

    fit, j = _pair_profiled(chi2)
    assert j["rho"] == pytest.approx(-0.5, abs=1e-6)
    assert j["sigma"]["opening_v_mm"] == pytest.approx(30.0, rel=1e-6)
    assert j["sigma"]["gap_mm"] == pytest.approx(10.0, rel=1e-6)
    assert fit.stderr["hypothesis.toy.gap_mm"] == pytest.approx(10.0, rel=1e-6)


def test_two_properties_on_a_ridge_are_an_unidentified_combination():
    """χ² = 10 + ((θ_a − 20)/4 + (θ_b − 150)/20)², profiled from (150, 20): only the combination is
    pinned.  The pair is said to be unidentified, with the extent of the refits within Δχ² = 4
    of the best: the profile's point (150, 20) and the diagonal one (170, 24), Δχ² = 4."""
    def chi2(v):
        t = (v["gap_mm"] - 20.0) / 4.0 + (v["opening_v_mm"] - 150.0) / 20.0
        return 10.0 + t * t

    fit, j = _pair_profiled(chi2)
    assert j["rho"] is None and j["sigma"] == {"opening_v_mm": None, "gap_mm": None}
    assert "hypothesis.toy.gap_mm" not in fit.stderr
    (olo, ohi), (glo, ghi) = j["range"]["opening_v_mm"], j["range"]["gap_mm"]
    assert (olo, ohi) == pytest.approx((150.0, 170.0)) and (glo, ghi) == pytest.approx((20.0, 24.0))


def test_a_mirror_behind_tubes_faces_the_room_from_the_wall_nearest_each_tube(tmp_path):
    """The mirror hypothesis' other placement: behind each tube, between it and the nearest wall
    across its axis (an open front is no wall), one reflector per direction; its YAML merged into
    the booth compiles to that hardware."""
    from lbscene.engine.scene.compile import compile_booth

    src = DATA / "validation" / "walls-05"
    ir = compile_booth(src / "booth.yaml")
    aug, _, _ = MirrorHypothesis.augment(ir, "L", [])
    geo = {p.name: p for p in MirrorHypothesis.geometry(aug, "L")}
    assert list(geo) == ["behind", "distance_mm", "width_mm"]
    # the widths that fit both placements: above, within the 240 mm between the tubes; behind,
    # within twice the 80 mm between the tubes' axes (z 620) and the ceiling (z 700)
    assert geo["width_mm"].grid == (40.0, 60.0, 90.0, 130.0)
    # tubes along x at y = ±110 mm in a box 600 mm deep with its front open: both mirrors are
    # toward the rear wall, facing −y
    out = MirrorHypothesis.regeometry(aug, "L", {"behind": 1.0, "distance_mm": 35.0, "width_mm": 60.0})
    assert {k: (r.normal, r.distance_mm, r.width_mm) for k, r in out.reflectors.items()} == {
        "fitted_mirror": ((0.0, -1.0, 0.0), 35.0, 60.0)}
    # tubes along y near the left and right walls: one mirror each side, facing the room
    tubes = tuple(lp.model_copy(update={"axis": (0.0, 1.0, 0.0), "position_mm": (x, 0.0, 620.0)})
                  for lp, x in zip(ir.lamps, (-420.0, 380.0)))
    side = ir.model_copy(update={"lamps": tubes})
    aug2, _, _ = MirrorHypothesis.augment(side, "L", [])
    out2 = MirrorHypothesis.regeometry(aug2, "L", {"behind": 1.0, "distance_mm": 60.0})
    by_lamp = {lp.id: out2.reflectors[lp.reflector].normal for lp in out2.lamps}
    assert by_lamp == {tubes[0].id: (1.0, 0.0, 0.0), tubes[1].id: (-1.0, 0.0, 0.0)}
    fit = _fake_fit({"effect.reflector.reflectance_scale": 0.6})
    text = MirrorHypothesis.hardware_yaml(out2, fit)
    # the comment says where the booth's mirrors are (no profile ran: no choice to report)
    assert text.startswith("reflectors:   # hypothesis: a mirror behind the lamps, facing the room; width "
                           "assumed, distance and reflectance fitted\n")
    booth = tmp_path / "b"
    shutil.copytree(src, booth)
    f = booth / "booth.yaml"
    f.write_text(paste_hardware(f.read_text(), text + "effects:\n  interreflection: {}\n  reflector: {}\n"))
    merged = compile_booth(f)
    assert {r.normal for k, r in merged.reflectors.items() if k.startswith("fitted_mirror")} == {
        (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)}


def test_a_type_is_chosen_with_each_choice_at_its_own_best_finish():
    """A plate's type (opal or rough glass) against its faces (a choice only opal has): opal with
    polished faces χ² 85, with matte faces 52, rough glass 84 (the aperture case on the reference
    truth).  The type is decided with opal at its better faces: opal, matte, and the choices'
    χ² recorded as compared (52 against 84), not opal at the faces it started with (85 against 84:
    rough glass, its profile never reaching the matte faces)."""
    table = {(0.0, 0.0): 85.0, (0.0, 1.0): 52.0, (1.0, 0.0): 84.0, (1.0, 1.0): 84.0}

    def chi2(v):
        return table[(v["rough"], v["matte_faces"])]

    def R(v):
        return _ToyFit(v, chi2)

    H = _toy_hypothesis(GeometryParameter("rough", (0.0, 1.0), 0.0, (0.0, 1.0), categorical=True),
                        GeometryParameter("matte_faces", (0.0, 1.0), 0.0, (0.0, 1.0), categorical=True))
    H.profiled = staticmethod(lambda name, values: not (name == "matte_faces" and values["rough"] >= 0.5))
    H.categorical_partner = staticmethod(lambda name: None)
    v0 = {"rough": 0.0, "matte_faces": 0.0}
    _, fit, _, _ = profile_geometry(H, v0, "L", lambda v, start: (None, R(v)), R(v0), None)
    geo = fit.hypothesis_data["geometry"]["toy"]
    assert geo["rough"][0] == 0.0 and geo["matte_faces"][0] == 1.0
    assert fit.hypothesis_data["choices"]["toy"]["rough"] == {0.0: 52.0, 1.0: 84.0}
    assert fit.chi2 == 52.0
