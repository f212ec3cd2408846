"""
Colour differences of band reflectances, as a multi-angle instrument reports them.

A reflectance factor given on the engine's 16 bands (centres 400–700 nm, 20 nm) is taken to
CIE XYZ with colour-science's ASTM E308 tristimulus weighting for a 20 nm interval (the
bands are the 20 nm samples), illuminant D65 and the CIE 1964 10° observer — the instrument
convention for automotive coatings — then to CIELAB (white: the perfect diffuser,
:math:`Y_n = 100`), and compared with CIE 2000 (colour-science ``delta_E(…, method="CIE
2000")``).  Reflectance factors above 1 (near the specular direction of a metallic) are valid
inputs: L* exceeds 100.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["lab_bands", "delta_e00_bands", "luminance_weights"]


@lru_cache(maxsize=1)
def _cmfs_illuminant():
    import colour

    cmfs = colour.MSDS_CMFS["CIE 1964 10 Degree Standard Observer"]
    ill = colour.SDS_ILLUMINANTS["D65"]
    return cmfs, ill


def lab_bands(bands, grid=None) -> np.ndarray:
    """CIELAB (D65, 10°) of band reflectance factors (…, 16)."""
    import colour

    from lbscene.engine.spectra.bands import DEFAULT_GRID

    grid = grid or DEFAULT_GRID
    cmfs, ill = _cmfs_illuminant()
    b = np.asarray(bands, float)
    flat = b.reshape(-1, b.shape[-1])
    wl = grid.centres_nm.tolist()
    ones = colour.SpectralDistribution(dict(zip(wl, [1.0] * len(wl))))
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):
        white_xy = colour.XYZ_to_xy(colour.sd_to_XYZ(ones, cmfs, ill, method="ASTM E308") / 100.0)
    labs = []
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):
        # (colour warns that it trims the observer to the bands' 400–700 nm: intended)
        for row in flat:
            sd = colour.SpectralDistribution(dict(zip(wl, row.tolist())))
            xyz = colour.sd_to_XYZ(sd, cmfs, ill, method="ASTM E308") / 100.0
            labs.append(colour.XYZ_to_Lab(xyz, white_xy))
    return np.asarray(labs).reshape(b.shape[:-1] + (3,))


def delta_e00_bands(a, b, grid=None) -> np.ndarray:
    """CIE 2000 colour difference between two band reflectances (…, 16)."""
    import colour

    return np.asarray(colour.delta_E(lab_bands(a, grid), lab_bands(b, grid), method="CIE 2000"))


@lru_cache(maxsize=4)
def _y_weights(count: int, first: float, width: float) -> np.ndarray:
    from lbscene.engine.spectra.bands import BandGrid

    grid = BandGrid(first, width, count)
    eye = np.eye(grid.count)
    import colour

    cmfs, ill = _cmfs_illuminant()
    wl = grid.centres_nm.tolist()
    w = []
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):
        for row in eye:
            sd = colour.SpectralDistribution(dict(zip(wl, row.tolist())))
            w.append(colour.sd_to_XYZ(sd, cmfs, ill, method="ASTM E308")[1] / 100.0)
    w = np.asarray(w)
    return w / w.sum()


def luminance_weights(grid=None) -> np.ndarray:
    """(B,) weights, summing to 1, of the luminance factor Y/100 of a band reflectance (D65,
    10°, ASTM E308 at 20 nm): ``bands @ w`` is the reflectance an instrument's camera, seeing
    luminance, reads."""
    from lbscene.engine.spectra.bands import DEFAULT_GRID

    grid = grid or DEFAULT_GRID
    return _y_weights(grid.count, grid.first_centre_nm, grid.width_nm)
