"""The public API (:mod:`lbscene.api`) answers bad values with :class:`LbsceneUserError` (located
``LB…`` diagnostics), or a plain ``TypeError`` for a value of the wrong Python type — never an
exception from numpy, moderngl or a dict lookup."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import lbscene
from lbscene import LbsceneUserError

REPO = Path(__file__).resolve().parents[1]
CFG = REPO / "tests" / "runtimes" / "data"


@pytest.fixture(scope="module")
def ir():
    return lbscene.compile_booth(REPO / "tests" / "data" / "minimal-booth")


def _user_error(fn) -> str:
    with pytest.raises(LbsceneUserError) as exc:
        fn()
    return exc.value.diagnostics[0].format()


def test_forward_model_bad_values(ir):
    FM = lbscene.ForwardModel
    assert _user_error(lambda: FM(ir, "D65")) == \
        "error LB202: the booth has no lighting configuration 'D65' (got 'D65'; expected one of A)"
    assert _user_error(lambda: FM(ir, effects={"nope": {}})).startswith(
        "error LB106: unknown effect id 'nope' (got 'nope'; expected one of angular_profile, ")
    assert _user_error(lambda: FM(ir, effects={"interreflection": {"patch_size_mm": -1}})).startswith(
        "error LB104: effects['interreflection'].patch_size_mm: Input should be greater than 1")
    fm = FM(ir)
    assert _user_error(lambda: fm.illuminance_lx([[np.nan, 0, 0]])) == \
        "error LB104: points must be finite (no NaN or infinity) (expected points (M, 3) in mm and unit normals (M, 3))"
    assert _user_error(lambda: fm.illuminance_lx([[0, 0, 0, 1]])).startswith(
        "error LB104: points must be an (M, 3) array of millimetres, got shape (1, 4)")
    assert _user_error(lambda: fm.illuminance_lx([[0, 0, 0]], [[0, 0, 0]])).startswith(
        "error LB104: normals must be finite and non-zero")
    assert _user_error(lambda: fm.illuminance_lx([[0, 0, 0], [1, 0, 0]], [[0, 0, 1]] * 3)).startswith(
        "error LB104: normals must be one (x, y, z) per point: shape (3, 3) for 2 points")
    for wrong in (None, "booth", 3):
        with pytest.raises(TypeError):
            FM(wrong)
    with pytest.raises(TypeError):
        fm.illuminance_lx("abc")
    with pytest.raises(TypeError):
        FM(ir, effects={"interreflection": 5})
    # what is right still works: the closed form of the 1000 cd point at 700 mm
    assert fm.illuminance_lx([[0.0, 0.0]])[0] == pytest.approx(1000 / 0.7 ** 2, rel=1e-6)
    assert fm.illuminance_lx(np.zeros((0, 3))).shape == (0,)


def test_plan_points_out_of_range(minimal_booth, tmp_path):
    m = tmp_path / "m"
    m.mkdir()
    (m / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n0,0,2000\n100,0,1900\n0,100,1900\n")
    (m / "meas.yaml").write_text(
        f"version: 1\nkind: measurement_set\nname: t\nbooth: {minimal_booth}\nlighting: A\n"
        "illuminance:\n  - path: grid.csv\n")
    for bad in (0, -3, 51):
        assert _user_error(lambda: lbscene.plan(m / "meas.yaml", points=bad)) == (
            f"error LB500: points must be 1 … 50 (got {bad}; expected a number of readings from 1 to 50 "
            "(the command's --points))")
    with pytest.raises(TypeError):
        lbscene.plan(m / "meas.yaml", points=2.5)


def test_render_from_config_bad_values(tmp_path):
    cfg = tmp_path / "cfg"
    shutil.copytree(CFG, cfg)
    r = lambda **kw: lbscene.render_from_config(cfg / "tube-gonio.yaml", out=tmp_path / "a.png", **kw)  # noqa: E731
    assert _user_error(lambda: r(size=(0, 0))) == \
        "error LB500: size 0x0 is out of range (got 0x0; expected each side 16..8192 px)"
    assert _user_error(lambda: r(size=(-5, 100))).startswith("error LB500: size -5x100 is out of range")
    assert _user_error(lambda: r(size=(8192, 8192))) == (
        "error LB510: pixels of one view (8192x8192): 67108864 exceeds the limit of 16777216 (got 67108864; "
        "expected at most 16777216 (about 136 bytes of memory each while it renders: 8192 × 8192 takes "
        "9 GB))\n    hint: raise the limit with the environment variable LBSCENE_MAX_PIXELS=N if the machine "
        "has the memory")
    assert _user_error(lambda: r(diffuse="x")) == \
        "error LB500: diffuse must be one of auto, baked, analytic (got 'x'; expected auto or baked or analytic)"
    assert _user_error(lambda: r(adaptation="x")) == \
        "error LB500: adaptation must be one of cat16, none (got 'x'; expected cat16 or none)"
    assert _user_error(lambda: r(geometry="x")).startswith("error LB303: --geometry: unknown viewing geometry 'x'")
    for wrong in ("100x100", (100,), (100.0, 100), (True, 100)):
        with pytest.raises(TypeError):
            r(size=wrong)


def test_load_booth_and_compile_booth_bad_values(tmp_path):
    assert _user_error(lambda: lbscene.load_booth(tmp_path)).endswith(
        "error LB011: no booth.yaml in this folder (expected a folder with booth.yaml)")
    assert _user_error(lambda: lbscene.compile_booth(tmp_path / ("a" * 300))).endswith(
        "error LB013: cannot use the path: the name is longer than the file system allows (expected an existing "
        "file or folder)")
    for wrong in (None, 123):
        with pytest.raises(TypeError):
            lbscene.load_booth(wrong)


def test_the_render_bound_from_the_command_line_and_the_config(tmp_path, run_cli):
    cfg = tmp_path / "cfg"
    shutil.copytree(CFG, cfg)
    code, _, err = run_cli("render", cfg / "tube-gonio.yaml", "--no-input", "--size", "8192x8192")
    assert code == 2 and "error LB510: pixels of one view (8192x8192): 67108864 exceeds the limit" in err
    text = (cfg / "tube-gonio.yaml").read_text()
    line = next(i for i, s in enumerate(text.splitlines(), 1) if "width_px" in s)
    import re

    (cfg / "big.yaml").write_text(re.sub(r"width_px: \d+", "width_px: 8192", re.sub(r"height_px: \d+",
                                                                                    "height_px: 8192", text)))
    code, _, err = run_cli("validate-config", cfg / "big.yaml")
    assert code == 2 and f"big.yaml:{line}:" in err and "error LB510: pixels of one view (8192x8192)" in err
