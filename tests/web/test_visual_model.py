"""The model's ΔE00 of a visual-test case (engine.visual.model) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.engine.visual.model import case_delta_e00, reflectance_at
from lbscene.runtimes.colour_bridge import srgb_display
from lbscene.engine.scene.sample import SampleSpec


def _d65_1nm():
    import colour

    sd = colour.SDS_ILLUMINANTS["D65"].copy().align(colour.SpectralShape(360, 830, 1))
    return np.asarray(sd.values, float) * 0.01       # W m⁻² nm⁻¹ scale (irrelevant: exposure is relative)


def _ciede2000_lightness_only(l1, l2):
    """CIEDE2000 of two neutrals (a* = b* = 0): ΔL' / S_L with
    S_L = 1 + 0.015 (L̄ − 50)² / √(20 + (L̄ − 50)²) (Sharma, Wu and Dalal 2005, eq. 17)."""
    lbar = (l1 + l2) / 2
    sl = 1 + 0.015 * (lbar - 50) ** 2 / np.sqrt(20 + (lbar - 50) ** 2)
    return abs(l2 - l1) / sl


def test_grey_on_srgb_is_quantisation_only():
    de = case_delta_e00(_d65_1nm(), np.full(471, 0.4), srgb_display())
    # D65 grey on the sRGB display (white D65): only 8-bit rounding (half a code ≈ 0.2 L*
    # at this level) and the D65 white's cmf integration vs the sRGB matrix's white
    assert de < 0.4


def test_brighter_than_white_is_clipped_to_the_display_white():
    # R = 1.3 everywhere: Y = 1.3 · white, the display shows its white (L* = 100);
    # L*(1.3) = 116 · 1.3^(1/3) − 16
    de = case_delta_e00(_d65_1nm(), np.full(471, 1.3), srgb_display())
    l1 = 116 * 1.3 ** (1 / 3) - 16
    assert de == pytest.approx(_ciede2000_lightness_only(l1, 100.0), abs=0.3)


def test_reflectance_between_measured_geometries():
    s = SampleSpec("g", [(15.0, "45as15", np.full(471, 0.2)), (45.0, "45as45", np.full(471, 0.6))])
    assert reflectance_at(s, 15.0)[0] == pytest.approx(0.2)
    assert reflectance_at(s, 30.0)[0] == pytest.approx(0.4)
    assert reflectance_at(s, 110.0)[0] == pytest.approx(0.6)     # constant beyond the last
    assert reflectance_at(SampleSpec.flat(np.full(471, 0.3)), 60.0)[0] == pytest.approx(0.3)
