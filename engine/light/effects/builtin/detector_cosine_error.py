"""
``detector_cosine_error``: the illuminance meter reads cos^k or an f2-type response instead of cos.

Kind ``instrument``: it changes what a meter reads, not the light in the booth, so only the
forward model and the reference engine model it.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect

__all__ = ["DetectorCosineErrorEffect", "f2_linear_coefficient"]


def f2_linear_coefficient(f2_percent: float) -> float:
    """Coefficient c of the response cos ε·(1 − c·ε/(π/2)) whose CIE f2 error is ``f2_percent``.

    CIE 69 / ISO/CIE 19476: f2 = ∫₀^{85°} |Y(ε)/(Y(0)·cos ε) − 1| sin 2ε dε.
    """
    eps = np.linspace(0.0, np.radians(85.0), 2001)
    unit = np.trapz((eps / (np.pi / 2)) * np.sin(2 * eps), eps)
    return float(f2_percent / 100.0 / unit)


@register_effect
class DetectorCosineErrorEffect(PhysicalEffect):
    id = "detector_cosine_error"
    summary = "The illuminance meter's imperfect cosine response (f2 error)."
    kind = "instrument"
    order = 200
    # a meter's response: Cycles' sensors and the realtime view are ideal cosine receivers
    backends = frozenset({"forward", "reference"})
    fit_parameters = {"exponent": (0.5, 2.0)}
    fit_initial = {"exponent": 1.05}

    class Params(EffectParams):
        model: Literal["power", "f2_linear"] = "power"
        exponent: float = Field(1.1, gt=0, le=5,
                                description="Response ∝ cos(θ)^exponent (power model).")
        f2_percent: float = Field(3.0, ge=0, le=50, description="CIE f2 error (f2_linear model).")

    @classmethod
    def fit_parameters_for(cls, ir, lighting) -> dict:
        return dict(cls.fit_parameters)

    @staticmethod
    def receiver_response(ctx, p, cos_i: np.ndarray) -> np.ndarray:
        """Meter reading relative to an ideal cosine receiver, per incidence cosine."""
        c = np.clip(cos_i, 0.0, 1.0)
        if p.model == "power":
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(c > 0, c ** (p.exponent - 1.0), 0.0)
        k = f2_linear_coefficient(p.f2_percent)
        eps = np.arccos(c)
        return np.clip(1.0 - k * eps / (np.pi / 2), 0.0, None)
