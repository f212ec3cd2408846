r"""
Colorimetry of a light at a point: chromaticity, CCT and Duv, colour rendering and fidelity.

Every quantity comes from colour-science, given the spectral irradiance on the 1 nm
reference grid (360–830 nm):

===========================  ====================================================================
field                        definition (colour-science call)
===========================  ====================================================================
``xy``                       CIE 1931 2° chromaticity (``sd_to_XYZ``, ``XYZ_to_xy``)
``uv_prime``                 CIE 1976 UCS u', v' (2°) (``xy_to_Luv_uv``)
``uv_prime_10deg``           CIE 1976 UCS u'10, v'10 with the CIE 1964 10° observer (ISO 3664)
``cct_K``, ``duv``           correlated colour temperature and distance from the Planckian locus
                             in CIE 1960 uv, Ohno (2013) (``uv_to_CCT(method="Ohno 2013")``)
``cri_ra``, ``cri_r``        CIE 13.3-1995 general index Ra and special indices R1–R14
                             (``colour_rendering_index``)
``cie2017_rf``               CIE 224:2017 colour fidelity index Rf
                             (``colour_fidelity_index(method="CIE 2017")``)
``tm30_rf``, ``tm30_rg``     ANSI/IES TM-30-18 fidelity and gamut indices
                             (``colour_fidelity_index(method="ANSI/IES TM-30-18")``)
``uv_to_visible_ratio``      :math:`\int_{360}^{400} E\,dλ / \int_{400}^{700} E\,dλ`, the part of the
                             UV that lbscene's 360–830 nm spectra can reach
===========================  ====================================================================

References
----------
CIE 13.3-1995, *Method of measuring and specifying colour rendering properties of light sources*.
CIE 15:2004, *Colorimetry*, 3rd edition.
CIE 224:2017, *CIE 2017 colour fidelity index for accurate scientific use*.
ANSI/IES TM-30-18, *IES method for evaluating light source color rendition*.
Y. Ohno (2014), Practical use and calculation of CCT and Duv, *LEUKOS* 10(1), 47–55.

Examples
--------
>>> import colour
>>> from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL
>>> sd = colour.SDS_ILLUMINANTS["FL2"]
>>> c = colorimetry_1nm(np.interp(WL, sd.wavelengths, sd.values, left=0, right=0))
>>> round(c.cri_ra)                       # CIE 15:2004 Table T.8: FL2 Ra = 64
64
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["LightColorimetry", "colorimetry_1nm", "reference_uv_prime_10deg", "UV_BAND_NM",
           "VISIBLE_BAND_NM"]

#: the UV band lbscene's spectra can reach (its 1 nm grid starts at 360 nm; ISO 3664's UV is 300–400 nm)
UV_BAND_NM = (360.0, 400.0)
VISIBLE_BAND_NM = (400.0, 700.0)

_OBS_2 = "CIE 1931 2 Degree Standard Observer"
_OBS_10 = "CIE 1964 10 Degree Standard Observer"


@dataclass(frozen=True)
class LightColorimetry:
    """Colorimetry of one spectral irradiance (see the module docstring for each field).

    Fields are ``None`` where a quantity is undefined for the light (no visible light, or a
    chromaticity too far from the Planckian locus for CCT and the colour rendering indices);
    ``notes`` say why.
    """

    xy: tuple[float, float] | None
    uv_prime: tuple[float, float] | None
    uv_prime_10deg: tuple[float, float] | None
    cct_K: float | None
    duv: float | None
    cri_ra: float | None
    cri_r: tuple[float, ...] | None          # R1 … R14
    cie2017_rf: float | None
    tm30_rf: float | None
    tm30_rg: float | None
    uv_to_visible_ratio: float | None
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict:
        d = asdict(self)
        for k in ("xy", "uv_prime", "uv_prime_10deg", "cri_r"):
            if d[k] is not None:
                d[k] = [round(float(v), 6 if k != "cri_r" else 3) for v in d[k]]
        for k in ("cct_K", "cri_ra", "cie2017_rf", "tm30_rf", "tm30_rg"):
            if d[k] is not None:
                d[k] = round(float(d[k]), 3)
        for k in ("duv", "uv_to_visible_ratio"):
            if d[k] is not None:
                d[k] = round(float(d[k]), 6)
        d["notes"] = list(self.notes)
        return d


def _sd(values_1nm, wavelengths_nm=None):
    import colour

    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM

    wl = REFERENCE_WAVELENGTHS_NM if wavelengths_nm is None else np.asarray(wavelengths_nm, float)
    return colour.SpectralDistribution(np.asarray(values_1nm, float), wl, name="light")


def _chromaticities(sd, observer: str):
    import colour

    XYZ = colour.sd_to_XYZ(sd, colour.MSDS_CMFS[observer])
    if not np.all(np.isfinite(XYZ)) or XYZ[1] <= 0 or XYZ.sum() <= 0:
        return None, None
    xy = colour.XYZ_to_xy(XYZ)
    return xy, colour.xy_to_Luv_uv(xy)


def reference_uv_prime_10deg(illuminant: str = "D50") -> np.ndarray:
    """u'10, v'10 of a CIE illuminant of colour-science's ``SDS_ILLUMINANTS`` (10° observer)."""
    import colour

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(_chromaticities(colour.SDS_ILLUMINANTS[illuminant], _OBS_10)[1], float)


def _band_integral(values_1nm, wl, band) -> float:
    m = (wl >= band[0]) & (wl <= band[1])
    return float(np.trapz(np.asarray(values_1nm, float)[m], wl[m])) if m.sum() > 1 else 0.0


def colorimetry_1nm(values_1nm, wavelengths_nm=None, *, uv_reached: bool = True) -> LightColorimetry:
    """Colorimetry of a spectral irradiance (any scale) sampled at ``wavelengths_nm``
    (default: lbscene's 1 nm grid, 360–830 nm).

    Parameters
    ----------
    values_1nm : array_like
        Spectral irradiance (or radiance, or a relative spectrum: every result is
        scale-invariant).
    wavelengths_nm : array_like, optional
        Its wavelengths (nm), increasing.
    uv_reached : bool
        False when the spectrum's data do not cover 360–400 nm: ``uv_to_visible_ratio`` is then
        ``None`` rather than a ratio of extrapolated zeros.

    Returns
    -------
    LightColorimetry

    Notes
    -----
    CCT and Duv follow Ohno (2013) in CIE 1960 uv.  CCT, and with it the CIE 13.3 and CIE 224
    indices (whose reference illuminant is chosen by CCT), are defined only near the Planckian
    locus (|Duv| ≤ 0.05, 1000–100 000 K here): further away those fields are ``None`` with a note.
    """
    import colour

    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM

    wl = REFERENCE_WAVELENGTHS_NM if wavelengths_nm is None else np.asarray(wavelengths_nm, float)
    v = np.clip(np.nan_to_num(np.asarray(values_1nm, float)), 0.0, None)
    notes: list[str] = []
    uv_ratio = None
    vis = _band_integral(v, wl, VISIBLE_BAND_NM)
    if uv_reached and vis > 0 and wl[0] <= UV_BAND_NM[0]:
        uv_ratio = _band_integral(v, wl, UV_BAND_NM) / vis
    elif uv_reached and vis > 0:
        notes.append(f"the spectrum starts at {wl[0]:g} nm: the UV ratio needs 360-400 nm")
    empty = LightColorimetry(None, None, None, None, None, None, None, None, None, None, uv_ratio)
    if not np.any(v > 0):
        return LightColorimetry(**{**asdict(empty), "notes": ("no light",)})
    with warnings.catch_warnings():
        # colour-science warns when it interpolates or extrapolates a spectrum onto its CMFs
        warnings.simplefilter("ignore")
        sd = _sd(v, wl)
        xy, uvp = _chromaticities(sd, _OBS_2)
        if xy is None:
            return LightColorimetry(**{**asdict(empty), "notes": ("no visible light",)})
        _, uvp10 = _chromaticities(sd, _OBS_10)
        cct, duv = (float(x) for x in colour.uv_to_CCT(colour.xy_to_UCS_uv(xy), method="Ohno 2013"))
        ra = r = rf = tm_rf = tm_rg = None
        near = abs(duv) <= 0.05 and 1000.0 <= cct <= 100000.0
        if not near:
            # CIE 15:2004: CCT is not meaningful this far from the Planckian locus
            notes.append(f"chromaticity too far from the Planckian locus (Ohno 2013 gives {cct:.0f} K, Duv "
                         f"{duv:+.4f}): CCT, Duv and the colour rendering and fidelity indices are undefined")
            cct = duv = None
        if near:
            spec = colour.colour_rendering_index(sd, additional_data=True)
            ra = float(spec.Q_a)
            r = tuple(float(spec.Q_as[i].Q_a) for i in range(1, 15))
            try:
                rf = float(colour.colour_fidelity_index(sd, method="CIE 2017"))
                tm = colour.colour_fidelity_index(sd, additional_data=True, method="ANSI/IES TM-30-18")
                tm_rf, tm_rg = float(tm.R_f), float(tm.R_g)
            except (ValueError, ZeroDivisionError, FloatingPointError) as exc:  # pragma: no cover
                notes.append(f"CIE 2017 / TM-30-18 not computed: {exc}")
    return LightColorimetry(
        xy=(float(xy[0]), float(xy[1])), uv_prime=(float(uvp[0]), float(uvp[1])),
        uv_prime_10deg=None if uvp10 is None else (float(uvp10[0]), float(uvp10[1])),
        cct_K=cct, duv=duv, cri_ra=ra, cri_r=r, cie2017_rf=rf, tm30_rf=tm_rf, tm30_rg=tm_rg,
        uv_to_visible_ratio=uv_ratio, notes=tuple(notes))
