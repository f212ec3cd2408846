"""
Evaluate :data:`~lbscene.schemas.spectrum.SpectrumSpec` nodes into numbers.

Every spectrum becomes a 1 nm array on
:data:`~lbscene.engine.spectra.bands.REFERENCE_WAVELENGTHS_NM` (360–830 nm); band
values come from :meth:`BandGrid.integrate` (band means), never from point
samples.  Standard data (CIE illuminants, measured light sources) come from
colour-science, imported lazily; V(λ) and the CMFs, which every booth needs, from
tables of its values shipped in ``data/`` (:data:`CIE_TABLES`).

``kind`` decides what happens outside a measured range: emission spectra are
zero there (unknown emission is not invented), reflectances and
transmittances hold their end values.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

import numpy as np

from lbscene.engine.files.diagnostics import LbsceneUserError
from lbscene.engine.files.yamlio import read_text_bounded

from .bands import REFERENCE_WAVELENGTHS_NM, to_reference

__all__ = [
    "SpectrumKind",
    "evaluate_spectrum",
    "read_spectrum_csv",
    "photopic_1nm",
    "cmfs_1nm",
    "luminous_efficacy_sum",
    "ILLUMINANT_ALIASES",
    "MAX_CSV_BYTES",
]

SpectrumKind = Literal["emission", "reflectance", "transmittance"]
MAX_CSV_BYTES = 16 * 1024 * 1024
#: Common short names → colour-science dataset names.
ILLUMINANT_ALIASES = {f"F{i}": f"FL{i}" for i in range(1, 13)}
K_M_LM_PER_W = 683.0


#: V(λ) and the CIE 1931 2° colour matching functions on the 1 nm reference grid, tabulated from
#: colour-science by ``scripts/gen_cie_tables.py`` (a test checks they are current): reading them
#: takes a millisecond, importing colour-science (which imports matplotlib) 1–5 s, which every
#: command's first frame paid
CIE_TABLES = Path(__file__).resolve().parent / "data" / "cie_1nm.npz"


def photopic_from_colour_science() -> np.ndarray:
    """CIE 1924 photopic V(λ) on the 1 nm reference grid, from colour-science (the table's source)."""
    import colour

    sd = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    return np.interp(REFERENCE_WAVELENGTHS_NM, sd.wavelengths, sd.values, left=0.0, right=0.0)


def cmfs_from_colour_science() -> np.ndarray:
    """CIE 1931 2° colour matching functions (471, 3), from colour-science (the table's source)."""
    import colour

    cm = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([np.interp(REFERENCE_WAVELENGTHS_NM, cm.wavelengths, cm.values[:, i],
                               left=0.0, right=0.0) for i in range(3)], axis=1)


@lru_cache(maxsize=1)
def _cie_tables() -> dict[str, np.ndarray]:
    try:
        with np.load(CIE_TABLES, allow_pickle=False) as z:
            t = {k: np.array(z[k], float) for k in ("photopic", "cmfs_1931_2deg")}
        if t["photopic"].shape == REFERENCE_WAVELENGTHS_NM.shape and \
                t["cmfs_1931_2deg"].shape == REFERENCE_WAVELENGTHS_NM.shape + (3,):
            return t
    except (OSError, ValueError, KeyError):
        pass
    # no usable table (a damaged install): the source itself
    return {"photopic": photopic_from_colour_science(), "cmfs_1931_2deg": cmfs_from_colour_science()}


def photopic_1nm() -> np.ndarray:
    """CIE 1924 photopic V(λ) on the 1 nm reference grid (471,)."""
    return _cie_tables()["photopic"]


def cmfs_1nm() -> np.ndarray:
    """CIE 1931 2° colour matching functions, shape (471, 3)."""
    return _cie_tables()["cmfs_1931_2deg"]


def luminous_efficacy_sum(spectral_1nm: np.ndarray) -> np.ndarray:
    """683·Σ S(λ)·V(λ)·1 nm: photometric value of a 1 nm radiometric spectrum (last axis)."""
    return K_M_LM_PER_W * np.asarray(spectral_1nm) @ photopic_1nm()


def _extrapolation(kind: SpectrumKind) -> str:
    return "zero" if kind == "emission" else "constant"


def read_spectrum_csv(path: Path, display: str, column: str | None = None,
                      kind: SpectrumKind = "emission") -> np.ndarray:
    """Read a ``wavelength_nm,<value>`` CSV onto the 1 nm grid, with located errors."""
    from lbscene.engine.files.yamlio import csv_rows

    text = read_text_bounded(path, display, MAX_CSV_BYTES)
    rows = [(i, r) for i, r in csv_rows(text, display) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise LbsceneUserError.single("LB407", "CSV file has no rows", display, 1, 1,
                                      expected="a header 'wavelength_nm,<value>' and data rows")
    hline, header = rows[0]
    header = [h.strip() for h in header]
    if "wavelength_nm" not in header:
        raise LbsceneUserError.single(
            "LB400", "missing column 'wavelength_nm'", display, hline, 1,
            value=",".join(header), expected="a header with 'wavelength_nm' and one value column")
    wcol = header.index("wavelength_nm")
    others = [h for h in header if h != "wavelength_nm"]
    if column is None:
        if len(others) != 1:
            raise LbsceneUserError.single(
                "LB400", "cannot tell which column holds the values", display, hline, 1,
                value=",".join(header), expected="exactly one value column, or `column:` in the spec")
        column = others[0]
    if column not in header:
        raise LbsceneUserError.single("LB400", f"missing column {column!r}", display, hline, 1,
                                      value=",".join(header))
    vcol = header.index(column)
    wl, vals = [], []
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise LbsceneUserError.single("LB400", f"row has {len(r)} fields, header has {len(header)}",
                                          display, line, 1)
        for col, dest in ((wcol, wl), (vcol, vals)):
            cell = r[col].strip()
            try:
                x = float(cell)
            except ValueError:
                x = float("nan")
            if not np.isfinite(x):
                colno = sum(len(c) + 1 for c in r[:col]) + 1
                raise LbsceneUserError.single("LB401", f"'{header[col]}' is not a finite number",
                                              display, line, colno, value=repr(cell),
                                              expected="a finite number")
            dest.append(x)
        if vals[-1] < 0:
            colno = sum(len(c) + 1 for c in r[:vcol]) + 1
            raise LbsceneUserError.single("LB402", f"negative {column}", display, line, colno,
                                          value=repr(vals[-1]), expected="a value >= 0")
        if len(wl) > 1 and wl[-1] <= wl[-2]:
            raise LbsceneUserError.single(
                "LB405", "wavelengths are not strictly increasing", display, line, 1,
                value=f"{wl[-1]:g} after {wl[-2]:g}", expected=f"a wavelength above {wl[-2]:g} nm")
    if len(wl) < 2:
        raise LbsceneUserError.single("LB407", "need at least two wavelengths", display, hline, 1)
    return to_reference(wl, vals, extrapolate=_extrapolation(kind))


#: colour-science's named spectra (``SDS_ILLUMINANTS``, ``SDS_LIGHT_SOURCES``) as it tabulates them,
#: written by ``scripts/gen_cie_tables.py`` (a test checks they are current): a booth naming
#: "D65" or "Philips TL-84" compiles without importing colour-science (2–3 s)
NAMED_SPECTRA = Path(__file__).resolve().parent / "data" / "named_spectra.npz"
#: the datasets of :data:`NAMED_SPECTRA`: spec type's dataset name → colour-science attribute
NAMED_DATASETS = {"illuminant": "SDS_ILLUMINANTS", "light_source": "SDS_LIGHT_SOURCES"}
#: second radiation constant c₂ (m·K) of Planck's law as CIE 15 adopts it for colorimetry (and
#: colour-science's ``planck_law`` uses)
PLANCK_C2_M_K = 1.4388e-2


class _NamedSpectrum:
    """A tabulated spectrum: ``wavelengths`` (nm), ``values``."""

    def __init__(self, wavelengths, values):
        self.wavelengths = np.asarray(wavelengths, float)
        self.values = np.asarray(values, float)


def named_spectra_from_colour_science() -> dict[str, np.ndarray]:
    """The arrays of :data:`NAMED_SPECTRA`, from colour-science (the table's source): for each
    dataset ``names_<dataset>`` and, per name ``i``, ``<dataset>_<i>_wl`` and ``<dataset>_<i>_values``."""
    import colour

    out: dict[str, np.ndarray] = {}
    for dataset, attr in NAMED_DATASETS.items():
        data = getattr(colour, attr)
        names = sorted(data.keys())
        out[f"names_{dataset}"] = np.array(names)
        for i, n in enumerate(names):
            out[f"{dataset}_{i}_wl"] = np.asarray(data[n].wavelengths, float)
            out[f"{dataset}_{i}_values"] = np.asarray(data[n].values, float)
    return out


@lru_cache(maxsize=1)
def _named_spectra() -> dict[str, dict[str, _NamedSpectrum]]:
    try:
        with np.load(NAMED_SPECTRA, allow_pickle=False) as z:
            arrays = {k: np.array(z[k]) for k in z.files}
    except (OSError, ValueError, KeyError):          # no table (a partial checkout): the source itself
        arrays = named_spectra_from_colour_science()
    out: dict[str, dict[str, _NamedSpectrum]] = {}
    for dataset in NAMED_DATASETS:
        names = [str(n) for n in arrays[f"names_{dataset}"]]
        out[dataset] = {n: _NamedSpectrum(arrays[f"{dataset}_{i}_wl"], arrays[f"{dataset}_{i}_values"])
                        for i, n in enumerate(names)}
    return out


def _colour_dataset_sd(dataset_name: str, name: str):
    data = _named_spectra()["illuminant" if dataset_name == "illuminant" else "light_source"]
    key = ILLUMINANT_ALIASES.get(name, name) if dataset_name == "illuminant" else name
    if key in data:
        return data[key]
    lower = {k.lower(): k for k in data}
    if key.lower() in lower:
        return data[lower[key.lower()]]
    return None


def known_names(dataset_name: str) -> list[str]:
    return sorted(_named_spectra()["illuminant" if dataset_name == "illuminant" else "light_source"])


def planck_relative(wavelengths_nm, cct_K: float) -> np.ndarray:
    """Planck's law relative to its value at :math:`λ_0` = 560 nm:
    :math:`(λ_0/λ)^5 (e^{c_2/(λ_0 T)} − 1) / (e^{c_2/(λ T)} − 1)` (:data:`PLANCK_C2_M_K`).

    >>> round(float(planck_relative([560.0], 3100.0)[0]), 12)
    1.0
    """
    wl_m = np.asarray(wavelengths_nm, float) * 1e-9
    ref_m = 560e-9
    return (ref_m / wl_m) ** 5 * np.expm1(PLANCK_C2_M_K / (ref_m * cct_K)) / np.expm1(PLANCK_C2_M_K / (wl_m * cct_K))


def evaluate_spectrum(spec, resolve=None, kind: SpectrumKind = "emission",
                      display: str = "<spectrum>") -> np.ndarray:
    """Evaluate a spectrum spec to a 1 nm array (values × ``spec.scale``).

    Parameters
    ----------
    spec
        A :data:`~lbscene.schemas.spectrum.SpectrumSpec` model.
    resolve
        Callable turning a file reference (as written) into a Path — e.g.
        :meth:`LoadedDocument.resolve`.  Needed for ``csv``/``instrument_file``.
    kind
        ``'emission'``, ``'reflectance'`` or ``'transmittance'``.
    display
        How to name the spectrum in error messages.
    """
    t = spec.type
    ext = _extrapolation(kind)
    if t == "constant":
        values = np.full(REFERENCE_WAVELENGTHS_NM.size, float(spec.value))
    elif t == "inline":
        values = to_reference(spec.wavelengths_nm, spec.values, extrapolate=ext)
    elif t in ("cie_illuminant", "light_source"):
        sd = _colour_dataset_sd("illuminant" if t == "cie_illuminant" else "light_source", spec.name)
        if sd is None:
            import difflib

            dataset = "illuminant" if t == "cie_illuminant" else "light_source"
            close = difflib.get_close_matches(spec.name, known_names(dataset), n=3, cutoff=0.5)
            raise LbsceneUserError.single(
                "LB204", f"unknown {t.replace('_', ' ')} {spec.name!r}", display,
                expected="a name in colour.SDS_ILLUMINANTS" if t == "cie_illuminant"
                else "a name in colour.SDS_LIGHT_SOURCES",
                hint=(f"did you mean {', '.join(repr(c) for c in close)}? " if close else "")
                + "Every name is listed in the documentation's file reference (Named spectra).")
        values = to_reference(sd.wavelengths, sd.values, extrapolate=ext)
    elif t == "blackbody":
        values = planck_relative(REFERENCE_WAVELENGTHS_NM, spec.cct_K)
    elif t == "daylight":
        import colour

        xy = colour.temperature.CCT_to_xy_CIE_D(spec.cct_K * 1.4388 / 1.4380)
        sd = colour.sd_CIE_illuminant_D_series(xy)
        values = to_reference(sd.wavelengths, sd.values, extrapolate=ext)
    elif t == "csv":
        path = resolve(spec.path)
        from lbscene.engine.files.load import display_path

        values = read_spectrum_csv(path, display_path(path), spec.column, kind)
    elif t == "instrument_file":
        values = _read_instrument(spec, resolve(spec.path), kind)
    else:  # pragma: no cover - the schema's discriminator prevents this
        raise ValueError(f"unknown spectrum type {t!r}")
    return np.asarray(values, float) * float(spec.scale)


def _read_instrument(spec, path: Path, kind: SpectrumKind) -> np.ndarray:
    import colour

    from lbscene.engine.files.load import display_path
    from lbscene.engine.files.yamlio import read_bytes_bounded

    display = display_path(path)
    # a regular file of bounded size before the reader of colour-science opens it (a FIFO would block)
    read_bytes_bounded(path, display, MAX_CSV_BYTES)
    try:
        if spec.format == "ies_tm27_14":
            sd = colour.io.SpectralDistribution_IESTM2714(str(path)).read()
            sds = {sd.name: sd}
        elif spec.format == "xrite":
            sds = colour.io.read_sds_from_xrite_file(str(path))
        elif spec.format == "sekonic":
            sd = colour.io.SpectralDistribution_Sekonic(str(path)).read()
            sds = {sd.name: sd}
        else:
            sd = colour.io.SpectralDistribution_UPRTek(str(path)).read()
            sds = {sd.name: sd}
    except Exception as exc:  # the readers raise many kinds of errors on bad files
        raise LbsceneUserError.single("LB203", f"cannot read {spec.format} file: {exc}", display,
                                      expected=f"a valid {spec.format} export")
    if spec.name is not None:
        if spec.name not in sds:
            raise LbsceneUserError.single("LB202", f"no spectrum named {spec.name!r} in the file",
                                          display, value=spec.name, expected=f"one of {sorted(sds)}")
        sd = sds[spec.name]
    else:
        sd = next(iter(sds.values())) if sds else None
    if sd is None:
        raise LbsceneUserError.single("LB203", f"no spectrum in the {spec.format} file", display,
                                      expected=f"a valid {spec.format} export")
    _check_instrument_values(np.asarray(sd.wavelengths, float), np.asarray(sd.values, float), display)
    return to_reference(sd.wavelengths, sd.values, extrapolate=_extrapolation(kind))


def _check_instrument_values(wl: np.ndarray, values: np.ndarray, display: str) -> None:
    """What the instrument file's reader returned: wavelengths finite and strictly increasing
    (``LB405``), values finite (``LB401``) and not negative (``LB402``), at least two
    (``LB407``); each problem named by its wavelength, in the file."""
    if wl.size < 2 or values.shape != wl.shape:
        raise LbsceneUserError.single("LB407", f"the file gives {wl.size} wavelength(s)", display,
                                      expected="a spectrum of at least two wavelengths")
    bad = np.nonzero(~np.isfinite(wl))[0]
    if bad.size == 0:
        bad = np.nonzero(np.diff(wl) <= 0)[0] + 1
    if bad.size:
        i = int(bad[0])
        raise LbsceneUserError.single("LB405", "wavelengths are not finite and strictly increasing", display,
                                      value=f"{wl[i]:g} nm" + (f" after {wl[i - 1]:g} nm" if i else ""),
                                      expected="strictly increasing wavelengths")
    for code, mask, what, exp in (("LB401", ~np.isfinite(values), "is not a finite number", "a finite number"),
                                  ("LB402", values < 0, "is negative", "a value ≥ 0")):
        bad = np.nonzero(mask)[0]
        if bad.size:
            i = int(bad[0])
            raise LbsceneUserError.single(
                code, f"the value at {wl[i]:g} nm {what}" + (f" ({bad.size} wavelengths)" if bad.size > 1 else ""),
                display, value=repr(float(values[i])), expected=exp)
