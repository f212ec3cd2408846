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


def test_the_named_spectra_are_colour_sciences():
    """Every illuminant and light source a booth may name is colour-science's, bit for bit, and a
    named spectrum evaluates as colour-science's dataset does."""
    import colour

    from lbscene.engine.spectra import evaluate as ev

    ev._named_spectra.cache_clear()
    for dataset, attr in ev.NAMED_DATASETS.items():
        data = getattr(colour, attr)
        assert ev.known_names(dataset) == sorted(data.keys())
        for name, sd in data.items():
            ours = ev._colour_dataset_sd(dataset, name)
            np.testing.assert_array_equal(ours.wavelengths, sd.wavelengths)
            np.testing.assert_array_equal(ours.values, sd.values)
    # aliases and case as before
    assert ev._colour_dataset_sd("illuminant", "F2") is ev._colour_dataset_sd("illuminant", "FL2")
    assert ev._colour_dataset_sd("light_source", "philips tl-84") is not None
    assert ev._colour_dataset_sd("light_source", "no such lamp") is None


def test_planck_against_colour_science_and_wien():
    """Relative Planck radiance: colour-science's ``planck_law`` (CIE's c₂) normalised at 560 nm,
    and Wien's displacement law (peak at 2.898e6 nm·K / T; c₂ = 1.4388e-2 m·K gives 2.8978e6)."""
    import colour

    from lbscene.engine.spectra import evaluate as ev
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    for T in (2300.0, 3100.0, 6500.0):
        ref = colour.colorimetry.planck_law(WL * 1e-9, T).ravel()
        np.testing.assert_allclose(ev.planck_relative(WL, T), ref / np.interp(560.0, WL, ref), rtol=1e-12)
    wl = np.linspace(800.0, 1500.0, 70001)
    peak = wl[np.argmax(ev.planck_relative(wl, 2500.0))]
    assert abs(peak - 2.8978e6 / 2500.0) < 0.05


def test_a_booth_naming_spectra_compiles_without_colour_science():
    """The shipped SpectraLight QC names D65, A, TL-84 and blackbodies: compiling it imports no
    colour-science (2–3 s of every first frame)."""
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    code = ("import sys\nfrom lbscene.engine.scene.compile import compile_booth\n"
            f"compile_booth({str(repo / 'booths' / 'xrite-spectralight-qc')!r})\n"
            "print('colour' in sys.modules)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip().splitlines()[-1] == "False"
