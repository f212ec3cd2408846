"""The public Python API exported from ``lbscene``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import lbscene

REPO = Path(__file__).resolve().parents[1]


def test_the_api_is_exported_and_importing_lbscene_stays_light():
    assert {"load_booth", "compile_booth", "ForwardModel", "validate", "build", "compare", "plan",
            "render_from_config", "LbsceneUserError"} <= set(lbscene.__all__)
    code = ("import sys, lbscene; heavy = [m for m in ('colour', 'pxr', 'moderngl', 'bpy', 'matplotlib', "
            "'scipy') if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    with pytest.raises(AttributeError):
        lbscene.no_such_function


def test_forward_model_of_a_point_lamp_is_the_inverse_square_law(minimal_booth):
    ir = lbscene.compile_booth(minimal_booth)
    fm = lbscene.ForwardModel(ir, "A")
    pts = np.array([[0.0, 0.0, 0.0], [300.0, 0.0, 0.0], [0.0, -200.0, 100.0]])
    d = np.array([0.0, 0.0, 700.0]) - pts
    r_m = np.linalg.norm(d, axis=1) / 1000
    expected = 1000.0 * (d[:, 2] / 1000 / r_m) / r_m ** 2          # I·cos θ / d², 1000 cd
    np.testing.assert_allclose(fm.illuminance_lx(pts), expected, rtol=1e-6)


def test_load_booth_raises_located_errors(minimal_booth):
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace("position_mm: [0, 0, 700]", "position_mm: [0, 0, 0]"))
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.load_booth(minimal_booth)
    d = ei.value.diagnostics[0]
    assert d.code == "LB309" and d.location.line == 15


def test_validate_build_and_compare(minimal_booth, tmp_path):
    report = lbscene.validate(REPO / "booths")
    assert report.files and not [d for d in report.diagnostics if d.severity.value == "error"]
    res = lbscene.build(minimal_booth, tmp_path / "b")
    assert (tmp_path / "b" / "manifest.json").is_file() and "scene.usda" in res.files
    # readings from the closed form: nothing is missing
    m = tmp_path / "m"
    m.mkdir()
    pts = [(x, y) for x in (-300, -100, 100, 300) for y in (-200, 0, 200)]
    lux = [1000 * 0.7 / (0.49 + (x * x + y * y) / 1e6) ** 1.5 for x, y in pts]
    (m / "g.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{x},{y},{e:.4f}\n" for (x, y), e in zip(pts, lux)))
    (m / "s.yaml").write_text(f"version: 1\nkind: measurement_set\nname: api\nbooth: {minimal_booth}\n"
                              "lighting: A\ninstrument: {illuminance_meter: m, repeatability_percent: 0.5}\n"
                              "known_output_groups: [bulb]\nilluminance:\n  - path: g.csv\n")
    r = lbscene.compare(m / "s.yaml")
    assert r.verdict == "none"
    assert r.fit.rmse_percent < 0.01
    assert not (m / "s.history.jsonl").exists()          # the API writes no history unless asked


@pytest.mark.gl
def test_render_from_config_returns_the_frames_and_writes_the_png(tmp_path):
    import shutil

    d = tmp_path / "cfg"
    shutil.copytree(REPO / "tests" / "runtimes" / "data", d)
    r = lbscene.render_from_config(d / "tube-gonio.yaml", out=tmp_path / "x.png", size=(64, 48))
    assert r.png == tmp_path / "x.png" and r.png.read_bytes()[:4] == b"\x89PNG"
    assert r.frames[0].rgba8.shape == (48, 64, 4)
    j = r.to_json()
    assert j["size"] == [64, 48] and j["views"][0]["view"] == "45as0"
