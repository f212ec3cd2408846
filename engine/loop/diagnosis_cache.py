"""
A finished diagnosis kept on disk, so that the same question is not answered twice.

The diagnosis refits the booth with every missing effect and hypothesis (seconds to a minute);
``lbscene compare`` in another format, ``compare --report`` after ``compare``, or ``lbscene plan``
after ``compare`` ask it again of the same booth and readings.  Each is a new process, so the
result is kept in the disk cache of :mod:`lbscene.engine.files.disk_cache` (its folder, size
bound, ownership rules and ``LBSCENE_CACHE_DIR=off``).

* **The key** is everything the result is computed from: the booth as compiled with the measured
  reflectances (its content hash), the lighting, the readings and the white tile (their values,
  positions, orientations, files and lines), the noise model, the enabled effects and free
  parameters, the candidates asked for, and a digest of the code of the light model, the
  measurement loop and the scene compiler.  Any change gives a new key, never a stale result.
* **The entry** is a JSON text of the result's objects (stored as the bytes of a ``uint8`` array:
  the cache reads only numeric ``.npy`` files, checked before anything is allocated).  Only
  lbscene's own result types are rebuilt from it (:data:`TYPES`); arrays are numeric, rebuilt
  from their bytes with their dtype and shape; a booth a hypothesis added is re-validated from
  its JSON and must hash to the content hash it was stored with.  An entry that fails any of
  this is ignored and the diagnosis computed again.
* A result is the same object graph whether computed or read: floats round-trip exactly
  (``repr``), arrays bit for bit.
"""

from __future__ import annotations

import base64
import dataclasses
import json
from pathlib import Path

import numpy as np

__all__ = ["cached_diagnosis", "diagnosis_key", "encode", "decode", "TYPES", "FORMAT"]

#: bump when the stored form changes
FORMAT = "lbscene-diagnosis-1"
#: the cache's folder (``kind``) of diagnoses
KIND = "diagnosis"


def _types() -> dict[str, type]:
    from lbscene.engine.loop.diagnose import Confidence, Diagnosis, NoiseModel, Suspect, Verdict
    from lbscene.engine.loop.fit import FitResult, FreeParameter

    return {c.__name__: c for c in (Diagnosis, Verdict, Suspect, Confidence, NoiseModel, FitResult,
                                    FreeParameter)}


#: the classes an entry may rebuild (name → class), filled on first use
TYPES: dict[str, type] = {}


class _NotStorable(Exception):
    pass


def _scene_ir_type():
    from lbscene.engine.scene.ir import SceneIR

    return SceneIR


def encode(obj) -> bytes:
    """``obj`` (a :class:`~lbscene.engine.loop.diagnose.Diagnosis`) as JSON bytes.

    Raises
    ------
    ValueError
        An object of a type the format does not hold (the result is then not stored).
    """
    if not TYPES:
        TYPES.update(_types())
    SceneIR = _scene_ir_type()

    def enc(x):
        if x is None or isinstance(x, (bool, str)):
            return x
        if isinstance(x, (int, np.integer)) and not isinstance(x, bool):
            return {"__int__": int(x)} if isinstance(x, np.integer) else x
        if isinstance(x, (float, np.floating)):
            return float(x)                 # written as repr: read back bit for bit
        if isinstance(x, np.bool_):
            return bool(x)
        if isinstance(x, np.ndarray):
            if x.dtype.kind not in "fiub":
                raise _NotStorable(f"array of {x.dtype}")
            a = np.ascontiguousarray(x)
            return {"__nd__": a.dtype.str, "shape": list(a.shape), "b64": base64.b64encode(a.tobytes()).decode()}
        if isinstance(x, tuple):
            return {"__tuple__": [enc(v) for v in x]}
        if isinstance(x, list):
            return [enc(v) for v in x]
        if isinstance(x, dict):
            if all(isinstance(k, str) for k in x):
                return {"__map__": {k: enc(v) for k, v in x.items()}}
            return {"__pairs__": [[enc(k), enc(v)] for k, v in x.items()]}
        if isinstance(x, SceneIR):
            return {"__ir__": x.model_dump(mode="json"), "hash": x.content_hash}
        t = type(x)
        if dataclasses.is_dataclass(x) and TYPES.get(t.__name__) is t:
            # attributes named with "_" are a process's own memos (a fit's spectral tables with
            # the problem they were computed on): not part of the result
            return {"__dc__": t.__name__, "attrs": {k: enc(v) for k, v in vars(x).items()
                                                    if not k.startswith("_")}}
        raise _NotStorable(f"an object of type {t.__name__}")

    try:
        return json.dumps(enc(obj), separators=(",", ":")).encode()
    except _NotStorable as e:
        raise ValueError(f"a diagnosis holding {e} cannot be stored") from None


def decode(data: bytes):
    """The object :func:`encode` stored.

    Raises
    ------
    ValueError
        Data that are not such an entry (any type outside :data:`TYPES`, a malformed array, a
        booth that does not hash to what it was stored with).
    """
    if not TYPES:
        TYPES.update(_types())
    SceneIR = _scene_ir_type()

    def dec(x):
        if x is None or isinstance(x, (bool, str, int, float)):
            return x
        if isinstance(x, list):
            return [dec(v) for v in x]
        if not isinstance(x, dict) or len(x) == 0:
            raise ValueError("not a stored diagnosis")
        if "__int__" in x:
            return int(x["__int__"])
        if "__nd__" in x:
            dt = np.dtype(x["__nd__"])
            if dt.kind not in "fiub" or dt.hasobject:
                raise ValueError("not a numeric array")
            shape = tuple(int(n) for n in x["shape"])
            raw = base64.b64decode(x["b64"], validate=True)
            if len(raw) != int(np.prod(shape, dtype=np.int64)) * dt.itemsize:
                raise ValueError("an array's bytes do not match its shape")
            return np.frombuffer(raw, dtype=dt).reshape(shape).copy()
        if "__tuple__" in x:
            return tuple(dec(v) for v in x["__tuple__"])
        if "__map__" in x:
            return {str(k): dec(v) for k, v in x["__map__"].items()}
        if "__pairs__" in x:
            return {_hashable(dec(k)): dec(v) for k, v in x["__pairs__"]}
        if "__ir__" in x:
            ir = SceneIR.model_validate(x["__ir__"])
            if ir.content_hash != x.get("hash"):
                raise ValueError("a stored booth does not hash to its recorded content")
            return ir
        if "__dc__" in x:
            cls = TYPES.get(x["__dc__"])
            if cls is None:
                raise ValueError(f"not a stored result type: {x['__dc__']!r}")
            obj = cls.__new__(cls)
            attrs = {str(k): dec(v) for k, v in x["attrs"].items()}
            names = {f.name for f in dataclasses.fields(cls)}
            if not names <= set(attrs):
                raise ValueError(f"a stored {cls.__name__} lacks fields")
            obj.__dict__.update(attrs)
            return obj
        raise ValueError("not a stored diagnosis")

    try:
        return dec(json.loads(data))
    except (TypeError, KeyError, AttributeError, RecursionError, OverflowError, ValueError) as e:
        raise ValueError(f"not a stored diagnosis: {e}") from None


def _hashable(k):
    return tuple(_hashable(v) for v in k) if isinstance(k, list) else k


def _code_digest(ir) -> str:
    """The light model's code digest over the measurement loop's and the scene compiler's files
    too, and every registered effect's module (the candidates are all of them, plugins included)."""
    import inspect

    from lbscene.engine import loop, scene
    from lbscene.engine.light.code_digest import light_code_digest
    from lbscene.engine.light.effects.registry import available_effects

    extra = []
    for pkg in (loop, scene):
        root = Path(pkg.__file__).parent
        extra += [f for f in root.rglob("*") if f.is_file() and "__pycache__" not in f.parts]
    for cls in available_effects().values():
        try:
            src = inspect.getsourcefile(cls)
        except TypeError:
            src = None
        if src:
            extra.append(Path(src))
    return light_code_digest(ir, extra)


def diagnosis_key(meas, problem, candidates) -> tuple[tuple, tuple]:
    """``(arrays, params)`` of the cache key of diagnosing ``problem`` on ``meas`` (see the module
    docstring)."""
    arrays, params = [], [FORMAT, meas.ir.content_hash, meas.lighting, str(meas.path), str(meas.booth_file),
                          tuple(meas.known_output_groups), repr(meas.declared_noise_percent),
                          repr(meas.spectral_noise_percent), repr(meas.model_uncertainty_percent),
                          tuple(meas.notes), json.dumps(problem.effects, sort_keys=True, default=repr),
                          tuple((fp.target, tuple(map(float, fp.bounds)), float(fp.initial)) for fp in problem.free),
                          repr(problem.noise_percent), repr(problem.spectral_noise_percent), repr(problem.tolerance),
                          None if candidates is None else tuple(candidates), _code_digest(meas.ir)]
    ill = meas.illuminance
    if ill is not None:
        arrays += [ill.points_mm, ill.normals, ill.lux, np.asarray(ill.lines, np.int64)]
        params += [tuple(ill.files), tuple(ill.labels)]
    else:
        params.append("no readings")
    tile = meas.tile
    if tile is not None:
        arrays += [tile.position_mm, tile.normal, tile.radiance_1nm, tile.covered, tile.reflectance_1nm]
        params += [tile.display, repr(tile.sampling_nm), repr(tile.first_sample_nm)]
    else:
        params.append("no tile")
    return tuple(np.asarray(a) for a in arrays), tuple(params)


def cached_diagnosis(meas, problem, compute, candidates=None):
    """``compute()`` (a diagnosis of ``problem`` on ``meas``), or the one an earlier process stored
    for the same inputs and code.  A result that cannot be stored is returned all the same."""
    from lbscene.engine.files import disk_cache as dc

    if dc.cache_dir() is None:
        return compute()
    arrays, params = diagnosis_key(meas, problem, candidates)
    hit = dc.load_entry(KIND, arrays, params)
    if hit is not None and hit.dtype == np.uint8 and hit.ndim == 1:
        try:
            return decode(hit.tobytes())
        except ValueError:
            pass
    d = compute()
    try:
        dc.store_entry(KIND, arrays, params, np.frombuffer(encode(d), dtype=np.uint8))
    except ValueError:
        pass
    return d
