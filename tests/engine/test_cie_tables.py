"""The shipped CIE tables (V(λ), CIE 1931 2° CMFs at 1 nm) are colour-science's, bit for bit."""

from __future__ import annotations

import numpy as np


def test_the_shipped_tables_are_current():
    from lbscene.engine.spectra import evaluate as ev

    ev._cie_tables.cache_clear()
    np.testing.assert_array_equal(ev.photopic_1nm(), ev.photopic_from_colour_science())
    np.testing.assert_array_equal(ev.cmfs_1nm(), ev.cmfs_from_colour_science())


def test_a_missing_table_falls_back_to_colour_science(tmp_path, monkeypatch):
    from lbscene.engine.spectra import evaluate as ev

    monkeypatch.setattr(ev, "CIE_TABLES", tmp_path / "missing.npz")
    ev._cie_tables.cache_clear()
    try:
        np.testing.assert_array_equal(ev.cmfs_1nm(), ev.cmfs_from_colour_science())
    finally:
        ev._cie_tables.cache_clear()
