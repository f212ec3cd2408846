#!/usr/bin/env python
"""
Generate the spectral CSV files of the shipped booths.

Run from the repository root (deterministic: the same inputs give
byte-identical files; no randomness, no network)::

    .venv/bin/python booths/tools/make_spectra.py          # write the CSVs
    .venv/bin/python booths/tools/make_spectra.py --check  # exit 1 if a CSV is stale
    .venv/bin/python booths/tools/make_spectra.py --report # CCT, Ra, ... of the sources

Every file is a 5 nm table ``wavelength_nm,<quantity>`` over 380-780 nm
(the UV lamp: 300-780 nm).  None of these spectra is a measurement: they
are plausible **estimates** built from physical models and CIE/colour-science
reference data, so that the booths are usable until someone replaces them
with their own measurements (each booth.yaml marks them ``status: estimate``).

What each file is and how it is made
------------------------------------
``xrite-spectralight-qc/spectra/d65_filter.csv`` (transmittance)
    The daylight-conversion filter in front of the 3100 K tungsten-halogen
    D65 lamps.  The exact ratio D65(λ)/B(λ, 3100 K) is smoothed with a
    4th-order polynomial in log space (coloured glass cannot follow D65's
    fine structure), a +6 % ripple is added around 560 nm (the seed paper
    reports that commercial filtered-halogen D65 deviates from CIE D65
    "for example around 560 nm"), and a smooth two-parameter tilt then
    restores D65's chromaticity exactly.  Peak transmittance 0.82 (two
    glass/air surfaces plus absorption).
``xrite-spectralight-qc/spectra/grey_n7.csv`` (reflectance)
    Matte neutral grey paint, Munsell N7 (luminous reflectance Y = 41.99 %,
    ASTM D1535): flat, with the drop below ~420 nm of TiO2-pigmented paints.
``xrite-spectralight-qc/spectra/glass_diffuser.csv`` (transmittance)
    4 mm soda-lime glass plate: Fresnel losses (~8 %), Fe3+ absorption edge
    toward 380 nm and the short-wave tail of the Fe2+ band toward the red.
``xrite-spectralight-qc/spectra/uva_blacklight.csv`` (relative_power)
    UVA "blacklight-blue" tube: SrB4O7:Eu2+-type phosphor band at 368 nm
    behind Wood's glass, the Hg lines that leak through it (404.7, 435.8 nm),
    and the faint deep-red leak of Wood's glass.
``byk-byko-spectra-effect/spectra/pl_l_55w_950.csv`` (relative_power)
    A Philips PL-L 55W/950-like multi-band de-luxe fluorescent lamp, 5000 K,
    CRI > 90: broad phosphor bands (BAM:Eu 450 nm, Sr4Al14O25:Eu 490 nm,
    a broad green-yellow band, (Gd,Ce)MgB5O10:Mn-like red at 630 nm,
    Mg-fluorogermanate:Mn deep red at 658 nm) plus the narrow lines of the
    trichromatic phosphors (Tb3+ 543 nm, Eu3+ 611 nm) and the Hg lines
    (404.7, 435.8, 546.1, 577-579 nm).  The narrow part is fixed; the broad
    bands are weighted around it by non-negative least squares to D50's shape
    and chromaticity.  More peaked than D50, as the seed says (CCT 5000 K,
    Ra 94).
``iso3664-p1-d50/spectra/led_d50.csv`` (relative_power)
    A multi-channel LED D50 simulator (violet 410 nm and royal-blue 450 nm
    chips, LuAG-like green, YAG-like yellow and nitride red phosphors); the
    channel weights (``LED_D50_WEIGHTS``) maximise colour rendering at D50's
    chromaticity (``--refit-led`` re-derives them): CCT 5001 K, Ra 94,
    R9-R14 >= 83, within 0.0014 of D50 in u'10 v'10.
``iso3664-p1-d50/spectra/grey_n8.csv`` (reflectance)
    Matte neutral grey, Munsell N8 (Y = 57.62 %, below ISO 3664's 60 %).

The script also prints derived numbers used in the booth files' comments
(CCT, Ra, luminous transmittance of the D65 filter, visible output of the
UV lamp).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

BOOTHS = Path(__file__).resolve().parents[1]
WL = np.arange(380.0, 781.0, 5.0)          # 5 nm, 380-780 nm
WL_UV = np.arange(300.0, 781.0, 5.0)       # UV lamp: from 300 nm

#: Colour temperature of the halogen lamps behind the D65 filters (estimate, 3000-3200 K is typical).
HALOGEN_D65_CCT_K = 3100.0
#: Munsell neutral values of the paints (luminous reflectance from ASTM D1535).
N7_VALUE, N8_VALUE = 7.0, 8.0


# --------------------------------------------------------------------------- helpers

def _colour():
    import colour

    warnings.filterwarnings("ignore", module="colour")
    return colour


def _sd(wl, values, name="sd"):
    colour = _colour()
    return colour.SpectralDistribution(dict(zip(wl.tolist(), np.asarray(values, float).tolist())), name=name)


def _cmfs(wl):
    colour = _colour()
    cm = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([np.interp(wl, cm.wavelengths, cm.values[:, i]) for i in range(3)], axis=1)


def _xy(wl, spd):
    X, Y, Z = _cmfs(wl).T @ spd
    return np.array([X, Y]) / (X + Y + Z)


def _d_illuminant(name, wl=WL):
    colour = _colour()
    sd = colour.SDS_ILLUMINANTS[name]
    return np.interp(wl, sd.wavelengths, sd.values)


def planck(wl_nm, T):
    """Relative Planckian radiance at ``wl_nm`` (c2 = 1.4388e-2 m·K, as ITS-90)."""
    c2 = 1.4388e-2
    lam = wl_nm * 1e-9
    return 1.0 / (lam ** 5 * (np.exp(c2 / (lam * T)) - 1.0))


def band_wavenumber(wl_nm, centre_nm, fwhm_nm):
    """A phosphor/LED emission band: Gaussian in photon energy (wavenumber),
    which gives the long-wave tail real bands have."""
    nu, nu0 = 1e7 / wl_nm, 1e7 / centre_nm
    dnu = fwhm_nm * 1e7 / centre_nm ** 2
    return np.exp(-4.0 * np.log(2.0) * ((nu - nu0) / dnu) ** 2)


def line(wl_grid, at_nm, power=1.0):
    """A spectral line on a 5 nm table: its power (per nm) split between the
    two neighbouring samples so that the centroid is exact.  Linear
    interpolation of the table then spreads it as a 10 nm triangle of the
    same area."""
    step = wl_grid[1] - wl_grid[0]
    out = np.zeros_like(wl_grid)
    i = int(np.floor((at_nm - wl_grid[0]) / step))
    f = (at_nm - wl_grid[i]) / step
    out[i] += (1 - f) * power / step
    out[i + 1] += f * power / step
    return out


def logistic(x):
    return 1.0 / (1.0 + np.exp(-x))


def fit_to_target(components: dict[str, np.ndarray], target: np.ndarray, wl=WL,
                  fixed: np.ndarray | None = None,
                  chroma_weight: float = 200.0) -> tuple[np.ndarray, dict[str, float]]:
    """Non-negative weights of ``components`` so that ``fixed + Σ w·component``
    best matches ``target`` (normalised to peak 1) in shape and, heavily
    weighted, in XYZ; deterministic (scipy NNLS).  Returns the spectrum
    (peak 1) and the weights."""
    from scipy.optimize import nnls

    names = sorted(components)
    A = np.stack([components[n] for n in names], axis=1)
    t = target / target.max()
    f = np.zeros_like(t) if fixed is None else fixed
    cm = _cmfs(wl)
    s = chroma_weight / (cm.T @ t)[1]
    M = np.vstack([A, s * (cm.T @ A)])
    b = np.concatenate([t - f, s * (cm.T @ (t - f))])
    w, _ = nnls(M, b)
    spd = A @ w + f
    return spd / spd.max(), dict(zip(names, w.tolist()))


def cct_duv(wl, spd):
    colour = _colour()
    uv = colour.xy_to_UCS_uv(_xy(wl, spd))
    cct, duv = colour.temperature.uv_to_CCT_Ohno2013(uv)
    return float(cct), float(duv)


def cri(wl, spd):
    return float(_colour().colour_rendering_index(_sd(wl, spd)))


def grey_paint(wl, value):
    """Neutral matte grey of Munsell value ``value``: flat, TiO2 edge below ~420 nm,
    scaled so that its luminous reflectance (D65, 2°) equals ASTM D1535's Y."""
    from colour.colorimetry import luminance_ASTMD1535

    shape = 1.0 - 0.30 * logistic((412.0 - wl) / 9.0)
    d65 = _d_illuminant("D65", wl)
    ybar = _cmfs(wl)[:, 1]
    y = float((shape * d65 * ybar).sum() / (d65 * ybar).sum())
    return shape * (float(luminance_ASTMD1535(value)) / 100.0) / y


# --------------------------------------------------------------------------- spectra

def d65_filter(wl=WL, halogen_K=HALOGEN_D65_CCT_K) -> np.ndarray:
    """Transmittance of the D65 conversion filter for a ``halogen_K`` lamp (see module doc)."""
    from scipy.optimize import least_squares

    d65 = _d_illuminant("D65", wl)
    bb = planck(wl, halogen_K)
    x = (wl - 580.0) / 200.0
    # smooth glass: 4th-order polynomial through log(D65/B)
    coef = np.polyfit(x, np.log(d65 / bb), 4)
    smooth = np.exp(np.polyval(coef, x))
    # the commercial-simulator ripple around 560 nm (seed paper, Fig. 5)
    smooth *= 1.0 + 0.06 * np.exp(-(((wl - 560.0) / 20.0) ** 2))
    xy_target = _xy(wl, d65)

    def residual(p):
        t = smooth * np.exp(p[0] * x + p[1] * x ** 2)
        return (_xy(wl, bb * t) - xy_target) * 1e3

    p = least_squares(residual, [0.0, 0.0], xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    t = smooth * np.exp(p[0] * x + p[1] * x ** 2)
    return 0.82 * t / t.max()


def glass_diffuser(wl=WL) -> np.ndarray:
    """Regular transmittance of a 4 mm soda-lime glass plate."""
    fresnel = 0.918                                           # two surfaces, n = 1.52
    fe3_edge = 0.06 * np.exp(-(wl - 380.0) / 18.0)            # Fe3+/UV edge
    fe2_tail = 0.035 * logistic((wl - 640.0) / 60.0)          # short-wave tail of the ~1000 nm band
    return fresnel - 0.012 - fe3_edge - fe2_tail


def uva_blacklight(wl=WL_UV) -> np.ndarray:
    """Relative SPD of a UVA blacklight-blue tube (peak 1 near 365-368 nm)."""
    phosphor = band_wavenumber(wl, 368.0, 20.0)
    # Wood's glass (NiO): passes 320-400 nm, blocks the visible down to ~1e-3, leaks deep red
    woods = (logistic((wl - 318.0) / 6.0) * logistic((402.0 - wl) / 7.0)
             + 1e-3 + 0.02 * logistic((wl - 715.0) / 15.0))
    hg = (line(wl, 365.0, 0.6) + line(wl, 404.7, 0.10) + line(wl, 435.8, 0.03)
          + line(wl, 546.1, 0.02) + line(wl, 577.0, 0.005) + line(wl, 579.1, 0.005))
    continuum = 2e-4  # recombination continuum and phosphor tails
    spd = (phosphor + hg + continuum) * woods
    return spd / spd.max()


def pl_l_950(wl=WL) -> tuple[np.ndarray, dict]:
    """Relative SPD of a PL-L 55W/950-like multi-band 5000 K fluorescent lamp.

    The narrow part (Hg discharge lines, Tb3+ and Eu3+ lines of the
    trichromatic phosphors) is fixed; the broad phosphor bands are fitted
    around it to D50 (shape and chromaticity)."""
    broad = {
        "BAM:Eu 450": band_wavenumber(wl, 450.0, 52.0),
        "SAE:Eu 490": band_wavenumber(wl, 492.0, 65.0),
        "green-yellow broad 545": band_wavenumber(wl, 545.0, 95.0),
        "Mn red 630": band_wavenumber(wl, 630.0, 85.0),
        "MGF:Mn 658": band_wavenumber(wl, 658.0, 18.0),
    }
    hg = (line(wl, 404.7, 1.0) + line(wl, 435.8, 2.2) + line(wl, 546.1, 2.0)
          + line(wl, 577.0, 0.35) + line(wl, 579.1, 0.4))
    tb = line(wl, 543.0, 2.0) + line(wl, 488.0, 0.4) + line(wl, 586.0, 0.3) + line(wl, 621.0, 0.2)
    eu = line(wl, 611.0, 1.5)
    # 2x: peak/median of the result ~2.5, i.e. clearly "more peaked than D50" (seed, Fig. 3)
    return fit_to_target(broad, _d_illuminant("D50", wl), wl, fixed=2.0 * (hg + tb + eu))


#: LED channel weights: found by ``--refit-led`` (Nelder-Mead on −(mean R1-R8 + min R1-R14)
#: with the chromaticity pinned to D50), starting from the NNLS fit to D50; rounded.
LED_D50_WEIGHTS = {"violet LED 410": 0.796, "blue LED 450": 1.679, "LuAG green 525": 1.116,
                   "YAG yellow 565": 0.141, "nitride red 640": 1.038}


def _led_channels(wl=WL) -> dict[str, np.ndarray]:
    return {
        "violet LED 410": band_wavenumber(wl, 410.0, 16.0),
        "blue LED 450": band_wavenumber(wl, 450.0, 20.0),
        "LuAG green 525": band_wavenumber(wl, 525.0, 100.0),
        "YAG yellow 565": band_wavenumber(wl, 565.0, 115.0),
        "nitride red 640": band_wavenumber(wl, 640.0, 90.0),
    }


def led_d50(wl=WL, weights=None) -> np.ndarray:
    """Relative SPD (peak 1) of a multi-channel LED D50 simulator."""
    ch = _led_channels(wl)
    w = LED_D50_WEIGHTS if weights is None else weights
    spd = sum(w[k] * ch[k] for k in sorted(ch))
    return spd / spd.max()


def refit_led_weights() -> dict[str, float]:
    """Re-derive :data:`LED_D50_WEIGHTS` (~15 s): maximise colour rendering at D50's chromaticity."""
    from scipy.optimize import minimize

    colour = _colour()
    ch = _led_channels()
    _, w0 = fit_to_target(ch, _d_illuminant("D50"))
    names = sorted(ch)
    A = np.stack([ch[n] for n in names], axis=1)
    uv0 = colour.xy_to_Luv_uv(_xy(WL, _d_illuminant("D50")))

    def objective(logw):
        spd = A @ np.exp(logw)
        spec = colour.colour_rendering_index(_sd(WL, spd), additional_data=True)
        r = [spec.Q_as[i].Q_a for i in range(1, 15)]
        duv = np.hypot(*(colour.xy_to_Luv_uv(_xy(WL, spd)) - uv0))
        return -(np.mean(r[:8]) + min(r)) + 2e4 * duv

    x0 = np.log([max(w0[n], 0.05) for n in names])
    res = minimize(objective, x0, method="Nelder-Mead", options=dict(maxiter=400, xatol=1e-4, fatol=1e-4))
    return {n: round(float(v), 3) for n, v in zip(names, np.exp(res.x))}


# --------------------------------------------------------------------------- writing

def _table(quantity: str, wl: np.ndarray, values: np.ndarray) -> str:
    lines = [f"wavelength_nm,{quantity}"]
    lines += [f"{w:g},{v:.6g}" for w, v in zip(wl, np.asarray(values, float))]
    return "\n".join(lines) + "\n"


def build_all() -> dict[Path, str]:
    """Every CSV this script owns: path → text."""
    qc = BOOTHS / "xrite-spectralight-qc" / "spectra"
    byk = BOOTHS / "byk-byko-spectra-effect" / "spectra"
    iso = BOOTHS / "iso3664-p1-d50" / "spectra"
    out = {
        qc / "d65_filter.csv": _table("transmittance", WL, d65_filter()),
        qc / "grey_n7.csv": _table("reflectance", WL, grey_paint(WL, N7_VALUE)),
        qc / "glass_diffuser.csv": _table("transmittance", WL, glass_diffuser()),
        qc / "uva_blacklight.csv": _table("relative_power", WL_UV, uva_blacklight()),
        byk / "pl_l_55w_950.csv": _table("relative_power", WL, pl_l_950()[0]),
        iso / "led_d50.csv": _table("relative_power", WL, led_d50()),
        iso / "grey_n8.csv": _table("reflectance", WL, grey_paint(WL, N8_VALUE)),
    }
    return out


def report() -> None:
    """Print the derived numbers quoted in the booth files' comments."""
    colour = _colour()
    bb = planck(WL, HALOGEN_D65_CCT_K)
    t = d65_filter()
    ybar = _cmfs(WL)[:, 1]
    sim = bb * t
    print(f"D65 simulator ({HALOGEN_D65_CCT_K:g} K halogen x filter): CCT, Duv = {cct_duv(WL, sim)}, "
          f"Ra = {cri(WL, sim):.1f}, luminous transmittance = {(bb * t * ybar).sum() / (bb * ybar).sum():.4f}")
    pl, w = pl_l_950()
    print(f"PL-L 950: CCT, Duv = {cct_duv(WL, pl)}, Ra = {cri(WL, pl):.1f}; weights {w}")
    led = led_d50()
    print(f"LED D50: CCT, Duv = {cct_duv(WL, led)}, Ra = {cri(WL, led):.1f}")
    uv = uva_blacklight()
    vl = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    v = np.interp(WL_UV, vl.wavelengths, vl.values, left=0, right=0)
    uva = (WL_UV >= 315) & (WL_UV <= 400)
    # cd per (W/sr of UVA) for this spectral shape
    print(f"UV lamp: 683*sum(S*V)/sum_UVA(S) = {683 * (uv * v).sum() / uv[uva].sum():.4g} lm/W(UVA)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if any CSV differs from what would be written")
    ap.add_argument("--report", action="store_true", help="print derived numbers (CCT, Ra, ...)")
    ap.add_argument("--refit-led", action="store_true", help="re-derive LED_D50_WEIGHTS and print them")
    args = ap.parse_args(argv)
    if args.refit_led:
        print(refit_led_weights())
        return 0
    files = build_all()
    stale = []
    for path, text in files.items():
        if path.exists() and path.read_text() == text:
            continue
        stale.append(path)
        if not args.check:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".csv.tmp")
            tmp.write_text(text)
            tmp.replace(path)
    for p in stale:
        print(("stale: " if args.check else "wrote: ") + str(p.relative_to(BOOTHS.parent)))
    if args.report:
        report()
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
