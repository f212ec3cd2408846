"""Timing helpers shared by the benchmark scripts (wall clock, ``time.perf_counter``)."""

from __future__ import annotations

import statistics
import time

__all__ = ["best_of", "median_of"]


def _times(fn, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def best_of(fn, repeat: int) -> float:
    """Fastest of ``repeat`` calls, seconds (least disturbed by other load)."""
    return min(_times(fn, repeat))


def median_of(fn, repeat: int) -> float:
    """Median of ``repeat`` calls, seconds."""
    return statistics.median(_times(fn, repeat))
