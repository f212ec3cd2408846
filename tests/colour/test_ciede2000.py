"""CIEDE2000 as used by every accuracy figure: colour-science's implementation, pinned
against the test data of Sharma, Wu & Dalal (2005), "The CIEDE2000 color-difference
formula: implementation notes, supplementary test data, and mathematical observations",
Color Res. Appl. 30(1), Table 1 (kL = kC = kH = 1)."""

import numpy as np
import pytest

# (pair, L1, a1, b1, L2, a2, b2, ΔE00) typed from Sharma et al. (2005), Table 1
SHARMA_2005 = [
    (1, 50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425),
    (2, 50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615),
    (3, 50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412),
    (4, 50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000),
    (7, 50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669),
    (9, 50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792),
    (10, 50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792),
    (11, 50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195),
    (13, 50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045),
    (15, 50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461),
    (16, 50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065),
    (17, 50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492),
    (19, 50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030),
    (22, 50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000),
    (25, 60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644),
    (26, 63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630),
    (29, 22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373),
    (31, 90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441),
    (33, 6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377),
    (34, 2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082),
]


@pytest.mark.parametrize("row", SHARMA_2005, ids=[f"pair{r[0]}" for r in SHARMA_2005])
def test_delta_e00_matches_sharma_2005(row):
    from lbscene.engine.colour.accuracy import delta_e00

    _, l1, a1, b1, l2, a2, b2, expected = row
    assert delta_e00([l1, a1, b1], [l2, a2, b2]) == pytest.approx(expected, abs=1e-4)
    # the formula is symmetric in its two arguments
    assert delta_e00([l2, a2, b2], [l1, a1, b1]) == pytest.approx(expected, abs=1e-4)


def test_delta_e00_vectorised():
    from lbscene.engine.colour.accuracy import delta_e00

    lab1 = np.array([r[1:4] for r in SHARMA_2005])
    lab2 = np.array([r[4:7] for r in SHARMA_2005])
    np.testing.assert_allclose(delta_e00(lab1, lab2), [r[7] for r in SHARMA_2005], atol=1e-4)
