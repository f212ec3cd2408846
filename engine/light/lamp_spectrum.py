"""
A lamp's spectrum as a whole, after the effects that change it.

The backends that take a lamp's spectrum as a whole (the reference engine, the Cycles
bake, the realtime graph, the USD stage, the Mitsuba truth, the IR's own spectra at the
sample) read it here, so the ``lamp_spectrum_shift`` and ``spectral_filter`` effects
mean one thing everywhere, exactly what the forward model's emitters carry.
"""

from __future__ import annotations

import numpy as np

from .effects.builtin.lamp_spectrum_shift import LampSpectrumShiftEffect, aged_spectrum_1nm
from .effects.builtin.spectral_filter import SpectralFilterEffect
from .effects.physics import effect_params, lamp_selected

__all__ = ["lamp_spectrum_1nm"]


def lamp_spectrum_1nm(ir, lamp, effects: dict) -> np.ndarray:
    """Peak spectral intensity of ``lamp`` (W·sr⁻¹·nm⁻¹) after the lamp-spectrum effects enabled
    in ``effects`` — ``lamp_spectrum_shift``, then ``spectral_filter`` — exactly as the forward
    model's emitters carry it."""
    e = np.asarray(lamp.peak_intensity_1nm, float)
    if "lamp_spectrum_shift" in effects:
        p = effect_params(LampSpectrumShiftEffect, effects["lamp_spectrum_shift"])
        if lamp_selected(p, lamp.id):
            e = aged_spectrum_1nm(e, p.shift_nm, p.tilt, p.curvature)
    if "spectral_filter" in effects:
        p = effect_params(SpectralFilterEffect, effects["spectral_filter"])
        fid = SpectralFilterEffect.filter_for(ir, p, lamp)
        if fid is not None:
            e = e * ir.filters[fid].transmittance.array_1nm
    return e
