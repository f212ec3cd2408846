"""The fit's nonlinear search: where it stops, and what it leaves alone.

A refit's χ² decides the diagnosis' scores, so the search must end at the minimum whatever the
path it took (a cold cache or a warm one), not where a tolerance happened to meet a short step.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def falloff_problem(tmp_path_factory):
    """Readings of a booth whose tubes fall off toward their ends (level 0.15 over 220 mm), and a
    problem fitting the fall-off's level and length with the lamps' output."""
    from lbscene.engine.loop.diagnose import noise_model
    from lbscene.engine.loop.fit import FitProblem, effect_parameter, resolve_free_parameters
    from lbscene.engine.loop.measurements import load_measurements
    from lbscene.engine.truth.synthetic import synthesize

    tmp = tmp_path_factory.mktemp("falloff")
    booth = tmp / "booth"
    shutil.copytree(DATA / "hidden-effect-booth", booth)
    truth = {"tube_end_falloff": {"end_level": 0.15, "falloff_length_mm": 220.0}}
    meas = load_measurements(synthesize(booth, tmp / "m", lighting="FL", truth_effects=truth, noise_percent=1.0))
    noise = noise_model(meas)
    effects = {k: dict(v) for k, v in meas.ir.effects.items()}
    effects["tube_end_falloff"] = {}
    free = resolve_free_parameters(meas.ir, meas.lighting, effects, meas.known_output_groups, str(meas.booth_file))
    free += [effect_parameter("tube_end_falloff", n, effects) for n in ("end_level", "falloff_length_mm")]

    def make(tolerance=1e-4):
        return FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, {}, tolerance=tolerance)
    return make


def test_the_predicted_gain_is_the_linear_models_best_step_within_the_bounds():
    from lbscene.engine.loop.fit import predicted_gain_chi2

    J = np.array([[1.0, 0.0], [0.0, 2.0], [0.0, 0.0]])
    r = np.array([3.0, 4.0, 1.0])
    # unbounded: both residuals brought to zero, χ² 26 → 1
    assert predicted_gain_chi2(J, r, np.array([-10.0, -10.0]), np.array([10.0, 10.0])) == pytest.approx(25.0)
    # the first parameter at its lower bound: only the second moves (χ² 26 → 10)
    assert predicted_gain_chi2(J, r, np.array([0.0, -10.0]), np.array([10.0, 10.0])) == pytest.approx(16.0)
    # at a minimum nothing is left
    assert predicted_gain_chi2(J, np.array([0.0, 0.0, 1.0]), np.array([-1.0, -1.0]),
                               np.array([1.0, 1.0])) == pytest.approx(0.0, abs=1e-12)


def test_a_search_stopped_short_by_its_tolerance_goes_on_to_the_minimum(falloff_problem, monkeypatch):
    """The first search of the solve is made to stop early (a loose ``ftol``, as a step the trust
    region shrank to meets the real one): the solve continues from there and ends where a
    tight search does."""
    import scipy.optimize

    tight = falloff_problem(1e-10).solve(errors=False)
    real = scipy.optimize.least_squares
    calls = []

    def first_stops_early(fun, x0, **kw):
        if not calls:
            kw = {**kw, "ftol": 0.3, "xtol": 0.3}
        sol = real(fun, x0, **kw)
        calls.append(2 * sol.cost)
        return sol

    monkeypatch.setattr(scipy.optimize, "least_squares", first_stops_early)
    fit = falloff_problem(1e-4).solve(errors=False)
    assert calls[0] > tight.chi2 + 1.0, "the first search did not stop short: nothing tested"
    assert len(calls) >= 2
    assert fit.chi2 == pytest.approx(tight.chi2, abs=0.1)


def test_a_parameter_that_moves_the_readings_only_at_rounding_level_stays_where_it_started(falloff_problem,
                                                                                          monkeypatch):
    """The fall-off's length made flat: it moves every residual by 1e-12 of the noise, as rounding
    does where a parameter has no effect (an opening larger than every light path).  Its column of
    the Jacobian is zero and the search leaves it at its start; the other parameters fit as they
    would without it."""
    from lbscene.engine.loop.fit import FitProblem

    prob = falloff_problem(1e-4)
    k = [prob.free[i].target for i in prob.nl].index("effect.tube_end_falloff.falloff_length_mm")
    start = prob.free[prob.nl[k]].initial
    real = FitProblem.residuals

    def flat_length(self, x, scales=None):
        x = np.asarray(x, float).copy()
        wobble = 1e-12 * np.sin(1e3 * x[k])
        x[k] = start
        return real(self, x, scales) + wobble

    monkeypatch.setattr(FitProblem, "residuals", flat_length)
    lo = np.array([prob.free[i].bounds[0] for i in prob.nl])
    hi = np.array([prob.free[i].bounds[1] for i in prob.nl])
    x0 = np.array([prob.free[i].initial for i in prob.nl])
    J = prob._jacobian(x0, lo, hi)
    assert np.all(J[:, k] == 0.0)
    assert all(np.any(J[:, j] != 0.0) for j in range(J.shape[1]) if j != k)
    fit = prob.solve(errors=False)
    assert fit.values["effect.tube_end_falloff.falloff_length_mm"] == start


def test_a_search_computes_no_point_twice(falloff_problem, monkeypatch):
    """A search evaluates a trial point and, when it keeps it, the forward steps of its Jacobian
    around it and the point again: the point is remembered, not computed again (remembering only
    the last evaluation, every kept step of a three-parameter fit cost five forward evaluations
    instead of four)."""
    from lbscene.engine.loop.fit import FitProblem

    computed = []
    real = FitProblem.model

    def counted(self, values_nl):
        computed.append(tuple(float(v) for v in values_nl))
        return real(self, values_nl)

    monkeypatch.setattr(FitProblem, "model", counted)
    prob = falloff_problem(1e-4)
    fit = prob.solve(errors=False)
    assert len(computed) == prob.nfev >= 10, "too short a search: nothing tested"
    assert len(set(computed)) == len(computed), [k for k in set(computed) if computed.count(k) > 1]
    assert fit.nfev == len(computed)


_SCORES = """
import json, sys
import lbscene.engine.loop.compare as C
r = C.run_compare(sys.argv[1], history=False)
print(json.dumps({"+".join(s.items): s.score for s in r.diagnosis.suspects}))
"""


@pytest.mark.slow
def test_a_diagnosis_scores_the_same_from_a_cold_cache_and_a_warm_one(tmp_path):
    """~3 min: the SpectraLight (its lamps' cosine error undeclared) diagnosed twice, in new
    processes: first with an empty cache, then with the light's caches from the first (the
    diagnosis' own cache emptied).  Warm, a fit's factorisations are read or updated from others,
    to rounding the same light; every candidate's score must come out the same.  The ceiling's and
    the walls' hypotheses came 8 and 13 χ² apart (a search that followed rounding along an opening
    larger than every light path, and one stopped short by its tolerance)."""
    import json
    import os
    import subprocess
    import sys

    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.truth.synthetic import synthesize

    booth = Path(__file__).resolve().parents[2] / "booths" / "xrite-spectralight-qc"
    ir = compile_booth(find_booth_file(booth))
    truth = {**{k: dict(v) for k, v in ir.effects.items()}, "detector_cosine_error": {"exponent": 1.2}}
    m = synthesize(booth, tmp_path / "m", lighting="D65", truth_effects=truth, noise_percent=1.0)
    cache = tmp_path / "cache"
    env = {**os.environ, "LBSCENE_CACHE_DIR": str(cache)}
    runs = []
    for _ in range(2):
        shutil.rmtree(cache / "diagnosis", ignore_errors=True)
        p = subprocess.run([sys.executable, "-c", _SCORES, str(m)], capture_output=True, text=True, env=env,
                           cwd=str(tmp_path), check=True)
        runs.append(json.loads(p.stdout.strip().splitlines()[-1]))
    cold, warm = runs
    assert cold.keys() == warm.keys() and len(cold) >= 4
    for k in cold:
        assert warm[k] == pytest.approx(cold[k], abs=0.5), k
