"""
The sample document: what is put on the booth's platform.

A multi-angle spectrophotometer (BYK-mac i, X-Rite MA-T12…) reports one
spectral reflectance factor per measurement geometry; solid colours may give
just one.  The renderer interpolates between measured geometries; a sample with
``effect_coating:`` is rendered with a BRDF fitted to them and with flakes
(:mod:`lbscene.schemas.coating`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from .base import Document, Provenance, StrictModel
from .booth import GeometryName, parse_geometry_name
from .coating import EffectCoating
from .spectrum import SpectrumSpec

__all__ = ["Sample", "GeometryReflectance"]


class GeometryReflectance(StrictModel):
    """Reflectance factor measured at one geometry."""

    geometry: GeometryName
    reflectance: SpectrumSpec = Field(description="Spectral reflectance factor (may exceed 1 near "
                                                  "the specular direction for effect coatings).")


class Sample(Document):
    """A flat sample: reflectance per measurement geometry, plus gloss."""

    kind: Literal["sample"] = Field(description="Document kind.")
    name: str = Field(min_length=1, max_length=200)
    provenance: Provenance
    instrument: str = Field("", description="Instrument that measured it, e.g. 'BYK-mac i'.")
    size_mm: tuple[float, float] = Field((100.0, 85.0), description="Sample width, height (seed: 100 × 85).")
    reflectance: SpectrumSpec | None = Field(
        None, description="Geometry-independent reflectance (solid colours), used when "
                          "`by_geometry` is empty or as the diffuse base.")
    by_geometry: list[GeometryReflectance] = Field(default_factory=list, max_length=64)
    gloss_GU: float = Field(0.0, ge=0, le=200, description="Specular gloss at 60° in gloss units.")
    roughness: float = Field(0.1, ge=0, le=1, description="Microfacet roughness of the clear coat.")
    effect_coating: EffectCoating | None = Field(
        None, description="Metallic or pearlescent coating: a BRDF fitted to `by_geometry` (colour "
                          "flop) and flakes (sparkle, graininess); see the 'Effect coatings' page.")

    @model_validator(mode="after")
    def _has_reflectance(self):
        if self.reflectance is None and not self.by_geometry:
            raise ValueError("a sample needs `reflectance` or `by_geometry`")
        names = [g.geometry for g in self.by_geometry]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"geometries measured twice: {sorted(dup)}")
        for n in names:
            parse_geometry_name(n)
        return self

    @field_validator("effect_coating")
    @classmethod
    def _enough_geometries(cls, v, info: ValidationInfo):
        if v is not None and "by_geometry" in info.data:
            have, need = len(info.data["by_geometry"]), v.flop.lobes + 2
            if have < need:
                raise ValueError(f"an effect coating with {v.flop.lobes} lobe(s) needs reflectances at {need} "
                                 f"or more geometries in `by_geometry` (has {have})")
        return v
