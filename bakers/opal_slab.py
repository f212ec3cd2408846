r"""
An opal plate as a plane-parallel scattering layer: adding–doubling, and the medium the bake draws.

The Cycles bake draws an opal (``lambertian``) diffuser plate as what it physically is, exactly
as the Mitsuba 3 truth does (:mod:`lbscene.engine.truth.mitsuba`): a slab of the declared
thickness whose faces are a smooth dielectric of the declared index :math:`n` (none when
:math:`n = 1`), filled with a homogeneous medium of extinction :math:`σ_t`, single-scattering
albedo :math:`ω` and a Henyey–Greenstein phase function of asymmetry :math:`g`,

.. math:: p(\cos Θ) = \frac{1}{4π}\,\frac{1 - g^2}{(1 + g^2 - 2 g \cos Θ)^{3/2}} .

Its datasheet gives the total normal transmittance :math:`T` and the diffuse fraction
:math:`f_d`.  The light that crosses unscattered falls as :math:`e^{-τ}`, so the optical depth
:math:`τ = σ_t\,d` follows from the regular part (:func:`~lbscene.engine.light.plates.opal_optical_depth`,
:math:`R_0 = ((n-1)/(n+1))^2`):

.. math:: (1 - f_d)\,T = \frac{(1 - R_0)^2 e^{-τ}}{1 - R_0^2 e^{-2τ}} ,

and :math:`g` is the one for which the non-absorbing (:math:`ω = 1`) plate transmits :math:`T`
in total at normal incidence (:func:`fit_asymmetry`).  Mitsuba finds :math:`g` by bisecting its
own Monte Carlo measurement; here :math:`T` comes from a deterministic solution of the
plane-parallel layer (:func:`slab_optics`), so the bake does not need Mitsuba.

Plane-parallel layer
--------------------
Only the azimuthal mean (Fourier mode 0) of the radiance enters the directional-hemispherical
:math:`T(θ)` and :math:`R(θ)`: the faces are azimuthally symmetric and the total flux integrates
the other modes out.  Directions inside the layer are discretised by :math:`μ = \cos θ` on
:math:`(0, 1]` (a composite Gauss–Radau rule with nodes at the breakpoints: :math:`μ = 1`, the
critical cosine :math:`μ_c = \sqrt{1 - 1/n^2}`, the refracted direction of the incidence: one
quadrature per incidence), weights
:math:`w_i`.  The mode-0 phase kernel, normalised to :math:`\tfrac12 \int_{-1}^{1} h\,dμ' = 1`,
is the Legendre series of the HG function (coefficients :math:`g^l`),

.. math:: h^{\pm}(μ_i, μ_j) = \sum_{l=0}^{L} (2l + 1)\,(\pm 1)^l g^l P_l(μ_i) P_l(μ_j)

(:math:`+`: both directions on the same side, transmission; :math:`-`: reflection), its
discrete columns renormalised so that a non-absorbing layer conserves flux exactly.  Operators
act on the flux carried by each direction bin (:math:`2π μ_j w_j L_j`).  A layer of optical depth
:math:`Δτ = τ / 2^k` (:math:`Δτ ≤ 10^{-7}`) scatters once:

.. math::
    T_{ij} = δ_{ij} e^{-Δτ/μ_j} + \frac{ω\,Δτ}{2 μ_j} w_i h^{+}_{ij}, \qquad
    R_{ij} = \frac{ω\,Δτ}{2 μ_j} w_i h^{-}_{ij},

and :math:`k` doublings of a symmetric layer give the whole one,

.. math:: C = (I - R R)^{-1}, \qquad R \leftarrow R + T C R T, \qquad T \leftarrow T C T .

The faces are diagonal: a bin reaching a face from inside leaves with :math:`1 - F(μ_i)` and is
reflected with the unpolarised Fresnel reflectance :math:`F(μ_i)` (1 beyond the critical angle);
light outside at :math:`θ` enters into the bin of its refracted direction with
:math:`1 - F`.  With :math:`D = \mathrm{diag}(F)`, the layer over its lower face and the slab
under its upper face are (adding)

.. math::
    u = (I - R D)^{-1} T\,y, \qquad y = (I - D R_b)^{-1} (1 - F_a) e_a, \qquad
    R_b = R + T D (I - R D)^{-1} T,

:math:`u` the flux reaching the lower face, :math:`y` the flux just under the upper one, so

.. math::
    T(θ) = \sum_i (1 - F_i)\,u_i, \qquad R(θ) = F_a + \sum_i (1 - F_i)\,(R_b\,y)_i .

A layer without scattering is the clear slab, :math:`T = (1 - R_0)/(1 + R_0)` at normal
incidence; a non-absorbing one has :math:`T + R = 1`.  ``tests/bakers/test_opal_slab.py`` holds
the solution to these, to a Monte Carlo simulation of the layer and to Mitsuba's measured plates
(``tests/data/validation/plate-optics/``).

A declared transmittance that varies with wavelength is drawn with the same scattering medium,
fitted at the band of highest transmittance, and an absorption coefficient per band
:math:`σ_a(λ)` that brings the plate's total normal transmittance down to :math:`T(λ)`
(:func:`opal_slab_medium`); the diffuse fraction then holds at that band only (absorption takes
more of the scattered light, which travels further, than of the regular part).

Examples
--------
The plate of the validation booth ``opal-cavity-45`` (total 0.60, diffuse fraction 0.92, 2.5 mm,
faces matched to the air):

>>> m = opal_slab_medium([0.60], 0.92, 1.0, 2.5)
>>> round(m.optical_depth, 3), round(m.anisotropy, 3)
(3.037, 0.552)
>>> round(float(slab_optics(m.optical_depth, m.anisotropy, 1.0, [1.0])[0][0]), 6)
0.6
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["OpalSlabMedium", "G_MAX", "fresnel_internal", "slab_optics", "fit_asymmetry",
           "absorption_depth", "opal_slab_medium", "scattered_transmittance_to_normal"]

#: the phase asymmetry is searched in [0, G_MAX] (as the Mitsuba truth's ``OPAL_G_MAX``)
G_MAX = 0.95
#: Gauss–Radau nodes per piece of the direction quadrature
NODES_PER_PIECE = 32
#: the doubling starts from a layer this thin (optical depth)
THIN_LAYER = 1e-7


@dataclass(frozen=True)
class OpalSlabMedium:
    """The medium of an opal slab: per-millimetre coefficients and the HG asymmetry.

    ``scattering_per_mm`` :math:`σ_s` (one value), ``absorption_per_mm`` :math:`σ_a` (one per
    declared band, zeros for a constant transmittance), ``anisotropy`` :math:`g`,
    ``optical_depth`` :math:`τ = σ_s d` of the scattering alone, ``thickness_mm`` :math:`d`,
    ``ior`` :math:`n` of the faces (1: none).
    """

    scattering_per_mm: float
    absorption_per_mm: tuple[float, ...]
    anisotropy: float
    optical_depth: float
    thickness_mm: float
    ior: float
    fit_band: int = 0


def fresnel_internal(mu, ior: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a face of index ``ior`` (outside: air) for light inside
    at cosine ``mu`` to the normal; 1 beyond the critical angle (the same value as for the light
    outside along the refracted direction)."""
    mu = np.clip(np.asarray(mu, float), 0.0, 1.0)
    n = float(ior)
    if n <= 1.0 + 1e-12:
        return np.zeros_like(mu)
    s2 = n * n * (1.0 - mu * mu)             # sin² of the outside direction
    c_out = np.sqrt(np.clip(1.0 - s2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = ((n * mu - c_out) / (n * mu + c_out)) ** 2
        rp = ((mu - n * c_out) / (mu + n * c_out)) ** 2
    return np.where((s2 >= 1.0) | (mu <= 0.0), 1.0, 0.5 * (rs + rp))


def _radau_right(a: float, b: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Radau nodes and weights on [a, b] with the right end b among the nodes."""
    c = np.zeros(n + 1)
    c[n - 1], c[n] = 1.0, 1.0                      # P_{n-1}(x) + P_n(x): roots with x = -1
    x = np.sort(np.polynomial.legendre.legroots(c).real)
    x = -x[::-1]                                   # mirror: x = +1 among them
    x[-1] = 1.0
    V = np.polynomial.legendre.legvander(x, n - 1).T
    w = np.linalg.solve(V, np.r_[2.0, np.zeros(n - 1)])
    return a + (b - a) * (x + 1.0) / 2.0, w * (b - a) / 2.0


@lru_cache(maxsize=64)
def _quadrature(breaks: tuple[float, ...], n: int) -> tuple[np.ndarray, np.ndarray]:
    mus, ws = [], []
    lo = 0.0
    for b in breaks:
        m, w = _radau_right(lo, b, n)
        mus.append(m)
        ws.append(w)
        lo = b
    return np.concatenate(mus), np.concatenate(ws)


def _breakpoints(ior: float, inner_mu) -> tuple[float, ...]:
    pts = {1.0}
    if ior > 1.0 + 1e-12:
        pts.add(math.sqrt(1.0 - 1.0 / ior ** 2))
    for m in inner_mu:
        pts.add(float(m))
    pts = sorted(p for p in pts if p > 1e-6)
    # merge breakpoints closer than 1e-4 (one node serves both)
    out = []
    for p in pts:
        if out and p - out[-1] < 1e-4:
            out[-1] = p
        else:
            out.append(p)
    return tuple(round(p, 12) for p in out)


@lru_cache(maxsize=256)
def _layer(tau: float, g: float, albedo: float, mu_key: tuple, w_key: tuple, L: int):
    """Flux operators (R, T) of a homogeneous layer (symmetric: the same from either side);
    phase series to degree ``L``."""
    mu = np.asarray(mu_key)
    w = np.asarray(w_key)
    N = len(mu)
    P = np.polynomial.legendre.legvander(mu, L).T             # (L+1, N): P_l(μ_i)
    l = np.arange(L + 1)
    coef = (2 * l + 1) * g ** l
    same = np.einsum("l,li,lj->ij", coef, P, P)
    back = np.einsum("l,li,lj->ij", coef * (-1.0) ** l, P, P)
    # renormalise each incident column: ½ Σ_i w_i (h⁺ + h⁻) = 1 (flux conservation)
    norm = 0.5 * (w @ same + w @ back)
    same, back = same / norm[None, :], back / norm[None, :]
    if tau <= 0.0:
        return np.zeros((N, N)), np.eye(N)
    k = max(0, int(math.ceil(math.log2(tau / THIN_LAYER))))
    dt = tau / 2 ** k
    s = albedo * dt / (2.0 * mu)[None, :] * w[:, None]
    T = np.diag(np.exp(-dt / mu)) + s * same
    R = s * back
    eye = np.eye(N)
    for _ in range(k):
        TC = T @ np.linalg.inv(eye - R @ R)
        R = R + TC @ R @ T
        T = TC @ T
    return R, T


def slab_optics(tau: float, g: float, ior: float, cos_theta, *, albedo: float = 1.0,
                nodes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Directional-hemispherical transmittance and reflectance of the slab (see the module's
    docstring) for light from outside at ``cos_theta``.

    Parameters
    ----------
    tau : float
        Optical depth :math:`σ_t d` of the medium (scattering and absorption).
    g : float
        Henyey–Greenstein asymmetry.
    ior : float
        Index of the faces (1: no interface).
    cos_theta : array_like
        Cosines of the incidence directions outside, in (0, 1].
    albedo : float
        Single-scattering albedo :math:`ω = σ_s / σ_t`.
    nodes : int, optional
        Gauss–Radau nodes per piece of the direction quadrature (default
        :data:`NODES_PER_PIECE`).

    Returns
    -------
    T, R : ndarray
        One value per incidence direction.
    """
    cos_theta = np.atleast_1d(np.asarray(cos_theta, float))
    n = float(ior)
    inner = np.sqrt(np.clip(1.0 - (1.0 - cos_theta ** 2) / n ** 2, 0.0, 1.0))
    if tau <= 0.0:
        # the clear slab (no scattering couples the bins: trapped light is never excited)
        F0 = fresnel_internal(inner, n)
        return (1.0 - F0) / (1.0 + F0), 2.0 * F0 / (1.0 + F0)
    k = NODES_PER_PIECE if nodes is None else int(nodes)
    Ts, Rs = [], []
    for c in inner:
        # one quadrature per incidence: its refracted direction is a node
        mu, w = _quadrature(_breakpoints(n, [c]), k)
        # each piece's Radau rule integrates degree 2k - 2 exactly: the phase series to that degree
        R, T = _layer(float(tau), float(g), float(albedo), tuple(mu), tuple(w), 2 * k - 2)
        F = fresnel_internal(mu, n)
        D = np.diag(F)
        eye = np.eye(len(mu))
        A = np.linalg.inv(eye - R @ D)
        Rb = R + T @ D @ A @ T
        a = int(np.argmin(np.abs(mu - c)))
        x0 = np.zeros(len(mu))
        x0[a] = 1.0 - F[a]
        y = np.linalg.solve(eye - D @ Rb, x0)
        u = A @ (T @ y)
        Ts.append(float((1.0 - F) @ u))
        Rs.append(float(F[a] + (1.0 - F) @ (Rb @ y)))
    return np.asarray(Ts), np.asarray(Rs)


def scattered_transmittance_to_normal(tau: float, g: float, *, albedo: float = 1.0,
                                      nodes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The bidirectional transmittance of the layer alone (no faces) into the normal.

    For a layer of optical depth ``tau`` and HG asymmetry ``g``: the scattered radiance leaving
    along the normal per irradiance arriving from direction :math:`μ_i` (sr⁻¹; the unscattered
    :math:`e^{-τ}` excluded), at the quadrature's nodes, from the flux operator
    :math:`T` of the module's docstring, :math:`f(μ_j → 1) = T_{1j} / (2π μ_1 w_1)`, :math:`μ_1 = 1`.

    Returns
    -------
    mu, f : ndarray
        The nodes :math:`μ_i` (increasing, 1 the last) and :math:`f(μ_i → 1)`.
    """
    k = NODES_PER_PIECE if nodes is None else int(nodes)
    mu, w = _quadrature((1.0,), k)
    _, T = _layer(float(tau), float(g), float(albedo), tuple(mu), tuple(w), 2 * k - 2)
    Td = T - np.diag(np.exp(-float(tau) / mu))
    return mu, Td[-1, :] / (2.0 * np.pi * mu[-1] * w[-1])


def fit_asymmetry(T: float, tau: float, ior: float) -> float:
    """The HG asymmetry :math:`g ∈ [0, G_\\text{max}]` for which the non-absorbing slab of optical
    depth ``tau`` transmits ``T`` in total at normal incidence (Brent's method on
    :func:`slab_optics`; the total rises with :math:`g`).  Raises ``ValueError`` when no
    :math:`g` in that range does."""
    from scipy.optimize import brentq

    def f(g):
        return float(slab_optics(tau, g, ior, [1.0])[0][0]) - T

    lo, hi = f(0.0), f(G_MAX)
    if not lo <= 0.0 <= hi:
        raise ValueError(f"a non-absorbing scattering layer of optical depth {tau:.3g} (ior {ior:g}) "
                         f"transmits {lo + T:.3f} to {hi + T:.3f} at normal incidence (HG asymmetry "
                         f"0 to {G_MAX:g}): the declared {T:.3f} is out of reach")
    return float(brentq(f, 0.0, G_MAX, xtol=1e-7))


def absorption_depth(T: float, tau_s: float, g: float, ior: float) -> float:
    """The absorption optical depth :math:`τ_a ≥ 0` that brings the slab of scattering depth
    ``tau_s`` and asymmetry ``g`` to the total normal transmittance ``T`` (Brent's method;
    albedo :math:`ω = τ_s / (τ_s + τ_a)`)."""
    from scipy.optimize import brentq

    def f(ta):
        t = tau_s + ta
        return float(slab_optics(t, g, ior, [1.0], albedo=tau_s / t if t > 0 else 1.0)[0][0]) - T

    if f(0.0) <= 0.0:
        return 0.0
    hi = 1.0
    while f(hi) > 0.0:
        hi *= 2.0
        if hi > 1e3:
            return hi
    return float(brentq(f, 0.0, hi, xtol=1e-9))


def opal_slab_medium(transmittance, diffuse_fraction: float, ior: float | None,
                     thickness_mm: float) -> OpalSlabMedium:
    """The opal plate's medium for the bake from its declaration.

    Parameters
    ----------
    transmittance : array_like
        Declared total normal transmittance per band (one value when constant).
    diffuse_fraction : float
        Declared :math:`f_d`, in (0, 1).
    ior : float or None
        Index of the faces (None or 1: faces matched to the air).
    thickness_mm : float
        Slab thickness :math:`d`.

    Returns
    -------
    OpalSlabMedium
        :math:`σ_s = τ/d` from the regular part of the band of highest transmittance, the
        :math:`g` that makes the non-absorbing slab transmit that band's total, and per band
        :math:`σ_a = τ_a / d` (:func:`absorption_depth`) for the others.

    Raises
    ------
    ValueError
        When no non-absorbing layer with :math:`g ∈ [0, G_\\text{max}]` has the declared total
        and diffuse fraction.
    """
    from lbscene.engine.light.plates import opal_optical_depth

    n = 1.0 if ior is None else float(ior)
    T = np.clip(np.atleast_1d(np.asarray(transmittance, float)), 0.0, 1.0)
    fd = float(diffuse_fraction)
    if not 0.0 < fd < 1.0:
        raise ValueError(f"an opal plate's diffuse fraction must lie in (0, 1) for its scattering "
                         f"medium (got {fd:g}): the regular part sets the optical depth")
    kmax = int(np.argmax(T))
    t_max = float(T[kmax])
    if t_max <= 0.0:
        raise ValueError("an opal plate that transmits nothing has no scattering medium")
    tau = opal_optical_depth((1.0 - fd) * t_max, n)
    g = fit_asymmetry(t_max, tau, n)
    cache: dict[float, float] = {}
    absorb = []
    for t in T:
        key = round(float(t), 9)
        if key not in cache:
            cache[key] = 0.0 if abs(t - t_max) < 1e-9 else absorption_depth(float(t), tau, g, n)
        absorb.append(cache[key] / thickness_mm)
    return OpalSlabMedium(scattering_per_mm=tau / thickness_mm,
                          absorption_per_mm=tuple(float(a) for a in absorb),
                          anisotropy=g, optical_depth=tau, thickness_mm=float(thickness_mm), ior=n,
                          fit_band=kmax)
