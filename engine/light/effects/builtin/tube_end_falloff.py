"""
``tube_end_falloff``: tube emission falls linearly toward the ends.

Kind ``geometric``: cathodes and phosphor ageing make a fluorescent tube darker over
``falloff_length_mm`` at each end, down to ``end_level`` at the very end.

A fit moves the fall-off over at most half the shortest tube that is on
(:meth:`TubeEndFalloffEffect.fit_parameters_for`): the middle of a tube keeps the output the
booth declares (a luminance is measured there).  A fall-off over more than half the tube dims its
middle too: with the output known, a uniform loss (an undeclared 80 % plate under 750 mm tubes)
was fitted as a fall-off over 560 mm from each end and called ``missing:tube_end_falloff``.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import (EmitterSet, LampSelection, PhysicalEffect, lamp_selected,
                                                  lamps_on)
from lbscene.engine.light.effects.registry import register_effect

__all__ = ["TubeEndFalloffEffect"]


@register_effect
class TubeEndFalloffEffect(PhysicalEffect):
    id = "tube_end_falloff"
    summary = "Emission of tubes falls toward their ends (cathodes, phosphor ageing)."
    kind = "geometric"
    order = 20
    fit_parameters = {"end_level": (0.0, 1.0), "falloff_length_mm": (5.0, 1000.0)}
    fit_initial = {"end_level": 0.5, "falloff_length_mm": 100.0}
    helpers = ("weight",)

    class Params(LampSelection):
        falloff_length_mm: float = Field(100.0, gt=0, le=2000,
                                         description="Length over which emission falls at each end.")
        end_level: float = Field(0.5, ge=0, le=1, description="Relative emission at the very end.")

    @classmethod
    def fit_parameters_for(cls, ir, lighting) -> dict:
        """The fit's bounds: ``falloff_length_mm`` up to half the shortest tube that is on."""
        tubes = [lp.length_mm for lp in lamps_on(ir, lighting) if lp.kind == "tube" and lp.length_mm > 0]
        out = dict(cls.fit_parameters)
        if tubes:
            lo, hi = out["falloff_length_mm"]
            out["falloff_length_mm"] = (lo, max(min(hi, 0.5 * min(tubes)), 2.0 * lo))
        return out

    @classmethod
    def applicable(cls, ir, lighting):
        if not any(lp.kind == "tube" for lp in lamps_on(ir, lighting)):
            return "no tube lamp is on"
        return None

    @staticmethod
    def weight(distance_from_end_mm, p) -> np.ndarray:
        """Relative emission at a distance from the nearer tube end (linear ramp)."""
        t = np.clip(np.asarray(distance_from_end_mm, float) / p.falloff_length_mm, 0.0, 1.0)
        return p.end_level + (1.0 - p.end_level) * t

    @classmethod
    def modify_emitters(cls, ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        if lamp.kind != "tube" or not lamp_selected(p, lamp.id):
            return es
        d_end = (0.5 - np.abs(es.s)) * lamp.length_mm
        return es.with_(weights=es.weights * cls.weight(d_end, p))
