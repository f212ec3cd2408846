"""CAT16 against published numbers: the M16 matrix and the CAM16 worked example of Li et al.
(2017), "Comprehensive colour solutions: CAM16, CAT16, and CAM16-UCS" (also CIE 248:2022)."""

from __future__ import annotations

import numpy as np
import pytest

#: M16 as printed in Li et al. (2017), equation (4)
M16_PUBLISHED = np.array([[0.401288, 0.650173, -0.051461],
                          [-0.250268, 1.204414, 0.045854],
                          [-0.002079, 0.048952, 0.953127]])
W_A = np.array([109.850, 100.0, 35.585])      # CIE illuminant A, CIE 15:2018 table
W_D65 = np.array([95.047, 100.0, 108.883])    # CIE D65, CIE 15:2018 table
COLOURS = np.array([[19.01, 20.00, 21.78], [48.90, 43.62, 6.25], [5.0, 3.0, 12.0], [60.0, 70.0, 10.0]])


def test_cat16_matrix_is_the_published_von_kries_form():
    from lbscene.engine.colour.adaptation import adaptation_matrix

    lms_s, lms_d = M16_PUBLISHED @ (W_A / 100), M16_PUBLISHED @ (W_D65 / 100)
    want = np.linalg.inv(M16_PUBLISHED) @ np.diag(lms_d / lms_s) @ M16_PUBLISHED
    got = adaptation_matrix(W_A * 7.3, W_D65 * 0.4)       # only chromaticities matter
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got @ W_A, W_D65, atol=1e-9)   # white onto white, luminance kept


def test_cam16_published_example_and_corresponding_colours():
    """colour-science's CAM16 reproduces the published worked example (J, C, h); with full
    adaptation (D = 1) the colour that has the same CAM16 appearance under D65 as a colour under A
    is the CAT16 corresponding colour (the rest of CAM16 sees only the adapted cone signals)."""
    import colour

    from lbscene.engine.colour.adaptation import adapt_xyz

    surround = colour.VIEWING_CONDITIONS_CAM16["Average"]
    spec = colour.XYZ_to_CAM16(np.array([19.01, 20.00, 21.78]), np.array([95.05, 100.00, 108.88]),
                               318.31, 20.0, surround)
    assert (spec.J, spec.C, spec.h) == pytest.approx((41.73, 0.10, 217.07), abs=0.006)

    for xyz in COLOURS:
        seen = colour.XYZ_to_CAM16(xyz, W_A, 318.31, 20.0, surround, discount_illuminant=True)
        corresponding = colour.CAM16_to_XYZ(seen, W_D65, 318.31, 20.0, surround, discount_illuminant=True)
        np.testing.assert_allclose(adapt_xyz(xyz, W_A, W_D65), corresponding, rtol=1e-6)


def test_none_is_identity_and_bad_method():
    from lbscene.engine.colour.adaptation import adaptation_matrix

    assert np.array_equal(adaptation_matrix(W_A, W_D65, "none"), np.eye(3))
    with pytest.raises(ValueError, match="adaptation must be one of"):
        adaptation_matrix(W_A, W_D65, "vonkries")


def test_display_model_grey_under_a_is_neutral():
    from lbscene.engine.colour.display_model import load_display
    from lbscene.engine.files.shipped import shipped_displays

    model = load_display(shipped_displays()["srgb-reference"])
    grey = W_A / 100 * 0.2 * model.xyz_white_seen[1]
    adapted = model.xyz_to_drive(grey, adapt_from_white_xyz=W_A)
    camera = model.xyz_to_drive(grey, adapt_from_white_xyz=W_A, adaptation="none")
    # the reference display reflects a D50 ambient (0.8 cd/m² of flare that drive values cannot
    # remove), so a grey that is neutral as seen is within 1.5 code values of R = G = B
    assert np.ptp(adapted) < 1.5 / 255
    assert camera[0] - camera[2] > 0.3


def test_equation_1_is_colour_sciences_von_kries_cat16():
    """The matrix is written out (colour-science is not imported on a render's path): it is
    colour-science's, and so is the transform."""
    import colour
    from colour.adaptation import matrix_chromatic_adaptation_VonKries

    from lbscene.engine.colour.adaptation import M_CAT16, adaptation_matrix

    np.testing.assert_array_equal(M_CAT16, colour.adaptation.CAT_CAT16)
    for ws, wt in ((W_A, W_D65), (W_D65, W_A), (np.array([96.4, 100.0, 82.5]), W_D65)):
        want = matrix_chromatic_adaptation_VonKries(ws / ws[1], wt / wt[1], transform="CAT16")
        np.testing.assert_allclose(adaptation_matrix(ws, wt), want, rtol=0, atol=1e-12)
