"""Product files and conventions, without Blender (independent references)."""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.bakers.job import BandGridSpec
from lbscene.bakers.products import (band_photopic_weights, cube_directions, cube_face_frames,
                                     environment_irradiance, equirect_directions, illuminance_lx,
                                     noise_summary, pixel_solid_angles, read_exr, read_product,
                                     write_exr)
from lbscene.engine.spectra.bands import band_labels


def test_exr_round_trip_is_exact_float32(tmp_path):
    rng = np.random.default_rng(1)
    data = rng.uniform(0, 1e3, size=(5, 7, 16)).astype(np.float32)
    data[0, 0, 0] = 1e-30          # tiny and huge values survive (no half floats, no clamping)
    data[0, 1, 0] = 3.4e37
    labels = band_labels()
    write_exr(tmp_path / "a.exr", data, labels, {"lbscene:units": "W·m⁻²·nm⁻¹",
                                                 "lbscene:band_edges_nm": "390,410,430,450,470,490,510,"
                                                 "530,550,570,590,610,630,650,670,690,710"})
    chans, header = read_exr(tmp_path / "a.exr")
    assert set(chans) == set(labels)
    assert all(c.dtype == np.float32 for c in chans.values())
    back, h2 = read_product(tmp_path / "a.exr")
    assert np.array_equal(back, data)
    assert h2["lbscene:units"] == "W·m⁻²·nm⁻¹"


def test_exr_rejects_wrong_channel_count(tmp_path):
    with pytest.raises(ValueError):
        write_exr(tmp_path / "b.exr", np.zeros((2, 2, 3)), band_labels())


def test_equirect_centre_is_forward_and_left_is_up_cross_forward():
    d = equirect_directions(64, forward=(0, 1, 0), up=(0, 0, 1))
    assert d.shape == (32, 64, 3)
    np.testing.assert_allclose(d[15:17, 31:33].mean(axis=(0, 1)) / np.linalg.norm(
        d[15:17, 31:33].mean(axis=(0, 1))), [0, 1, 0], atol=1e-9)
    # a quarter of the width left of centre looks to the observer's left (−x)
    np.testing.assert_allclose(d[15:17, 15:17].mean(axis=(0, 1)) / np.linalg.norm(
        d[15:17, 15:17].mean(axis=(0, 1))), [-1, 0, 0], atol=1e-9)
    assert d[0, :, 2].min() > 0.99           # top row looks up


@pytest.mark.parametrize("projection, shape", [("equirect", (64, 128)), ("cube", (16, 96))])
def test_pixel_solid_angles_cover_the_sphere(projection, shape):
    assert pixel_solid_angles(shape, projection).sum() == pytest.approx(4 * np.pi, rel=1e-12)


@pytest.mark.parametrize("projection, shape", [("equirect", (128, 256)), ("cube", (48, 288))])
@pytest.mark.parametrize("normal", [(0, 0, 1), (0.3, -0.5, 0.8)])
def test_uniform_radiance_gives_pi_L(projection, shape, normal):
    """A uniform sky of radiance L gives E = πL on any plane (closed form)."""
    data = np.full(shape + (2,), 2.0)
    E = environment_irradiance(data, projection, (0, 1, 0), (0, 0, 1), normal)
    np.testing.assert_allclose(E, 2.0 * np.pi, rtol=2e-3)


def test_cube_faces_are_an_orthonormal_right_handed_set():
    faces = cube_face_frames((0, 1, 0), (0, 0, 1))
    dirs = np.array([f[0] for f in faces])
    np.testing.assert_allclose(dirs, [[0, 1, 0], [0, -1, 0], [-1, 0, 0], [1, 0, 0], [0, 0, 1], [0, 0, -1]],
                               atol=1e-12)
    for d, r, u in faces:
        np.testing.assert_allclose(np.cross(r, u), -d, atol=1e-12)   # camera: right × up = back
    c = cube_directions(8)
    assert c.shape == (8, 48, 3)
    np.testing.assert_allclose(np.linalg.norm(c, axis=-1), 1.0)


def test_photopic_weights_match_the_cie_table():
    """683·∫V over 390–710 nm = 683·(∫V over 360–830 nm minus the tails): from colour's table."""
    import colour

    v = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    wl = np.arange(390, 711)
    ref = 683.0 * np.trapz(np.interp(wl, v.wavelengths, v.values), wl)
    w = band_photopic_weights(BandGridSpec())
    assert w.sum() == pytest.approx(ref, rel=1e-6)
    # flat 1 W·m⁻²·nm⁻¹ over the grid → 683·∫V ≈ 72 900 lx (∫V ≈ 106.7 nm)
    assert illuminance_lx(np.ones(16), BandGridSpec()) == pytest.approx(ref, rel=1e-6)


def test_noise_summary_of_identical_halves_is_zero_and_scales():
    a = np.ones((10, 16))
    s = noise_summary(a, a, np.ones(16))
    assert s["relative_rms_all_bands"] == 0 and s["illuminance_relative_rms"] == 0
    b = a * 1.02                   # halves 2 % apart → σ of their mean ≈ 1 %
    s = noise_summary(a, b, np.ones(16))
    assert s["illuminance_relative_rms"] == pytest.approx(0.01 / 1.01, rel=1e-3)
