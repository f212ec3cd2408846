"""
``aperture_occlusion``: occluders (aperture plates, cavity panels) block lamp→point paths, and
the paths from a diffuser plate's cells to the room.

Kind ``geometric``.  The occluders' rectangles with their openings are
:func:`lbscene.engine.light.plates.occluder_rects`; the fitted ``opening_scale`` scales
the openings.  A lamp's light is occluded segment by segment of the tube
(:meth:`ForwardContext.fraction_hitting`); the light a diffuser plate re-emits (its diffuse part,
a rough plate's scattered light) is occluded over :data:`SOURCE_SUBCELLS` ² points of each cell
(``source_path_factors``): a plate in a cavity sends its light to the room only through the
aperture below it.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import PathChannel, PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect
from lbscene.engine.light.geometry import mirrored_front_part
from lbscene.engine.light.plates import occluder_rects
from lbscene.schemas.base import Identifier

__all__ = ["ApertureOcclusionEffect", "SOURCE_SUBCELLS"]

#: points per side of a diffuser cell over which its light's occlusion is averaged: an aperture
#: 20 mm under a plate spreads the shadow of a cell's edge over hundreds of millimetres of floor
SOURCE_SUBCELLS = 6


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
    def _rects(ctx, p):
        key = ("occ", p.opening_scale, p.opening_scale_u, p.opening_scale_v, tuple(p.occluders or ()))
        rects = ctx.cache.get(key)
        if rects is None:
            rects = ctx.cache[key] = occluder_rects(ctx.ir, p)
        return rects

    @staticmethod
    def source_path_factors(ctx, p, polys, rx):
        from lbscene.engine.light.geometry import quad_subpoints, segment_hits_rectangle

        # occluders that stop every lamp (a cavity's plate and panels): a plate's light leaves
        # the cavity through them as the lamps' light does
        rects = [rect for o, rect in ApertureOcclusionEffect._rects(ctx, p) if o.lamps is None]
        if not rects:
            return None

        def compute():
            pts, w = quad_subpoints(np.asarray(polys, float), SOURCE_SUBCELLS)
            S, K, _ = pts.shape
            flat = pts.reshape(-1, 3)
            seen = np.ones((len(rx), S * K))
            for rect in rects:
                seen *= ~segment_hits_rectangle(flat, rx, rect)
            return np.einsum("msk,sk->ms", seen.reshape(len(rx), S, K), w)

        return ctx.memo("source-occ", (polys, rx, *(a for r in rects for a in r.key_arrays)), compute,
                        limit=16)

    @staticmethod
    def path_factors(ctx, p, es, rx):
        rects = ApertureOcclusionEffect._rects(ctx, p)
        blocked = None
        # a mirror image (in a glass plate, a reflector): its mirror's plane, the normal toward the lamp
        plane = es.meta.get("mirror_plane")
        for o, rect in rects:
            if o.lamps is not None and es.lamp_id not in o.lamps:
                continue
            b = ctx.fraction_hitting(es, rx, rect)
            if plane is not None and (m := mirrored_front_part(rect, *plane)) is not None:
                # a mirror image's light: the occluders its first leg, from the lamp to the
                # mirror, passes stand mirrored on the image's straight path
                hit = ctx.fraction_hitting(es, rx, m)
                b = 1.0 - (1.0 - b) * (1.0 - hit)
            # several occluders on one path: the blocked fractions combine as independent
            blocked = b if blocked is None else 1.0 - (1.0 - blocked) * (1.0 - b)
        if blocked is None or not blocked.any():
            return None
        return [PathChannel(1.0 - blocked)]

