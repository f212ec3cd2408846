"""The inter-reflected light is continuous in every fitted number (a fit's χ² must not step).

The patches' lamp light is computed on a grid of the fitted numbers that shape lamp light
(relative steps of 2 %, :data:`~lbscene.engine.light.radiosity.TRANSPORT_PARAM_STEP`) and
interpolated between a number's two neighbours on it; an opal plate's entry law is continuous as
its layer thins to nothing (τ → 0)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.light.plates import opal_entry_relative
from lbscene.engine.light.radiosity import TRANSPORT_PARAM_STEP, _bracket_number, _round_number
from lbscene.engine.scene.compile import compile_booth

SCENE = Path(__file__).resolve().parents[1] / "data" / "validation" / "opal-grey" / "booth.yaml"


def _indirect(ir, fd: float, cache: dict, P, N) -> np.ndarray:
    """Inter-reflected light per receiver (summed over bands) with the plate's diffuse fraction
    ``fd`` (a number that shapes lamp light: the patches' light is computed on the grid)."""
    fm = ForwardModel(ir, "L", effects={"diffuser": {"diffuse_fraction": fd}, "interreflection": {}},
                      cache=cache)
    pred = fm.predict(P, N, np.ones(len(P), bool))
    return sum(t.geo_bands.sum(axis=-1) for t in pred.terms if t.kind == "indirect")


@pytest.fixture(scope="module")
def opal_grey():
    ir = compile_booth(SCENE)
    x, y = np.meshgrid(np.linspace(-300, 300, 4), np.linspace(-200, 200, 3))
    P = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    return ir, P, N, {}


def test_a_grid_bracket_holds_the_number_between_its_neighbours():
    for v in (0.0004, 0.0371, 0.05, 0.31, 0.8968, 1.0, 7.3, -0.42):
        lo, hi, w = _bracket_number(v)
        assert min(lo, hi) <= v <= max(lo, hi) and 0.0 <= w < 1.0
        assert _round_number(v) in (pytest.approx(lo, rel=1e-12, abs=1e-15), pytest.approx(hi, rel=1e-12))
    lo, hi, _ = _bracket_number(0.9)
    assert hi / lo == pytest.approx(1.0 + TRANSPORT_PARAM_STEP, rel=1e-12)


def test_the_indirect_light_does_not_step_where_rounding_changes_neighbour(opal_grey):
    """At the middle between two grid values, rounding to the nearest jumped a whole step (the
    opal plate's diffuse fraction 0.80 → 0.816: 0.1 % of the light below it, 0.5 to 1 in the
    χ² of 55 readings at 1 % noise); interpolated, both sides agree."""
    ir, P, N, cache = opal_grey
    step = math.log1p(TRANSPORT_PARAM_STEP)
    mid = math.exp((math.floor(math.log(0.8) / step) + 0.5) * step)
    below = _indirect(ir, mid * (1 - 1e-9), cache, P, N)
    above = _indirect(ir, mid * (1 + 1e-9), cache, P, N)
    lo = _indirect(ir, mid / math.sqrt(1 + TRANSPORT_PARAM_STEP), cache, P, N)
    hi = _indirect(ir, mid * math.sqrt(1 + TRANSPORT_PARAM_STEP), cache, P, N)
    # the two grid values differ visibly: the step rounding made
    assert np.max(np.abs(hi / lo - 1)) > 5e-4
    np.testing.assert_allclose(above, below, rtol=1e-7)
    # halfway in the logarithm: the neighbours' mean
    np.testing.assert_allclose(below, 0.5 * (lo + hi), rtol=1e-7)


def test_an_opal_layer_thinning_to_nothing_keeps_its_entry_law():
    c = np.linspace(0.02, 1.0, 40)
    thin = [opal_entry_relative(c, 1.49, tau) for tau in (1e-3, 1e-6, 1e-9)]
    zero = opal_entry_relative(c, 1.49, 0.0)
    np.testing.assert_allclose(thin[1], zero, rtol=1e-5)
    np.testing.assert_allclose(thin[2], zero, rtol=1e-8)
    # a thin layer scatters along its path: grazing light more than normal light, past
    # the interface's loss (n 1.49: cos θ_t ≥ 0.74 inside)
    assert zero[-1] == pytest.approx(1.0) and zero[20] > 1.0
