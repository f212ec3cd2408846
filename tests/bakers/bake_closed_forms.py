"""
Closed-form radiometry references, independent of the baker's code.

One job multiplexes several closed-form set-ups by band (Cycles' colour
channels are independent, so each band sees only its own emitter):

========  ==========================================================================
bands     set-up (all emitters above sensors facing +z unless stated)
========  ==========================================================================
0–2       isotropic point source at (0, 0, 1000) mm, I = 1, 0.5, 0.25 W·sr⁻¹·nm⁻¹
3–5       same place, Gaussian profile σ = 20°: I(θ) = exp(−(θ/2σ)²)
6         same place, cos²θ profile
7         same place, tabulated profile (linear between table points)
8         same place, Gaussian σ = 30° aimed along (1, 0, −1)/√2
9–10      Lambertian rectangle 400 × 200 mm at z = 800 mm over (3000, 0), L = 1, 2
11        Lambertian disk R = 300 mm at z = 600 mm over (−3000, 0), L = 1
12–13     point source (0, 3000, 1000) behind a clear sheet (T0 = 0.8, 0.5, n = 1.52) at z = 500
14–15     point source (0, −3000, 1000) over a 2 × 2 m Lambertian floor (ρ = 0.5, 0.9);
          a downward sensor at z = 300 mm sees only the floor's single bounce
========  ==========================================================================
"""

from __future__ import annotations

import numpy as np

H0 = 1000.0  # mm, height of the point sources


def point_irradiance(I, src, p, n=(0, 0, 1), aim=(0, 0, -1), profile=lambda th: 1.0):
    """E = I·f(θ)·cos(ψ)/d² (W·m⁻²·nm⁻¹), distances in mm."""
    src, p, n, aim = (np.asarray(x, float) for x in (src, p, n, aim))
    d = p - src
    dist = np.linalg.norm(d)
    u = d / dist
    cos_rx = max(0.0, float(-u @ (n / np.linalg.norm(n))))
    theta = np.degrees(np.arccos(np.clip(u @ (aim / np.linalg.norm(aim)), -1, 1)))
    return I * profile(theta) * cos_rx / (dist * 1e-3) ** 2


def rect_corner_E(L, a, b, h):
    """Irradiance under one corner of a parallel Lambertian a×b rectangle at height h.

    E = π L F with the differential-area view factor
    F = 1/2π [A/√(1+A²)·atan(B/√(1+A²)) + B/√(1+B²)·atan(A/√(1+B²))], A = a/h, B = b/h.
    """
    A, B = a / h, b / h
    F = (A / np.sqrt(1 + A * A) * np.arctan(B / np.sqrt(1 + A * A))
         + B / np.sqrt(1 + B * B) * np.arctan(A / np.sqrt(1 + B * B))) / (2 * np.pi)
    return np.pi * L * F


def rect_E(L, x0, x1, y0, y1, h):
    """Irradiance at the origin under a parallel rectangle [x0,x1]×[y0,y1] at height h (signed sum)."""
    def corner(x, y):
        return np.sign(x) * np.sign(y) * rect_corner_E(L, abs(x), abs(y), h)

    return corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)


def disk_E(L, R, h):
    """On-axis irradiance under a Lambertian disk: E = π L R²/(R² + h²)."""
    return np.pi * L * R * R / (R * R + h * h)


def slab_T(cos_i, n):
    """Unpolarised transmittance of a clear non-absorbing plate, (1−r)/(1+r) per polarisation."""
    ci = cos_i
    ct = np.sqrt(1 - (1 - ci * ci) / n ** 2)
    rs = ((ci - n * ct) / (ci + n * ct)) ** 2
    rp = ((ct - n * ci) / (ct + n * ci)) ** 2
    return 0.5 * ((1 - rs) / (1 + rs) + (1 - rp) / (1 + rp))


def single_bounce_down_sensor(I, rho, lamp_h, sensor_h, half_size, n=1500):
    """Downward sensor on the axis of a point lamp over a Lambertian square floor.

    E_s = ∫ ρ/π · E_f(x, y) · cosθ_f cosθ_s / D² dA, E_f = I·h/dist³ (midpoint rule, mm→m).
    """
    c = (np.arange(n) + 0.5) / n * 2 * half_size - half_size
    x, y = np.meshgrid(c, c)
    r2 = (x * x + y * y) * 1e-6
    hl, hs = lamp_h * 1e-3, sensor_h * 1e-3
    Ef = I * hl / (hl * hl + r2) ** 1.5
    geo = hs * hs / (hs * hs + r2) ** 2
    dA = (2 * half_size * 1e-3 / n) ** 2
    return float((rho / np.pi * Ef * geo).sum() * dA)
