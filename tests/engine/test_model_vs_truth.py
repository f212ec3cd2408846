"""The forward model against an independent truth: Mitsuba 3 renders of the validation scenes.

The scenes (``tests/data/validation/<scene>/booth.yaml``) declare every input and enable exactly
the physics their truth includes; the truth (``truth-a3.csv``, ``truth-floor.csv``) was rendered
by ``tests/data/validation/render_truth.py`` with Mitsuba 3 and committed, so the default suite
needs no Mitsuba: it reads the CSVs and evaluates the forward model once per scene and grid.

Per scene and grid the forward model's RMS relative deviation from the truth, with the truth's
own noise removed in quadrature, must be within the scene's threshold
(``render_truth.THRESHOLDS_PERCENT``).  A scene the model does not meet yet is an ``xfail``
(strict) naming the physics it lacks, so that the test flips when the physics is fixed.
The slow test re-renders a few receivers with fresh seeds and checks the committed values.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.truth.validation import (GRIDS, booth_files_sha256, compare_with_truth, read_truth_csv,
                                             validation_grid)

VALIDATION = Path(__file__).resolve().parents[1] / "data" / "validation"
SCRIPT = VALIDATION / "render_truth.py"


def _load_script():
    spec = importlib.util.spec_from_file_location("render_truth", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


RT = _load_script()
#: the truth's own noise must be small against the thresholds for a comparison to mean something
MAX_TRUTH_NOISE_PERCENT = 0.3

#: (scene, grid) the forward model does not meet yet: what physics it is missing, as measured
#: (empty: every scene meets its threshold)
KNOWN_GAPS: dict[tuple[str, str], str] = {}

CASES = [(s, g) for s in RT.SCENES for g in RT.grids_of(s)]


def _case(scene, grid):
    reason = KNOWN_GAPS.get((scene, grid))
    marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
    return pytest.param(scene, grid, id=f"{scene}-{grid}", marks=marks)


@lru_cache(maxsize=None)
def _ir(scene):
    return compile_booth(VALIDATION / scene)


@lru_cache(maxsize=None)
def _comparison(scene, grid):
    return compare_with_truth(VALIDATION / scene, grid, ir=_ir(scene))


def _truth(scene, grid):
    path = VALIDATION / scene / f"truth-{grid}.csv"
    assert path.is_file(), f"{path} is missing: run tests/data/validation/render_truth.py {scene}"
    return read_truth_csv(path)


def test_every_scene_has_a_threshold_and_a_booth():
    assert set(RT.THRESHOLDS_PERCENT) == set(RT.SCENES)
    assert set(RT.SCENE_GRIDS) <= set(RT.SCENES) and all(set(g) <= set(GRIDS) for g in RT.SCENE_GRIDS.values())
    assert sorted(p.parent.name for p in VALIDATION.glob("*/booth.yaml")) == sorted(RT.SCENES)


@pytest.mark.parametrize("scene,grid", CASES, ids=[f"{s}-{g}" for s, g in CASES])
def test_truth_was_rendered_from_this_booth(scene, grid):
    t = _truth(scene, grid)
    assert t.meta.get("booth_sha256") == booth_files_sha256(VALIDATION / scene), (
        f"{scene}/booth.yaml (or a file beside it) changed after its truth was rendered: "
        f"re-run tests/data/validation/render_truth.py {scene}")
    ir = _ir(scene)
    # the truth included exactly the physics the booth enables, with its lighting
    # (parameters added to an effect since, at their defaults, change nothing)
    from lbscene.engine.light.effects.registry import get_effect

    def norm(eff):
        return {k: get_effect(k).Params.model_validate(v or {}).model_dump(mode="json") for k, v in eff.items()}
    assert norm(json.loads(t.meta["effects"])) == norm({k: dict(v) for k, v in ir.effects.items()})
    assert t.meta["lighting"] in ir.lighting
    # on the grid the tests evaluate (written with 6 significant digits), facing up
    np.testing.assert_allclose(t.points_mm, validation_grid(ir, grid), rtol=0, atol=1e-3)
    np.testing.assert_allclose(t.normals, np.tile([0.0, 0.0, 1.0], (len(t.normals), 1)))


@pytest.mark.parametrize("scene,grid", CASES, ids=[f"{s}-{g}" for s, g in CASES])
def test_truth_noise_is_small_enough_to_mean_something(scene, grid):
    t = _truth(scene, grid)
    rel = t.std_error_lx / t.illuminance_lx
    assert np.all(t.illuminance_lx > 0) and np.all(t.std_error_lx > 0)
    assert np.all(t.passes >= 2)                       # a standard error needs a spread
    assert 100 * np.sqrt(np.mean(rel ** 2)) <= MAX_TRUTH_NOISE_PERCENT, 100 * rel.max()
    # and small against the scene's threshold: its removal in quadrature changes little
    assert 100 * np.sqrt(np.mean(rel ** 2)) <= RT.THRESHOLDS_PERCENT[scene] / 2


@pytest.mark.parametrize("scene,grid", [_case(s, g) for s, g in CASES])
def test_forward_model_matches_the_truth(scene, grid):
    _truth(scene, grid)
    c = _comparison(scene, grid)
    assert c.booth_sha256_ok, f"stale truth: re-run tests/data/validation/render_truth.py {scene}"
    limit = RT.THRESHOLDS_PERCENT[scene]
    d = 100 * (c.model_lx / c.truth.illuminance_lx - 1)
    assert c.rms_noise_removed_percent <= limit, (
        f"{scene} {grid}: RMS {c.rms_noise_removed_percent:.2f} % (noise removed; raw {c.rms_percent:.2f} %, "
        f"truth noise {c.truth_noise_percent:.2f} %), max {c.max_percent:.2f} %, mean {d.mean():+.2f} %; "
        f"threshold {limit} %")


def test_noise_removal_is_the_quadrature_difference():
    # the figure tested above, recomputed here from the CSV and the model values
    c = _comparison("direct-shapes", "a3")
    t = c.truth
    d = c.model_lx / t.illuminance_lx - 1
    nu2 = np.mean((t.std_error_lx / t.illuminance_lx) ** 2)
    expected = 100 * np.sqrt(max(0.0, np.mean(d ** 2) - nu2))
    assert c.rms_noise_removed_percent == pytest.approx(expected, rel=1e-12)
    assert c.rms_noise_removed_percent < c.rms_percent


def test_the_truth_accepts_every_scene_as_declared():
    # MitsubaTruth refuses (LB603) what it cannot represent: every scene must be representable
    pytest.importorskip("mitsuba")
    from lbscene.engine.truth.mitsuba import MitsubaTruth

    for scene in RT.SCENES:
        MitsubaTruth(_ir(scene), RT.LIGHTING)


@pytest.mark.slow
def test_committed_truth_agrees_with_a_fresh_render():
    """Re-render two receivers per scene and grid with seeds the committed render never used:
    within 4 combined standard errors of the CSV (``render_truth.py --check``)."""
    pytest.importorskip("mitsuba")
    out = subprocess.run([sys.executable, str(SCRIPT), "--check", "--points", "2", "--json"],
                         capture_output=True, text=True, timeout=3000)
    assert out.returncode in (0, 1), out.stderr[-3000:]
    rows = json.loads(out.stdout)
    assert len(rows) == 2 * len(CASES)
    bad = [r for r in rows if not r["agree"]]
    assert not bad and out.returncode == 0, bad


@pytest.mark.slow
@pytest.mark.parametrize("grid", ["a3", "floor"])
def test_straight_paths_miss_what_a_wide_lobe_close_under_tubes_turns_down(grid):
    # aperture-diffuser meets its threshold through the plate's re-emitting cells, which 'auto'
    # picks for its wide lobe (GGX alpha 0.3: 90 % of the light beyond 29 deg; the default test
    # above).  Straight paths with the slab's T(theta) keep each grazing path's direction where
    # the lobe turns light toward the plate's normal: the model is low everywhere (measured
    # 2.4 % / 3.1 % RMS, mean -2.4 % / -3.0 %), the reason 'auto' does not take them here
    ir = _ir("aperture-diffuser")
    effects = {k: dict(v) for k, v in ir.effects.items()}
    effects["diffuser"] = {**effects["diffuser"], "rough_transport": "regular"}
    c = compare_with_truth(VALIDATION / "aperture-diffuser", grid, ir=ir.model_copy(update={"effects": effects}))
    r = np.asarray(c.model_lx) / c.truth.illuminance_lx - 1
    assert c.rms_noise_removed_percent > 2 * RT.THRESHOLDS_PERCENT["aperture-diffuser"], c.rms_percent
    assert np.mean(r) < -0.015


def test_the_diagnosis_coarse_opal_cells_keep_the_level():
    """The diagnosis' many refits gather an opal plate's light on 100 mm cells
    (``DiffuserEffect.diagnosis_params``); each sends it from sub-cells in proportion to what its
    parts gathered.  Spreading it evenly over the cell put the A3 sheet under the plate 1.1 % low
    against Mitsuba 3: the level must stay within 0.5 %, as the default cells' does."""
    from lbscene.engine.light.effects.builtin.diffuser import DiffuserEffect

    ir = _ir("opal-black")
    eff = {**ir.effects, "diffuser": DiffuserEffect.diagnosis_params(dict(ir.effects.get("diffuser") or {}))}
    assert eff["diffuser"]["cell_size_mm"] == 100.0
    for grid in ("a3", "floor"):
        c = compare_with_truth(VALIDATION / "opal-black", grid, ir=ir.model_copy(update={"effects": eff}))
        d = 100.0 * (np.asarray(c.model_lx) / c.truth.illuminance_lx - 1.0)
        assert abs(d.mean()) <= 0.5, (grid, d.mean())
        assert c.rms_noise_removed_percent <= RT.THRESHOLDS_PERCENT["opal-black"], grid
