r"""
The requirements of the viewing standards a lighting configuration can name, as checks.

A lighting's ``standard:`` (booth file) selects the requirements; each becomes a
:class:`Check` with a verdict ``pass``, ``fail`` or ``not_applicable``, the figure it
was judged on, the requirement in words and the clause it comes from.

ISO 3664:2009, conditions P1 (critical comparison) and P2 (practical appraisal) of prints:

=====================  ======================================================  ==================
check                  requirement                                             judged on
=====================  ======================================================  ==================
``illuminance``        P1 2000 lx ± 500 lx, P2 500 lx ± 125 lx at the centre    the sample position
                       of the viewing area
``uniformity``         at least 0.75 over the viewing area                     min/mean of the grid
``chromaticity``       CIE D50 within 0.005 in u'10 v'10 (10° observer)        the sample position
``colour_rendering``   CIE 13.3 general index Ra ≥ 90                          the sample position
``special_indices``    CIE 13.3 special indices R9–R14 ≥ 80                    the sample position
``surround``           neutral, matt surround and backing of luminance factor   floor and walls
                       below 60 %
``uv_content``         UV like D50's, stated through the CIE 51.2 UV            not assessed
                       metamerism index (see below)
``metamerism_visible`` CIE 51.2 / ISO 23603 visible-range metamerism index,     not assessed
                       category C or better (MI_vis ≤ 1.0)
``metamerism_uv``      CIE 51.2 / ISO 23603 UV-range metamerism index            not assessed
                       (MI_UV ≤ 1.5)
=====================  ======================================================  ==================

ASTM D1729 and ISO 3668 booths are checked for their illuminance range at the sample
(:data:`lbscene.engine.scene.lint.ILLUMINANCE_RANGES_LX`, the ranges the linter's LB310 uses);
their daylight-simulator quality is the CIE 51.2 metamerism index, not assessed.

Not assessed, and why: the CIE 51.2 (ISO 23603) metamerism indices are mean CIELAB
differences of five visible and three fluorescent metameric pairs whose spectral
radiance factors are tabulated only in the (paid) CIE and ISO publications; neither
colour-science nor any openly licensed data set carries them, and lbscene does not ship
copies.  The UV content lbscene can see (360–400 nm, its spectra start at 360 nm) is
reported as its ratio to the visible relative to D50's, for information: ISO 3664 sets no
tolerance on that ratio.

References
----------
ISO 3664:2009, *Graphic technology and photography — Viewing conditions*, clause 4.
CIE 13.3-1995, *Method of measuring and specifying colour rendering properties of light sources*.
CIE 51.2-1999 / ISO 23603:2005, *Standard method of assessing the spectral quality of daylight
simulators for visual appraisal and measurement of colour*.
ASTM D1729-16, *Standard practice for visual appraisal of colors and color differences of
diffusely-illuminated opaque materials*.  ISO 3668:2017, *Paints and varnishes — Visual
comparison of colour of paints*.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = ["Check", "Verdict", "ISO_3664", "standard_checks", "surround_check", "overall_verdict",
           "STANDARD_TITLES"]

Verdict = Literal["pass", "fail", "not_applicable"]

STANDARD_TITLES = {
    "ISO_3664_P1": "ISO 3664:2009 P1 (critical comparison of prints)",
    "ISO_3664_P2": "ISO 3664:2009 P2 (practical appraisal of prints)",
    "ASTM_D1729": "ASTM D1729 (visual appraisal of colours)",
    "ISO_3668": "ISO 3668 (visual comparison of paint colours)",
    "none": "no standard named",
}

#: ISO 3664:2009 requirements for the print viewing conditions (clause 4; see the module docstring)
ISO_3664 = {
    "reference_illuminant": "D50",
    "chromaticity_tolerance_uv_prime": 0.005,
    "illuminance_lx": {"ISO_3664_P1": (2000.0, 500.0), "ISO_3664_P2": (500.0, 125.0)},
    "uniformity_min": 0.75,
    "cri_ra_min": 90.0,
    "special_indices": tuple(range(9, 15)),
    "special_index_min": 80.0,
    "surround_luminance_factor_max": 0.60,
    "mi_visible_max": 1.0,
    "mi_uv_max": 1.5,
}

_REF_ISO = "ISO 3664:2009 clause 4"
_WHY_MI = ("the CIE 51.2 / ISO 23603 metameric pairs are published only in the paid standards (not in "
           "colour-science or an openly licensed data set), so lbscene cannot compute the index")


@dataclass(frozen=True)
class Check:
    """One requirement of a standard judged on one source (``model`` or ``measured``)."""

    id: str
    title: str
    source: str
    verdict: Verdict
    value: float | list | None
    unit: str
    requirement: str
    reference: str
    note: str = ""

    def to_json(self) -> dict:
        v = self.value
        if isinstance(v, (float, np.floating)):
            v = round(float(v), 6)
        elif isinstance(v, (list, tuple)):
            v = [round(float(x), 6) if isinstance(x, (float, np.floating)) else x for x in v]
        return {"id": self.id, "title": self.title, "source": self.source, "verdict": self.verdict,
                "value": v, "unit": self.unit, "requirement": self.requirement,
                "reference": self.reference, "note": self.note}


def _na(id_, title, source, requirement, reference, note, value=None, unit="") -> Check:
    return Check(id_, title, source, "not_applicable", value, unit, requirement, reference, note)


def _verdict(ok: bool) -> Verdict:
    return "pass" if ok else "fail"


@dataclass
class SourceFigures:
    """What the checks need from one source (the model or the measurements)."""

    source: str
    illuminance_at_sample_lx: float | None
    uniformity: float | None
    colorimetry: object | None            # LightColorimetry
    uv_reached: bool = True
    notes: list[str] = field(default_factory=list)


def _illuminance_check(standard: str, fig: SourceFigures) -> Check:
    from lbscene.engine.scene.lint import ILLUMINANCE_RANGES_LX

    if standard in ISO_3664["illuminance_lx"]:
        nominal, tol = ISO_3664["illuminance_lx"][standard]
        lo, hi = nominal - tol, nominal + tol
        req = f"{nominal:.0f} lx ± {tol:.0f} lx at the centre of the viewing area"
        ref = _REF_ISO
    else:
        lo, hi = ILLUMINANCE_RANGES_LX[standard]
        req = f"{lo:.0f}-{hi:.0f} lx at the viewing plane"
        ref = {"ASTM_D1729": "ASTM D1729-16", "ISO_3668": "ISO 3668:2017 clause 5.2"}[standard]
    E = fig.illuminance_at_sample_lx
    if E is None:
        return _na("illuminance", "illuminance at the sample", fig.source, req, ref,
                   "no illuminance at the sample position in this source", unit="lx")
    return Check("illuminance", "illuminance at the sample", fig.source, _verdict(lo <= E <= hi), E, "lx",
                 req, ref)


def standard_checks(standard: str, fig: SourceFigures) -> list[Check]:
    """The checks of ``standard`` (a lighting's ``standard:``) judged on the figures of one source."""
    if standard == "none":
        return []
    out = [_illuminance_check(standard, fig)]
    c = fig.colorimetry
    if standard.startswith("ISO_3664"):
        iso = ISO_3664
        req_u = f"at least {iso['uniformity_min']:.2f} over the viewing area (min/mean)"
        if fig.uniformity is None:
            out.append(_na("uniformity", "illuminance uniformity", fig.source, req_u, _REF_ISO,
                           "fewer than 3 readings on the viewing area"))
        else:
            out.append(Check("uniformity", "illuminance uniformity", fig.source,
                             _verdict(fig.uniformity >= iso["uniformity_min"]), fig.uniformity, "min/mean",
                             req_u, _REF_ISO))
        from .colorimetry import reference_uv_prime_10deg

        req_c = f"CIE D50 within {iso['chromaticity_tolerance_uv_prime']} in u'10 v'10 (CIE 1964 10° observer)"
        if c is None or c.uv_prime_10deg is None:
            out.append(_na("chromaticity", "chromaticity", fig.source, req_c, _REF_ISO,
                           "no spectrum in this source"))
        else:
            d = float(np.hypot(*(np.asarray(c.uv_prime_10deg) - reference_uv_prime_10deg("D50"))))
            out.append(Check("chromaticity", "chromaticity (Δu'10v'10 from D50)", fig.source,
                             _verdict(d <= iso["chromaticity_tolerance_uv_prime"]), d, "Δu'v'", req_c, _REF_ISO))
        req_ra = f"CIE 13.3 general colour rendering index Ra ≥ {iso['cri_ra_min']:.0f}"
        idx = iso["special_indices"]
        req_ri = (f"CIE 13.3 special indices R{idx[0]}–R{idx[-1]} ≥ {iso['special_index_min']:.0f}")
        if c is None or c.cri_ra is None:
            why = "no spectrum in this source" if c is None else "; ".join(c.notes) or "undefined"
            out.append(_na("colour_rendering", "colour rendering (Ra)", fig.source, req_ra, "CIE 13.3-1995; " + _REF_ISO, why))
            out.append(_na("special_indices", f"special indices R{idx[0]}–R{idx[-1]}", fig.source, req_ri,
                           "CIE 13.3-1995; " + _REF_ISO, why))
        else:
            out.append(Check("colour_rendering", "colour rendering (Ra)", fig.source,
                             _verdict(c.cri_ra >= iso["cri_ra_min"]), c.cri_ra, "Ra", req_ra,
                             "CIE 13.3-1995; " + _REF_ISO))
            ri = [c.cri_r[i - 1] for i in idx]
            worst = int(idx[int(np.argmin(ri))])
            out.append(Check("special_indices", f"special indices R{idx[0]}–R{idx[-1]}", fig.source,
                             _verdict(min(ri) >= iso["special_index_min"]), ri, "Ri", req_ri,
                             "CIE 13.3-1995; " + _REF_ISO, note=f"lowest: R{worst} = {min(ri):.1f}"))
        ratio = None if c is None else c.uv_to_visible_ratio
        d50 = _d50_uv_ratio()
        if ratio is None or not fig.uv_reached:
            note = "the spectrum does not reach 360-400 nm" if c is not None else "no spectrum in this source"
            out.append(_na("uv_content", "UV content", fig.source, "UV content of D50 (CIE 51.2 MI_UV)",
                           _REF_ISO, note))
        else:
            out.append(_na("uv_content", "UV content (360–400 nm / 400–700 nm, relative to D50)", fig.source,
                           f"UV content of D50, judged by the CIE 51.2 UV metamerism index "
                           f"(MI_UV ≤ {iso['mi_uv_max']})", _REF_ISO,
                           "for information: ISO 3664 sets no tolerance on this ratio and " + _WHY_MI,
                           value=ratio / d50, unit="× D50"))
        out.append(_na("metamerism_visible", "metamerism index, visible (CIE 51.2)", fig.source,
                       f"MI_vis ≤ {iso['mi_visible_max']} (category C or better)",
                       "CIE 51.2-1999 / ISO 23603:2005; " + _REF_ISO, _WHY_MI))
        out.append(_na("metamerism_uv", "metamerism index, UV (CIE 51.2)", fig.source,
                       f"MI_UV ≤ {iso['mi_uv_max']}", "CIE 51.2-1999 / ISO 23603:2005; " + _REF_ISO, _WHY_MI))
    else:
        out.append(_na("metamerism_visible", "metamerism index, visible (CIE 51.2)", fig.source,
                       "daylight simulator quality by CIE 51.2 / ISO 23603",
                       "CIE 51.2-1999 / ISO 23603:2005", _WHY_MI))
    return out


_D50_RATIO: list[float] = []


def _d50_uv_ratio() -> float:
    """CIE D50's 360–400 nm to 400–700 nm ratio (colour-science's tabulated D50)."""
    if not _D50_RATIO:
        import colour

        from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL
        from .colorimetry import UV_BAND_NM, VISIBLE_BAND_NM, _band_integral

        sd = colour.SDS_ILLUMINANTS["D50"]
        v = np.interp(WL, sd.wavelengths, sd.values)
        _D50_RATIO.append(_band_integral(v, WL, UV_BAND_NM) / _band_integral(v, WL, VISIBLE_BAND_NM))
    return _D50_RATIO[0]


def surround_check(standard: str, surfaces: list[tuple[str, str, np.ndarray, str]]) -> Check | None:
    """ISO 3664's surround: every floor and wall material neutral, matt, luminance factor < 60 %.

    ``surfaces``: ``(role, material id, 1 nm reflectance, material type)``.  The luminance factor
    is Y of the reflectance under CIE D50 (2° observer); the chroma C*ab under D50 is reported
    (ISO 3664 asks for "neutral" without a number, so it is not judged).
    """
    if not standard.startswith("ISO_3664"):
        return None
    import warnings

    import colour

    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    lim = ISO_3664["surround_luminance_factor_max"]
    req = f"neutral, matt, luminance factor below {100 * lim:.0f} %"
    ill = colour.SDS_ILLUMINANTS["D50"]
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        white = colour.sd_to_XYZ(colour.SpectralDistribution(np.ones(WL.size), WL), cmfs, ill) / 100
        for role, mid, refl, mtype in surfaces:
            XYZ = colour.sd_to_XYZ(colour.SpectralDistribution(np.asarray(refl, float), WL), cmfs, ill) / 100
            lab = colour.XYZ_to_Lab(XYZ, colour.XYZ_to_xy(white))
            rows.append((role, mid, float(XYZ[1]), float(np.hypot(lab[1], lab[2])), mtype))
    if not rows:
        return _na("surround", "surround", "model", req, _REF_ISO, "the booth declares no floor or walls")
    bad = [r for r in rows if r[2] >= lim or r[4] != "diffuse"]
    worst = max(rows, key=lambda r: r[2])
    note = "; ".join(f"{role} ({mid}): Y {100 * Y:.1f} %, C*ab {C:.1f}, {mtype}" for role, mid, Y, C, mtype in rows)
    return Check("surround", "surround (floor and walls)", "model", _verdict(not bad), worst[2], "luminance factor",
                 req, _REF_ISO, note=note)


def overall_verdict(checks: list[Check]) -> Verdict:
    """``fail`` if any check fails, ``pass`` if at least one passes and none fails, else
    ``not_applicable``."""
    vs = {c.verdict for c in checks}
    if "fail" in vs:
        return "fail"
    return "pass" if "pass" in vs else "not_applicable"
