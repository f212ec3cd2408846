"""Regenerate the rough-slab tables that travel with lbscene (``engine/light/data/rough_slab``).

Run after any change to the slab's Monte Carlo (``lbscene.engine.light.rough_slab``): the shipped tables
are used only when their recorded computation matches the current one, and
``tests/engine/test_rough_slab.py`` fails while they are stale.

    .venv/bin/python scripts/gen_rough_slab_tables.py
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor

from lbscene.engine.light.rough_slab import SHIPPED_PLATES, write_shipped_table


def _one(plate: tuple[float, float]) -> str:
    roughness, ior = plate
    t0 = time.perf_counter()
    path = write_shipped_table(roughness, ior)
    return (f"roughness {roughness:g}, ior {ior:g}: {path.name} "
            f"({path.stat().st_size / 1024:.0f} KiB, {time.perf_counter() - t0:.1f} s)")


def main() -> None:
    # one plate per process (each table is a single-threaded Monte Carlo)
    with ProcessPoolExecutor(max_workers=max(1, min(len(SHIPPED_PLATES), os.cpu_count() or 1))) as pool:
        for line in pool.map(_one, SHIPPED_PLATES):
            print(line, flush=True)


if __name__ == "__main__":
    main()
