"""
``reflector``: a mirror behind a lamp adds its mirror image and blocks what is behind it.

Kind ``geometric``.  The image method: the lamp's emitters mirrored across the mirror's
plane, times its reflectance, shining only through the mirror's extent.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import (EmitterSet, LampSelection, PathChannel, PhysicalEffect,
                                                  lamp_selected, lamps_on)
from lbscene.engine.light.effects.registry import register_effect

__all__ = ["ReflectorEffect"]


def _mirror_rect(ir, lamp, refl):
    from lbscene.engine.light.geometry import Rectangle

    n = np.asarray(refl.normal, float)
    c = np.asarray(lamp.position_mm, float) - n * refl.distance_mm
    ax = np.asarray(lamp.axis, float)
    ax = ax - n * (ax @ n)
    if np.linalg.norm(ax) < 1e-9:                   # lamp axis along the mirror normal
        ax = np.cross(n, [1.0, 0.0, 0.0])
        if np.linalg.norm(ax) < 1e-9:
            ax = np.cross(n, [0.0, 1.0, 0.0])
    ax = ax / np.linalg.norm(ax)
    along = (lamp.length_mm if lamp.kind in ("tube", "panel") else refl.width_mm) / 2
    return Rectangle(c, n, ax, (along, refl.width_mm / 2))


@register_effect
class ReflectorEffect(PhysicalEffect):
    id = "reflector"
    summary = "Mirrors behind lamps send back-emitted light forward."
    kind = "geometric"
    order = 60
    fit_parameters = {"reflectance_scale": (0.05, 1.5)}
    fit_initial = {"reflectance_scale": 1.0}

    class Params(LampSelection):
        reflectance_scale: float = Field(1.0, gt=0, le=1.5)

    @classmethod
    def applicable(cls, ir, lighting):
        if not any(lp.reflector for lp in lamps_on(ir, lighting)):
            return "no lamp that is on has a reflector:"
        return None

    @staticmethod
    def extra_emitters(ctx, p, lamp, es: EmitterSet) -> list[EmitterSet]:
        if not lamp.reflector or not lamp_selected(p, lamp.id) or lamp.reflector not in ctx.ir.reflectors:
            return []
        refl = ctx.ir.reflectors[lamp.reflector]
        rect = _mirror_rect(ctx.ir, lamp, refl)
        n = rect.normal
        pts = es.points_mm - 2.0 * ((es.points_mm - rect.centre) @ n)[:, None] * n[None, :]
        R = np.clip(refl.reflectance.array_1nm * p.reflectance_scale, 0.0, 1.0)

        def reflect(u, n=n):
            return u - 2.0 * (u @ n)[..., None] * n

        half = None if es.half_step is None else es.half_step - 2.0 * (es.half_step @ n) * n
        return [es.with_(points_mm=pts, spectrum_1nm=es.spectrum_1nm * R, half_step=half,
                         spectral_key=es.spectral_key + (f"reflector:{lamp.reflector}",),
                         direction_map=reflect, tag=f"image:{lamp.reflector}",
                         meta={**es.meta, "mirror": rect})]

    @staticmethod
    def path_factors(ctx, p, es, rx):
        lamp = ctx.ir.lamp(es.lamp_id)
        if not lamp.reflector or not lamp_selected(p, lamp.id) or lamp.reflector not in ctx.ir.reflectors:
            return None
        if es.tag.startswith("image:"):
            # the image shines only through the mirror's extent, and past the lamp itself: light
            # the mirror sends back toward the lamp's own body is stopped there (below a tube
            # under its mirror the image is hidden entirely)
            rect = es.meta["mirror"]
            f = ctx.fraction_hitting(es, rx, rect)
            from lbscene.engine.light.geometry import lamp_body

            body = lamp_body(lamp) if lamp.mount == "booth" else None
            if body is not None:
                f = f * ctx.fraction_past_body(es, rx, body)
            return [PathChannel(f)]
        rect = _mirror_rect(ctx.ir, lamp, ctx.ir.reflectors[lamp.reflector])
        blocked = ctx.fraction_hitting(es, rx, rect)
        if not blocked.any():
            return None
        return [PathChannel(1.0 - blocked)]
