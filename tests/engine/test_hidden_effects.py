"""The measurement loop on data with a hidden effect.

The truth is the brute-force Monte Carlo :class:`ReferenceEngine` (thousands
of jittered lamp samples, per-ray occlusion, its own finer radiosity): a
different computation from the forward model being fitted, so these tests
cannot pass by symmetry.  ``LBSCENE_HIDDEN_EFFECT_TRUTH=mitsuba`` draws the
truth of the effects Mitsuba can represent from the independent renderer
instead (``engine/truth/mitsuba.py``); the others stay with the reference engine.  Readings get 1 % meter noise (fixed seed).  The
booth file given to the tool lacks the effect; the fix is an edit of the
booth YAML only — the diagnosis' own snippet — never code.

Two layouts, as in the issue:

* lamp output **fitted** (the default): a 55-point A3 grid pins the lamp level,
  so effects that change the grid almost uniformly are weakly identifiable;
* lamp output **declared known** (``known_output_groups``): the level
  mismatch counts as evidence.

Where a layout cannot tell effects apart the verdict must be ``ambiguous``
with the truth listed; the points ``plan`` proposes, measured from the same
truth, must then resolve it.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.loop.compare import run_compare
from lbscene.engine.truth.synthetic import synthesize

BOOTH = Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth"
NOISE_PERCENT = 1.0
#: "after adding it the RMSE falls to within 1.5× the noise" (issue 3)
AFTER_FACTOR = 1.5

#: hidden effects with parameters that make them physically sizeable
TRUTHS = {
    "none": {},
    "angular_profile": {"angular_profile": {"sigma_deg": 40}},
    "interreflection": {"interreflection": {}},
    "diffuser": {"diffuser": {}},
    "aperture_occlusion": {"aperture_occlusion": {}},
    "tube_end_falloff": {"tube_end_falloff": {"end_level": 0.3, "falloff_length_mm": 150}},
    "spectral_filter": {"spectral_filter": {}},
    "detector_cosine_error": {"detector_cosine_error": {"exponent": 1.3}},
    "reflector": {"reflector": {}},
}


#: where the synthetic truth comes from: 'reference' (the brute-force Monte Carlo engine) or 'mitsuba'
#: (the independent renderer, engine/truth/mitsuba.py); with 'mitsuba', the hidden effects Mitsuba
#: cannot represent still come from 'reference'
TRUTH_PROVIDER = os.environ.get("LBSCENE_HIDDEN_EFFECT_TRUTH", "reference")
#: hidden effects (as set up here) that Mitsuba refuses: lamp profiles and overrides, end falloff,
#: mirrors other than plane ones, a meter response, a Lambertian diffuse-fraction plate
MITSUBA_CANNOT = {"angular_profile", "tube_end_falloff", "reflector", "detector_cosine_error", "diffuser"}


def truth_engine_for(booth: Path, truth: str):
    """The engine the truth ``truth`` comes from (None: ``synthesize`` makes the reference one)."""
    if TRUTH_PROVIDER == "reference" or truth in MITSUBA_CANNOT:
        return None
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.synthetic import truth_engine

    # the booth's slot plates are declared per lamp; real plates block every lamp
    return truth_engine(compile_booth(booth), "FL", TRUTHS[truth], provider=TRUTH_PROVIDER,
                        allow_lamp_specific_occluders=True)


@pytest.fixture
def booth(tmp_path) -> Path:
    """A private copy of the test booth that the test may edit."""
    dst = tmp_path / "booth"
    shutil.copytree(BOOTH, dst)
    return dst


def measure(booth: Path, out: Path, truth: str, *, known: bool, extra_sets=()) -> Path:
    engine = truth_engine_for(booth, truth)
    return synthesize(booth, out, lighting="FL", truth_effects=TRUTHS[truth],
                      noise_percent=NOISE_PERCENT, known_output_groups=["fl"] if known else (),
                      extra_sets=extra_sets, engine=engine,
                      provider="reference" if engine is None else TRUTH_PROVIDER)


def add_to_booth(booth: Path, snippet: str) -> None:
    """What the user does: replace the booth's ``effects:`` section by the suggested one."""
    f = booth / "booth.yaml"
    text = re.sub(r"(?ms)^effects:\n(?:[ \t]+.*\n?)*", "", f.read_text())
    f.write_text(text.rstrip("\n") + "\n" + snippet.rstrip("\n") + "\n")


def resolve_with_plan(booth: Path, out: Path, truth: str, known: bool, result):
    """Measure the planned points from the same truth and compare again."""
    plan = result.plan
    assert plan is not None and plan.points, "an ambiguous verdict must come with a plan"
    P = np.array([p.position_mm for p in plan.points])
    N = np.array([p.normal for p in plan.points])
    m = measure(booth, out, truth, known=known, extra_sets=[("planned.csv", P, N)])
    return m, run_compare(m)


def assert_fixed_by_snippet(booth: Path, m: Path, diagnosis, truth: str) -> None:
    assert diagnosis.snippet and f"{truth}:" in diagnosis.snippet
    add_to_booth(booth, diagnosis.snippet)
    after = run_compare(m)
    assert after.fit.rmse_percent <= AFTER_FACTOR * NOISE_PERCENT, after.fit.rmse_percent
    assert after.verdict == "none"


# --------------------------------------------------------------------------- control

@pytest.mark.parametrize("known", [False, True], ids=["fitted-output", "known-output"])
def test_control_without_a_hidden_effect_says_none(booth, tmp_path, known):
    m = measure(booth, tmp_path / "m", "none", known=known)
    res = run_compare(m)
    assert res.verdict == "none"
    assert res.fit.rmse_percent <= AFTER_FACTOR * NOISE_PERCENT
    assert res.diagnosis.snippet is None


# --------------------------------------------------------------------------- identifiable

@pytest.mark.parametrize("truth,known", [
    # a 55-point grid with the lamp level fitted still sees these
    ("interreflection", False), ("diffuser", False), ("spectral_filter", False),
    ("detector_cosine_error", False),
    # with the lamp output known, the level mismatch names the rest
    ("angular_profile", True), ("interreflection", True),
    # the slowest case (every refit with the plate solves the inter-reflection anew): the diffuser
    # stays in the default suite with the output fitted (above; the weaker layout) and with
    # inter-reflection (test_two_hidden_effects_are_named_together), the known-output layout with
    # the six other effects here
    pytest.param("diffuser", True, marks=pytest.mark.slow),
    ("aperture_occlusion", True), ("spectral_filter", True), ("detector_cosine_error", True),
    ("reflector", True),
], ids=lambda v: v if isinstance(v, str) else ("known" if v else "fitted"))
def test_hidden_effect_is_named_and_the_booth_edit_fixes_it(booth, tmp_path, truth, known):
    m = measure(booth, tmp_path / "m", truth, known=known)
    res = run_compare(m)
    v = res.verdict
    c = res.diagnosis.confidence
    if v.kind == "unstable" or c.widened_from is not None:
        # the lead over a rival is within the noise (an aperture's level drop against an end
        # fall-off, output known): the data name the truth, and most resamples name it too; the
        # tie of the two is reported where the resamples support it, the truth first
        point = str(v.point if v.kind == "unstable" else c.widened_from[0])
        assert point == f"missing:{truth}", str(v)
        if v.kind == "ambiguous":
            assert v.alternatives[0] == (truth,) and c.recurrence >= 0.5, (str(v), c)
        else:
            assert sum(share for r, share in v.rivals if truth in r) > 0.5, str(v)
        return
    assert v == f"missing:{truth}", [(s.effect, round(s.score, 1)) for s in res.diagnosis.suspects]
    assert res.fit.rmse_percent > AFTER_FACTOR * NOISE_PERCENT or res.diagnosis.suspects[0].score > 10
    assert_fixed_by_snippet(booth, m, res.diagnosis, truth)


def test_white_tile_spectrum_separates_a_filter_from_geometry(booth, tmp_path):
    """Only the spectral effect fixes the white-tile spectrum; geometric suspects cannot."""
    res = run_compare(measure(booth, tmp_path / "m", "spectral_filter", known=False))
    sus = {s.effect: s for s in res.diagnosis.suspects}
    before = res.diagnosis.base.spectral_rmse_percent
    assert sus["spectral_filter"].spectral_rmse_after < 0.5 * before
    for eid in ("aperture_occlusion", "angular_profile", "diffuser", "tube_end_falloff"):
        assert sus[eid].spectral_rmse_after > 0.8 * before, eid


# --------------------------------------------------------------------------- ties → plan

@pytest.mark.parametrize("truth,known", [
    ("aperture_occlusion", False), ("angular_profile", False), ("tube_end_falloff", True),
], ids=lambda v: v if isinstance(v, str) else ("known" if v else "fitted"))
def test_a_tie_is_reported_and_the_planned_points_resolve_it(booth, tmp_path, truth, known):
    m = measure(booth, tmp_path / "m", truth, known=known)
    res = run_compare(m, do_plan=True)
    assert res.verdict.kind == "ambiguous", str(res.verdict)
    tied = res.verdict.tied
    assert truth in tied and len(tied) >= 2
    # the plan is where the tied candidates disagree: every planned point separates them
    assert set(res.plan.candidates) == set(tied)
    assert all(p.spread_percent > 2 * NOISE_PERCENT for p in res.plan.points)

    m2, res2 = resolve_with_plan(booth, tmp_path / "m", truth, known, res)
    assert res2.verdict == f"missing:{truth}", [(s.effect, round(s.score, 1)) for s in res2.diagnosis.suspects]
    assert_fixed_by_snippet(booth, m2, res2.diagnosis, truth)


# --------------------------------------------------------------------------- two at once

def test_two_hidden_effects_are_named_together(booth, tmp_path):
    """Neither hidden effect alone brings the residual to the noise, so the honest verdict names
    the pair (not "missing:X" for a partial explanation), and its snippet fixes the booth."""
    m = synthesize(booth, tmp_path / "m", lighting="FL", noise_percent=NOISE_PERCENT,
                   truth_effects={"interreflection": {}, "diffuser": {}})
    res = run_compare(m)
    sus = {s.effect: s for s in res.diagnosis.suspects}
    assert not sus["interreflection"].explains and not sus["diffuser"].explains
    assert res.verdict.kind == "missing", str(res.verdict)
    assert sorted(res.verdict.effects) == ["diffuser", "interreflection"]
    assert str(res.verdict) in ("missing:interreflection+diffuser", "missing:diffuser+interreflection")
    assert res.diagnosis.confidence.recurrence > 0.9
    add_to_booth(booth, res.diagnosis.snippet)
    final = run_compare(m)
    assert final.verdict == "none"
    assert final.fit.rmse_percent <= AFTER_FACTOR * NOISE_PERCENT
    found = list(res.verdict.effects)

    # the history next to the measurements records the fall, labelled with what changed
    hist = [json.loads(line) for line in (m.parent / "measurements.history.jsonl").read_text().splitlines()]
    assert [h["step"] for h in hist] == [1, 2]
    assert hist[0]["rmse_percent"] > hist[1]["rmse_percent"]
    assert all(e in hist[1]["label"] for e in found)
