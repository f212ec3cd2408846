"""Regenerate the rough-slab tables that travel with lbscene (``engine/light/data/rough_slab``).

Run after any change to the slab's Monte Carlo (``lbscene.engine.light.rough_slab``): the shipped tables
are used only when their recorded computation matches the current one, and
``tests/engine/test_rough_slab.py`` fails while they are stale.

    .venv/bin/python scripts/gen_rough_slab_tables.py
"""

from __future__ import annotations

import time

from lbscene.engine.light.rough_slab import SHIPPED_PLATES, write_shipped_table


def main() -> None:
    for roughness, ior in SHIPPED_PLATES:
        t0 = time.perf_counter()
        path = write_shipped_table(roughness, ior)
        print(f"roughness {roughness:g}, ior {ior:g}: {path.name} "
              f"({path.stat().st_size / 1024:.0f} KiB, {time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
