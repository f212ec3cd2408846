"""Regenerate the CIE tables that travel with lbscene (``engine/spectra/data/cie_1nm.npz``).

V(λ) and the CIE 1931 2° colour matching functions on the 1 nm reference grid, as
colour-science gives them, and its named illuminants and light sources
(``engine/spectra/data/named_spectra.npz``) as it tabulates them; run after upgrading colour-science or changing the grid
(``tests/engine/test_cie_tables.py`` fails while the table is stale).

    .venv/bin/python scripts/gen_cie_tables.py
"""

from __future__ import annotations

import numpy as np

from lbscene.engine.spectra.evaluate import (CIE_TABLES, NAMED_SPECTRA, cmfs_from_colour_science,
                                             named_spectra_from_colour_science, photopic_from_colour_science)


def main() -> None:
    CIE_TABLES.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(CIE_TABLES, photopic=photopic_from_colour_science(),
                        cmfs_1931_2deg=cmfs_from_colour_science())
    print(f"{CIE_TABLES.name}: {CIE_TABLES.stat().st_size / 1024:.0f} KiB")
    np.savez_compressed(NAMED_SPECTRA, **named_spectra_from_colour_science())
    print(f"{NAMED_SPECTRA.name}: {NAMED_SPECTRA.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
