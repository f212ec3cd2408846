"""The visual-test protocol: STRESS against a hand example, the ISO 105-A02 grey scale,
the balanced trial order, and simulated observers whose answers are generated from a known
ground truth (scale factor, repeat noise, observer bias) → the statistics recover it.
``lbscene visual-report``: pinned errors, the HTML report."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lbscene.engine.visual.protocol import balanced_blocks, load_session, plan_trials
from lbscene.engine.visual.report import analyse
from lbscene.engine.visual.stats import (delta_e_to_grey_scale, grey_scale_to_delta_e, inter_observer_stress,
                                         intra_observer_stress, stress)

DATA = Path(__file__).resolve().parent / "data"
SESSION = DATA / "session-tube.yaml"


# --------------------------------------------------------------------------- STRESS

def test_stress_hand_example():
    # ΔE = (1, 2), ΔV = (2, 1): F1 = (1 + 4) / (2 + 2) = 1.25;
    # Σ(ΔE − F1ΔV)² = (1 − 2.5)² + (2 − 1.25)² = 2.8125; Σ(F1ΔV)² = 6.25 + 1.5625 = 7.8125
    # STRESS = 100 √(2.8125 / 7.8125) = 100 · 0.6 = 60
    assert stress([1.0, 2.0], [2.0, 1.0]) == pytest.approx(60.0, abs=1e-9)
    # three pairs, worked by hand: ΔE = (1, 2, 3), ΔV = (1, 1, 2): F1 = 14 / 9;
    # residuals (1 − 14/9, 2 − 14/9, 3 − 28/9) = (−5/9, 4/9, −1/9): Σ² = 42/81;
    # Σ(F1ΔV)² = (196/81)(1 + 1 + 4) = 1176/81 → STRESS = 100 √(42/1176) = 18.898…
    assert stress([1, 2, 3], [1, 1, 2]) == pytest.approx(100 * math.sqrt(42 / 1176), rel=1e-12)


def test_stress_is_scale_invariant_and_symmetric_in_use():
    e = np.array([0.5, 1.2, 3.0, 4.1])
    v = np.array([0.7, 1.0, 3.3, 3.9])
    assert stress(e, 7.0 * v) == pytest.approx(stress(e, v), rel=1e-12)
    assert stress(e, e * 3) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError):
        stress([1.0], [1.0])


def test_grey_scale_table_iso_105_a02():
    # the standard's CIELAB differences of grades 5, 4-5, 4, 3-4, 3, 2-3, 2, 1-2, 1
    grades = [5, 4.5, 4, 3.5, 3, 2.5, 2, 1.5, 1]
    assert grey_scale_to_delta_e(grades).tolist() == [0.0, 0.8, 1.7, 2.5, 3.4, 4.8, 6.8, 9.6, 13.6]
    assert float(grey_scale_to_delta_e(3.75)) == pytest.approx((2.5 + 1.7) / 2)
    assert delta_e_to_grey_scale(grey_scale_to_delta_e(grades)).tolist() == grades


# --------------------------------------------------------------------------- order

@pytest.mark.parametrize("cases,blocks", [(4, 8), (6, 6), (5, 3), (24, 32)])
def test_balanced_order(cases, blocks):
    plan = balanced_blocks(cases, blocks, seed=3)
    assert len(plan) == blocks
    for b in plan:
        assert sorted(b) == list(range(cases))            # every case once per block
    counts = np.zeros((cases, cases), int)                 # case × serial position
    for b in plan:
        for pos, c in enumerate(b):
            counts[c, pos] += 1
    lo, hi = blocks // cases, -(-blocks // cases)
    assert counts.min() >= lo and counts.max() <= hi       # positions spread evenly
    assert balanced_blocks(cases, blocks, seed=3) == plan   # seeded
    if cases > 3:
        assert balanced_blocks(cases, blocks, seed=4) != plan


def test_session_trials():
    ses = load_session(SESSION)
    m = ses.model
    assert len(ses.cases) == 1 * 2 * 2
    assert len(ses.trials) == len(m.observers) * m.repeats * len(ses.cases)
    for obs in ("O1", "O2"):
        mine = [t for t in ses.trials if t["observer"] == obs]
        assert [t["order"] for t in mine] == list(range(1, len(mine) + 1))
        for rep in (1, 2):
            got = sorted((t["lighting"], t["geometry"], t["sample"]) for t in mine if t["repeat"] == rep)
            assert got == sorted(ses.cases)
    assert plan_trials(m, [s.name for s in ses.samples]) == ses.trials


# --------------------------------------------------------------------------- simulated observers

def _simulate(n_obs=16, n_cases=24, repeats=2, gain_spread=0.0, bias_sd=0.0, noise_sd=0.0, seed=0):
    """ΔV of observer o, case c, repeat r = g_o · (ΔE_c + b_oc) + ε_ocr."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(0.5, 6.0, n_cases)
    gains = np.exp(rng.uniform(-gain_spread, gain_spread, n_obs))
    rows = []
    for o in range(n_obs):
        bias = rng.normal(0.0, bias_sd, n_cases)
        for r in range(1, repeats + 1):
            eps = rng.normal(0.0, noise_sd, n_cases)
            for c in range(n_cases):
                rows.append({"observer": f"O{o:02d}", "repeat": r, "case": ("L", "G", f"S{c:02d}"),
                             "score": gains[o] * (truth[c] + bias[c] + eps[c]), "response_time_ms": 1000.0})
    return truth, rows


def _session_like(n_cases=24, response="delta_e_estimate"):
    return SimpleNamespace(model=SimpleNamespace(name="sim", response=SimpleNamespace(type=response)),
                           cases=[("L", "G", f"S{c:02d}") for c in range(n_cases)], hash="0")


def test_simulated_noiseless_observers_with_different_scales():
    # observers who use the ΔE scale differently (gains ×0.5…×2) but consistently: STRESS is 0
    truth, rows = _simulate(gain_spread=0.7)
    model = {("L", "G", f"S{c:02d}"): truth[c] for c in range(len(truth))}
    st = analyse(rows, _session_like(), model)
    assert st["summary"]["intra_observer_stress_mean"] == pytest.approx(0.0, abs=1e-6)
    assert st["summary"]["stress_vs_model"] == pytest.approx(0.0, abs=0.01)
    # the panel mean mixes the gains but stays proportional to the truth: inter-observer 0 too
    assert max(st["inter_observer_stress"].values()) == pytest.approx(0.0, abs=1e-6)


def test_simulated_observers_recover_known_variability():
    noise, bias, n_obs = 0.4, 0.5, 16
    truth, rows = _simulate(n_obs=n_obs, noise_sd=noise, bias_sd=bias, seed=11)
    rms = float(np.sqrt(np.mean(truth ** 2)))
    for r in rows:
        r["delta_v"] = r["score"]
    # expected values (gain 1, F1 ≈ 1): STRESS ≈ 100 · rms(residual) / rms(ΔE), with residuals
    # intra: ε_r − mean_r ε (2 repeats: sd σ/√2); inter: b + mean ε − panel mean (sd √(τ² + σ²/2));
    # against the model: the panel mean's error (sd √(τ²/N + σ²/(2N)))
    intra_expected = 100 * (noise / np.sqrt(2)) / rms
    inter_expected = 100 * np.sqrt((bias ** 2 + noise ** 2 / 2) * (1 - 1 / n_obs)) / rms
    model_expected = 100 * np.sqrt(bias ** 2 / n_obs + noise ** 2 / (2 * n_obs)) / rms
    intra = np.mean(list(intra_observer_stress(rows).values()))
    inter = np.mean(list(inter_observer_stress(rows).values()))
    model = {("L", "G", f"S{c:02d}"): truth[c] for c in range(len(truth))}
    st = analyse(rows, _session_like(), model)
    assert intra == pytest.approx(intra_expected, rel=0.15)
    assert inter == pytest.approx(inter_expected, rel=0.15)
    assert st["summary"]["stress_vs_model"] == pytest.approx(model_expected, rel=0.35)
    # more repeat noise → worse intra-observer repeatability
    _, noisy = _simulate(n_obs=n_obs, noise_sd=2 * noise, bias_sd=bias, seed=11)
    for r in noisy:
        r["delta_v"] = r["score"]
    assert np.mean(list(intra_observer_stress(noisy).values())) > 1.6 * intra


def test_simulated_grey_scale_observers():
    # answers on the grey scale (rounded to half grades) of noiseless observers: the ΔV back
    # from the grades follows the truth up to the scale's quantisation
    truth, rows = _simulate(n_obs=8, noise_sd=0.0)
    for r in rows:
        r["score"] = float(np.round(delta_e_to_grey_scale(r["score"]) * 2) / 2)
    model = {("L", "G", f"S{c:02d}"): truth[c] for c in range(len(truth))}
    st = analyse(rows, _session_like(response="grey_scale"), model)
    assert st["summary"]["stress_vs_model"] < 15
    assert st["summary"]["intra_observer_stress_mean"] == pytest.approx(0.0, abs=1e-9)


# --------------------------------------------------------------------------- CLI

def _write_results(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["session", "observer", "repeat", "order", "lighting", "geometry", "sample", "display",
                    "score", "response_time_ms"])
        for r in rows:
            w.writerow(r)


def _all_answers(ses, score_of):
    return [[ses.model.name, t["observer"], t["repeat"], t["order"], t["lighting"], t["geometry"], t["sample"],
             "sRGB", score_of(t), 1500] for t in ses.trials]


def test_visual_report_cli(run_cli, tmp_path):
    ses = load_session(SESSION)
    res = tmp_path / "results.csv"
    _write_results(res, _all_answers(ses, lambda t: 4.5 if t["sample"].startswith("Grey") else 3.0))
    model = tmp_path / "model.csv"
    model.write_text("lighting,geometry,sample,delta_e00\n" + "".join(
        f'{lt},{g},"{s}",{0.8 if s.startswith("Grey") else 3.4}\n' for lt, g, s in ses.cases))
    out = tmp_path / "report.html"
    code, stdout, err = run_cli("visual-report", res, "--session", SESSION, "--model-de", model,
                                "--report", out, "--format", "json")
    assert code == 0, err
    import json

    st = json.loads(stdout)
    assert st["responses"] == 16 and st["observers"] == ["O1", "O2"]
    # grades 4.5 and 3 are ΔV 0.8 and 3.4 (ISO 105-A02): exactly proportional to the model
    assert st["summary"]["stress_vs_model"] == pytest.approx(0.0, abs=1e-6)
    assert {c["mean_score"] for c in st["cases"]} == {4.5, 3.0}
    html = out.read_text()
    assert html.count("data:image/png;base64,") == 3 and "<script" not in html and "http" not in html


def test_visual_report_unknown_case_is_located(run_cli, tmp_path):
    ses = load_session(SESSION)
    rows = _all_answers(ses, lambda t: 4)
    rows[2][6] = "Red (not in the session)"
    res = tmp_path / "results.csv"
    _write_results(res, rows)
    code, _, err = run_cli("visual-report", res, "--session", SESSION)
    assert code == 2
    assert (f"{res}:4:1: error LB711: case D65 / {rows[2][5]} / Red (not in the session) is not in session "
            "'tube-test' (expected a lighting, geometry and sample of the session)") in err
    assert "Traceback" not in err


def test_visual_report_score_off_the_scale(run_cli, tmp_path):
    ses = load_session(SESSION)
    rows = _all_answers(ses, lambda t: 4)
    rows[0][8] = 6
    res = tmp_path / "results.csv"
    _write_results(res, rows)
    code, _, err = run_cli("visual-report", res, "--session", SESSION)
    assert code == 2
    assert f"{res}:2:1: error LB710: score 6 is outside the grey scale 1–5" in err


def test_session_schema_errors_are_located(run_cli, tmp_path):
    text = SESSION.read_text().replace("repeats: 2", "repeats: 0")
    bad = tmp_path / "session.yaml"
    bad.write_text(text)
    for name in ("sample-gonio.yaml", "sample-grey.yaml", "tube-gonio.yaml"):
        (tmp_path / name).write_text((DATA / name).read_text())
    line = next(i for i, s in enumerate(text.splitlines(), 1) if s.startswith("repeats:"))
    code, _, err = run_cli("validate-config", bad)
    assert code == 2
    assert f"session.yaml:{line}:10: error" in err and "repeats" in err


def _default_session(tmp_path):
    """The test session as a user writes it first: no repeats (the default, 1), no options."""
    for name in ("sample-gonio.yaml", "sample-grey.yaml", "tube-gonio.yaml"):
        (tmp_path / name).write_text((DATA / name).read_text())
    ses_file = tmp_path / "session.yaml"
    ses_file.write_text(SESSION.read_text().replace("repeats: 2\n", ""))
    return ses_file


def test_visual_report_with_default_session_text_json_html(run_cli, tmp_path):
    # repeats: 1 (the default) gives no intra-observer STRESS: the report says so instead of
    # raising TypeError while formatting None
    ses_file = _default_session(tmp_path)
    ses = load_session(ses_file)
    assert ses.model.repeats == 1
    res = tmp_path / "results.csv"
    _write_results(res, _all_answers(ses, lambda t: 4.0 if t["observer"] == "O1" else 3.5))
    code, out, err = run_cli("visual-report", res, "--session", ses_file)
    assert code == 0, err
    assert ("intra-observer STRESS: mean — (one repeat per observer: no intra-observer STRESS)  "
            "inter-observer STRESS: mean 0.0  (no --model-de: no STRESS against the model)") in out
    code, out, err = run_cli("visual-report", res, "--session", ses_file, "--format", "json")
    assert code == 0, err
    import json

    st = json.loads(out)
    assert st["summary"]["intra_observer_stress_mean"] is None
    assert st["intra_observer_stress"] == {"O1": None, "O2": None}
    # every case: the two observers' grades 4 and 3.5 (ISO 105-A02: ΔV 1.7 and 2.5)
    assert {(c["mean_score"], c["mean_delta_v"]) for c in st["cases"]} == {(3.75, 2.1)}
    report = tmp_path / "report.html"
    code, _, err = run_cli("visual-report", res, "--session", ses_file, "--report", report)
    assert code == 0, err
    html = report.read_text()
    assert "<tr><td>—</td><td>0.0</td>" in html and html.count("data:image/png;base64,") == 2


def _json_results(ses, responses):
    import json

    return json.dumps({"format": "lbscene.visual_results", "session": ses.model.name, "responses": responses})


def _response(t, score=4.0, **kw):
    return {"observer": t["observer"], "repeat": t["repeat"], "lighting": t["lighting"],
            "geometry": t["geometry"], "sample": t["sample"], "score": score, "response_time_ms": 900, **kw}


@pytest.mark.parametrize("change,expected", [
    (lambda r: r[1].update(score=True), "results.json: error LB710: responses[1]: score must be a finite number "
                                        "(got True; expected a finite number)"),
    (lambda r: r[1].update(score="NaN"), "results.json: error LB710: responses[1]: score must be a finite number "
                                         "(got 'NaN'; expected a finite number)"),
    (lambda r: r[2].update(score=[4]), "results.json: error LB710: responses[2]: score must be a finite number "
                                       "(got [4]; expected a finite number)"),
    (lambda r: r[0].update(repeat=1.5), "results.json: error LB710: responses[0]: repeat must be a whole number "
                                        "≥ 1 (got 1.5; expected a whole number ≥ 1)"),
    (lambda r: r[0].update(sample={"x": 1}), "results.json: error LB710: responses[0]: sample must be text "
                                             "(got {'x': 1}; expected a string)"),
    (lambda r: r[0].pop("observer"), "results.json: error LB710: responses[0]: missing field 'observer'"),
    (lambda r: r.__setitem__(0, "O1"), "results.json:1:1: error LB710: 'responses' must be a list of objects"),
])
def test_visual_results_json_with_wrong_types(run_cli, tmp_path, change, expected):
    ses = load_session(SESSION)
    responses = [_response(t) for t in ses.trials]
    change(responses)
    res = tmp_path / "results.json"
    res.write_text(_json_results(ses, responses))
    code, _, err = run_cli("visual-report", res, "--session", SESSION, cwd=tmp_path)
    assert code == 2 and "Traceback" not in err
    assert expected in err


def test_visual_results_nan_score_encoding_and_nesting(run_cli, tmp_path):
    ses = load_session(SESSION)
    res = tmp_path / "results.csv"
    rows = _all_answers(ses, lambda t: 4)
    rows[3][8] = "nan"                      # a NaN grade used to pass as "outside the grey scale" or not at all
    _write_results(res, rows)
    code, _, err = run_cli("visual-report", res, "--session", SESSION, cwd=tmp_path)
    assert code == 2 and "results.csv:5:1: error LB710: score must be a finite number (got 'nan'; expected a " \
                         "finite number)" in err
    _write_results(res, _all_answers(ses, lambda t: 4))
    res.write_bytes(res.read_text().encode("utf-16"))          # an odd encoding
    code, _, err = run_cli("visual-report", res, "--session", SESSION, cwd=tmp_path)
    assert code == 2 and "results.csv: error LB003: file contains NUL bytes: binary data, not text" in err
    deep = tmp_path / "deep.json"
    deep.write_text('{"format": "lbscene.visual_results", "responses": ' + "[" * 100_000 + "]" * 100_000 + "}")
    code, _, err = run_cli("visual-report", deep, "--session", SESSION, cwd=tmp_path)
    assert code == 2 and "Traceback" not in err
    assert "deep.json:1:" in err and "error LB015: JSON nested too deeply (expected at most 64 levels)" in err


def test_model_delta_e_must_be_finite(run_cli, tmp_path):
    ses = load_session(SESSION)
    res = tmp_path / "results.csv"
    _write_results(res, _all_answers(ses, lambda t: 4))
    model = tmp_path / "model.csv"
    model.write_text("lighting,geometry,sample,delta_e00\n" + "".join(
        f'{lt},{g},"{s}",{"inf" if i == 1 else 1.0}\n' for i, (lt, g, s) in enumerate(ses.cases)))
    code, _, err = run_cli("visual-report", res, "--session", SESSION, "--model-de", model, cwd=tmp_path)
    assert code == 2 and "model.csv:3:1: error LB710: delta_e00 must be a finite number ≥ 0 (got 'inf'" in err


def test_session_trials_are_bounded_before_they_are_planned(run_cli, tmp_path, monkeypatch):
    # 2 observers × 2 repeats × 4 cases = 16 trials; a session of 60 000 observers (240 000 trials)
    # wrote a 568 MB viewer: it is refused when the session is read, by every command
    monkeypatch.setenv("LBSCENE_MAX_TRIALS", "15")
    line = next(i for i, s in enumerate(SESSION.read_text().splitlines(), 1) if s.startswith("observers:"))
    expected = (f"session-tube.yaml:{line + 1}:3: error LB510: trials of session 'tube-test' (2 observers × 2 repeats × "
                "4 cases): 16 exceeds the limit of 15")
    code, _, err = run_cli("validate-config", SESSION)
    assert code == 2 and expected in err and "LBSCENE_MAX_TRIALS=N" in err
    res = tmp_path / "results.csv"
    _write_results(res, _all_answers(_unbounded_session(monkeypatch), lambda t: 4))
    code, _, err = run_cli("visual-report", res, "--session", SESSION)
    assert code == 2 and expected in err


def _unbounded_session(monkeypatch):
    monkeypatch.delenv("LBSCENE_MAX_TRIALS")
    ses = load_session(SESSION)
    monkeypatch.setenv("LBSCENE_MAX_TRIALS", "15")
    return ses


def test_export_web_counts_the_session_against_max_mb(run_cli, tmp_path):
    code, _, err = run_cli("export-web", "--session", SESSION, "--out", tmp_path / "viewer", "--max-mb", "0.001")
    assert code == 2
    assert "error LB701: the session alone would hold 0 MB of trials (got 0.0 MB; expected at most --max-mb 0.001)" \
        in err
    assert not (tmp_path / "viewer").exists()
    code, _, err = run_cli("export-web", "--session", SESSION, "--out", tmp_path / "viewer", "--max-mb", "0")
    assert code == 2 and "error LB500: --max-mb must be a positive number of megabytes (got 0; expected a number " \
                         "> 0)" in err
