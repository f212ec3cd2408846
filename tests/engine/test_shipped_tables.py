"""The shipped tables (precomputed light of the shipped booths) and the patch radiosity on disk.

* every view of every shipped booth and lighting finds its light in the tables (no forward model
  runs), and a table holds what the model computes (slow: re-made by ``scripts/make_tables.py``);
* the tables are keyed robustly (another machine's last bit does not miss them, a changed input
  does) and are never read for another booth, a damaged file or when turned off;
* the inter-reflection solution kept on disk is reused by a later process without form factors,
  and gives the same light as the receiver operators.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
WALLS_BOOTH = REPO / "tests" / "data" / "validation" / "walls-45"
SHIPPED = ["byk-byko-spectra-effect", "xrite-spectralight-qc", "iso3664-p1-d50"]
SAMPLE = REPO / "examples" / "render" / "sample-colorchecker-moderate-red-glossy.yaml"


def _sample():
    from lbscene.engine.files.load import load_document
    from lbscene.engine.scene.sample import SampleSpec
    from lbscene.schemas.sample import Sample

    return SampleSpec.from_document(load_document(SAMPLE, Sample))


@pytest.mark.parametrize("booth", SHIPPED)
def test_every_view_of_a_shipped_booth_reads_the_tables(booth, tmp_path, monkeypatch):
    """No forward model runs for the example sample's views: a model edited without
    ``scripts/make_tables.py`` fails here (the tables would be silently unused)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes import scene
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.graph import build_render_graph

    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("LBSCENE_SHIPPED_TABLES", raising=False)

    def no_model(*a, **k):
        raise AssertionError(f"{booth}: the light was computed; run scripts/make_tables.py")

    monkeypatch.setattr(scene, "_forward_model", no_model)
    ir = compile_booth(REPO / "booths" / booth)
    sample = _sample()
    views = 0
    for lighting in ir.lighting:
        sb = scene.SceneBuilder(ir, build_render_graph(ir, lighting), sample, srgb_display())
        for name in sb.view_names:
            vi = sb.view(name)
            views += 1
            assert vi.sample_irradiance_1nm.max() > 0
    assert views >= len(ir.lighting)
    assert not any(tmp_path.iterdir())          # read from the package, nothing copied to the cache


@pytest.mark.parametrize("booth", SHIPPED)
def test_the_first_compare_on_the_a3_grid_reads_the_tables(booth, monkeypatch):
    """``compare`` on the seed's A3 grid starts with the tables: no form factors, no visibility
    test of the grid's view of the patches (the direct light is computed, it is cheap)."""
    from lbscene.engine.light import radiosity
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.synthetic import a3_grid

    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    monkeypatch.delenv("LBSCENE_SHIPPED_TABLES", raising=False)

    def computed(*a, **k):
        raise AssertionError(f"{booth}: computed; run scripts/make_tables.py")

    for name in ("patch_form_factors", "_hidden_points", "pairs_near_bodies", "pyramids_clear_of"):
        monkeypatch.setattr(radiosity, name, computed)
    ir = compile_booth(REPO / "booths" / booth)
    lighting = next(iter(ir.lighting))         # every lighting: scripts/make_tables.py --check (slow)
    E = ForwardModel(ir, lighting).illuminance_lx(a3_grid())
    assert E.shape == (55,) and np.all(E > 0)


def test_a_booths_light_key_is_the_same_under_another_processors_linear_algebra():
    """The light's key does not hold what the compiler derives for colour: the SpectraLight's grey
    under UV light projects to 0.4289462734 with one OpenBLAS kernel and …733 with another, which
    kept every table of that booth from another machine (its whole IR hash changed).  Two kernels
    every x86-64 processor runs (elsewhere the setting is ignored and the test is moot)."""
    code = ("from lbscene.engine.scene.compile import compile_booth; from pathlib import Path; "
            f"ir = compile_booth(Path({str(REPO / 'booths' / 'xrite-spectralight-qc')!r})); "
            "print(ir.light_hash)")
    out = []
    for core in ("Nehalem", "Prescott"):
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "OPENBLAS_CORETYPE": core})
        out.append(p.stdout.strip())
    assert out[0] == out[1]


def test_the_first_compare_of_a_declared_booth_reads_its_patch_light(monkeypatch):
    """``compare``'s first evaluation is the declared booth (its fit starts there): the lamps'
    profile widths it passes as overrides equal the declared ones and find the shipped patch
    radiosity (they missed it: 25 s of the README walkthrough's first minute)."""
    from lbscene.engine.light import radiosity
    from lbscene.engine.loop.compare import run_compare

    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    monkeypatch.delenv("LBSCENE_SHIPPED_TABLES", raising=False)

    def computed(*a, **k):
        raise AssertionError("the patch radiosity was computed")

    monkeypatch.setattr(radiosity.RadiosityTransport, "_solve_now", computed)
    r = run_compare(REPO / "examples" / "walkthrough-spectralight-d65" / "measurements.yaml", history=False,
                    fit=False, do_diagnose=False)
    assert r.fit.lux_pred is not None and np.all(r.fit.lux_pred > 0)


def test_the_tables_are_off_when_asked(monkeypatch):
    from lbscene.engine.files import disk_cache

    monkeypatch.setenv("LBSCENE_SHIPPED_TABLES", "off")
    assert disk_cache.tables_dir() is None
    monkeypatch.setenv("LBSCENE_SHIPPED_TABLES", "")
    assert disk_cache.tables_dir() == disk_cache.TABLES_DIR


def test_a_table_key_survives_the_last_bit_but_not_a_change():
    from lbscene.engine.files.disk_cache import TABLE_KEY_DECIMALS, table_entry_name

    rng = np.random.default_rng(3)
    pts = rng.uniform(-600.0, 600.0, (5000, 3))
    name = table_entry_name("vertex_irradiance", (pts,), ("booth", "D65"))
    ulp = pts * (1 + 4 * np.finfo(float).eps)           # another machine's rounding
    assert table_entry_name("vertex_irradiance", (ulp,), ("booth", "D65")) == name
    assert table_entry_name("vertex_irradiance", (-0.0 * pts[:1] + 0.0,), ("b",)) == \
        table_entry_name("vertex_irradiance", (0.0 * pts[:1],), ("b",))
    moved = pts.copy()
    moved[17, 2] += 10.0 ** -(TABLE_KEY_DECIMALS - 1)
    assert table_entry_name("vertex_irradiance", (moved,), ("booth", "D65")) != name
    assert table_entry_name("vertex_irradiance", (pts,), ("booth", "A")) != name
    assert table_entry_name("patch_radiosity", (pts,), ("booth", "D65")) != name


def _fake_tables(tmp_path, monkeypatch):
    from lbscene.engine.files import disk_cache

    root = tmp_path / "tables"
    monkeypatch.setattr(disk_cache, "TABLES_DIR", root)
    monkeypatch.delenv("LBSCENE_SHIPPED_TABLES", raising=False)
    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path / "cache"))
    return disk_cache, root


def test_a_table_is_read_as_float64_and_only_with_its_shape(tmp_path, monkeypatch):
    disk_cache, root = _fake_tables(tmp_path, monkeypatch)
    x = np.linspace(0.0, 1.0, 7)
    name = disk_cache.table_entry_name("vertex_irradiance", (x,), ("p",))
    (root / name).parent.mkdir(parents=True)
    np.save(root / name, np.full((7, 2), 0.25, np.float32))
    calls = []

    def compute():
        calls.append(1)
        return np.ones((7, 2))

    got = disk_cache.cached_array("vertex_irradiance", (x,), ("p",), compute, shape=(7, 2), shipped=True)
    assert got.dtype == np.float64 and np.all(got == 0.25) and not calls
    # without shipped=True, or with another expected shape, the table is not used
    assert np.all(disk_cache.cached_array("vertex_irradiance", (x,), ("p",), compute, shape=(7, 2)) == 1.0)
    assert len(calls) == 1
    other_shape = disk_cache.cached_array("vertex_irradiance", (x,), ("p",), lambda: np.ones((7, 3)),
                                          shape=(7, 3), shipped=True)
    assert other_shape.shape == (7, 3) and np.all(other_shape == 1.0)
    # a damaged table (not an array) costs a computation, nothing else
    (root / name).write_bytes(b"not a table")
    calls.clear()
    got = disk_cache.cached_array("vertex_irradiance", (x,), ("q",), compute, shape=(7, 2), shipped=True)
    assert calls and np.all(got == 1.0)
    assert (root / name).read_bytes() == b"not a table"       # never rewritten


def test_recording_computes_everything_and_peek_finds_only_what_exists(tmp_path, monkeypatch):
    disk_cache, root = _fake_tables(tmp_path, monkeypatch)
    x = np.arange(4.0)
    disk_cache.cached_array("patch_radiosity", (x,), ("k",), lambda: x * 2, shipped=True)     # into the cache
    assert np.all(disk_cache.peek_array("patch_radiosity", (x,), ("k",)) == x * 2)
    assert disk_cache.peek_array("patch_radiosity", (x,), ("other",)) is None
    with disk_cache.recording_tables() as rec:
        out = disk_cache.cached_array("patch_radiosity", (x,), ("k",), lambda: x * 3, shipped=True)
        assert disk_cache.peek_array("patch_radiosity", (x,), ("k",)) is None
    assert np.all(out == x * 3)                               # computed, not read
    assert list(rec) == [disk_cache.table_entry_name("patch_radiosity", (x,), ("k",))]
    assert not root.exists()


@pytest.fixture(scope="module")
def tube_ir():
    from lbscene.engine.scene.compile import compile_booth

    return compile_booth(WALLS_BOOTH)


def _grid():
    x, y = np.meshgrid(np.linspace(-250.0, 250.0, 6), np.linspace(-180.0, 180.0, 5))
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]


def test_the_solution_on_disk_is_reused_without_form_factors(tube_ir, tmp_path, monkeypatch):
    """A later process (a fresh forward model) reads the patch radiosity the first one kept, and
    the light gathered from it equals the receiver operators' (one solve, two routes)."""
    from lbscene.engine.light import radiosity
    from lbscene.engine.light.forward import ForwardModel

    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("LBSCENE_SHIPPED_TABLES", "off")
    lighting = next(iter(tube_ir.lighting))
    pts = _grid()
    first = ForwardModel(tube_ir, lighting).illuminance_lx(pts)
    assert len(list((tmp_path / "patch_radiosity").glob("*.npy"))) == 1

    def no_form_factors(*a, **k):
        raise AssertionError("form factors computed although the solution is on disk")

    monkeypatch.setattr(radiosity, "patch_form_factors", no_form_factors)
    monkeypatch.setattr(radiosity, "cached_array", lambda kind, *a, **k: (
        no_form_factors() if kind == "form_factors" else _cached(kind, *a, **k)))
    again = ForwardModel(tube_ir, lighting).illuminance_lx(pts)
    np.testing.assert_array_equal(again, first)
    monkeypatch.undo()
    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    monkeypatch.setattr(radiosity.RadiosityTransport, "_use_solution", lambda self, P: False)
    operators = ForwardModel(tube_ir, lighting).illuminance_lx(pts)
    np.testing.assert_allclose(first, operators, rtol=1e-9)
    # the inter-reflected part is there to be compared at all
    ind = ForwardModel(tube_ir, lighting, effects={k: v for k, v in
                                                   ForwardModel(tube_ir, lighting).effects.items()
                                                   if k != "interreflection"}).illuminance_lx(pts)
    assert np.min(first / ind) > 1.01


def _cached(kind, *a, **k):
    from lbscene.engine.files.disk_cache import cached_array

    return cached_array(kind, *a, **k)


def test_a_fit_uses_the_operators_after_the_first_evaluation(tube_ir, monkeypatch):
    """The solution route serves the first evaluation at a set of receivers; a fit's next ones
    (other lamp parameters, same receivers) use the operators, built once."""
    from lbscene.engine.light import radiosity
    from lbscene.engine.light.forward import ForwardModel

    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    routes = []
    orig_ops = radiosity.RadiosityTransport._receiver_operators
    orig_sol = radiosity.RadiosityTransport._gather_solution
    monkeypatch.setattr(radiosity.RadiosityTransport, "_receiver_operators",
                        lambda self, G, P, *a: routes.append("ops") or orig_ops(self, G, P, *a))
    monkeypatch.setattr(radiosity.RadiosityTransport, "_gather_solution",
                        lambda self, G, P, *a: routes.append("solution") or orig_sol(self, G, P, *a))
    lighting = next(iter(tube_ir.lighting))
    fm = ForwardModel(tube_ir, lighting)
    pts = _grid()
    fm.illuminance_lx(pts)
    cache = fm.ctx.cache
    fm2 = ForwardModel(tube_ir, lighting, cache=cache)
    fm2.illuminance_lx(pts)
    assert routes == ["solution", "ops"]


@pytest.mark.slow
def test_the_tables_are_current():
    """``scripts/make_tables.py --check``: the tables hold what the model computes now."""
    res = subprocess.run([sys.executable, str(REPO / "scripts" / "make_tables.py"), "--check"],
                         capture_output=True, text=True, cwd=REPO)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    assert "shipped tables current" in res.stdout
