"""
Bounds on the work a command may start, checked before the work starts.

Each bound has a default sized for a 2-core, 8 GB machine and an environment
variable that raises (or lowers) it.  A file that asks for more is refused with
``LB510``, naming the limit, the amount asked for, and the variable; the process
never discovers the problem by running out of memory.

Measured peak memory of ``lbscene compare`` (fit and diagnosis, every effect the booth
enables; ``benchmarks/bench_limits.py``):

============================  ==========  ===========  ==============
booth                         55 readings  1000 readings  per reading
============================  ==========  ===========  ==============
X-Rite SpectraLight QC        0.56 GB     1.46 GB      ≈ 0.9 MB
BYK byko-spectra effect       0.81 GB     3.58 GB      ≈ 2.9 MB
============================  ==========  ===========  ==============

so with the default bounds a compare stays under about 4 GB.

Examples
--------
>>> LIMITS["readings"].default
1000
>>> check_work("readings", 55)          # within the bound: nothing happens
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from .diagnostics import Diagnostic, LbsceneUserError, SourceLocation

__all__ = ["Limit", "LIMITS", "limit_value", "check_work", "check_environment"]


@dataclass(frozen=True)
class Limit:
    """One bound: its environment variable, default and what it counts."""

    env: str
    default: int
    counts: str
    cost: str


#: Every bound, by name.
LIMITS: dict[str, Limit] = {
    "readings": Limit("LBSCENE_MAX_READINGS", 1000, "illuminance readings in one measurement set",
                      "about 1 MB of memory and 20 ms of a compare each"),
    "lamps": Limit("LBSCENE_MAX_LAMPS", 256, "lamps in one booth", "each lamp is integrated at every point"),
    "source_points": Limit("LBSCENE_MAX_SOURCE_POINTS", 20000,
                           "point sources over all lamps (the sum of point_sources)",
                           "memory grows with points × receivers × patches"),
    "patches": Limit("LBSCENE_MAX_PATCHES", 6000, "inter-reflection patches (booth interior and meshes)",
                     "form factors take patches² × 8 bytes"),
    "pixels": Limit("LBSCENE_MAX_PIXELS", 4096 * 4096, "pixels of one rendered view (width × height)",
                    "about 136 bytes of memory each while it renders: 8192 × 8192 takes 9 GB"),
    "trials": Limit("LBSCENE_MAX_TRIALS", 100_000,
                    "trials of a visual session (observers × repeats × lightings × geometries × samples)",
                    "about 100 bytes each in the viewer's data and a row of the results"),
    "mesh_triangles": Limit("LBSCENE_MAX_MESH_TRIANGLES", 20000,
                            "mesh triangles of one geometry file (a polygon of n corners counts n − 2)",
                            "each triangle is two inter-reflection patches and a visibility test at "
                            "every receiver"),
}

_MAX_RAISED = 10 ** 9


def limit_value(name: str) -> int:
    """The bound ``name`` in force: its environment variable if set, else the default.

    Raises
    ------
    LbsceneUserError
        ``LB501`` when the variable is not a whole number from 1 to 10⁹.
    """
    lim = LIMITS[name]
    raw = os.environ.get(lim.env)
    if raw is None or not raw.strip():
        return lim.default
    try:
        v = float(raw)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v != int(v) or not 1 <= v <= _MAX_RAISED:
        raise LbsceneUserError(Diagnostic("LB501", f"{lim.env} must be a whole number", None,
                                          value=repr(raw), expected=f"a whole number from 1 to {_MAX_RAISED}"))
    return int(v)


def check_work(name: str, count: int, location: SourceLocation | None = None, what: str | None = None) -> None:
    """Refuse ``count`` of ``name`` past its bound (``LB510``), before the work starts."""
    n = limit_value(name)
    if count <= n:
        return
    lim = LIMITS[name]
    raise LbsceneUserError(Diagnostic(
        "LB510", f"{what or lim.counts}: {count} exceeds the limit of {n}", location,
        value=str(count), expected=f"at most {n} ({lim.cost})",
        hint=f"raise the limit with the environment variable {lim.env}=N if the machine has the memory"))


def check_environment() -> None:
    """Validate every lbscene environment variable once, at the start of a command."""
    for name in LIMITS:
        limit_value(name)
    if os.environ.get("LBSCENE_CACHE_MAX_MB") is not None:
        from .disk_cache import max_bytes

        max_bytes()
