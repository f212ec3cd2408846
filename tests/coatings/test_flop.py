"""The flop BRDF: closed forms of its pieces, the fit, and leave-one-geometry-out ΔE00.

Expected values come from outside the code: Fresnel's equations, the distributions' cumulative
forms, the diffuse reflectance of a glass surface in the literature, colour-science."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.coatings.flop import FlopModel, MeasuredGeometry, fit_flop, leave_one_out
from lbscene.engine.coatings.optics import (diffuse_transmittance, fresnel_transmittance,
                                            geometry_directions, refract_into_coat)

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples" / "render"


def test_fresnel_at_normal_incidence_and_grazing():
    for n in (1.3, 1.5, 1.8):
        assert fresnel_transmittance(1.0, n) == pytest.approx(1 - ((n - 1) / (n + 1)) ** 2, abs=1e-12)
    assert fresnel_transmittance(0.0, 1.5) == pytest.approx(0.0, abs=1e-9)


def test_diffuse_transmittance_matches_the_glass_value():
    # external reflectance of a glass surface (n = 1.5) for diffuse light: 0.092 (Judd 1942;
    # Wyszecki & Stiles, Color Science, 2nd ed., table 1(2.4))
    assert 1 - diffuse_transmittance(1.5) == pytest.approx(0.092, abs=0.001)


def test_snell_inside_the_coat():
    l, v = geometry_directions(45.0, np.array([-15.0, 45.0, 110.0]))
    li = refract_into_coat(l, 1.5)
    assert np.degrees(np.arcsin(np.linalg.norm(li[..., :2], axis=-1))) == pytest.approx(
        np.degrees(np.arcsin(np.sin(np.radians(45.0)) / 1.5)), abs=1e-9)
    assert np.linalg.norm(refract_into_coat(v, 1.5), axis=-1) == pytest.approx(1.0)
    # viewing angles of the six geometries: θ_v = 45° − aspecular
    assert np.degrees(np.arctan2(v[:, 0], v[:, 2])) == pytest.approx([60.0, 0.0, -65.0])


@pytest.mark.parametrize("distribution,alpha,expected", [
    ("ggx", 0.1, 1 / (1 + 0.1 ** 2)), ("ggx", 0.4, 1 / (1 + 0.4 ** 2)),
    ("beckmann", 0.1, 1 - np.exp(-1 / 0.1 ** 2)), ("beckmann", 0.5, 1 - np.exp(-1 / 0.5 ** 2))])
def test_lobe_energy(distribution, alpha, expected):
    """Directional albedo of a unit lobe at normal incidence: ∫ D cos θ_h dω_h over θ_h < 45°
    (GGX: 1/(1 + α²); Beckmann: 1 − exp(−1/α²)); n = 1 so that the coat does not enter."""
    m = FlopModel(1.0, np.array([alpha]), np.zeros(1), np.ones((1, 1)), distribution)
    nt, nphi = 4000, 8
    t = (np.arange(nt) + 0.5) / nt * np.pi / 2            # θ_v
    phi = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    T, P = np.meshgrid(t, phi, indexing="ij")
    v = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    l = np.broadcast_to([0.0, 0.0, 1.0], v.shape)
    f = m.brdf(l, v)[..., 0]
    albedo = (f * np.cos(T) * np.sin(T)).sum() * (np.pi / 2 / nt) * (2 * np.pi / nphi)
    assert albedo == pytest.approx(expected, rel=2e-3)


def test_fit_recovers_a_model():
    rng = np.random.default_rng(3)
    truth = FlopModel(1.5, np.array([0.08, 0.3]), rng.uniform(0.02, 0.1, 16),
                      rng.uniform(0.05, 0.5, (2, 16)), "beckmann")
    meas = [MeasuredGeometry(45.0, a, truth.at_geometry(45.0, a)) for a in (-15, 15, 25, 45, 75, 110)]
    fit = fit_flop(meas, lobes=2)
    assert fit.alphas == pytest.approx(truth.alphas, rel=0.02)
    assert fit.rms_relative < 1e-3


def _measured(path):
    from lbscene.engine.files.load import load_document
    from lbscene.engine.spectra.bands import DEFAULT_GRID
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    sp = SampleSpec.from_document(load_document(path, Sample))
    return [MeasuredGeometry(45.0, a, DEFAULT_GRID.integrate(r)) for a, _, r in sp.geometries]


def test_delta_e00_of_bands_is_colour_science():
    import colour

    from lbscene.engine.coatings.colorimetry import delta_e00_bands, lab_bands

    # a flat 18 % reflectance: L* = 116·0.18^(1/3) − 16, a* = b* = 0
    assert lab_bands(np.full(16, 0.18)) == pytest.approx([116 * 0.18 ** (1 / 3) - 16, 0, 0], abs=1e-6)
    a, b = np.full(16, 0.30), np.linspace(0.25, 0.35, 16)
    expect = colour.delta_E(lab_bands(a), lab_bands(b), method="CIE 2000")
    assert delta_e00_bands(a, b) == pytest.approx(expect)


@pytest.mark.parametrize("name", ["fine-silver", "coarse-silver", "blue-pearl"])
def test_leave_one_geometry_out(name):
    """The shipped coatings (made from flakes that hide one another, not from this model: see their
    script) are predicted at each geometry from the other five within ΔE00 2 (two Beckmann lobes;
    measured: max 1.8, fine silver at 45as45), 1.2 on average."""
    loo = leave_one_out(_measured(EXAMPLES / f"sample-coating-{name}.yaml"), lobes=2)
    de = [r["delta_e00"] for r in loo]
    assert len(de) == 6
    assert max(de) < 2.0 and np.mean(de) < 1.2, de
