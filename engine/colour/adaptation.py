r"""
Chromatic adaptation to the white of the booth's lighting.

A person in a light booth adapts to its white: a neutral grey under illuminant A looks grey,
not orange.  A camera does not.  The display model therefore takes, before it computes drive
values, the colour of what is seen to the *corresponding colour* under the display's white,
with a von Kries transform in the CAT16 cone space (Li et al. 2017, "Comprehensive colour
solutions: CAM16, CAT16, and CAM16-UCS"; CIE 248:2022)::

    XYZ_d = M16⁻¹ · diag(Λ) · M16 · XYZ_s,     Λ = (M16 · ŵ_d) / (M16 · ŵ_s)            (1)

with ``ŵ = XYZ_w / Y_w`` the source white (a perfect white diffuser under the lighting, at the
sample) and the destination white (the display's white as seen), each normalised to ``Y = 1``
so that the transform keeps luminance (the exposure sets the level), and full adaptation
(``D = 1``: the observer has been in the booth long enough).  Equation (1) is one 3×3 matrix,
so the shaders apply it as a ``mat3`` uniform (``u_adaptation`` in ``lib_display.glsl``).

Methods (``ADAPTATION_METHODS``):

``"cat16"`` (default)
    what a person in the booth sees: equation (1), as colour-science's
    ``matrix_chromatic_adaptation_VonKries(..., transform="CAT16")`` computes it.
``"none"``
    what a camera sees (a fixed D65 white balance): the identity; a scene under illuminant A
    looks orange on a D65 display.

Examples
--------
>>> import numpy as np
>>> a = adaptation_matrix([109.85, 100.0, 35.585], [95.047, 100.0, 108.883])
>>> np.round(a @ np.array([109.85, 100.0, 35.585]), 3)     # A's white → D65's white
array([  95.047,  100.   ,  108.883])
>>> adaptation_matrix([109.85, 100.0, 35.585], [95.047, 100.0, 108.883], "none")
array([[ 1.,  0.,  0.],
       [ 0.,  1.,  0.],
       [ 0.,  0.,  1.]])
"""

from __future__ import annotations

import numpy as np

__all__ = ["ADAPTATION_METHODS", "DEFAULT_ADAPTATION", "ADAPTATION_DESCRIPTIONS", "M_CAT16",
           "adaptation_matrix", "adapt_xyz"]

ADAPTATION_METHODS = ("cat16", "none")
#: the CAT16 matrix M16, XYZ → cone space (Li et al. 2017, equation (4); colour-science's ``CAT_CAT16``,
#: which ``tests/colour/test_cat16.py`` checks equation (1) against): written out, because
#: importing colour-science (with matplotlib) cost every command's first frame 1–5 s
M_CAT16 = np.array([[0.401288, 0.650173, -0.051461],
                    [-0.250268, 1.204414, 0.045854],
                    [-0.002079, 0.048952, 0.953127]])
DEFAULT_ADAPTATION = "cat16"
#: one line per method, for reports, PNG metadata and ``--help``
ADAPTATION_DESCRIPTIONS = {
    "cat16": "CAT16 (von Kries, D = 1) from the lighting's white to the display's white: "
             "what a person in the booth sees",
    "none": "no chromatic adaptation: what a camera with a fixed D65 white balance sees",
}


def adaptation_matrix(white_source_xyz, white_target_xyz, method: str = DEFAULT_ADAPTATION) -> np.ndarray:
    """The 3×3 matrix of equation (1): XYZ seen under ``white_source`` → XYZ under ``white_target``.

    Parameters
    ----------
    white_source_xyz, white_target_xyz
        Tristimulus values of the two whites (any common scale, e.g. cd/m²); only their
        chromaticities matter (each is normalised to ``Y = 1``).
    method
        ``"cat16"`` or ``"none"`` (identity).

    Returns
    -------
    numpy.ndarray
        (3, 3); ``XYZ_target = A @ XYZ_source``; maps the source white, normalised, onto the
        target white, normalised (luminance kept).
    """
    if method not in ADAPTATION_METHODS:
        raise ValueError(f"adaptation must be one of {ADAPTATION_METHODS}, not {method!r}")
    if method == "none":
        return np.eye(3)
    ws = np.asarray(white_source_xyz, float)
    wt = np.asarray(white_target_xyz, float)
    if not (ws[1] > 0 and wt[1] > 0):
        raise ValueError("adaptation whites need Y > 0")
    lms_s = M_CAT16 @ (ws / ws[1])
    lms_t = M_CAT16 @ (wt / wt[1])
    return np.linalg.inv(M_CAT16) @ ((lms_t / lms_s)[:, None] * M_CAT16)


def adapt_xyz(xyz, white_source_xyz, white_target_xyz, method: str = DEFAULT_ADAPTATION) -> np.ndarray:
    """Apply :func:`adaptation_matrix` to XYZ values (..., 3)."""
    return np.asarray(xyz, float) @ adaptation_matrix(white_source_xyz, white_target_xyz, method).T
