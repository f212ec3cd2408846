"""
The display document: how a screen turns drive values into light, and what
light of the room it reflects.

The model (MDCIM-style, after the mobile display characterisation and
illumination model cited by the seed paper) predicts the absolute tristimulus
values an observer sees on the screen::

    XYZ_seen(d) = XYZ_black + XYZ_ambient + M · f(d)

* ``d``: drive values (R, G, B) in [0, 1] (code / 255 for an 8-bit display).
* ``f``: per-channel tone response (``tone_response.red/green/blue``):
  normalised, black-corrected channel luminance, ``f(0) = 0``, ``f(1) = 1``.
* ``M``: 3×3 matrix whose columns are the black-corrected XYZ of the three
  primaries at full drive, built from ``primaries_xy`` and the black-corrected
  white ``XYZ_white − XYZ_black`` (SMPTE RP 177 normalised primary matrix).
* ``XYZ_black``: light emitted at zero drive in a dark room
  (``black_luminance_cd_m2``, chromaticity ``black_xy`` or the white's).
* ``XYZ_ambient``: the room light the screen reflects toward the observer,
  ``screen_reflectance × illuminance_lx / π`` in cd/m² with the chromaticity
  of the ambient spectrum (diffuse reflection model).

:mod:`lbscene.engine.colour.display_model` builds and inverts it.

Example (YAML)::

    version: 1
    kind: display
    name: sRGB reference display
    provenance: {status: published, source: IEC 61966-2-1}
    primaries_xy: {red: [0.64, 0.33], green: [0.30, 0.60], blue: [0.15, 0.06]}
    white_xy: [0.3127, 0.3290]
    white_luminance_cd_m2: 80
    black_luminance_cd_m2: 0
    tone_response:
      red: {type: srgb}
      green: {type: srgb}
      blue: {type: srgb}
    screen_reflectance: 0.0393
    ambient: {spd: {type: cie_illuminant, name: D50}, illuminance_lx: 64}
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from .base import Document, Provenance, StrictModel
from .spectrum import SpectrumSpec

__all__ = [
    "Display",
    "Chromaticity_xy",
    "Primaries",
    "GammaResponse",
    "SrgbResponse",
    "GogResponse",
    "LutResponse",
    "ToneResponse",
    "ToneResponses",
    "AmbientLight",
    "MAX_LUT_POINTS",
]

MAX_LUT_POINTS = 4096

Chromaticity_xy = Annotated[
    tuple[Annotated[float, Field(gt=0, lt=1)], Annotated[float, Field(gt=0, lt=1)]],
    Field(description="CIE 1931 chromaticity coordinates [x, y] (2° observer)."),
]


class Primaries(StrictModel):
    """Chromaticities of the black-corrected primaries at full drive."""

    red: Chromaticity_xy
    green: Chromaticity_xy
    blue: Chromaticity_xy

    @model_validator(mode="after")
    def _triangle(self):
        (xr, yr), (xg, yg), (xb, yb) = self.red, self.green, self.blue
        area2 = (xg - xr) * (yb - yr) - (xb - xr) * (yg - yr)
        if abs(area2) < 1e-4:
            raise ValueError("the three primaries are (almost) collinear: they span no gamut")
        return self


class GammaResponse(StrictModel):
    """Pure power law ``f(d) = d^gamma``."""

    type: Literal["gamma"]
    gamma: float = Field(gt=0.5, lt=5.0, description="Exponent (2.2 for a typical display).")


class SrgbResponse(StrictModel):
    """The IEC 61966-2-1 piecewise sRGB curve (linear toe below d = 0.04045, then 2.4 power)."""

    type: Literal["srgb"]


class GogResponse(StrictModel):
    """Gain-offset-gamma (Berns 1996): ``f(d) = max(gain·d + offset, 0)^gamma``.

    ``gain + offset`` must be 1 (so that ``f(1) = 1``) and ``offset <= 0``: the
    light at zero drive is the separate ``black_luminance_cd_m2``.
    """

    type: Literal["gog"]
    gain: float = Field(ge=1.0, le=10.0)
    offset: float = Field(ge=-9.0, le=0.0)
    gamma: float = Field(gt=0.5, lt=5.0)

    @model_validator(mode="after")
    def _normalised(self):
        if abs(self.gain + self.offset - 1.0) > 1e-3:
            raise ValueError(f"gain + offset must be 1 (f(1) = 1); got {self.gain + self.offset:.6g}")
        return self


class LutResponse(StrictModel):
    """A measured table: ``output`` (black-corrected channel luminance, normalised
    to 1 at full drive) at ``drive`` values; linear interpolation between them.

    ``drive`` runs from 0 to 1 and ``output`` from 0 to 1, both strictly increasing
    (smooth a noisy measurement first: the model must be invertible).
    """

    type: Literal["lut"]
    drive: list[float] = Field(min_length=2, max_length=MAX_LUT_POINTS)
    output: list[float] = Field(min_length=2, max_length=MAX_LUT_POINTS)

    @model_validator(mode="after")
    def _check(self):
        d, o = self.drive, self.output
        if len(d) != len(o):
            raise ValueError(f"drive has {len(d)} entries but output has {len(o)}; "
                             f"they must have the same length")
        if d[0] != 0.0 or d[-1] != 1.0:
            raise ValueError("drive must start at 0 and end at 1")
        if abs(o[0]) > 1e-9 or abs(o[-1] - 1.0) > 1e-9:
            raise ValueError("output must start at 0 and end at 1 (black-corrected, normalised)")
        for name, v in (("drive", d), ("output", o)):
            for i in range(1, len(v)):
                if not v[i] > v[i - 1]:
                    raise ValueError(f"{name} must be strictly increasing (entry {i}: {v[i]} "
                                     f"after {v[i - 1]})")
        return self


ToneResponse = Annotated[
    Union[GammaResponse, SrgbResponse, GogResponse, LutResponse],
    Field(discriminator="type"),
]


class ToneResponses(StrictModel):
    """Tone response of each channel."""

    red: ToneResponse
    green: ToneResponse
    blue: ToneResponse


class AmbientLight(StrictModel):
    """Room light falling on the screen."""

    spd: SpectrumSpec = Field(description="Relative spectral power distribution of the ambient "
                                          "light (only its chromaticity is used).")
    illuminance_lx: float = Field(ge=0, le=200_000, description="Illuminance on the screen plane.")


class Display(Document):
    """A characterised display in its viewing environment."""

    kind: Literal["display"] = Field(description="Document kind.")
    name: str = Field(min_length=1, max_length=200)
    provenance: Provenance
    technology: Literal["lcd", "oled", "crt", "projector", "other"] = "lcd"
    primaries_xy: Primaries
    white_xy: Chromaticity_xy = Field(description="Chromaticity of full drive (1, 1, 1).")
    white_luminance_cd_m2: float = Field(gt=0, le=20_000, description="Luminance of full drive "
                                         "(1, 1, 1) in a dark room, black level included.")
    black_luminance_cd_m2: float = Field(0.0, ge=0, description="Luminance of drive (0, 0, 0) in "
                                         "a dark room.")
    black_xy: Chromaticity_xy | None = Field(None, description="Chromaticity of the black level "
                                             "(default: that of the white).")
    tone_response: ToneResponses
    screen_reflectance: float = Field(0.0, ge=0, le=1, description="Luminance factor of the "
                                      "screen for the ambient light (unitless, diffuse model: "
                                      "reflected luminance = screen_reflectance · E / π).")
    ambient: AmbientLight | None = Field(None, description="Room light on the screen; none: dark room.")
    bit_depth: int = Field(8, ge=6, le=16, description="Bits per channel of the drive values.")
    diagonal_mm: float | None = Field(None, gt=0, le=10_000)
    resolution_px: tuple[Annotated[int, Field(gt=0, le=65536)],
                         Annotated[int, Field(gt=0, le=65536)]] | None = Field(
        None, description="Width, height in pixels.")

    @model_validator(mode="after")
    def _levels(self):
        if self.black_luminance_cd_m2 >= self.white_luminance_cd_m2:
            raise ValueError("black_luminance_cd_m2 must be below white_luminance_cd_m2")
        (xr, yr), (xg, yg), (xb, yb) = (self.primaries_xy.red, self.primaries_xy.green,
                                        self.primaries_xy.blue)
        x, y = self.white_xy

        def side(ax, ay, bx, by):
            return (bx - ax) * (y - ay) - (by - ay) * (x - ax)

        s = [side(xr, yr, xg, yg), side(xg, yg, xb, yb), side(xb, yb, xr, yr)]
        if not (all(v > 0 for v in s) or all(v < 0 for v in s)):
            raise ValueError(f"white_xy {list(self.white_xy)} lies outside the primaries' triangle")
        return self
