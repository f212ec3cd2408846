"""
Optics of a clear-coated effect layer: measurement directions, refraction at the clear coat
and Fresnel transmittance.

Sample frame: the sample normal is +z; the measurement plane is x–z, with the light on the −x
side.  A geometry ``<illumination>as<aspecular>`` (DIN 6175-2 / ASTM E2194 naming) puts the
light at polar angle :math:`θ_i` and the viewer at the signed polar angle
:math:`θ_v = θ_i − θ_{as}` (positive: on the far side from the light), so

.. math::

    \\mathbf l = (−\\sin θ_i, 0, \\cos θ_i), \\qquad \\mathbf v = (\\sin θ_v, 0, \\cos θ_v).

Inside a clear coat of refractive index :math:`n`, a direction of polar angle θ becomes
:math:`θ' = \\arcsin(\\sin θ / n)` with the same azimuth (Snell's law), solid angles shrink by
:math:`dω' = dω \\cos θ / (n^2 \\cos θ')`, and radiance crossing the interface gains
:math:`n^2` and loses the Fresnel reflectance, so a layer below the coat with BRDF
:math:`f'` is seen from the air as (single pass, no inter-reflection under the coat)

.. math::

    f(\\mathbf l, \\mathbf v) = \\frac{T(θ_l)\\, T(θ_v)}{n^2}\\, f'(\\mathbf l', \\mathbf v').

References
----------
.. [1] M. Born, E. Wolf, *Principles of Optics*, §1.5 (Fresnel equations).
.. [2] E. Kirchner, W. Cramer, "Making sense of measurement geometries for multi-angle
   spectrophotometers", Color Research & Application 37 (2012): effect-coating
   reflectance is a function of the angles *inside* the clear coat.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "BYK_ASPECULAR_DEG",
    "BYK_ILLUMINATION_DEG",
    "geometry_directions",
    "refract_into_coat",
    "fresnel_transmittance",
    "diffuse_transmittance",
    "half_vector",
]

#: The six aspecular angles of a BYK-mac i (and of the byko-spectra effect booth), degrees.
BYK_ASPECULAR_DEG = (-15.0, 15.0, 25.0, 45.0, 75.0, 110.0)
#: Their illumination angle, degrees from the normal.
BYK_ILLUMINATION_DEG = 45.0


def geometry_directions(illumination_deg, aspecular_deg) -> tuple[np.ndarray, np.ndarray]:
    """Unit light and view directions (…, 3) in the sample frame of in-plane geometries.

    >>> l, v = geometry_directions(45.0, 45.0)
    >>> np.round(v, 12).tolist()
    [0.0, 0.0, 1.0]
    """
    ti = np.radians(np.asarray(illumination_deg, float))
    tv = ti - np.radians(np.asarray(aspecular_deg, float))
    ti, tv = np.broadcast_arrays(ti, tv)
    z = np.zeros_like(ti)
    return (np.stack([-np.sin(ti), z, np.cos(ti)], -1), np.stack([np.sin(tv), z, np.cos(tv)], -1))


def refract_into_coat(d: np.ndarray, n: float) -> np.ndarray:
    """Direction (…, 3) above the surface (z > 0, pointing away from it) → the direction inside
    a coat of index ``n`` that leaves along it: same azimuth, :math:`\\sin θ' = \\sin θ / n`."""
    d = np.asarray(d, float)
    t = d[..., :2] / n
    z = np.sqrt(np.clip(1.0 - (t * t).sum(-1), 0.0, None))
    return np.concatenate([t, z[..., None]], -1)


def fresnel_transmittance(cos_theta, n: float) -> np.ndarray:
    """Unpolarised Fresnel transmittance 1 − R of the air → coat interface at incidence
    :math:`θ` (cosine given, measured in air).

    >>> round(float(fresnel_transmittance(1.0, 1.5)), 6)    # 1 − ((n − 1)/(n + 1))²
    0.96
    """
    ci = np.clip(np.asarray(cos_theta, float), 0.0, 1.0)
    si2 = 1.0 - ci * ci
    ct = np.sqrt(np.clip(1.0 - si2 / (n * n), 0.0, None))
    rs = (ci - n * ct) / np.maximum(ci + n * ct, 1e-300)
    rp = (n * ci - ct) / np.maximum(n * ci + ct, 1e-300)
    return 1.0 - 0.5 * (rs * rs + rp * rp)


def diffuse_transmittance(n: float, samples: int = 2048) -> float:
    """Transmittance of the interface for uniform diffuse light from the air,
    :math:`2\\int_0^{π/2} T(θ) \\cos θ \\sin θ\\, dθ` (n = 1.5: 0.908)."""
    mu = (np.arange(samples) + 0.5) / samples          # cos θ, midpoint rule in μ²
    w = 2.0 * mu / samples
    return float((fresnel_transmittance(mu, n) * w).sum())


def half_vector(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normalised a + b along the last axis."""
    h = np.asarray(a, float) + np.asarray(b, float)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)
