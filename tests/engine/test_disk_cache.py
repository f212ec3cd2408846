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


# --------------------------------------------------------------------------- only what the cache wrote


def test_pruning_never_deletes_files_the_cache_did_not_write(cache, monkeypatch):
    """Over its size bound the cache removes entries recorded in its own index, never a file
    that merely matches ``*/*.npy``."""
    import os

    cache.mkdir(parents=True)
    (cache / "mine").mkdir()
    np.save(cache / "mine" / "results.npy", np.arange(200_000.0))          # 1.6 MB of the user's
    (cache / "ff").mkdir()
    np.save(cache / "ff" / "notes.npy", np.arange(10.0))                  # under a cache folder's name
    for f in (cache / "mine" / "results.npy", cache / "ff" / "notes.npy"):
        os.utime(f, (1_000_000, 1_000_000))                              # "least recently used"
    monkeypatch.setenv("LBSCENE_CACHE_MAX_MB", str(1e6 / 2 ** 20))        # room for one 0.8 MB entry

    def put(i):
        return disk_cache.cached_array("ff", (np.array([i]),), (), lambda: np.full(100_000, float(i)))

    put(0)
    put(1)
    np.testing.assert_array_equal(np.load(cache / "mine" / "results.npy"), np.arange(200_000.0))
    np.testing.assert_array_equal(np.load(cache / "ff" / "notes.npy"), np.arange(10.0))
    left = sorted(float(np.load(f)[0]) for f in (cache / "ff").glob("*.npy") if f.name != "notes.npy")
    assert left == [1.0]                                                  # its own oldest entry went


def test_a_file_put_under_an_entrys_name_is_not_replaced(cache):
    """A file at an entry's name that the cache did not write (not its index's file) is left as it is."""
    calls, compute = counter()
    a = np.arange(3.0)
    key = disk_cache._key("ff", (a,), ())
    (cache / "ff").mkdir(parents=True)
    mine = cache / "ff" / f"{key}.npy"
    mine.write_bytes(b"the user's bytes")
    out = disk_cache.cached_array("ff", (a,), (), compute)
    assert calls == [1.0] and out.shape == (3, 2)
    assert mine.read_bytes() == b"the user's bytes"


_FIFO_SCRIPT = """
import os, sys
import numpy as np
from lbscene.engine.files import disk_cache
a = np.arange(3.0)
out = disk_cache.cached_array("ff", (a,), (), lambda: np.ones((3, 2)))
print(out.sum())
"""


@pytest.mark.parametrize("where", ["entry", "index"])
def test_a_fifo_in_the_cache_does_not_hang(cache, where):
    import os
    import subprocess
    import sys

    a = np.arange(3.0)
    (cache / "ff").mkdir(parents=True)
    fifo = cache / "ff" / f"{disk_cache._key('ff', (a,), ())}.npy" if where == "entry" else \
        cache / disk_cache.INDEX_NAME
    os.mkfifo(fifo)
    p = subprocess.run([sys.executable, "-c", _FIFO_SCRIPT], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "LBSCENE_CACHE_DIR": str(cache)})   # a hang times out here
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "6.0"
    import stat

    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)                          # left as it was


def test_a_header_claiming_a_huge_array_is_not_allocated(cache):
    """A cache entry whose header claims 10¹¹ float64 (745 GiB) is checked against the file's size
    before anything is allocated, then recomputed."""
    import tracemalloc

    calls, compute = counter()
    a = np.arange(4.0)
    disk_cache.cached_array("ff", (a,), (), compute)
    (f,) = (cache / "ff").glob("*.npy")
    header = {"descr": "<f8", "fortran_order": False, "shape": (10 ** 11,)}
    with open(f, "r+b") as fh:                                             # the cache's own file, rewritten
        fh.truncate(0)
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(np.zeros(2).tobytes())
    tracemalloc.start()
    try:
        out = disk_cache.cached_array("ff", (a,), (), compute)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert calls == [1.0, 1.0]
    np.testing.assert_array_equal(out, np.ones((3, 2)))
    assert peak < 50 * 2 ** 20
    np.testing.assert_array_equal(np.load(f), np.ones((3, 2)))           # and replaced


def test_an_index_nested_past_the_json_parser_owns_nothing(cache):
    """A cache index of 100 000 nested arrays (RecursionError in the parser) is not believed: the
    value is computed, nothing is deleted, no traceback."""
    cache.mkdir(parents=True)
    (cache / disk_cache.INDEX_NAME).write_text("[" * 100_000 + "]" * 100_000)
    (cache / "mine.npy").write_bytes(b"the user's file")
    calls, compute = counter()
    out = disk_cache.cached_array("ff", (np.zeros(2),), (1,), compute)
    assert calls == [1.0] and out.shape == (3, 2)
    assert (cache / "mine.npy").read_bytes() == b"the user's file"
