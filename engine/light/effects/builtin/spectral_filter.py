"""
``spectral_filter``: a filter's transmittance multiplies a lamp's spectrum.

Kind ``spectral``.  The filter is the effect's ``filter`` for the lamps it names, or each
lamp's own ``filter:``.
"""

from __future__ import annotations

from pydantic import Field

from lbscene.engine.light.effects.physics import EmitterSet, PhysicalEffect, lamps_on
from lbscene.engine.light.effects.registry import EffectParams, register_effect
from lbscene.schemas.base import Identifier

__all__ = ["SpectralFilterEffect"]


@register_effect
class SpectralFilterEffect(PhysicalEffect):
    id = "spectral_filter"
    summary = "A spectral filter in front of a lamp changes its spectrum."
    kind = "spectral"
    order = 30

    class Params(EffectParams):
        filter: Identifier | None = Field(None, description="Filter id applied to `lamps` "
                                          "(default: each lamp's own `filter:`).")
        lamps: list[Identifier] | None = None

    @classmethod
    def applicable(cls, ir, lighting):
        if not ir.filters:
            return "the booth has no filters: section"
        if not any(lp.filter for lp in lamps_on(ir, lighting)):
            return "no lamp that is on names a filter (give `filter:` and `lamps:` to the effect)"
        return None

    helpers = ("filter_for",)

    @staticmethod
    def filter_for(ir, p, lamp) -> str | None:
        """The filter in front of ``lamp``: the effect's ``filter`` (or the lamp's own) when the
        effect selects the lamp, and the booth defines it; else None."""
        if p.lamps is not None and lamp.id not in p.lamps:
            return None
        fid = p.filter if p.filter is not None else lamp.filter
        return fid if fid and fid in ir.filters else None

    @classmethod
    def modify_emitters(cls, ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        fid = cls.filter_for(ctx.ir, p, lamp)
        if fid is None:
            return es
        t = ctx.ir.filters[fid].transmittance.array_1nm
        return es.with_(spectrum_1nm=es.spectrum_1nm * t, spectral_key=es.spectral_key + (f"filter:{fid}",))
