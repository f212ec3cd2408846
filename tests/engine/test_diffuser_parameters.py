"""The diffuser effect's parameters mean the plate they describe, everywhere the plate is read.

A fit (the diagnosis' plate hypothesis) varies an opal plate's ``diffuse_fraction`` and
``transmittance_scale``; the booth a user pastes declares the fitted values instead.  Both must
predict the same light, with the inter-reflection, and the light must not jump where an opal
plate stops passing anything unscattered.  Each lamp group's light through the plate is that
group's alone (the outputs of groups are fitted one by one).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.scene.ir import IRLighting, IRSpectrum

#: three tubes each in a group of their own over an opal plate (T 0.62, f_d 0.9) in a grey box
BOOTH = Path(__file__).resolve().parents[1] / "data" / "hypotheses" / "opal-plate"
#: the plate's light at the diagnosis' resolution (coarse cells: a fast evaluation)
COARSE = {"cell_size_mm": 100.0, "cell_subpoints": 2, "opal_modes": 12}
P = np.array([[0.0, 0.0, 0.0], [300.0, 200.0, 0.0], [-450.0, -250.0, 0.0], [0.0, 340.0, 380.0]])
N = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@lru_cache(maxsize=None)
def _ir():
    return compile_booth(BOOTH)


def _with_plate(ir, transmittance: float, fd: float):
    d = ir.diffuser.model_copy(update={"transmittance": IRSpectrum.from_1nm(np.full(471, transmittance), ir.grid),
                                       "scattering": {"type": "lambertian", "diffuse_fraction": fd,
                                                      "reflectance": None}})
    return ir.model_copy(update={"diffuser": d})


def _lux(ir, diffuser: dict, interreflection: bool = True, lighting: str = "L") -> dict[str, np.ndarray]:
    eff = {"diffuser": {**COARSE, **diffuser}}
    if interreflection:
        eff["interreflection"] = {}
    fm = ForwardModel(ir, lighting, effects=eff, cache={})
    return fm.predict(P, N, np.ones(len(P), bool)).lux_by_group()


def _total(by_group):
    return sum(by_group.values())


def test_a_fitted_transmittance_and_diffuse_fraction_predict_as_the_plate_declaring_them():
    # declared T 1.0 and f_d 0.5, the effect scaling T to 0.62 and setting f_d 0.9: the plate of
    # the booth file declaring T 0.62 and f_d 0.9 (the opal layer's depth and asymmetry, its
    # reflectance and its transfer between faces follow the total it is fitted to)
    ir = _ir()
    declared = _total(_lux(_with_plate(ir, 0.62, 0.9), {}))
    fitted = _total(_lux(_with_plate(ir, 1.0, 0.5), {"transmittance_scale": 0.62, "diffuse_fraction": 0.9}))
    # the same plate, the same light (to the 10 digits a declared spectrum keeps): the patches'
    # light too, which followed the fitted numbers in 2 % steps once (0.2 % apart here)
    np.testing.assert_allclose(fitted, declared, rtol=1e-6)


@pytest.mark.parametrize("name", ["transmittance_scale", "diffuse_fraction"])
def test_the_light_follows_a_fitted_plate_parameter_without_steps(name):
    # a fit's forward differences (steps of 1e-4) read the light's slope: over 3 % of either
    # number (more than a step of any grid of 2 % steps) each of eight equal steps changes
    # the readings alike.  While the patches' light followed the fitted numbers in 2 % steps,
    # one step here changed the readings 25 times as much as the others (an opal plate's
    # transmittance on the aperture booth: 6 χ² units across a step's edge)
    ir = _with_plate(_ir(), 1.0, 0.5)
    start = {"transmittance_scale": 0.62, "diffuse_fraction": 0.9}
    xs = start[name] * (1.0 + np.linspace(0.0, 0.03, 9))
    lux = np.array([_total(_lux(ir, {**start, name: float(x)})) for x in xs])
    step = np.linalg.norm(np.diff(lux, axis=0), axis=1)       # each step's change, all readings
    assert step.min() > 0
    # they differ by the light's curvature and the opal layer's blend between its solved depths
    # (a kink at each, a few per cent of a step) only
    assert step.max() <= 1.2 * step.min(), step


def test_the_light_is_continuous_where_an_opal_plate_stops_passing_light_unscattered():
    # f_d → 1: the regular part along the lines between patches vanishes (at steep lines it
    # underflows before); a line the plate passes nothing through still crosses the plate
    ir = _ir()
    near = _total(_lux(_with_plate(ir, 0.62, 0.999), {}))
    full = _total(_lux(_with_plate(ir, 0.62, 1.0), {}))
    np.testing.assert_allclose(full, near, rtol=5e-3)


def test_each_groups_light_through_an_opal_plate_is_its_own():
    # the left tube's share with the three on is the light with the left tube alone on
    ir = _ir()
    alone = ir.model_copy(update={"lighting": {**ir.lighting, "left": IRLighting(name="left", lamps=("tube_left",), dimming={})}})
    both = _lux(alone, {}, interreflection=False)
    left = _lux(alone, {}, interreflection=False, lighting="left")
    assert set(both) == {"tube_left", "tube_mid", "tube_right"} and set(left) == {"tube_left"}
    np.testing.assert_allclose(both["tube_left"], left["tube_left"], rtol=1e-6)
    # the left and right tubes mirror each other across x = 0 (the middle tube's is its own)
    assert both["tube_left"][0] == pytest.approx(both["tube_right"][0], rel=1e-3)
    assert both["tube_mid"][0] > both["tube_left"][0] > 0


@pytest.mark.parametrize("tau", [0.0, 1e-9, 2.0, 40.0])
def test_an_opal_plates_regular_part_is_finite_from_normal_to_grazing_incidence(tau):
    # a fitted total at the clear slab's own puts the layer at no depth: at grazing incidence both
    # faces reflect everything (F = 1) and nothing passes (the limit (1 - F)/(1 + F)), not 0/0
    from lbscene.engine.light.plates import opal_regular_relative

    c = np.array([0.0, 1e-3, 0.2, 0.6, 1.0])
    r = opal_regular_relative(c, 1.49, tau)
    assert np.all(np.isfinite(r)) and r[0] == 0.0 and r[-1] == pytest.approx(1.0)
    assert np.all(np.diff(r) >= 0)
