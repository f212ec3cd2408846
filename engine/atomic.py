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
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "write_atomic", "temporary_dir_for", "atomic_replace_dir"]


def _umask() -> int:
    # os.umask can only be read by setting it; done once per call, restored at once
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: Path | str, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary sibling of ``path``; on success it replaces ``path``.

    ``suffix`` lets writers that infer the format from the name (``np.save``,
    matplotlib) see the right extension.  On any exception the temporary file
    is removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
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


def temporary_dir_for(out_dir: Path | str) -> Path:
    """A fresh, empty sibling folder of ``out_dir`` to assemble it in (see :func:`atomic_replace_dir`)."""
    out_dir = Path(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.tmp-", dir=out_dir.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    return tmp


def atomic_replace_dir(tmp_dir: Path | str, out_dir: Path | str) -> None:
    """Move a finished folder into place, replacing ``out_dir`` (the old one is kept until then)."""
    out_dir = Path(out_dir)
    old = None
    if out_dir.exists():
        old = out_dir.with_name(f".{out_dir.name}.old-{os.getpid()}")
        os.replace(out_dir, old)
    os.replace(tmp_dir, out_dir)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
