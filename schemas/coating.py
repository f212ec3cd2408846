"""
Effect coatings (metallic and pearlescent paints): what a sample file adds to its
reflectance per geometry so that colour flop, sparkle and graininess can be rendered.

The colour flop comes from the sample's ``by_geometry`` reflectances (six aspecular
angles of a BYK-mac i style multi-angle spectrophotometer: −15°, 15°, 25°, 45°, 75°,
110° at 45° illumination), to which :mod:`lbscene.engine.coatings.flop` fits a
multi-lobe BRDF per band.  The texture is given either as the instrument reports it
(``texture: {type: measured}``: sparkle area ``S_a`` and intensity ``S_i`` under
directional light at 15°, 45° and 75°, graininess ``G`` under diffuse light), from which
:mod:`lbscene.engine.coatings.fit_texture` fits the flake parameters, or as the flake
parameters themselves (``texture: {type: flakes}``).

The sparkle and graininess values are read on **lbscene's scale**: the instrument's own
image analysis is not public, so lbscene defines its own (documented in
:mod:`lbscene.engine.coatings.instrument` and the "Effect coatings" documentation page)
and fits the flakes so that *its* analysis of a simulated instrument image gives the
declared numbers.  Readings of a real instrument are on a comparable, not identical,
scale.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from .base import StrictModel
from .spectrum import SpectrumSpec

__all__ = [
    "SPARKLE_ILLUMINATION_DEG",
    "ClearCoat",
    "SparkleReading",
    "MeasuredTexture",
    "FlakeDiameter",
    "FlakeTexture",
    "TextureSpec",
    "FlopModelSpec",
    "EffectCoating",
]

#: Illumination angles (degrees from the sample normal, camera along the normal) at which a
#: BYK-mac i style instrument reports sparkle.
SPARKLE_ILLUMINATION_DEG = (15.0, 45.0, 75.0)


class ClearCoat(StrictModel):
    """The clear coat over the effect layer: light and view directions refract at it."""

    refractive_index: float = Field(1.5, ge=1.3, le=1.8,
                                    description="Refractive index of the clear coat (automotive "
                                                "clear coats: about 1.5).")
    thickness_um: float = Field(40.0, ge=5, le=200,
                                description="Clear-coat thickness in micrometres (flakes lie "
                                            "below it; used by the Mitsuba reference scenes).")


class SparkleReading(StrictModel):
    """Sparkle under directional light at one illumination angle (camera along the normal)."""

    illumination_deg: float = Field(description="Illumination angle from the normal: 15, 45 or 75.")
    area: float = Field(ge=0, le=1000, description="Sparkle area S_a (lbscene's scale: glint pixels "
                                                  "per thousand pixels of the simulated image).")
    intensity: float = Field(ge=0, le=1000, description="Sparkle intensity S_i (lbscene's scale: mean "
                                                       "reflectance factor of the glint pixels / 10).")

    @model_validator(mode="after")
    def _angle(self):
        if self.illumination_deg not in SPARKLE_ILLUMINATION_DEG:
            raise ValueError(f"sparkle is read at illumination 15, 45 or 75 degrees, not "
                             f"{self.illumination_deg:g}")
        return self


class MeasuredTexture(StrictModel):
    """Texture as a multi-angle instrument reports it; the flake parameters are fitted."""

    type: Literal["measured"]
    instrument: str = Field("", max_length=200, description="e.g. 'BYK-mac i'.")
    sparkle: list[SparkleReading] = Field(min_length=1, max_length=3,
                                          description="S_a, S_i at 15°, 45°, 75° illumination.")
    graininess: float = Field(ge=0, le=50, description="Graininess G under diffuse light "
                                                       "(lbscene's scale: see the documentation).")
    flake_reflectance: SpectrumSpec | None = Field(
        None, description="Reflectance of a flake (mirror) seen through the coat; default: "
                          "0.9 for metallics (aluminium), or give the pearl's interference colour.")
    diameter_spread: float = Field(0.35, ge=0, le=1.5,
                                   description="σ of ln(diameter) assumed when fitting (not fitted).")

    @model_validator(mode="after")
    def _unique(self):
        angles = [s.illumination_deg for s in self.sparkle]
        dup = sorted({a for a in angles if angles.count(a) > 1})
        if dup:
            raise ValueError(f"sparkle given twice at illumination {', '.join(f'{a:g}' for a in dup)} deg")
        return self


class FlakeDiameter(StrictModel):
    """Log-normal flake diameter: ln d ~ N(ln median_um, spread²)."""

    median_um: float = Field(ge=2, le=200, description="Median flake diameter in micrometres.")
    spread: float = Field(0.35, ge=0, le=1.5, description="Standard deviation of ln(diameter).")


class FlakeTexture(StrictModel):
    """The flakes directly: mirror discs in the effect layer under the clear coat."""

    type: Literal["flakes"]
    density_per_mm2: float = Field(gt=0, le=20000, description="Flakes per mm² of sample surface.")
    diameter: FlakeDiameter
    orientation_spread_deg: float = Field(
        ge=0.5, le=45, description="atan(α) of the Beckmann distribution of flake normals about the "
                                   "sample normal (α: RMS slope / √2 per axis).")
    flake_reflectance: SpectrumSpec | None = Field(
        None, description="Reflectance of a flake; default 0.9 (aluminium).")


TextureSpec = Annotated[Union[MeasuredTexture, FlakeTexture], Field(discriminator="type")]


class FlopModelSpec(StrictModel):
    """Options of the BRDF fitted to the reflectance per geometry."""

    lobes: int = Field(2, ge=1, le=3, description="Cook-Torrance lobes besides the diffuse base.")
    distribution: Literal["beckmann", "ggx"] = Field(
        "beckmann", description="Normal distribution of the lobes: beckmann (Cook and Torrance's) or ggx.")


class EffectCoating(StrictModel):
    """An effect coating: the flop model's options and the texture."""

    clear_coat: ClearCoat = ClearCoat()
    flop: FlopModelSpec = FlopModelSpec()
    texture: TextureSpec | None = Field(None, description="Sparkle and graininess; none: flop only.")
