"""
``lamp_spectrum_shift``: the lamps' spectrum differs from the declared one.

Kind ``spectral``: a wavelength shift, a tilt and a curvature (a lamp's colour changing
slowly with age), :func:`shifted_spectrum_1nm`, at the declared luminous output
(:func:`aged_spectrum_1nm`):

.. math:: S_a(λ) = S'(λ)\\,\\frac{\\int S V\\,dλ}{\\int S' V\\,dλ}

A lamp's output is declared as it was measured; the effect reshapes the spectrum and keeps
that output (an 8 nm shift of D65 alone would change the luminous output by about 1 %).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import EmitterSet, LampSelection, PhysicalEffect, lamp_selected
from lbscene.engine.light.effects.registry import register_effect

__all__ = ["LampSpectrumShiftEffect", "shifted_spectrum_1nm", "aged_spectrum_1nm"]


def shifted_spectrum_1nm(values_1nm, shift_nm: float, tilt: float = 0.0,
                         curvature: float = 0.0) -> np.ndarray:
    """A 1 nm spectrum (360–830 nm) moved by ``shift_nm``, tilted and curved.

    .. math:: S'(λ) = S(λ − Δλ)\\,\\bigl(1 + t\\,x + c\\,x^2\\bigr), \\quad x = (λ − 555)/200

    ``Δλ > 0`` moves every feature to longer wavelengths (linear interpolation; zero outside
    the sampled range); the tilt ``t`` and the curvature ``c`` (the factor clipped so it stays
    ≥ 0) are the slow change of a lamp's colour with age: the first two terms of any smooth
    reshaping across the visible range (a power law :math:`(λ/λ_0)^p` is
    :math:`1 + 0.36\\,p\\,x + 0.064\\,p(p − 1)\\,x^2 + …` about 560 nm).  Δλ = 0, t = 0 and c = 0
    return the spectrum unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> s = np.zeros(471); s[200] = 1.0                 # a line at 560 nm
    >>> int(np.argmax(shifted_spectrum_1nm(s, 3.0)))    # now at 563 nm
    203
    """
    v = np.asarray(values_1nm, float)
    wl = np.arange(360.0, 360.0 + v.size)
    out = np.interp(wl - shift_nm, wl, v, left=0.0, right=0.0) if shift_nm else v.copy()
    if tilt or curvature:
        x = (wl - 555.0) / 200.0
        out = out * np.clip(1.0 + tilt * x + curvature * x * x, 0.0, None)
    return out


def aged_spectrum_1nm(values_1nm, shift_nm: float, tilt: float = 0.0, curvature: float = 0.0) -> np.ndarray:
    """:func:`shifted_spectrum_1nm` rescaled to the luminous output of ``values_1nm``:
    :math:`\\int S_a V\\,dλ = \\int S V\\,dλ` (CIE 1924 photopic V).  A spectrum with no
    luminous output is returned reshaped, unscaled."""
    from lbscene.engine.spectra.evaluate import photopic_1nm

    v = np.asarray(values_1nm, float)
    out = shifted_spectrum_1nm(v, shift_nm, tilt, curvature)
    V = photopic_1nm()
    before, after = float(v @ V), float(out @ V)
    return out * (before / after) if before > 0 and after > 0 else out


@register_effect
class LampSpectrumShiftEffect(PhysicalEffect):
    id = "lamp_spectrum_shift"
    summary = ("The lamps' spectrum differs from the declared one: a wavelength shift, a tilt and a "
               "curvature (ageing), at the declared luminous output.")
    kind = "spectral"
    order = 29
    fit_parameters = {"shift_nm": (-15.0, 15.0), "tilt": (-0.5, 0.5), "curvature": (-0.5, 0.5)}
    fit_initial = {"shift_nm": 0.0, "tilt": 0.0, "curvature": 0.0}

    class Params(LampSelection):
        shift_nm: float = Field(0.0, ge=-50, le=50, description="Wavelength shift of the whole spectrum "
                                "(positive: toward the red).")
        tilt: float = Field(0.0, ge=-1, le=1, description="Relative slope of a linear tilt per 200 nm, "
                            "around 555 nm (positive: redder).")
        curvature: float = Field(0.0, ge=-1, le=1, description="Relative curvature of the reshaping: the "
                                 "factor's second-order term in (λ − 555 nm)/200 nm (negative: the "
                                 "middle of the spectrum raised against its ends).")

    @staticmethod
    def modify_emitters(ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        if not lamp_selected(p, lamp.id) or (p.shift_nm == 0.0 and p.tilt == 0.0 and p.curvature == 0.0):
            return es
        key = f"shift:{p.shift_nm:.6g}:{p.tilt:.6g}" + (f":{p.curvature:.6g}" if p.curvature else "")
        return es.with_(spectrum_1nm=aged_spectrum_1nm(es.spectrum_1nm, p.shift_nm, p.tilt, p.curvature),
                        spectral_key=es.spectral_key + (key,))
