"""The geometry disk cache: hits, misses on any changed input, corrupt files, off switch, pruning."""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.engine.files import disk_cache


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path / "c"))
    return tmp_path / "c"


def counter():
    calls = []

    def compute(value=1.0):
        calls.append(value)
        return np.full((3, 2), value)

    return calls, compute


def test_second_call_is_read_from_disk(cache):
    calls, compute = counter()
    a = np.arange(6.0).reshape(2, 3)
    first = disk_cache.cached_array("ff", (a,), (2, 3.0), compute)
    again = disk_cache.cached_array("ff", (a.copy(),), (2, 3.0), compute)
    assert calls == [1.0]
    np.testing.assert_array_equal(first, again)
    assert len(list((cache / "ff").glob("*.npy"))) == 1


@pytest.mark.parametrize("change", ["value", "shape", "dtype", "params", "kind"])
def test_any_changed_input_misses(cache, change):
    calls, compute = counter()
    a = np.arange(6.0).reshape(2, 3)
    disk_cache.cached_array("ff", (a,), (2,), compute)
    b, params, kind = a, (2,), "ff"
    if change == "value":
        b = a + 1e-12
    elif change == "shape":
        b = a.reshape(3, 2)
    elif change == "dtype":
        b = a.astype(np.float32)
    elif change == "params":
        params = (3,)
    else:
        kind = "vis"
    disk_cache.cached_array(kind, (b,), params, compute)
    assert len(calls) == 2


def test_a_corrupt_file_is_recomputed_and_replaced(cache):
    calls, compute = counter()
    disk_cache.cached_array("ff", (np.zeros(2),), (), compute)
    (f,) = (cache / "ff").glob("*.npy")
    f.write_bytes(b"not an npy file")
    out = disk_cache.cached_array("ff", (np.zeros(2),), (), compute)
    assert len(calls) == 2 and out.shape == (3, 2)
    assert np.load(f).shape == (3, 2)


def test_off_switch(monkeypatch, tmp_path):
    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    assert disk_cache.cache_dir() is None
    calls, compute = counter()
    for _ in range(2):
        disk_cache.cached_array("ff", (np.zeros(2),), (), compute)
    assert len(calls) == 2


def test_default_location_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.delenv("LBSCENE_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert disk_cache.cache_dir() == tmp_path / "lbscene"


def test_size_bound_removes_least_recently_used(cache, monkeypatch):
    import os

    monkeypatch.setenv("LBSCENE_CACHE_MAX_MB", str(2.5 * 8e5 / 2 ** 20))   # room for two 0.8 MB arrays

    def put(i):
        return disk_cache.cached_array("big", (np.array([i]),), (), lambda: np.full(100_000, float(i)))

    put(0)
    put(1)
    # entry 0 used more recently than entry 1: entry 1 is the one to go
    (f0,) = [f for f in (cache / "big").glob("*.npy") if np.load(f)[0] == 0.0]
    (f1,) = [f for f in (cache / "big").glob("*.npy") if np.load(f)[0] == 1.0]
    os.utime(f1, (1_000_000, 1_000_000))
    os.utime(f0, (2_000_000, 2_000_000))
    put(2)
    left = sorted(float(np.load(f)[0]) for f in (cache / "big").glob("*.npy"))
    assert left == [0.0, 2.0]


def test_unwritable_cache_only_costs_time(monkeypatch, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(blocker / "sub"))     # a path below a file
    calls, compute = counter()
    out = disk_cache.cached_array("ff", (np.zeros(2),), (), compute)
    assert out.shape == (3, 2) and calls == [1.0]


@pytest.mark.parametrize("bad", ["shape", "nan", "dtype"])
def test_an_entry_of_the_wrong_shape_or_with_nan_is_recomputed(cache, bad):
    """A file in the right format under the right name but with the wrong content (a damaged or
    foreign cache entry) must not reach the caller: it is recomputed and replaced."""
    calls, compute = counter()
    a = np.arange(4.0)
    disk_cache.cached_array("ff", (a,), (), compute, shape=(3, 2))
    (f,) = (cache / "ff").glob("*.npy")
    wrong = {"shape": np.ones((5, 5)), "nan": np.full((3, 2), np.nan),
             "dtype": np.array([["a", "b"]] * 3)}[bad]
    np.save(f, wrong)
    out = disk_cache.cached_array("ff", (a,), (), compute, shape=(3, 2))
    assert calls == [1.0, 1.0]
    np.testing.assert_array_equal(out, np.ones((3, 2)))
    np.testing.assert_array_equal(np.load(f), np.ones((3, 2)))        # the bad entry was replaced


@pytest.mark.parametrize("value", ["inf", "-1", "nan", "lots", "1e400"])
def test_cache_size_bound_must_be_a_finite_size(cache, monkeypatch, value):
    from lbscene.engine.files.diagnostics import LbsceneUserError

    monkeypatch.setenv("LBSCENE_CACHE_MAX_MB", value)
    with pytest.raises(LbsceneUserError) as ei:
        disk_cache.cached_array("ff", (np.zeros(1),), (), lambda: np.zeros(2))
    d = ei.value.diagnostics[0]
    assert d.code == "LB501"
    assert d.format() == (f"error LB501: LBSCENE_CACHE_MAX_MB must be a size in MiB (got {value!r}; "
                          "expected a finite number from 0 to 1073741824)")
