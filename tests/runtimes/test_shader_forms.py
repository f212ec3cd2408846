"""Closed forms the realtime shaders use in place of slower ones, checked against the functions
they replace: the rational θ/sin θ of the LTC edge term (sample.frag) and the display model's
affine part as one matrix (lib_display.glsl, ``display.linear``)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

SHADERS = Path(__file__).resolve().parents[2] / "runtimes" / "shaders"


def _theta_over_sin_from_shader():
    """θ/sin θ as sample.frag's edge_integral computes it (its coefficients read from the source)."""
    src = (SHADERS / "sample.frag").read_text()
    m = re.search(r"float r = \(([\d.]+) \+ \(([\d.]+) \+ ([\d.]+) \* y\) \* y\) / "
                  r"\(([\d.]+) \+ \(([\d.]+) \+ y\) \* y\);", src)
    assert m, "edge_integral's rational function not found in sample.frag"
    a0, a1, a2, b0, b1 = (float(g) for g in m.groups())

    def f(x):
        y = np.abs(x)
        r = (a0 + (a1 + a2 * y) * y) / (b0 + (b1 + y) * y)
        return np.where(x >= 0.0, r, np.pi / np.sqrt(np.maximum(1.0 - x * x, 1e-7)) - r)

    return f


def test_edge_term_rational_function_matches_acos():
    f = _theta_over_sin_from_shader()
    x = np.linspace(-0.9999, 0.9999, 200001)
    want = np.arccos(x) / np.sqrt(1.0 - x * x)
    assert np.max(np.abs(f(x) / want - 1.0)) < 2e-6
    # the ends: a vanishing arc (θ/sin θ → 1) and a right angle (π/2)
    assert abs(float(f(np.array(1.0))) - 1.0) < 2e-6
    assert abs(float(f(np.array(0.0))) / (np.pi / 2) - 1.0) < 2e-6


def test_edge_term_of_a_quarter_circle_of_the_horizon():
    """Lambert's edge term of the arc from x to y on the horizon: (a × b)_z · θ/sin θ = θ = π/2."""
    f = _theta_over_sin_from_shader()
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    assert abs(np.cross(a, b)[2] * float(f(np.array(a @ b))) - np.pi / 2) < 1e-5


def test_display_linear_matrix_is_the_display_models_affine_part():
    from lbscene.runtimes.scene import _gl, display_linear_matrix

    rng = np.random.default_rng(7)
    exposure, inv_span = 0.37, 1.0 / 79.5
    adapt = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    to_rgb = rng.standard_normal((3, 3))
    offset = np.array([0.4, 0.5, 0.6])
    m = display_linear_matrix(exposure, adapt, offset, to_rgb, inv_span)
    for xyz in rng.uniform(0.0, 200.0, (5, 3)):
        display_xyz = exposure * (adapt @ xyz)
        want_lin = to_rgb @ (display_xyz - offset)
        want_y = (display_xyz[1] - offset[1]) * inv_span
        got = m @ np.r_[xyz, 1.0]
        np.testing.assert_allclose(got, np.r_[want_lin, want_y], rtol=1e-12, atol=1e-12)
    # column-major for the GL uniform: the first four numbers are the first column
    np.testing.assert_allclose(_gl(m)[:4], m[:, 0].astype(np.float32))
