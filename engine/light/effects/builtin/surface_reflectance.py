"""
``surface_reflectance``: a surface reflects otherwise than its declared material says.

Kind ``global``: the inter-reflection (:func:`lbscene.engine.light.radiosity.surface_patch_scales`) multiplies the
declared reflectance :math:`ρ(λ)` of the ceiling, of the side and rear walls, and of the floor by
``ceiling_scale``, ``walls_scale`` and ``floor_scale``,

.. math:: ρ'(λ) = \\min(s_\\text{surface}\\,ρ(λ),\\ 0.99) ,

the same clip as the ``interreflection`` effect's global ``reflectance_scale``.  Without
``interreflection`` the surfaces reflect nothing and the effect changes nothing.  The diagnosis
fits it as the hypotheses ``ceiling_reflectance`` and ``walls_reflectance``
(:mod:`lbscene.engine.loop.hypotheses`), and suggests the fitted material itself; the
effect lets a booth file state a correction it has measured without editing its materials.
"""

from __future__ import annotations

from pydantic import Field

from lbscene.engine.light.effects.physics import PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect

__all__ = ["SurfaceReflectanceEffect"]


@register_effect
class SurfaceReflectanceEffect(PhysicalEffect):
    id = "surface_reflectance"
    summary = "The ceiling, walls or floor reflect otherwise than their declared materials."
    kind = "global"
    order = 890
    # no hook of its own: the inter-reflection's radiosity applies the scales to its patches
    applied_by = "interreflection"
    # the Monte Carlo reference engine, Cycles and the realtime graph's own shading do not scale
    # the surfaces (the realtime graph's vertex light comes from the forward model)
    backends = frozenset({"forward"})
    fit_parameters = {"ceiling_scale": (0.02, 3.0), "walls_scale": (0.02, 3.0)}
    fit_initial = {"ceiling_scale": 1.0, "walls_scale": 1.0}

    class Params(EffectParams):
        ceiling_scale: float = Field(1.0, ge=0, le=5, description="Multiplier on the ceiling's reflectance.")
        walls_scale: float = Field(1.0, ge=0, le=5, description="Multiplier on the side and rear walls' "
                                                                  "reflectance.")
        floor_scale: float = Field(1.0, ge=0, le=5, description="Multiplier on the floor's reflectance.")

    @classmethod
    def applicable(cls, ir, lighting):
        # the diagnosis tries one surface at a time, as hypotheses with the fitted material
        return ("tried by the diagnosis as the hypotheses ceiling_reflectance and walls_reflectance "
                "(the surface's material fitted)")

