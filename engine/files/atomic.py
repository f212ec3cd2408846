"""
Atomic file output: a file or folder appears complete or not at all.

Every writer in lbscene goes through here, so an interrupted command never
leaves a half-written product and the previous output survives until the new
one is complete.  Temporary files are siblings of the target (same file
system, so ``os.replace`` is atomic) and get the permissions an ordinary
``open()`` would have given (0666 / 0777 minus the umask): ``mkstemp`` and
``mkdtemp`` create them private (0600 / 0700), which would leave reports and
build folders unreadable to the rest of a team.

Examples
--------
>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> write_atomic(d / "a.txt", "hello")
>>> (d / "a.txt").read_text()
'hello'
>>> with atomic_path(d / "b.bin") as tmp:
...     _ = tmp.write_bytes(b"x")
>>> (d / "b.bin").read_bytes()
b'x'
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .outputs import _tmp_name, _umask, clean_leftovers, replace_dir, temporary_dir_for

__all__ = ["atomic_path", "write_atomic", "temporary_dir_for", "atomic_replace_dir"]


@contextmanager
def atomic_path(path: Path | str, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary sibling of ``path``; on success it replaces ``path``.

    ``suffix`` lets writers that infer the format from the name (``np.save``,
    matplotlib) see the right extension.  On any exception the temporary file
    is removed and ``path`` is left as it was.  The temporary's name carries the
    process id, so a later run can remove what a killed one left
    (:func:`lbscene.engine.files.outputs.clean_leftovers`).

    This is for lbscene's own files (caches, bake products); outputs a user names go
    through :mod:`lbscene.engine.files.outputs`, which also checks and records them.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(path.parent, path.name)
    tmp = _tmp_name(path, suffix=suffix)
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: Path | str, data: bytes | str) -> None:
    """Write ``data`` (str as UTF-8) to ``path`` atomically."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_path(path) as tmp:
        tmp.write_bytes(raw)


def atomic_replace_dir(tmp_dir: Path | str, out_dir: Path | str) -> None:
    """Move a finished folder into place, replacing ``out_dir`` (the old one is kept until then)."""
    replace_dir(tmp_dir, out_dir)
