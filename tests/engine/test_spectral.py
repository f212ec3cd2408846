"""Band integration against closed forms."""

import numpy as np
import pytest

from lbscene.engine.spectra.bands import (DEFAULT_GRID, REFERENCE_WAVELENGTHS_NM, BandGrid, band_labels,
                                          to_reference)


def test_default_grid_matches_seed_16_bands_400_700():
    g = DEFAULT_GRID
    assert g.count == 16
    np.testing.assert_allclose(g.centres_nm, np.arange(400, 701, 20))
    assert (g.edges_nm[0], g.edges_nm[-1]) == (390.0, 710.0)
    assert band_labels()[0] == "390-410nm" and band_labels()[-1] == "690-710nm"


def test_band_mean_of_linear_spectrum_is_value_at_centre():
    # mean of a linear function over a band = its value at the band centre (exact)
    values = 0.01 * REFERENCE_WAVELENGTHS_NM - 2.0
    np.testing.assert_allclose(DEFAULT_GRID.integrate(values), 0.01 * DEFAULT_GRID.centres_nm - 2.0,
                               rtol=0, atol=1e-12)


def test_narrow_line_counts_its_area_not_the_centre_sample():
    # A 1 nm-wide triangular line of area 1 at 546 nm (Hg line, F-lamps): band 530-550 gets area/width.
    wl = np.array([300.0, 545.0, 546.0, 547.0, 900.0])
    v = np.array([0.0, 0.0, 1.0, 0.0, 0.0])
    bands = DEFAULT_GRID.integrate(to_reference(wl, v))
    k = int(np.argmin(abs(DEFAULT_GRID.centres_nm - 540)))
    assert bands[k] == pytest.approx(1.0 / 20.0, rel=1e-9)
    # point sampling at the band centre would give 0 here
    assert np.interp(540.0, wl, v) == 0.0
    assert bands.sum() == pytest.approx(1.0 / 20.0)


def test_to_reference_rejects_non_increasing():
    with pytest.raises(ValueError, match="strictly increasing"):
        to_reference([400, 400, 500], [1, 2, 3])


def test_grid_outside_reference_range_rejected():
    with pytest.raises(ValueError, match="reference range"):
        BandGrid(first_centre_nm=300.0)
