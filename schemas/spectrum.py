"""
Spectrum specifications: how a file says "this spectral distribution".

Every spectral quantity in a booth, sample, filter or measurement file is one
of these ``type:``-discriminated nodes.  They are turned into numbers by
:func:`lbscene.engine.spectra.evaluate.evaluate_spectrum` (1 nm reference sampling, then
band integration).

Examples (YAML)::

    spd: {type: cie_illuminant, name: D65}
    spd: {type: blackbody, cct_K: 2856}
    spd: {type: light_source, name: "Philips TL-84"}
    reflectance: {type: constant, value: 0.18}
    transmittance: {type: csv, path: spectra/d65_filter.csv}
    reflectance: {type: inline, wavelengths_nm: [380, 550, 780], values: [0.1, 0.5, 0.6]}
    spd: {type: instrument_file, format: ies_tm27_14, path: meas/lamp.spdx}
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from .base import StrictModel
from .refs import FileRef

__all__ = [
    "SpectrumSpec",
    "CieIlluminantSpectrum",
    "LightSourceSpectrum",
    "BlackbodySpectrum",
    "DaylightSpectrum",
    "ConstantSpectrum",
    "InlineSpectrum",
    "CsvSpectrum",
    "InstrumentFileSpectrum",
    "MAX_SPECTRUM_SAMPLES",
]

MAX_SPECTRUM_SAMPLES = 20_000


class _SpectrumBase(StrictModel):
    scale: float = Field(1.0, gt=0, description="Multiplier applied to the values (unitless).")


class CieIlluminantSpectrum(_SpectrumBase):
    """A CIE illuminant from colour-science's ``SDS_ILLUMINANTS`` (D65, A, FL2, FL11…)."""

    type: Literal["cie_illuminant"]
    name: str = Field(description="Name in colour.SDS_ILLUMINANTS, e.g. 'D65', 'A', 'FL11' "
                                  "(aliases F2, F7, F11 are accepted).")


class LightSourceSpectrum(_SpectrumBase):
    """A measured light source from colour-science's ``SDS_LIGHT_SOURCES``."""

    type: Literal["light_source"]
    name: str = Field(description="Name in colour.SDS_LIGHT_SOURCES, e.g. 'Philips TL-84'.")


class BlackbodySpectrum(_SpectrumBase):
    """Planckian radiator at a colour temperature (tungsten-halogen lamps)."""

    type: Literal["blackbody"]
    cct_K: float = Field(gt=500, lt=25000, description="Temperature in kelvin.")


class DaylightSpectrum(_SpectrumBase):
    """CIE daylight series at a correlated colour temperature (4000-25000 K)."""

    type: Literal["daylight"]
    cct_K: float = Field(ge=4000, le=25000, description="Correlated colour temperature in kelvin.")


class ConstantSpectrum(_SpectrumBase):
    """The same value at every wavelength (e.g. a neutral grey reflectance)."""

    type: Literal["constant"]
    value: float = Field(ge=0, description="Value at every wavelength (unit of the field it fills).")


class InlineSpectrum(_SpectrumBase):
    """A table written in the file."""

    type: Literal["inline"]
    wavelengths_nm: list[float] = Field(min_length=2, max_length=MAX_SPECTRUM_SAMPLES)
    values: list[float] = Field(min_length=2, max_length=MAX_SPECTRUM_SAMPLES)

    @model_validator(mode="after")
    def _check(self):
        if len(self.wavelengths_nm) != len(self.values):
            raise ValueError(f"wavelengths_nm has {len(self.wavelengths_nm)} entries but values has "
                             f"{len(self.values)}; they must have the same length")
        w = self.wavelengths_nm
        for i in range(1, len(w)):
            if not w[i] > w[i - 1]:
                raise ValueError(f"wavelengths_nm must be strictly increasing (entry {i}: {w[i]} "
                                 f"after {w[i - 1]})")
        return self


class CsvSpectrum(_SpectrumBase):
    """A CSV file with a ``wavelength_nm`` column and a value column."""

    type: Literal["csv"]
    path: FileRef = Field(description="CSV file, relative to the referring file.")
    column: str | None = Field(
        None, description="Value column; default: the only column besides wavelength_nm.")


class InstrumentFileSpectrum(_SpectrumBase):
    """An instrument export that colour-science reads."""

    type: Literal["instrument_file"]
    format: Literal["ies_tm27_14", "xrite", "sekonic", "uprtek"] = Field(
        description="ies_tm27_14 (.spdx XML), xrite (.txt), sekonic (.csv), uprtek (.xls text export).")
    path: FileRef
    name: str | None = Field(None, description="Which spectrum of a multi-spectrum file.")


SpectrumSpec = Annotated[
    Union[
        CieIlluminantSpectrum,
        LightSourceSpectrum,
        BlackbodySpectrum,
        DaylightSpectrum,
        ConstantSpectrum,
        InlineSpectrum,
        CsvSpectrum,
        InstrumentFileSpectrum,
    ],
    Field(discriminator="type"),
]
