"""Blue-noise dithering before 8-bit quantisation removes banding on a smooth gradient."""

import numpy as np
import pytest


def test_mask_is_a_deterministic_permutation_of_thresholds():
    from lbscene.engine.colour.dither import blue_noise

    m = blue_noise(32)
    assert m.shape == (32, 32)
    ranks = np.rint(m.ravel() * 1024 - 0.5).astype(int)
    assert sorted(ranks.tolist()) == list(range(1024))
    assert np.array_equal(m, blue_noise(32)) and not m.flags.writeable
    assert not np.array_equal(m, blue_noise(32, seed=1))


def test_mask_spectrum_is_blue():
    """Blue noise: almost no power at low spatial frequencies (white noise: flat, ≈ 1)."""
    from lbscene.engine.colour.dither import blue_noise, radial_power_spectrum, white_noise_mask

    f, p = radial_power_spectrum(blue_noise(64))
    low = p[f < 0.1].mean()
    high = p[(f > 0.3) & (f < 0.5)].mean()
    assert low < 0.05 and high > 1.0
    fw, pw = radial_power_spectrum(white_noise_mask(64))
    assert 0.5 < pw[fw < 0.1].mean() < 1.5


def test_constant_level_is_reproduced_on_average():
    from lbscene.engine.colour.dither import blue_noise, dither_quantise

    m = blue_noise(32)
    for v in (0.0, 0.1234, 0.5, 200.3 / 255, 1.0):
        codes = dither_quantise(np.full((32, 32), v), m)
        assert codes.dtype == np.uint8
        # each threshold once per tile: the mean is exact to 1/N² of a code
        assert abs(codes.mean() - v * 255) <= 1 / 1024 + 1e-12
        assert codes.max() - codes.min() <= 1


def test_gradient_banding_is_removed():
    """Plain rounding of a slow ramp: the error is a sawtooth of RMS 1/√12 ≈ 0.289 codes
    (closed form) that survives averaging over 8-column strips (the bands); dithered, the
    strip means spread an order of magnitude less."""
    from lbscene.engine.colour.dither import (banding_metrics, blue_noise, dither_quantise,
                                              quantise_nearest, white_noise_mask)

    ramp = np.tile(np.linspace(0.2, 0.25, 1024), (64, 1))
    nearest = banding_metrics(quantise_nearest(ramp), ramp)
    blue = banding_metrics(dither_quantise(ramp, blue_noise(64)), ramp)
    white = banding_metrics(dither_quantise(ramp, white_noise_mask(64)), ramp)
    assert nearest["pixel_rms_codes"] == pytest.approx(1 / np.sqrt(12), abs=0.005)
    assert nearest["strip_mean_error_std_codes"] > 0.2
    assert nearest["strip_mean_error_max_codes"] > 0.4
    assert blue["strip_mean_error_std_codes"] < 0.03
    assert blue["strip_mean_error_max_codes"] < 0.1
    assert abs(blue["mean_error_codes"]) < 0.01
    # what the eye averages (Gaussian σ = 2 px): blue noise leaves less than white noise
    assert blue["blurred_rms_codes"] < 0.5 * white["blurred_rms_codes"]
    assert blue["blurred_rms_codes"] < 0.25 * nearest["blurred_rms_codes"]


def test_channels_read_the_mask_at_offsets():
    from lbscene.engine.colour.dither import blue_noise, channel_offsets_xy, dither_quantise

    m = blue_noise(16)
    img = np.random.default_rng(0).random((40, 50, 3))
    out = dither_quantise(img, m)
    assert out.shape == img.shape and out.dtype == np.uint8
    for c, (dx, dy) in enumerate(channel_offsets_xy(16)):
        rolled = np.roll(np.roll(m, -dy, axis=0), -dx, axis=1)
        np.testing.assert_array_equal(out[..., c], dither_quantise(img[..., c], rolled))
    assert channel_offsets_xy(64) == ((0, 0), (32, 21), (21, 32))


def test_bad_input():
    from lbscene.engine.colour.dither import blue_noise, dither_quantise

    with pytest.raises(ValueError):
        dither_quantise(np.array([[np.nan]]), None)
    with pytest.raises(ValueError):
        blue_noise(2)
    # out of range values clip to the end codes
    np.testing.assert_array_equal(dither_quantise(np.array([[-0.2, 1.3]]), None), [[0, 255]])
