"""
``aperture_occlusion``: occluders (aperture plates, cavity panels) block lamp→point paths.

Kind ``geometric``.  The occluders' rectangles with their openings are
:func:`lbscene.engine.light.plates.occluder_rects`; the fitted ``opening_scale`` scales
the openings.
"""

from __future__ import annotations

from pydantic import Field

from lbscene.engine.light.effects.physics import PathChannel, PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect
from lbscene.engine.light.plates import occluder_rects
from lbscene.schemas.base import Identifier

__all__ = ["ApertureOcclusionEffect"]


@register_effect
class ApertureOcclusionEffect(PhysicalEffect):
    id = "aperture_occlusion"
    summary = "The luminaire cavity, an aperture or another occluder blocks part of the lamp light."
    kind = "geometric"
    order = 40
    fit_parameters = {"opening_scale": (0.3, 3.0)}
    fit_initial = {"opening_scale": 1.0}

    class Params(EffectParams):
        occluders: list[Identifier] | None = Field(None, description="Occluders used (default: all).")
        opening_scale: float = Field(1.0, gt=0, le=5, description="Multiplier on aperture openings.")
        opening_scale_u: float = Field(1.0, gt=0, le=5, description="Further multiplier on the openings' "
                                       "u extent (fitted for an undeclared aperture, see hypotheses).")
        opening_scale_v: float = Field(1.0, gt=0, le=5, description="Further multiplier on the openings' "
                                       "v extent.")

    @classmethod
    def applicable(cls, ir, lighting):
        on = set(ir.lighting[lighting].lamps)
        if not any(o.lamps is None or on & set(o.lamps) for o in ir.occluders):
            return "the booth has no occluders: (apertures, cavity panels) for the lamps on"
        return None

    @staticmethod
    def path_factors(ctx, p, es, rx):
        key = ("occ", p.opening_scale, p.opening_scale_u, p.opening_scale_v, tuple(p.occluders or ()))
        rects = ctx.cache.get(key)
        if rects is None:
            rects = ctx.cache[key] = occluder_rects(ctx.ir, p)
        blocked = None
        for o, rect in rects:
            if o.lamps is not None and es.lamp_id not in o.lamps:
                continue
            b = ctx.fraction_hitting(es, rx, rect)
            # several occluders on one path: the blocked fractions combine as independent
            blocked = b if blocked is None else 1.0 - (1.0 - blocked) * (1.0 - b)
        if blocked is None or not blocked.any():
            return None
        return [PathChannel(1.0 - blocked)]
