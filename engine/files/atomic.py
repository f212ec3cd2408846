"""
Atomic file output: a file or folder appears complete or not at all.

Every writer in lbscene goes through here, so an interrupted command never
leaves a half-written product and the previous output survives until the new
one is complete.  Temporaries lie beside the target (same file system, so the
final rename is atomic), are created exclusively and written through their
descriptor (or, for writers that need a path, inside a private ``0700`` folder),
and get the permissions an ordinary ``open()`` would have given (0666 / 0777
minus the umask) only when they are moved into place.

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
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .outputs import (_O_NOFOLLOW_READ, _dir_fd, _own_regular_file, _tmp_prefix, _umask, clean_leftovers,
                      commit_file, replace_dir, temporary_dir_for, write_via_temporary)

__all__ = ["atomic_path", "write_atomic", "temporary_dir_for", "atomic_replace_dir"]


@contextmanager
def atomic_path(path: Path | str, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a path to write; on success the file written there replaces ``path``.

    ``suffix`` lets writers that infer the format from the name (``np.save``,
    matplotlib) see the right extension.  The path lies in a private folder (``0700``,
    named in lbscene's temporary pattern) inside ``path``'s folder, so that nobody else can
    swap it for a link; what the writer leaves must be a regular file.  On any exception
    ``path`` is left as it was and nothing is left behind; a later run removes what a killed
    one left (:func:`lbscene.engine.files.outputs.clean_leftovers`).

    This is for lbscene's own files (bake products, job files, generated schemas): an existing
    regular file of the current user is replaced; a link, a folder or another user's file in
    its place is not (``LB611``).  Outputs a user names go through
    :mod:`lbscene.engine.files.outputs`, which also checks them against the folder's ledger.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(path.parent, path.name)
    private = Path(tempfile.mkdtemp(prefix=_tmp_prefix(path), dir=path.parent))
    inner = private / f"output{suffix}"
    try:
        yield inner
        with _dir_fd(private) as pfd, _dir_fd(path.parent) as dfd:
            fd = os.open(inner.name, _O_NOFOLLOW_READ, dir_fd=pfd)
            try:
                if not stat.S_ISREG(os.fstat(fd).st_mode):
                    raise OSError(f"{path}: the writer did not leave a regular file")
                os.fchmod(fd, 0o666 & ~_umask())
            finally:
                os.close(fd)
            commit_file(pfd, inner.name, dfd, path.name, shown=path, may_replace=_own_regular_file)
    finally:
        shutil.rmtree(private, ignore_errors=True)


def write_atomic(path: Path | str, data: bytes | str) -> None:
    """Write ``data`` (str as UTF-8) to ``path`` atomically, through the descriptor of an
    exclusively created temporary (see :func:`atomic_path` for what may be replaced)."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(path.parent, path.name)
    with _dir_fd(path.parent) as dfd:
        write_via_temporary(dfd, path, raw, may_replace=_own_regular_file)


def atomic_replace_dir(tmp_dir: Path | str, out_dir: Path | str, *, option: str | None = None) -> None:
    """Move a finished folder into place, replacing ``out_dir`` only if every file in it is
    lbscene's and unchanged (:func:`lbscene.engine.files.outputs.replace_dir`)."""
    replace_dir(tmp_dir, out_dir, option=option)
