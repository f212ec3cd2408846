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
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = ["cache_dir", "cached_array", "max_bytes", "FORMAT", "array_key"]

#: bump when a cached computation changes its result for the same inputs
FORMAT = "lbscene-geometry-1"
DEFAULT_MAX_MB = 2048


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


def _prune(root: Path, max_bytes: int) -> None:
    files = [(p.stat().st_atime, p.stat().st_size, p) for p in root.glob("*/*.npy")]
    total = sum(s for _, s, _ in files)
    for _, size, p in sorted(files, key=lambda t: t[0]):
        if total <= max_bytes:
            break
        p.unlink(missing_ok=True)
        total -= size


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


def cached_array(kind: str, arrays: tuple, params: tuple, compute: Callable[[], np.ndarray],
                 shape: tuple | None = None) -> np.ndarray:
    """``compute()``, or its earlier result for the same ``kind``, input ``arrays`` and ``params``.

    ``kind`` names the computation (a folder of the cache); ``params`` are plain
    values (numbers, strings, tuples) that change its result.  An entry that cannot be
    read, or has another ``shape`` than expected, non-finite values or a non-numeric dtype
    (a damaged or foreign file under the right name), is recomputed and replaced.
    """
    root = cache_dir()
    if root is None:
        return compute()
    limit = max_bytes()
    path = root / kind / f"{_key(kind, arrays, params)}.npy"
    try:
        out = np.load(path, allow_pickle=False, mmap_mode=None)
        if isinstance(out, np.ndarray) and _valid(out, shape):
            os.utime(path)                     # least recently *used* goes first when pruning
            return out
    except (OSError, ValueError, EOFError):
        pass
    out = np.asarray(compute())
    try:
        from .atomic import atomic_path

        with atomic_path(path, suffix=".npy") as tmp:
            np.save(tmp, out, allow_pickle=False)
        _prune(root, limit)
    except (OSError, ValueError):
        pass
    return out
