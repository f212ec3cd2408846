"""Truths written independently of lbscene's emitters, shared by the tests that need them."""

from __future__ import annotations

import math

import numpy as np


def cylinder_quadrature_lx(lv_cd_m2, centre_mm, length_mm, radius_mm, p_mm, n, n_along=3000, n_around=720,
                           weight=None, visible=None):
    """Illuminance (lx) at ``p_mm`` (normal ``n``) from a Lambertian cylinder of luminance ``lv_cd_m2``
    along x: a dense midpoint quadrature over its lateral surface, ∫ L w cos θs cos θr / ρ² dA.

    ``weight(x_mm)``: relative luminance at ``x`` along the axis from the centre (default 1);
    ``visible(points_mm, p_mm)``: which surface elements the receiver sees (default all)."""
    x = (np.arange(n_along) + 0.5) / n_along * length_mm - length_mm / 2
    a = (np.arange(n_around) + 0.5) / n_around * 2 * math.pi
    X, A = np.meshgrid(x, a, indexing="ij")
    nrm = np.stack([np.zeros_like(A), np.cos(A), np.sin(A)], -1)
    pts = np.asarray(centre_mm) + np.stack([X, np.zeros_like(X), np.zeros_like(X)], -1) + radius_mm * nrm
    d = np.asarray(p_mm) - pts
    rho = np.linalg.norm(d, axis=-1)
    cs = np.clip((d * nrm).sum(-1) / rho, 0, None)
    cr = np.clip(-(d @ np.asarray(n)) / rho, 0, None)
    da = (length_mm / n_along) * (2 * math.pi * radius_mm / n_around) * 1e-6
    f = cs * cr / (rho * 1e-3) ** 2
    if weight is not None:
        f = f * weight(X)
    if visible is not None:
        f = f * visible(pts, np.asarray(p_mm, float))
    return float(lv_cd_m2 * f.sum() * da)


def mirror_image_visible(mirror_z_mm, half_length_mm, half_width_mm, tube_z_mm, radius_mm):
    """``visible(points, p)`` for :func:`cylinder_quadrature_lx` of a tube's mirror image: the
    elements whose straight path to ``p`` crosses the mirror rectangle (plane z = ``mirror_z_mm``,
    |x| ≤ half length, |y| ≤ half width) and misses the real tube (radius ``radius_mm`` about the
    x axis at z = ``tube_z_mm``, |x| ≤ half length; the path is tested where it passes the
    tube's height band)."""

    def visible(pts, p):
        d = p - pts
        t = (mirror_z_mm - pts[..., 2]) / d[..., 2]
        ok = (t > 0) & (t < 1) & (np.abs(pts[..., 0] + t * d[..., 0]) <= half_length_mm) & \
            (np.abs(pts[..., 1] + t * d[..., 1]) <= half_width_mm)
        for z in np.linspace(tube_z_mm - radius_mm, tube_z_mm + radius_mm, 53):
            tz = (z - pts[..., 2]) / d[..., 2]
            x, y = pts[..., 0] + tz * d[..., 0], pts[..., 1] + tz * d[..., 1]
            ok &= ~((np.hypot(y, z - tube_z_mm) < radius_mm) & (np.abs(x) <= half_length_mm))
        return ok

    return visible
