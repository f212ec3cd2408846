"""The forward model's plate laws against plates measured in Mitsuba 3.

``tests/data/validation/plate-optics/<plate>.csv`` holds each plate's directional-hemispherical
transmittance T(θ) and reflectance R(θ), measured in Mitsuba 3 by reciprocity
(:func:`lbscene.engine.truth.mitsuba.plate_optics`; written by ``measure_plates.py`` there) for a
plate declared as a booth declares it.  The model's plate (:mod:`lbscene.engine.light.plates`)
with the same declaration must transmit and reflect the same; a slow test re-measures.
"""

from __future__ import annotations

import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light import plates
from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.scene.ir import IRSpectrum

HERE = Path(__file__).resolve().parents[1] / "data" / "validation"
SCRIPT = HERE / "plate-optics" / "measure_plates.py"
#: a booth whose diffuser is replaced by each measured plate
BOOTH = HERE / "rough-diffuser-r030"
#: allowed |model − Mitsuba| (absolute, besides 3 standard errors): rough slabs (the model's
#: tables are their own Monte Carlo of the same microfacet physics)
ROUGH_T_ABS, ROUGH_R_ABS = 0.006, 0.004
#: opal plates: the model's laws are closed forms of a scattering layer (plates module, no constant
#: fitted to these plates), to 70°
OPAL_T_REL, OPAL_R_ABS = 0.04, 0.03


def _load():
    spec = importlib.util.spec_from_file_location("measure_plates", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


MP = _load()


@lru_cache(maxsize=None)
def _base():
    return compile_booth(BOOTH)


def _ir(name):
    d = MP.PLATES[name]
    sc = dict(d["scattering"])
    if sc["type"] == "lambertian":
        sc.setdefault("reflectance", None)
    ir = _base()
    update = {"scattering": sc, "ior": d["ior"], "thickness_mm": d["thickness_mm"]}
    if d["transmittance"] is not None:
        update["transmittance"] = IRSpectrum.from_1nm(np.full(471, d["transmittance"]), ir.grid)
    df = ir.diffuser.model_copy(update=update)
    return ir.model_copy(update={"diffuser": df})


def _model(name, mu):
    d = MP.PLATES[name]
    ir = _ir(name)
    T = d["transmittance"] if d["transmittance"] is not None else plates.reference_transmittance(ir)
    # the plate as a booth declares it: total transmittance at normal incidence, diffuse fraction
    Tm = T * plates.plate_directional_relative(ir, mu)
    return Tm, plates.plate_reflectance(ir, mu, np.array([T]))[:, 0]


@pytest.mark.parametrize("name", [n for n in MP.PLATES if MP.PLATES[n]["scattering"]["type"] == "roughness"])
def test_a_rough_plate_transmits_and_reflects_as_in_mitsuba(name):
    m = MP.read(name)
    mu = np.cos(np.deg2rad(m["theta_deg"]))
    T, R = _model(name, mu)
    assert np.all(np.abs(T - m["T"]) <= ROUGH_T_ABS + 3 * m["T_se"]), np.c_[m["theta_deg"], m["T"], T]
    assert np.all(np.abs(R - m["R"]) <= ROUGH_R_ABS + 3 * m["R_se"]), np.c_[m["theta_deg"], m["R"], R]


def test_a_non_absorbing_rough_plate_transmits_its_reference_at_normal_incidence():
    # the declared total transmittance is relative to this value: Mitsuba's plate of the same
    # roughness and index transmits it too (GGX α 0.3: 0.81, not the clear slab's 0.925)
    m = MP.read("rough-a030")
    assert plates.reference_transmittance(_ir("rough-a030")) == pytest.approx(m["T"][0], abs=0.003 + 3 * m["T_se"][0])
    assert m["T"][0] < 0.85


#: opal plates the model's law does not meet yet, as measured (strict xfail: the test flips when
#: fixed).  None since the layer's solution replaced the diffusion picture, which put opal-t070 (4 mm,
#: n 1.52, T 0.70, f_d 0.85; transport depth about 1) 3.2 % (40°) to 7.4 % (70°) high.
KNOWN_PLATE_GAPS: dict[str, str] = {}


def _opal_case(name):
    reason = KNOWN_PLATE_GAPS.get(name)
    return pytest.param(name, marks=[pytest.mark.xfail(strict=True, reason=reason)] if reason else [])


@pytest.mark.parametrize("name", [_opal_case(n) for n in MP.PLATES
                                  if MP.PLATES[n]["scattering"]["type"] == "lambertian"])
def test_an_opal_plate_transmits_and_reflects_as_in_mitsuba(name):
    # with a Fresnel boundary (ior 1.49, 1.5: the plates a booth has) and without one (ior 1: the
    # faces of the opal booth scenes); three thicknesses, transmittances and diffuse fractions
    m = MP.read(name)
    d = MP.PLATES[name]
    # the measured plate transmits what it declares at normal incidence
    assert m["T"][0] == pytest.approx(d["transmittance"], abs=0.01)
    mu = np.cos(np.deg2rad(m["theta_deg"]))
    T, R = _model(name, mu)
    sel = m["theta_deg"] <= 80
    assert np.all(np.abs(T[sel] / m["T"][sel] - 1) <= OPAL_T_REL + 3 * m["T_se"][sel] / m["T"][sel]), \
        np.c_[m["theta_deg"], m["T"], T]
    assert np.all(np.abs(R[sel] - m["R"][sel]) <= OPAL_R_ABS + 3 * m["R_se"][sel]), np.c_[m["theta_deg"], m["R"], R]


@pytest.mark.slow
def test_the_committed_plate_measurements_are_current():
    pytest.importorskip("mitsuba")
    for name in MP.PLATES:
        m = MP.read(name)
        new = MP.measure(name, spp=MP.SPP, passes=4)
        se = np.hypot(m["T_se"], new["T_se"])
        assert np.all(np.abs(new["T"] - m["T"]) <= 4 * se + 1e-4), name


def test_an_opal_layer_thinning_to_nothing_keeps_its_entry_law():
    """τ → 0 (a regular part as large as the clear slab's, as a hypothesised plate's fitted
    diffuse fraction can ask for): the entry law tends to the thin layer's, which scatters along
    its path; taking it as 1 at τ = 0 stepped the direct light by 0.75 %."""
    from lbscene.engine.light.opal_layer import opal_layer

    c = np.linspace(0.02, 1.0, 40)
    thin = [opal_layer(tau, 0.3, 1.49).entry_relative(c) for tau in (1e-3, 1e-5, 1e-6)]
    # beyond 84° light enters near the critical angle and bounces between the faces many times,
    # scattering on each pass: there the limit is reached only where τ/μ is below 1 − F
    far = c >= 0.1
    np.testing.assert_allclose(thin[1][far], thin[2][far], rtol=2e-4)
    np.testing.assert_allclose(thin[0][far], thin[2][far], rtol=5e-3)
    # single scattering: the light scattered grows with the path in the layer, 1/cos θ_t, behind
    # the face's Fresnel loss (n 1.49: cos θ_t ≥ 0.74 inside), so grazing light scatters more once
    # past the interface's loss; the booth's plate at the smallest depth it takes is this layer
    zero = thin[2]
    assert zero[-1] == pytest.approx(1.0) and zero[20] > 1.0
    r0 = ((1.49 - 1) / (1.49 + 1)) ** 2
    clear = (1 - r0) ** 2 / (1 - r0 ** 2)
    # a plate of total 0.93 whose regular part is the clear slab's: τ = 0, taken at its least
    fd = 1.0 - clear / 0.93
    ir = _ir("opal-t055")
    df = ir.diffuser.model_copy(update={"transmittance": IRSpectrum.from_1nm(np.full(471, 0.93), ir.grid),
                                        "scattering": {"type": "lambertian", "diffuse_fraction": fd},
                                        "ior": 1.49})
    layer = plates.opal_plate_layer(ir.model_copy(update={"diffuser": df}), fd)
    assert layer.tau == pytest.approx(plates.OPAL_MIN_DEPTH, rel=1e-3)
    assert np.all(np.isfinite(layer.entry_relative(c)))
    # the optical depth of a plate whose regular part reaches the clear slab's is 0
    assert plates.opal_optical_depth(clear, 1.49) == pytest.approx(0.0, abs=1e-12)
