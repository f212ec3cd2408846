"""
The light model's code, as a hash: part of the key of every stored result of the model.

Results of the forward model kept across processes (the disk cache, the shipped tables) are
keyed by what they are computed from: the booth's content, the receivers, the parameters and
this digest of the model's code — the source and data files of the transport
(``engine/light``, its effects and tables), of the spectra (``engine/spectra``) and of every
enabled effect's module (plugins included).  An edited model therefore never reads a stale
result.  Files are hashed by name and content, not by path, so a checkout and an installed
wheel of the same code agree.

Examples
--------
>>> from lbscene.engine.light.code_digest import light_code_digest   # doctest: +SKIP
>>> len(light_code_digest(ir))                                       # doctest: +SKIP
32
"""

from __future__ import annotations

import hashlib
import inspect
from pathlib import Path

__all__ = ["light_code_digest", "code_files"]

_DIGESTS: dict = {}


def code_files(ir, extra=()) -> set[Path]:
    """The files :func:`light_code_digest` hashes for ``ir`` (its enabled effects name the plugin
    modules), plus ``extra``."""
    from lbscene.engine import light, spectra
    from lbscene.engine.light.effects.registry import get_effect

    files = {Path(f) for f in extra}
    for pkg in (light, spectra):
        root = Path(pkg.__file__).parent
        files.update(f for f in root.rglob("*") if f.is_file() and "__pycache__" not in f.parts)
    for eid in sorted(ir.effects):
        try:
            src = inspect.getsourcefile(get_effect(eid))
        except (KeyError, TypeError):
            src = None
        if src:
            files.add(Path(src))
    return files


def light_code_digest(ir, extra=()) -> str:
    """Hex digest (32 characters) of :func:`code_files` (hashing ~2 MB: a few ms, once per process
    and set of files).

    Parameters
    ----------
    ir
        The compiled booth.
    extra
        More files whose code shapes the stored result (a runtime's own module).
    """
    files = code_files(ir, extra)
    key = tuple(sorted(str(f) for f in files))
    hit = _DIGESTS.get(key)
    if hit is None:
        h = hashlib.blake2b(digest_size=16)
        for f in sorted(files, key=lambda f: (f.name, f.read_bytes())):
            h.update(f.name.encode())
            h.update(f.read_bytes())
        hit = _DIGESTS[key] = h.hexdigest()
    return hit
