"""Whether a cross-check's differences are the bake's noise: the statistics on made-up checks.

Differences drawn from the per-point noise the check declares must count as agreement in
almost every draw; a bias of a few standard errors of the mean, or a scatter twice the declared
noise, must not, and the summary, the JSON row, the table and the exit status say the same.
No Cycles here: the checks are built by hand.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.bakers.crosscheck import CHI2_P_MIN, MEAN_SIGMAS, MODEL_PRECISION_PERCENT, CrossCheck

N = 55
SIGMA = 0.004            # 0.4 % relative noise per point, a final bake's inter-reflection


def _check(ratio, sigma=SIGMA, mode="interreflection") -> CrossCheck:
    model = np.full(N, 1000.0)
    return CrossCheck("b", "L", mode, np.zeros((N, 3)), model * ratio, model,
                      np.ones((N, 16)), np.ones((N, 16)), np.full(N, sigma), 1024, 1.0)


def _se_mean(sigma=SIGMA) -> float:
    """Standard error of the mean difference: the noise over √N and the model's floor."""
    return float(np.hypot(sigma / np.sqrt(N), MODEL_PRECISION_PERCENT / 100))


def test_pure_noise_is_within_the_noise_in_almost_every_draw():
    rng = np.random.default_rng(11)
    ok = [_check(1.0 + SIGMA * rng.standard_normal(N)).agrees for _ in range(400)]
    # false alarms: the mean test at 3 σ (0.27 %) plus the χ² test at p 0.001 (0.1 %)
    assert sum(ok) >= 400 - 6, 400 - sum(ok)


def test_a_bias_of_a_few_standard_errors_is_not_noise():
    rng = np.random.default_rng(12)
    c = _check(1.0 + 5 * _se_mean() + SIGMA * rng.standard_normal(N))
    assert c.mean_diff_sigmas > MEAN_SIGMAS
    assert not c.agrees
    # the shipped SpectraLight's old inter-reflection result: +0.97 % mean at 0.38 % noise
    assert not _check(np.full(N, 1.0097), 0.0038).agrees
    # a bright ceiling's old final bake: −3.0 % at 0.44 % noise (25 standard errors of the bake)
    assert not _check(np.full(N, 0.970), 0.0044).agrees


def test_a_scatter_twice_the_declared_noise_is_not_noise():
    rng = np.random.default_rng(13)
    d = 2 * SIGMA * rng.standard_normal(N)
    c = _check(1.0 + d - d.mean())          # no bias at all
    assert abs(c.mean_diff_sigmas) < 1e-9
    assert c.chi2_p < CHI2_P_MIN and not c.agrees


def test_summary_reports_the_noise_statistics():
    s = _check(np.full(N, 1.0)).summary()
    assert s["agrees"] is True and s["mean_diff_sigmas"] == 0.0 and s["chi2_p"] == pytest.approx(1.0)
    s = _check(np.full(N, 1.01)).summary()
    assert s["agrees"] is False and s["mean_diff_sigmas"] == pytest.approx(0.01 / _se_mean(), rel=1e-3)
    assert s["model_precision_percent"] == MODEL_PRECISION_PERCENT
    # one verdict: no second, looser key beside it
    assert "passed" not in s and "within_noise" not in s


def test_without_a_noise_estimate_only_the_model_floor_is_allowed():
    # a bake that reports no noise: the differences are held to the model's own precision
    assert _check(np.full(N, 1.0 + 0.5 * MODEL_PRECISION_PERCENT / 100), sigma=0.0).agrees
    c = _check(np.full(N, 1.0 + 4 * MODEL_PRECISION_PERCENT / 100), sigma=0.0)
    assert c.mean_diff_sigmas == pytest.approx(4.0) and not c.agrees


def _preview_at_5_9_sigma() -> CrossCheck:
    """A preview bake (2 % noise per point) whose mean is 5.9 of its standard errors off."""
    sigma = 0.02
    rng = np.random.default_rng(14)
    e = rng.standard_normal(N)
    d = sigma * (e - e.mean()) / e.std()                # the noise declared, no bias of its own
    return _check(1.0 + 5.9 * _se_mean(sigma) + d, sigma, mode="direct")


def test_a_preview_check_at_5_9_sigma_disagrees_everywhere(monkeypatch, capsys):
    import json

    import typer

    from lbscene.commands import bake as bake_cmd

    c = _preview_at_5_9_sigma()
    assert c.mean_diff_sigmas == pytest.approx(5.9, abs=1e-6)
    assert not c.agrees
    assert c.summary()["agrees"] is False

    monkeypatch.setattr("lbscene.bakers.crosscheck.cross_check_all", lambda *a, **k: [c])
    monkeypatch.setattr(bake_cmd, "_load_ir", lambda *a, **k: (type("IR", (), {
        "booth_name": "b", "content_hash": "h", "lighting": {"L": None}})(), None, None))
    monkeypatch.setattr(bake_cmd, "_lighting_names", lambda *a, **k: ["L"])
    for fmt in (bake_cmd.Format.text, bake_cmd.Format.json):
        with pytest.raises(typer.Exit) as exc:
            bake_cmd._run_cross_check(Path("b"), None, "preview", None, fmt, bake_cmd.CrossMode.direct, None)
        assert exc.value.exit_code == 1
        out = capsys.readouterr().out
        if fmt is bake_cmd.Format.json:
            (row,) = json.loads(out)["cross_check"]
            assert row["agrees"] is False and row["mean_diff_sigmas"] == pytest.approx(5.9, abs=0.01)
        else:
            assert "DISAGREE" in out and "+5.9" in out
            assert "0/1 checks agree" in out
