"""
A content-addressed disk cache for the forward model's geometry-only arrays.

Form factors between a booth's patches and the mesh visibility of receivers
depend on nothing but geometry, yet they are the first evaluation's whole cost
(BYK: 10 s of form factors, then 5–8 s of visibility per rendered view).  Every
``lbscene compare`` / ``render`` is a new process, so an in-memory cache does
not help the edit → compare loop; this one keeps them on disk.

* The key is a hash of the arrays the result is computed from (their bytes,
  shapes and dtypes), the computation's parameters and :data:`FORMAT`: a changed
  booth, patch size or algorithm gives a new key, never a stale hit.
* Location: ``$LBSCENE_CACHE_DIR``, else ``$XDG_CACHE_HOME/lbscene``, else
  ``~/.cache/lbscene``; ``LBSCENE_CACHE_DIR=off`` turns it off.
* Files are plain ``.npy`` (``allow_pickle=False``), written atomically; one
  that fails to load is recomputed and rewritten.  The folder is kept under
  ``$LBSCENE_CACHE_MAX_MB`` (default 2048) by removing the least recently used.
* A cache that cannot be written (read-only home, full disk) only costs time.
* **Shipped tables.**  A computation called with ``shipped=True`` is also looked up, under the
  same key, among the read-only tables that travel with lbscene (``engine/tables/``, made by
  ``scripts/make_tables.py`` for the shipped booths): the first frame of a shipped booth on a new
  machine reads its light at the vertices instead of computing it.  The key holds everything
  the result depends on (the booth's content, the receivers, the model's code), so an edited
  booth or model finds no table and computes, as before.  ``LBSCENE_SHIPPED_TABLES=off`` turns
  them off (benchmarks of a new booth, the test that re-makes them).

What the cache touches (the folder may hold anything else):

* It **deletes and replaces only entries it wrote**, recorded in its index
  ``lbscene-cache-index.json`` (entry name, device, inode, size): a file is removed
  (over the size bound) or replaced (when damaged) only while it is still the
  very file the cache wrote, checked again after moving it aside.  A file of
  another name, or one put under an entry's name by someone else, is left alone;
  so are entries of earlier lbscene versions (no index: remove the folder by
  hand).  An index that is not a regular file of the current user disables
  writing.
* It **reads without blocking and without trusting the header**: an entry is
  opened ``O_NONBLOCK | O_NOFOLLOW`` and used only if it is a regular file (a FIFO
  is skipped at once), its ``.npy`` header names a numeric dtype and a shape whose
  byte size is exactly what the file holds after the header and at most the
  cache's size bound — checked before anything is allocated.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = ["cache_dir", "cached_array", "max_bytes", "FORMAT", "INDEX_NAME", "array_key", "tables_dir",
           "recording_tables", "table_entry_name", "peek_array", "load_entry", "store_entry"]

#: bump when a cached computation changes its result for the same inputs
FORMAT = "lbscene-geometry-1"
DEFAULT_MAX_MB = 2048
#: The cache's record of the entries it wrote (the only files it ever deletes or replaces).
INDEX_NAME = "lbscene-cache-index.json"
_MAX_INDEX_BYTES = 32 * 2 ** 20
_KIND_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_ENTRY_RE = re.compile(r"^(?P<kind>[A-Za-z0-9_-]{1,64})/(?P<name>[0-9a-f]{40}\.npy)$")
_O_READ = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
_O_DIR = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


#: the shipped tables' folder (``kind-key.npy``, float32), inside the installed package
TABLES_DIR = Path(__file__).resolve().parents[1] / "tables"
#: a shipped table is read only up to this size
MAX_TABLE_BYTES = 64 * 2 ** 20
#: while :func:`recording_tables` runs: ``{"kind-key.npy": array}`` of every shipped-table computation
_RECORD: dict | None = None


def tables_dir() -> Path | None:
    """The shipped tables' folder, or None when ``LBSCENE_SHIPPED_TABLES`` is ``off``."""
    if os.environ.get("LBSCENE_SHIPPED_TABLES", "").strip().lower() in ("off", "0", "no", "false"):
        return None
    return TABLES_DIR


#: decimals to which float arrays are rounded in a shipped table's key: the table is made on one
#: machine and read on another, whose libraries may differ in the last bit of a computed
#: coordinate (10⁻¹³ mm) — never by 10⁻⁴
TABLE_KEY_DECIMALS = 4


def table_entry_name(kind: str, arrays: tuple, params: tuple) -> str:
    """``kind-key.npy``: the file of a computation's shipped table in :func:`tables_dir` (the key
    of :func:`cached_array`'s, with float arrays rounded to :data:`TABLE_KEY_DECIMALS`)."""
    def rounded(a):
        a = np.asarray(a)
        return np.round(a, TABLE_KEY_DECIMALS) + 0.0 if a.dtype.kind == "f" else a     # + 0.0: no −0

    return f"{kind}-{_key(kind, tuple(rounded(a) for a in arrays), params)}.npy"


class recording_tables:
    """Context manager: collect ``{"kind-key.npy": result}`` of every ``shipped=True`` computation
    run inside it (cache and shipped tables bypassed: each is computed), for the script that
    writes the tables.

    >>> with recording_tables() as rec:                          # doctest: +SKIP
    ...     render_every_view()
    """

    def __enter__(self) -> dict:
        global _RECORD
        self._saved, _RECORD = _RECORD, {}
        return _RECORD

    def __exit__(self, *exc) -> None:
        global _RECORD
        _RECORD = self._saved


def array_key(*arrays) -> str:
    """Short content hash of arrays (cache keys)."""
    h = hashlib.blake2b(digest_size=12)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def cache_dir() -> Path | None:
    """The cache folder, or None when caching is off."""
    env = os.environ.get("LBSCENE_CACHE_DIR")
    if env is not None:
        return None if env.strip().lower() in ("", "off", "0", "none") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "lbscene"


def _key(kind: str, arrays: tuple, params: tuple) -> str:
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{FORMAT}|{kind}|{params!r}".encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"|{a.dtype.str}{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _read_index(root_fd: int) -> dict[str, dict] | None:
    """The index's entries (``kind/key.npy`` → ``{dev, ino, size}``); ``{}`` without an index (or
    with a damaged one of the current user's), None when the index is not the cache's (not a
    regular file of the current user): nothing may be written or deleted then."""
    try:
        fd = os.open(INDEX_NAME, _O_READ, dir_fd=root_fd)
    except FileNotFoundError:
        return {}
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_size > _MAX_INDEX_BYTES:
            return None
        with os.fdopen(os.dup(fd), "rb") as f:
            d = json.loads(f.read(_MAX_INDEX_BYTES + 1))
        entries = d.get("entries") if isinstance(d, dict) else None
        if not isinstance(entries, dict):
            return {}
        return {k: v for k, v in entries.items() if _ENTRY_RE.match(k) and isinstance(v, dict)
                and all(isinstance(v.get(f), int) for f in ("dev", "ino", "size"))}
    except (OSError, ValueError, RecursionError):    # unreadable or nested past the parser: owns nothing
        return {}
    finally:
        os.close(fd)


def _write_index(root: Path, root_fd: int, entries: dict[str, dict]) -> None:
    from .outputs import _own_regular_file, write_via_temporary

    text = json.dumps({"about": "entries written by lbscene's geometry cache; the only files it deletes "
                                "or replaces", "format": FORMAT, "entries": dict(sorted(entries.items()))},
                      indent=0) + "\n"
    write_via_temporary(root_fd, root / INDEX_NAME, text.encode(), may_replace=_own_regular_file)


def _is_entry(dir_fd: int, name: str, rec: dict | None) -> bool:
    """Whether ``name`` is still the very file the index recorded (a regular file of this user, the
    same device and inode: written over in place it is still the cache's own file)."""
    if not rec:
        return False
    try:
        st = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except OSError:
        return False
    return (stat.S_ISREG(st.st_mode) and st.st_uid == os.geteuid()
            and (st.st_dev, st.st_ino) == (rec["dev"], rec["ino"]))


def _delete_entry(root: Path, kind_fd: int, name: str, rec: dict) -> bool:
    """Delete an entry the index recorded: moved aside first, checked there (so a file swapped in at
    the last moment is put back, not deleted), then removed."""
    from .outputs import _RENAME_NOREPLACE, _renameat2, _tmp_name

    aside = _tmp_name(root / name).name
    try:
        os.rename(name, aside, src_dir_fd=kind_fd, dst_dir_fd=kind_fd)
    except OSError:
        return False
    if _is_entry(kind_fd, aside, rec):
        os.unlink(aside, dir_fd=kind_fd)
        return True
    try:
        if not _renameat2(kind_fd, aside, kind_fd, name, _RENAME_NOREPLACE):
            os.link(aside, name, src_dir_fd=kind_fd, dst_dir_fd=kind_fd, follow_symlinks=False)
            os.unlink(aside, dir_fd=kind_fd)
    except OSError:
        pass                   # the name was taken meanwhile; the file stays under the aside name
    return False


def _prune(root: Path, root_fd: int, entries: dict[str, dict], max_bytes: int) -> None:
    """Remove the least recently used of the index's entries (never another file) until the entries
    take at most ``max_bytes``; entries no longer the cache's files leave the index."""
    live = []
    kind_fds: dict[str, int] = {}
    try:
        for rel, rec in list(entries.items()):
            m = _ENTRY_RE.match(rel)
            kind = m["kind"]
            if kind not in kind_fds:
                try:
                    kind_fds[kind] = os.open(kind, _O_DIR, dir_fd=root_fd)
                except OSError:
                    kind_fds[kind] = -1
            kfd = kind_fds[kind]
            if kfd < 0 or not _is_entry(kfd, m["name"], rec):
                del entries[rel]
                continue
            st = os.stat(m["name"], dir_fd=kfd, follow_symlinks=False)
            live.append((st.st_atime_ns, st.st_size, rel, m["name"], kfd))
        total = sum(size for _, size, *_ in live)
        for _, size, rel, name, kfd in sorted(live):
            if total <= max_bytes:
                break
            if _delete_entry(root, kfd, name, entries[rel]):
                total -= size
            del entries[rel]
    finally:
        for fd in kind_fds.values():
            if fd >= 0:
                os.close(fd)


def max_bytes() -> int:
    """The cache's size bound from ``$LBSCENE_CACHE_MAX_MB`` (a finite number ≥ 0 of MiB).

    Raises
    ------
    LbsceneUserError
        ``LB501`` for a value that is not a finite, non-negative number.
    """
    raw = os.environ.get("LBSCENE_CACHE_MAX_MB")
    if raw is None or not raw.strip():
        return DEFAULT_MAX_MB * 2 ** 20
    try:
        mb = float(raw)
    except ValueError:
        mb = float("nan")
    if not np.isfinite(mb) or mb < 0 or mb > 2 ** 30:
        from .diagnostics import LbsceneUserError

        raise LbsceneUserError.single("LB501", "LBSCENE_CACHE_MAX_MB must be a size in MiB",
                                      value=repr(raw), expected="a finite number from 0 to 1073741824")
    return int(mb * 2 ** 20)


def _valid(out: np.ndarray, shape: tuple | None) -> bool:
    """A cache entry is used only with the shape its caller expects and finite values."""
    if shape is not None and tuple(out.shape) != tuple(shape):
        return False
    if out.dtype.kind == "f" and not np.isfinite(out).all():
        return False
    return out.dtype.kind in "fiub"


def _load(path: Path, shape: tuple | None, limit: int, touch: bool = True) -> np.ndarray | None:
    """The entry at ``path`` if it is a sound one, else None — without blocking (a FIFO) and without
    allocating more than the file holds (a header claiming 10¹¹ elements)."""
    try:
        fd = os.open(path, _O_READ)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return None
        with os.fdopen(os.dup(fd), "rb") as f:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                dims, fortran, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                dims, fortran, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                return None
            if dtype.hasobject or dtype.kind not in "fiub" or (shape is not None and tuple(dims) != tuple(shape)):
                return None
            nbytes = math.prod(dims) * dtype.itemsize
            if nbytes > limit or f.tell() + nbytes != st.st_size:
                return None
            buf = bytearray(nbytes)
            view, got = memoryview(buf), 0
            while got < nbytes:
                n = f.readinto(view[got:])
                if not n:
                    return None
                got += n
        out = np.frombuffer(buf, dtype=dtype).reshape(dims, order="F" if fortran else "C")
        if not _valid(out, shape):
            return None
        if touch:
            os.utime(fd)                   # least recently *used* goes first when pruning
        return out
    except (OSError, ValueError, EOFError, OverflowError):
        return None
    finally:
        os.close(fd)


def _store(root: Path, kind: str, key: str, out: np.ndarray, limit: int) -> None:
    """Write the entry ``kind/key.npy`` (unless a file the cache did not write has that name), record
    it in the index and prune, under an exclusive lock on the cache folder."""
    from .outputs import clean_leftovers, write_via_temporary
    from .diagnostics import LbsceneUserError

    root.mkdir(parents=True, exist_ok=True)
    root_fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        fcntl.flock(root_fd, fcntl.LOCK_EX)
        entries = _read_index(root_fd)
        if entries is None:
            return
        try:
            os.mkdir(kind, 0o777, dir_fd=root_fd)
        except FileExistsError:
            pass
        kind_fd = os.open(kind, _O_DIR, dir_fd=root_fd)
        try:
            name, rel = f"{key}.npy", f"{kind}/{key}.npy"
            try:
                os.stat(name, dir_fd=kind_fd, follow_symlinks=False)
                exists = True
            except FileNotFoundError:
                exists = False
            if exists and not _is_entry(kind_fd, name, entries.get(rel)):
                return                      # not the cache's file: left alone, the result not kept
            clean_leftovers(root / kind, name)
            rec = entries.get(rel)

            def save(fd: int) -> None:
                with os.fdopen(os.dup(fd), "wb") as f:
                    np.lib.format.write_array(f, np.ascontiguousarray(out), allow_pickle=False)

            try:
                st = write_via_temporary(kind_fd, root / rel, save, suffix=".npy",
                                         may_replace=lambda d, n: _is_entry(d, n, rec))
            except LbsceneUserError:
                return                      # a file appeared under the name meanwhile: not ours
            entries[rel] = {"dev": st.st_dev, "ino": st.st_ino, "size": st.st_size}
        finally:
            os.close(kind_fd)
        _prune(root, root_fd, entries, limit)
        _write_index(root, root_fd, entries)
    finally:
        os.close(root_fd)


def _table(kind: str, arrays: tuple, params: tuple, shape: tuple | None) -> np.ndarray | None:
    """The shipped table of a computation, as float64, or None (none, turned off, or unsound)."""
    tables = tables_dir()
    if tables is None:
        return None
    hit = _load(tables / table_entry_name(kind, arrays, params), shape, MAX_TABLE_BYTES, touch=False)
    return None if hit is None else hit.astype(np.float64)


def cached_array(kind: str, arrays: tuple, params: tuple, compute: Callable[[], np.ndarray],
                 shape: tuple | None = None, shipped: bool = False) -> np.ndarray:
    """``compute()``, or its earlier result for the same ``kind``, input ``arrays`` and ``params``.

    ``kind`` names the computation (a folder of the cache); ``params`` are plain
    values (numbers, strings, tuples) that change its result.  An entry that cannot be
    read, or has another ``shape`` than expected, non-finite values or a non-numeric dtype
    (a damaged or foreign file under the right name), is recomputed; it is replaced only if
    it is the cache's own file (see the module's notes).  ``shipped``: also look among the
    shipped tables (before the cache; a table is read as float64).
    """
    if _RECORD is not None and shipped:
        out = np.asarray(compute())
        _RECORD[table_entry_name(kind, arrays, params)] = out
        return out
    if not _KIND_RE.match(kind):
        return compute()
    if shipped:
        hit = _table(kind, arrays, params, shape)
        if hit is not None:
            return hit
    root = cache_dir()
    if root is None:
        return compute()
    limit = max_bytes()
    key = _key(kind, arrays, params)
    out = _load(root / kind / f"{key}.npy", shape, limit)
    if out is not None:
        return out
    out = np.asarray(compute())
    try:
        _store(root, kind, key, out, limit)
    except (OSError, ValueError):
        pass
    return out


def peek_array(kind: str, arrays: tuple, params: tuple, shape: tuple | None = None) -> np.ndarray | None:
    """The result :func:`cached_array` (with ``shipped=True``) would return without computing:
    the shipped table or the cache's entry, as float64; None when neither has it (nothing is
    computed, nothing written; while tables are being recorded, always None)."""
    if _RECORD is not None or not _KIND_RE.match(kind):
        return None
    hit = _table(kind, arrays, params, shape)
    if hit is not None:
        return hit
    root = cache_dir()
    if root is None:
        return None
    out = _load(root / kind / f"{_key(kind, arrays, params)}.npy", shape, max_bytes())
    return None if out is None else out.astype(np.float64, copy=False)


def load_entry(kind: str, arrays: tuple, params: tuple) -> np.ndarray | None:
    """The cache's entry for ``kind``, ``arrays`` and ``params`` (the key of :func:`cached_array`),
    as stored, or None (none, caching off, or not a sound entry).  For results that are not one
    array computed in one call (a diagnosis, stored as bytes): :func:`store_entry` writes them."""
    root = cache_dir()
    if root is None or not _KIND_RE.match(kind):
        return None
    return _load(root / kind / f"{_key(kind, arrays, params)}.npy", None, max_bytes())


def store_entry(kind: str, arrays: tuple, params: tuple, out: np.ndarray) -> None:
    """Keep ``out`` (a numeric array) as the entry :func:`load_entry` reads, with the rules of
    :func:`cached_array` (only the cache's own files replaced, the size bound kept); an entry
    larger than the bound, or a cache that cannot be written, is not kept."""
    root = cache_dir()
    if root is None or not _KIND_RE.match(kind):
        return
    limit = max_bytes()
    out = np.asarray(out)
    if out.dtype.kind not in "fiub" or out.nbytes > limit:
        return
    try:
        _store(root, kind, _key(kind, arrays, params), out, limit)
    except (OSError, ValueError):
        pass
