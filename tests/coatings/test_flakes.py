"""Flakes as mirrors: the orientation distribution, the glint condition and its probability,
extended against point-like lamps, and lbscene's texture instrument and fit.

Expected values: the Beckmann distribution's cumulative form, the mirror law checked flake by
flake (an explicit Monte Carlo of normals, independent of the closed form), Poisson statistics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.coatings.flakes import FlakeModel, beckmann_normal_pdf, sample_normals
from lbscene.engine.coatings.instrument import (GlintPool, reflected_directions, sparkle_glints,
                                                texture_metrics)

REPO = Path(__file__).resolve().parents[2]


def test_beckmann_pdf_is_normalised_and_sampled():
    alpha = 0.25
    nt = 20000
    t = (np.arange(nt) + 0.5) / nt * np.pi / 2
    m = np.stack([np.sin(t), 0 * t, np.cos(t)], -1)
    total = (beckmann_normal_pdf(m, alpha) * np.sin(t)).sum() * 2 * np.pi * (np.pi / 2 / nt)
    assert total == pytest.approx(1.0, abs=1e-6)
    n = sample_normals(np.random.default_rng(1).standard_normal((200000, 2)), alpha)
    tan = np.linalg.norm(n[:, :2], axis=1) / n[:, 2]
    for t0 in (0.1, 0.25, 0.5):   # P(tan θ < t0) = 1 − exp(−t0²/α²)
        assert (tan < t0).mean() == pytest.approx(1 - np.exp(-t0 ** 2 / alpha ** 2), abs=0.004)


def _glint_fraction_by_mirror_law(model, l_air, half_angle_deg, count=2_000_000, seed=5):
    """Explicit flakes: a camera along +z sees a flake glint when its mirror reflection of +z,
    refracted out of the coat, lies within the lamp's cone."""
    m = sample_normals(np.random.default_rng(seed).standard_normal((count, 2)), model.alpha)
    _, leaves, r = reflected_directions(m, model.n)
    hit = leaves & (r @ l_air >= np.cos(np.radians(half_angle_deg)))
    return hit.mean(), hit.sum()


@pytest.mark.parametrize("illumination_deg", [15.0, 45.0, 75.0])
def test_glint_probability_closed_form_vs_mirror_law(illumination_deg):
    model = FlakeModel.from_spread_deg(1000, 20, 0.3, 18.0, 0.9)
    th = np.radians(illumination_deg)
    l = np.array([-np.sin(th), 0.0, np.cos(th)])
    delta = 1.5
    omega = 2 * np.pi * (1 - np.cos(np.radians(delta)))
    expected = float(model.glint_probability(l, np.array([0.0, 0.0, 1.0]), omega))
    frac, hits = _glint_fraction_by_mirror_law(model, l, delta)
    assert hits > 150
    assert frac == pytest.approx(expected, rel=4 / np.sqrt(hits) + 0.02)


def test_instrument_glint_count_is_poisson_around_the_closed_form():
    model = FlakeModel.from_spread_deg(2000, 15, 0.35, 12.0, 0.9)
    th = np.radians(45.0)
    l = np.array([-np.sin(th), 0.0, np.cos(th)])
    omega = 2 * np.pi * (1 - np.cos(np.radians(2.5)))
    for seed in (1, 2, 3):
        g = sparkle_glints(model, 45.0, GlintPool(seed), field_mm=30.0)
        expected = g.flakes_in_field * float(model.glint_probability(l, np.array([0.0, 0.0, 1.0]), omega))
        assert abs(len(g.diameters_um) - expected) < 4 * np.sqrt(expected) + 0.02 * expected


def test_extended_lamp_gives_more_dimmer_glints():
    """Same lamp intensity, 5× its angular size: about 25× the glints, each about 1/25 as bright."""
    model = FlakeModel.from_spread_deg(2000, 15, 0.35, 12.0, 0.9)
    small = sparkle_glints(model, 45.0, GlintPool(4), field_mm=40.0, source_half_angle_deg=0.5)
    large = sparkle_glints(model, 45.0, GlintPool(4), field_mm=40.0, source_half_angle_deg=2.5)
    ratio_count = len(large.diameters_um) / len(small.diameters_um)
    omega_ratio = (1 - np.cos(np.radians(2.5))) / (1 - np.cos(np.radians(0.5)))
    assert ratio_count == pytest.approx(omega_ratio, rel=0.25)
    # a glint's radiance is the lamp's: at equal intensity, 1/Ω
    assert np.median(large.full_pixel_value) / np.median(small.full_pixel_value) == pytest.approx(
        np.sin(np.radians(0.5)) ** 2 / np.sin(np.radians(2.5)) ** 2, rel=0.02)


def test_mean_lobe_is_the_average_of_the_glints():
    """The flakes' mean reflectance factor (microfacet form) equals the instrument's glint
    pixels averaged over the field (small lamp, flakes apart)."""
    model = FlakeModel.from_spread_deg(300, 15, 0.35, 12.0, 0.9)
    th = np.radians(25.0)
    l = np.array([-np.sin(th), 0.0, np.cos(th)])
    mean_r = float(model.mean_reflectance_factor(l, np.array([0.0, 0.0, 1.0]))[0])
    field = 60.0
    g = sparkle_glints(model, 25.0, GlintPool(9), field_mm=field, source_half_angle_deg=1.0)
    from lbscene.engine.coatings.instrument import PIXEL_UM

    npx = (field * 1000 / PIXEL_UM) ** 2
    field_mean = float((g.pixel_fraction * g.full_pixel_value).sum() / npx)
    assert field_mean == pytest.approx(mean_r, rel=4 / np.sqrt(len(g.diameters_um)) + 0.03)


def test_texture_metrics_grow_with_flake_size():
    base = 0.05
    small = texture_metrics(FlakeModel.from_spread_deg(1500, 12, 0.35, 12, 0.9), base, seed=1)
    large = texture_metrics(FlakeModel.from_spread_deg(1500 * (12 / 30) ** 2, 30, 0.35, 12, 0.9), base, seed=1)
    # same covered area: larger flakes are brighter spots and a coarser pattern
    assert large.graininess > 1.5 * small.graininess
    assert large.sparkle[45.0][1] > small.sparkle[45.0][1]
    # sparkle falls as the source moves away from the camera's mirror direction
    assert small.sparkle[15.0][0] > small.sparkle[45.0][0] > small.sparkle[75.0][0]


def _coating(name):
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    return SampleSpec.from_document(load_document(REPO / "examples" / "render" / f"sample-coating-{name}.yaml",
                                                  Sample))


def _recovered(name):
    from lbscene.engine.coatings.model import coating_appearance

    c = coating_appearance(_coating(name))
    target = c.readings.vector()
    got = []
    for a in sorted(c.readings.sparkle):
        got.extend(c.predicted.sparkle[a])
    got.append(c.predicted.graininess)
    return np.asarray(got) / target - 1


def test_fitted_flakes_reproduce_the_coarse_silver_readings():
    err = _recovered("coarse-silver")
    assert np.abs(err).max() < 0.10, err


@pytest.mark.slow
def test_fitted_flakes_reproduce_the_fine_silver_readings():
    err = _recovered("fine-silver")
    assert np.abs(err).max() < 0.10, err
