"""
Built-in physical effects (ids are part of the file format: never rename).

Each effect declares the parameters a booth file may give it.  The physics
(how the forward model applies it) is implemented next to the parameters.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from lbscene.schemas.base import Identifier

from .registry import Effect, EffectParams, register_effect

__all__ = [
    "AngularProfileEffect",
    "InterreflectionEffect",
    "DiffuserEffect",
    "ApertureOcclusionEffect",
    "TubeEndFalloffEffect",
    "SpectralFilterEffect",
    "DetectorCosineErrorEffect",
    "ReflectorEffect",
]


class _LampSelection(EffectParams):
    lamps: list[Identifier] | None = Field(None, description="Lamps it applies to (default: all on).")


@register_effect
class AngularProfileEffect(Effect):
    id = "angular_profile"
    summary = "Lamps emit with their declared angular profile instead of isotropically."
    kind = "geometric"

    class Params(_LampSelection):
        sigma_deg: float | None = Field(
            None, gt=0, le=1000,
            description="Gaussian σ for lamps without a declared profile (seed: I0·exp(−(θ/2σ)²)).")


@register_effect
class InterreflectionEffect(Effect):
    id = "interreflection"
    summary = "Light reflected between floor, walls and ceiling (radiosity with spectral reflectances)."
    kind = "global"

    class Params(EffectParams):
        patch_size_mm: float = Field(50.0, gt=1, le=1000, description="Radiosity patch size.")
        max_bounces: int = Field(0, ge=0, le=100, description="0: solve to convergence.")
        reflectance_scale: float = Field(1.0, gt=0, le=3, description="Multiplier on all surface reflectances.")


@register_effect
class DiffuserEffect(Effect):
    id = "diffuser"
    summary = "A plate below the lamps transmits and scatters their light."
    kind = "geometric"

    class Params(EffectParams):
        transmittance_scale: float = Field(1.0, gt=0, le=1.5)
        diffuse_fraction: float | None = Field(
            None, ge=0, le=1, description="Override of the booth diffuser's diffuse fraction.")


@register_effect
class ApertureOcclusionEffect(Effect):
    id = "aperture_occlusion"
    summary = "The luminaire cavity, an aperture or another occluder blocks part of the lamp light."
    kind = "geometric"

    class Params(EffectParams):
        occluders: list[Identifier] | None = Field(None, description="Occluders used (default: all).")
        opening_scale: float = Field(1.0, gt=0, le=5, description="Multiplier on aperture openings.")


@register_effect
class TubeEndFalloffEffect(Effect):
    id = "tube_end_falloff"
    summary = "Emission of tubes falls toward their ends (cathodes, phosphor ageing)."
    kind = "geometric"

    class Params(_LampSelection):
        falloff_length_mm: float = Field(100.0, gt=0, le=2000,
                                         description="Length over which emission falls at each end.")
        end_level: float = Field(0.5, ge=0, le=1, description="Relative emission at the very end.")


@register_effect
class SpectralFilterEffect(Effect):
    id = "spectral_filter"
    summary = "A spectral filter in front of a lamp changes its spectrum."
    kind = "spectral"

    class Params(EffectParams):
        filter: Identifier | None = Field(None, description="Filter id applied to `lamps` "
                                          "(default: each lamp's own `filter:`).")
        lamps: list[Identifier] | None = None


@register_effect
class DetectorCosineErrorEffect(Effect):
    id = "detector_cosine_error"
    summary = "The illuminance meter's imperfect cosine response (f2 error)."
    kind = "instrument"

    class Params(EffectParams):
        model: Literal["power", "f2_linear"] = "power"
        exponent: float = Field(1.1, gt=0, le=5,
                                description="Response ∝ cos(θ)^exponent (power model).")
        f2_percent: float = Field(3.0, ge=0, le=50, description="CIE f2 error (f2_linear model).")


@register_effect
class ReflectorEffect(Effect):
    id = "reflector"
    summary = "Mirrors behind lamps send back-emitted light forward."
    kind = "geometric"

    class Params(_LampSelection):
        reflectance_scale: float = Field(1.0, gt=0, le=1.5)
