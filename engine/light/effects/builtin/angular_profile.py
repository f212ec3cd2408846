"""
``angular_profile``: lamps emit I0·f(θ) (their declared profile, or a Gaussian σ).

Kind ``geometric``.  A lamp that declares a profile (Gaussian, cosⁿ, IES) emits with it;
one that declares none is isotropic unless the effect gives a Gaussian ``sigma_deg``
(the parameter the diagnosis fits).  Profiles: :mod:`lbscene.engine.spectra.profiles`.
"""

from __future__ import annotations

from pydantic import Field

from lbscene.engine.light.effects.physics import (EmitterSet, LampSelection, PhysicalEffect, lamp_selected,
                                                  lamps_on)
from lbscene.engine.light.effects.registry import register_effect

__all__ = ["AngularProfileEffect"]


@register_effect
class AngularProfileEffect(PhysicalEffect):
    id = "angular_profile"
    summary = "Lamps emit with their declared angular profile instead of isotropically."
    kind = "geometric"
    order = 10
    fit_parameters = {"sigma_deg": (5.0, 1000.0)}
    fit_initial = {"sigma_deg": 60.0}

    class Params(LampSelection):
        sigma_deg: float | None = Field(
            None, gt=0, le=1000,
            description="Gaussian σ for lamps without a declared profile (seed: I0·exp(−(θ/2σ)²)).")

    @classmethod
    def fit_parameters_for(cls, ir, lighting) -> dict:
        # σ of the effect only matters for lamps that declare no profile of their own
        if any(lp.profile.get("type") == "isotropic" for lp in lamps_on(ir, lighting)):
            return dict(cls.fit_parameters)
        return {}

    @staticmethod
    def modify_emitters(ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        from lbscene.engine.spectra.profiles import GaussianShape, profile_shape

        if not lamp_selected(p, lamp.id):
            return es
        sigma = ctx.lamp_overrides.get(lamp.id, {}).get("sigma_deg")
        if sigma is not None:
            return es.with_(shape=GaussianShape(float(sigma)))
        if lamp.profile.get("type") != "isotropic":
            key = ("profile", lamp.id)
            shape = ctx.cache.get(key)
            if shape is None:
                shape = ctx.cache[key] = profile_shape(lamp.profile)
            return es.with_(shape=shape)
        if p.sigma_deg is not None:
            return es.with_(shape=GaussianShape(float(p.sigma_deg)))
        return es
