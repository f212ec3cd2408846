r"""
An opal plate's scattering layer as a plane-parallel slab: adding–doubling, every azimuth.

An opal (``lambertian``) diffuser plate is, physically, a slab of thickness :math:`d` whose faces
are a smooth dielectric of index :math:`n` (none when :math:`n = 1`), filled with a homogeneous
medium of extinction :math:`σ_t`, single-scattering albedo :math:`ω` and a Henyey–Greenstein
phase function of asymmetry :math:`g`,

.. math:: p(\cos Θ) = \frac{1}{4π}\,\frac{1 - g^2}{(1 + g^2 - 2 g \cos Θ)^{3/2}}
          = \frac{1}{4π} \sum_l (2l + 1)\,g^l P_l(\cos Θ) .

That is how the Mitsuba 3 truth (:mod:`lbscene.engine.truth.mitsuba`) and the Cycles bake
(``lbscene.bakers.opal_slab``) draw it.  A datasheet gives the plate's total normal
transmittance :math:`T` and diffuse fraction :math:`f_d`: the optical depth :math:`τ = σ_t d`
follows from the regular part (:func:`~lbscene.engine.light.plates.opal_optical_depth`) and
:math:`g` is the one for which the non-absorbing plate transmits :math:`T` in total
(:func:`fit_asymmetry`).  This module solves that layer deterministically; the forward model
takes from it the light the plate scatters from any incoming direction into any outgoing one
(:class:`OpalLayer`).

Azimuthal modes
---------------
With the addition theorem :math:`P_l(\cos Θ) = \sum_m (2 - δ_{m0}) Λ_{lm} P_l^m(μ) P_l^m(μ')
\cos m(φ - φ')`, :math:`Λ_{lm} = (l - m)!/(l + m)!`, the radiance of a layer lit by a beam at
azimuth :math:`φ_i` is :math:`L(μ, φ) = \sum_m L_m(μ) \cos m(φ - φ_i)` and each mode obeys a
plane-parallel equation of its own with the kernel

.. math:: h_m^{\pm}(μ_i, μ_j) = \sum_{l=m}^{L} (2l + 1)\,g^l Λ_{lm}\,
          P_l^m(\pm μ_i) P_l^m(μ_j)

(:math:`+`: both directions on the same side, transmission; :math:`-`: reflection).  Mode 0 alone
gives the directional-hemispherical :math:`T(θ)` and :math:`R(θ)`; its discrete columns are
renormalised so that a non-absorbing layer conserves flux exactly.  Directions inside the layer
are discretised by :math:`μ = \cos θ` on :math:`(0, 1]` (a composite Gauss–Radau rule with nodes
at the breakpoints: :math:`μ = 1`, the critical cosine :math:`μ_c = \sqrt{1 - 1/n^2}`, where asked
the refracted direction of an incidence), weights :math:`w_i`.  Operators act on the flux carried
by each direction bin (:math:`2π μ_j w_j L_j` in mode 0).  In a layer the fluxes travelling down,
:math:`u`, and up, :math:`v`, obey

.. math::
    \frac{du}{dτ} = -A u + B v, \qquad -\frac{dv}{dτ} = -A v + B u, \qquad
    A = \mathrm{diag}(1/μ) - S^{+}, \quad B = S^{-}, \quad
    S^{\pm}_{ij} = \frac{ω}{2 μ_j} w_i h^{\pm}_{ij} .

A thin layer of optical depth :math:`Δτ = τ / 2^k` (:math:`Δτ ≤` :data:`THIN_LAYER`, and at most
:data:`THIN_FRACTION` of :math:`τ`) is solved by the diamond (trapezoidal) rule over its depth
(Wiscombe 1976), with :math:`a = A\,Δτ/2`, :math:`b = B\,Δτ/2`, :math:`G = (I + a)^{-1}`:

.. math::
    T = (I + a - b G b)^{-1} (I - a + b G b), \qquad R = G\,b\,(I + T) .

Its error is third order in :math:`Δτ` per layer, and it keeps the net flux :math:`u - v` exactly
as the equations do (a non-absorbing layer conserves flux at every doubling).  The single-scattering
layer (:math:`T = \mathrm{diag}(e^{-Δτ/μ}) + Δτ S^{+}`, :math:`R = Δτ S^{-}`), first order, needed
:math:`Δτ = 10^{-7}` for errors of a few :math:`10^{-5}` and twice the doublings.

and :math:`k` doublings of a symmetric layer give the whole one,

.. math:: C = (I - R R)^{-1}, \qquad R \leftarrow R + T C R T, \qquad T \leftarrow T C T .

The faces are diagonal: a bin reaching a face from inside leaves with :math:`1 - F(μ_i)` and is
reflected with the unpolarised Fresnel reflectance :math:`F(μ_i)` (1 beyond the critical angle);
light outside at :math:`θ` enters into the bin of its refracted direction with
:math:`1 - F`.  With :math:`D = \mathrm{diag}(F)`, :math:`E = \mathrm{diag}(1 - F)` the layer
over its lower face and the slab under its upper face are (adding)

.. math::
    X = E\,(I - R D)^{-1} T\,(I - D R_b)^{-1} E, \qquad
    R_b = R + T D (I - R D)^{-1} T,

:math:`X_{ij}` the flux leaving the lower face in bin :math:`i` per unit flux arriving on the
upper one in bin :math:`j`; its mode-0 column sums are :math:`T(θ)`.  The unscattered light is
its diagonal part :math:`(1 - F)^2 e^{-τ/μ} / (1 - F^2 e^{-2τ/μ})` in every mode.  Outside, a bin
of width :math:`w_i` inside spans :math:`μ_o\,dμ_o = n^2 μ_i\,dμ_i`, so the scattered radiance
leaving toward :math:`(μ_o, φ_o)` per unit irradiance arriving from :math:`(μ_a, φ_a)` is

.. math:: f(μ_a, μ_o, Δφ) = \sum_m (2 - δ_{m0})\,
          \frac{X^{(m)}_{ia} - \text{unscattered}}{2π n^2 μ_i w_i}\,\cos m Δφ,
          \qquad Δφ = φ_o - φ_a

(:math:`φ` the azimuth the light travels toward: :math:`Δφ = 0` goes on the way it came).  Tests
(``tests/engine/test_opal_layer.py``): the clear slab, a purely absorbing layer, single
scattering, flux conservation, reciprocity :math:`f(μ_a, μ_o) = f(μ_o, μ_a)`, and a Monte Carlo
simulation of the layer in three dimensions that shares no code with this one; and
``tests/data/validation/plate-optics/`` holds Mitsuba's measured plates.

References
----------
W. J. Wiscombe, "On initialization, error and flux conservation in the doubling method",
*Journal of Quantitative Spectroscopy and Radiative Transfer* 16 (1976) 637–658.

Examples
--------
A non-absorbing layer of optical depth 3 with HG asymmetry 0.55, faces matched to the air:

>>> T, R = slab_optics(3.0, 0.55, 1.0, [1.0])
>>> round(float(T[0] + R[0]), 5)                       # no absorption: every photon leaves
1.0
>>> layer = opal_layer(3.0, 0.55, 1.0)
>>> round(float(layer.scattered_total(np.array([1.0]))[0] + np.exp(-3.0)), 6) == round(float(T[0]), 6)
True
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from lbscene.engine.files.parallel import blas_single_thread

__all__ = ["G_MAX", "NODES_PER_PIECE", "THIN_LAYER", "THIN_FRACTION", "fresnel_internal", "slab_optics",
           "fit_asymmetry", "absorption_depth",
           "scattered_transmittance_to_normal", "OpalLayer", "opal_layer", "opal_layer_at", "PHI_STEPS",
           "DEPTH_STEP", "ASYMMETRY_STEPS"]

#: the phase asymmetry is searched in [0, G_MAX] (as the Mitsuba truth's ``OPAL_G_MAX``)
G_MAX = 0.95
#: Gauss–Radau nodes per piece of the direction quadrature
NODES_PER_PIECE = 32
#: the doubling starts from a layer this thin (optical depth; diamond rule, module docstring) …
THIN_LAYER = 1e-3
#: … and no thicker than this fraction of the whole (a thin plate's grazing directions, where
#: :math:`Δτ/μ` is largest, weigh more in its light): within 1e-5 of the converged layer
THIN_FRACTION = 1e-2
#: azimuthal modes of :class:`OpalLayer` kept: those with :math:`g^m` above this (at most
#: :data:`MAX_MODES`; the phase series stops at degree :math:`2 × ` :data:`NODES_PER_PIECE` − 2)
MODE_TOLERANCE = 1e-4
MAX_MODES = 48
#: azimuth steps of the histograms :meth:`OpalLayer.histogram` bins incoming light into
PHI_STEPS = 128


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


@lru_cache(maxsize=512)
def _phase_kernels(g: float, mu_key: tuple, w_key: tuple, L: int, m: int):
    """The mode-``m`` kernels :math:`(h_m^+, h_m^-)` on the nodes (module docstring); mode 0's
    columns renormalised to conserve flux."""
    from scipy.special import gammaln, lpmv

    mu = np.asarray(mu_key)
    w = np.asarray(w_key)
    N = len(mu)
    if m > L:
        return np.zeros((N, N)), np.zeros((N, N))
    l = np.arange(m, L + 1)
    # P_l^m(μ) √Λ_lm: the normalisation keeps the products finite for large m
    P = lpmv(m, l[:, None], mu[None, :]) * np.exp(0.5 * (gammaln(l - m + 1) - gammaln(l + m + 1)))[:, None]
    coef = (2 * l + 1) * g ** l
    same = np.einsum("l,li,lj->ij", coef, P, P)
    # P_l^m(−μ) = (−1)^(l+m) P_l^m(μ)
    back = np.einsum("l,li,lj->ij", coef * (-1.0) ** (l + m), P, P)
    if m == 0:
        # renormalise each incident column: ½ Σ_i w_i (h⁺ + h⁻) = 1 (flux conservation)
        norm = 0.5 * (w @ same + w @ back)
        same, back = same / norm[None, :], back / norm[None, :]
    return same, back


@lru_cache(maxsize=512)
def _layer(tau: float, g: float, albedo: float, mu_key: tuple, w_key: tuple, L: int, m: int = 0):
    """Flux operators (R, T) of a homogeneous layer (symmetric: the same from either side) in
    azimuthal mode ``m``; phase series to degree ``L``."""
    R, T = _layers(tau, g, albedo, mu_key, w_key, L, (int(m),))
    return R[0], T[0]


def _layers(tau: float, g: float, albedo: float, mu_key: tuple, w_key: tuple, L: int, modes: tuple):
    """:func:`_layer` for several modes at once, ``(len(modes), N, N)`` each: one doubling of
    the stacked operators (a layer's modes share its depth and steps)."""
    mu = np.asarray(mu_key)
    w = np.asarray(w_key)
    N = len(mu)
    if tau <= 0.0:
        return np.zeros((len(modes), N, N)), np.broadcast_to(np.eye(N), (len(modes), N, N)).copy()
    kern = [_phase_kernels(float(g), mu_key, w_key, int(L), int(m)) for m in modes]
    same = np.stack([k[0] for k in kern])
    back = np.stack([k[1] for k in kern])
    k = max(0, int(math.ceil(math.log2(tau / min(THIN_LAYER, THIN_FRACTION * tau)))))
    dt = tau / 2 ** k
    eye = np.eye(N)
    # the thin layer by the diamond rule (module docstring): a = A Δτ/2, b = B Δτ/2
    s = (albedo * dt / (4.0 * mu)[None, :] * w[:, None])[None]
    a = np.diag(dt / (2.0 * mu))[None] - s * same
    b = s * back
    G = np.linalg.inv(eye + a)
    bGb = b @ G @ b
    T = np.linalg.solve(eye + a - bGb, eye - a + bGb)
    R = G @ b @ (eye + T)
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
        with blas_single_thread():
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
    return _fit_asymmetry(round(float(T), 12), round(float(tau), 12), round(float(ior), 12))


@lru_cache(maxsize=256)
def _fit_asymmetry(T: float, tau: float, ior: float) -> float:
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


class OpalLayer:
    """The scattered light of a non-absorbing opal layer between two faces, every direction.

    Built from the layer's optical depth ``tau``, HG asymmetry ``g`` and the faces' index
    ``ior`` (use :func:`opal_layer`, which keeps one per set).  Attributes:

    * ``cos_nodes`` (N,): cosines outside the plate of the quadrature's nodes that light can
      cross a face along (increasing, from grazing to the normal);
    * ``kernel`` (M + 1, N, N): per azimuthal mode :math:`m`, :math:`f_m(μ_a → μ_o)` at
      ``[m, o, a]`` (sr⁻¹, per unit irradiance arriving; module docstring), the unscattered
      light excluded;
    * ``modes``: :math:`M`, those with :math:`g^m ≥` :data:`MODE_TOLERANCE` (at most
      :data:`MAX_MODES`).

    Between nodes every quantity is linear in the cosines.  Light arriving from outside is
    binned once per plate cell into a histogram over (node, azimuth) (:meth:`histogram`) that
    does not depend on the layer, so a fit that varies the plate only re-applies the kernel
    (:meth:`exit_modes`, :meth:`radiance_at`).
    """

    def __init__(self, tau: float, g: float, ior: float):
        self.tau, self.g, self.ior = float(tau), float(g), float(ior)
        n = self.ior
        k = NODES_PER_PIECE
        self._L = 2 * k - 2
        mu, w = _quadrature(_breakpoints(n, []), k)
        F = fresnel_internal(mu, n)
        crossing = F < 1.0
        if n > 1.0 + 1e-12:                    # the critical direction: the outside's grazing node
            crossing |= np.isclose(mu, math.sqrt(1.0 - 1.0 / n ** 2), atol=1e-12)
        self._sel = np.nonzero(crossing)[0]
        self.cos_nodes = np.sqrt(np.clip(1.0 - n * n * (1.0 - mu[self._sel] ** 2), 0.0, 1.0))
        if self.g <= 0.0:
            M = 0
        else:
            M = int(math.ceil(math.log(MODE_TOLERANCE) / math.log(min(self.g, 0.999999))))
        self.modes = int(min(max(M, 0), MAX_MODES, self._L))
        self._mu, self._w, self._F = mu, w, F
        e = np.exp(-self.tau / mu)
        E = 1.0 - F
        self._unscattered = np.diag(E * E * e / (1.0 - F * F * e * e))
        self._kernels: dict[int, np.ndarray] = {}
        self._parts = None
        # the scattered total per incidence node: the mode-0 exit flux
        flux = (2.0 * np.pi * n * n * mu * w)[self._sel]
        self._scattered_nodes = flux @ self._mode(0)

    def _mode(self, m: int) -> np.ndarray:
        """:math:`f_m(μ_a → μ_o)` at ``[o, a]`` on :attr:`cos_nodes` (computed once)."""
        K = self._kernels.get(m)
        if K is None and self._parts is not None:          # a mixture (:meth:`mixture`): its parts' modes
            K = sum(w * x._mode(m) for x, w in self._parts if m <= x.modes)
            K = self._kernels[m] = K if isinstance(K, np.ndarray) else np.zeros_like(self._parts[0][0]._mode(0))
        if K is None:
            self._solve_modes(range(m, m + 1))
            K = self._kernels[m]
        return K

    def _solve_modes(self, modes) -> None:
        """Solve the modes ``modes`` not solved yet, all at once (:func:`_layers`)."""
        todo = tuple(m for m in modes if m not in self._kernels)
        if not todo:
            return
        if self._parts is not None:
            for x, _ in self._parts:
                x._solve_modes([m for m in todo if m <= x.modes])
            for m in todo:
                self._mode(m)
            return
        mu, w, F, n = self._mu, self._w, self._F, self.ior
        with blas_single_thread():
            R, T = _layers(self.tau, self.g, 1.0, tuple(mu), tuple(w), self._L, todo)
            D = np.diag(F)
            E = 1.0 - F
            eye = np.eye(len(mu))
            A = np.linalg.inv(eye - R @ D)
            Rb = R + T @ D @ A @ T
            X = E[:, None] * (A @ T @ np.linalg.inv(eye - D @ Rb)) * E[None, :]
        to_radiance = 1.0 / (2.0 * np.pi * n * n * mu * w)
        K = ((X - self._unscattered) * to_radiance[:, None])[:, self._sel][:, :, self._sel]
        for k, m in enumerate(todo):
            self._kernels[m] = K[k]

    @property
    def kernel(self) -> np.ndarray:
        """``(M + 1, N, N)``: every mode's :math:`f_m` (class docstring)."""
        self._solve_modes(range(self.modes + 1))
        return np.asarray([self._mode(m) for m in range(self.modes + 1)])

    @classmethod
    def mixture(cls, parts) -> "OpalLayer":
        """The layer whose every mode's kernel and scattered totals are :math:`\\sum_k w_k`
        times those of the layers of ``parts`` (``[(layer, w_k), …]``, same faces; weights
        summing to 1, some negative for a cubic interpolation).  A fit that moves the plate's
        optical depth or total reads its law between layers solved on a grid of both
        (:func:`opal_layer_at`): continuous in them, and a new solution only when the fit leaves
        their cell.  A mode is mixed when first asked for (the totals need mode 0 only)."""
        parts = [(x, float(w)) for x, w in parts if w != 0.0]
        if not parts:
            raise ValueError("a mixture needs a layer of non-zero weight")
        a = parts[0][0]
        if any(x.ior != a.ior for x, _ in parts):
            raise ValueError("layers with other faces cannot be blended")
        out = cls.__new__(cls)
        out.tau = sum(w * x.tau for x, w in parts)
        out.g = sum(w * x.g for x, w in parts)
        out.ior, out.cos_nodes, out._L = a.ior, a.cos_nodes, a._L
        out._mu, out._w, out._F, out._sel = a._mu, a._w, a._F, a._sel
        out.modes = max(x.modes for x, _ in parts)
        out._kernels = {}
        out._parts = parts
        out._scattered_nodes = sum(w * x._scattered_nodes for x, w in parts)
        out._unscattered = None
        return out

    # ------------------------------------------------------------------ per direction
    def _split(self, cos):
        """Node below each cosine and the linear weight toward the one above."""
        c = np.clip(np.asarray(cos, float), self.cos_nodes[0], self.cos_nodes[-1])
        j = np.clip(np.searchsorted(self.cos_nodes, c, side="right") - 1, 0, len(self.cos_nodes) - 2)
        f = (c - self.cos_nodes[j]) / (self.cos_nodes[j + 1] - self.cos_nodes[j])
        return j, np.clip(f, 0.0, 1.0)

    def scattered_total(self, cos_i) -> np.ndarray:
        """The part of the light arriving at ``cos_i`` that leaves the far face scattered (the
        unscattered light excluded)."""
        j, f = self._split(cos_i)
        return (1.0 - f) * self._scattered_nodes[j] + f * self._scattered_nodes[j + 1]

    def entry_relative(self, cos_i) -> np.ndarray:
        """:func:`scattered_total` relative to normal incidence, :math:`t(θ_i) = T_s(θ_i)/T_s(0)`;
        by reciprocity also the shape of the scattered radiance leaving under diffuse light,
        :math:`L(θ_o) ∝ t(θ_o)`."""
        return self.scattered_total(cos_i) / max(float(self._scattered_nodes[-1]), 1e-300)

    def exit_shape(self, cos_o) -> np.ndarray:
        """The scattered radiance leaving at ``cos_o`` under diffuse (Lambertian) light arriving,
        relative to a Lambertian emitter of the same exitance: :math:`t(θ_o)/t_h`,
        :math:`t_h = 2\\int_0^1 t(μ)\\,μ\\,dμ` (reciprocity: the light leaving toward
        :math:`θ_o` is the light that would arrive from there and get through)."""
        return self.entry_relative(cos_o) / self._entry_hemispherical()

    def _entry_hemispherical(self) -> float:
        h = getattr(self, "_th", None)
        if h is None:
            x, w = np.polynomial.legendre.leggauss(64)
            mu = 0.5 * (x + 1.0)
            h = self._th = float(np.sum(w * mu * self.entry_relative(mu)))
        return h

    def btdf(self, cos_i, cos_o, dphi_rad) -> np.ndarray:
        """:math:`f(μ_i, μ_o, Δφ)` (sr⁻¹; module docstring), broadcast over the arguments."""
        ji, fi = self._split(cos_i)
        jo, fo = self._split(cos_o)
        out = 0.0
        for m in range(self.modes + 1):
            Km = self._mode(m)
            v = ((1 - fo) * ((1 - fi) * Km[jo, ji] + fi * Km[jo, ji + 1])
                 + fo * ((1 - fi) * Km[jo + 1, ji] + fi * Km[jo + 1, ji + 1]))
            out = out + (1.0 if m == 0 else 2.0) * v * np.cos(m * np.asarray(dphi_rad, float))
        return out

    # ------------------------------------------------------------------ many arriving directions
    def histogram(self, cos_i, phi_i_rad, weights, n_phi: int = PHI_STEPS) -> np.ndarray:
        """``(C, N, n_phi)``: per group ``c`` (a plate cell) the weights of light arriving from
        directions ``(cos_i, phi_i_rad)`` (C, P) (``phi``: the azimuth it travels toward), split
        linearly between the two nearest nodes and the two nearest of ``n_phi`` azimuths
        :math:`φ_b = -π + 2πb/n_φ`."""
        from .rough_slab import _azimuth_split

        w = np.asarray(weights, float)
        C, P = w.shape
        N = len(self.cos_nodes)
        if P == 0 or C == 0:
            return np.zeros((C, N, n_phi))
        j, f = self._split(cos_i)
        b0, b1, fr = _azimuth_split(phi_i_rad, n_phi)
        row = np.arange(C)[:, None] * (N * n_phi)
        H = np.zeros(C * N * n_phi)
        for jj, wj in ((j, 1.0 - f), (j + 1, f)):
            for bb, wb in ((b0, 1.0 - fr), (b1, fr)):
                H += np.bincount((row + jj * n_phi + bb).ravel(), (w * wj * wb).ravel(), minlength=H.size)
        return H.reshape(C, N, n_phi)

    @staticmethod
    def histogram_modes(hist, modes: int) -> np.ndarray:
        """``(C, N, modes + 1, …)`` complex: the Fourier coefficients
        :math:`B_{m,a} = \\sum_p w_p e^{-i m φ_p}` of a :meth:`histogram` ``(C, N, n_φ, …)`` (any
        trailing axes after its azimuth), corrected for its linear azimuth split (a triangle
        one step wide on either side: :math:`\\mathrm{sinc}^2(m π / n_φ)`)."""
        H = np.asarray(hist, float)
        n_phi = H.shape[2]
        if modes >= n_phi // 2:
            raise ValueError(f"{n_phi} azimuth steps cannot hold {modes} modes")
        Hf = np.fft.rfft(H, axis=2)[:, :, :modes + 1]
        m = np.arange(modes + 1)
        x = m * np.pi / n_phi
        hat = (np.sin(x) / np.where(m == 0, 1.0, x)) ** 2
        hat[0] = 1.0
        # φ_b = −π + 2πb/n_φ: Σ_b H_b e^{−imφ_b} = (−1)^m rfft(H)_m
        corr = ((-1.0) ** m / hat).reshape((1, 1, modes + 1) + (1,) * (H.ndim - 3))
        return Hf * corr

    def exit_modes(self, coef, modes: int | None = None) -> np.ndarray:
        """``(C, M + 1, N, …)`` complex: per group the scattered radiance leaving toward each
        node's cosine in each azimuthal mode, :math:`G_m(μ_o) = \\sum_a f_m(μ_a → μ_o) B_{m,a}`,
        from the arriving light's coefficients ``coef`` (:meth:`histogram_modes`, at least
        :math:`M` + 1 of them); :math:`M` = :attr:`modes`, or ``modes`` where fewer (a coarser
        azimuthal law: the series cut there)."""
        M = self.modes if modes is None else max(0, min(int(modes), self.modes))
        B = np.asarray(coef)[:, :, :M + 1]
        self._solve_modes(range(M + 1))
        K = np.asarray([self._mode(m) for m in range(M + 1)])
        return np.einsum("moa,cam...->cmo...", K, B)

    def radiance_at(self, modes, cos_o, phi_o_rad) -> np.ndarray:
        """``(C, R, …)``: the radiance of :meth:`exit_modes` ``(C, M + 1, N, …)`` toward ``R``
        directions per group ``(cos_o, phi_o_rad)`` (C, R): linear in the cosine between nodes,
        :math:`\\sum_m (2 - δ_{m0})\\,\\mathrm{Re}(G_m e^{i m φ_o})`, the series summed by
        Horner's rule in :math:`z = e^{i φ_o}` (one complex exponential per direction instead of a
        cosine and a sine per mode)."""
        G = np.asarray(modes)
        C, M1, N = G.shape[:3]
        trail = G.shape[3:]
        nt = int(np.prod(trail, dtype=int))
        jo, fo = self._split(cos_o)                                           # (C, R)
        # each node's modes side by side: one gather per direction reads them all
        Gn = np.ascontiguousarray(np.moveaxis(G, 1, 2)).reshape(C * N, M1, nt)
        idx = (np.arange(C)[:, None] * N + jo).ravel()
        w = fo.reshape(-1, 1, 1)
        z1 = np.exp(1j * np.asarray(phi_o_rad, float)).reshape(-1, 1)
        out = np.empty((idx.size, nt))
        # directions a block at a time: a block's (n, M + 1, …) modes stay in the cache
        step = max(256, RADIANCE_BLOCK // max(M1 * nt, 1))
        for a in range(0, idx.size, step):
            i = idx[a:a + step]
            g = Gn[i] * (1.0 - w[a:a + step]) + Gn[i + 1] * w[a:a + step]      # (n, M + 1, …)
            v = g[:, 0].real
            if M1 > 1:
                z = z1[a:a + step]
                acc = g[:, M1 - 1]
                for m in range(M1 - 2, 0, -1):
                    acc = acc * z + g[:, m]
                v = v + 2.0 * (acc * z).real
            out[a:a + step] = v
        return out.reshape(jo.shape + trail)


#: complex mode values per block of :meth:`OpalLayer.radiance_at` (its blocks of directions stay
#: in the processor's cache: 54 cells × 21852 directions × 13 modes, 1.0 → 0.2 s)
RADIANCE_BLOCK = 65536


#: the optical depths :func:`opal_layer_at` solves the layer at: a geometric grid of this ratio
#: (linear in :math:`\\ln τ` between two, within 1e-4 of the layer solved between them; a cubic
#: over four a ratio 1.1 apart is within 2e-5, but a fit crossing the plate's depths then solves
#: twice the layers: 2.5 times the time)
DEPTH_STEP = 1.02
#: and the asymmetries: this many steps, even in :math:`x = -\\ln(1 - g)` from 0 to
#: :data:`G_MAX` (finer where the forward peak sharpens); a cubic between four of them is within
#: 3e-5 of the layer solved between them, and a linear blend of totals a step of 0.01 apart was
#: within 6e-3 at high asymmetry (and coarser than the whole reachable range of a thin layer)
ASYMMETRY_STEPS = 32


def opal_layer_at(tau: float, T: float, ior: float) -> OpalLayer:
    """The non-absorbing layer of optical depth ``tau`` that transmits ``T`` in total at normal
    incidence, faces ``ior``: a :meth:`~OpalLayer.mixture` of the layers solved on a grid.

    Linear in :math:`\\ln τ` between the two depths of a grid of ratio :data:`DEPTH_STEP`
    around ``tau``; at each, cubic (Lagrange, four nodes) in :math:`x = -\\ln(1 - g)` on a grid
    of :data:`ASYMMETRY_STEPS` steps, at the :math:`x` where the cubic through the nodes' totals at
    normal incidence is ``T`` (the non-absorbing layer's total rises with :math:`g`).  The
    mixture transmits ``T`` exactly; a total out of reach of every :math:`g` in
    :math:`[0, G_\\text{max}]` (a plate that absorbs, or a very thin one) takes the nearer end.
    The light a layer scatters changes by up to 1.6 % for 1 % in its depth, and steeply with
    its total: a fit moving either (a fitted diffuse fraction, a fitted transmittance) needs the
    law continuous, and solving it at every step (0.2 to 0.7 s) would dominate the fit.

    Examples
    --------
    Between the grid's depths and asymmetries, the scattered total at normal incidence of the
    layer solved at its own asymmetry:

    >>> one = np.array([1.0])
    >>> mixed = opal_layer_at(2.0, 0.615, 1.49).scattered_total(one)[0]
    >>> solved = opal_layer(2.0, fit_asymmetry(0.615, 2.0, 1.49), 1.49).scattered_total(one)[0]
    >>> abs(float(mixed / solved) - 1.0) < 1e-4
    True
    """
    return _layer_at(round(float(tau), 12), round(float(T), 9), round(float(ior), 9))


_X_MAX = -math.log(1.0 - G_MAX)


def _node_g(j: int) -> float:
    return G_MAX if j >= ASYMMETRY_STEPS else 1.0 - math.exp(-_X_MAX * j / ASYMMETRY_STEPS)


@lru_cache(maxsize=4096)
def _node_total(i: int, j: int, ior: float) -> float:
    """Total normal transmittance of the grid's layer at depth ``i``, asymmetry ``j``."""
    return float(slab_optics(DEPTH_STEP ** i, _node_g(j), ior, [1.0])[0][0])


def _lagrange(t: float) -> np.ndarray:
    """Weights of the cubic through nodes at −1, 0, 1, 2 (steps) at ``t``."""
    return np.array([-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2,
                     -(t + 1) * t * (t - 2) / 2, (t + 1) * t * (t - 1) / 6])


def _asymmetry_weights(i: int, T: float, ior: float) -> list[tuple[int, float]]:
    """``[(j, w_j)]``: the asymmetry nodes at depth ``i`` and their weights for the total ``T``."""
    S = ASYMMETRY_STEPS
    if T <= _node_total(i, 0, ior):
        return [(0, 1.0)]
    if T >= _node_total(i, S, ior):
        return [(S, 1.0)]
    lo, hi = 0, S                                   # T(lo) < T ≤ T(hi): bisect to one step
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if _node_total(i, mid, ior) < T else (lo, mid)
    k0 = min(max(lo - 1, 0), S - 3)                 # the four nodes around the step
    Tk = np.array([_node_total(i, k0 + k, ior) for k in range(4)])
    a, b = lo - k0 - 1, lo - k0                     # the step, in the cubic's offsets

    def f(t):
        return float(_lagrange(t) @ Tk) - T

    from scipy.optimize import brentq

    t = float(brentq(f, a, b, xtol=1e-12)) if f(a) * f(b) < 0 else (a if abs(f(a)) < abs(f(b)) else b)
    return [(k0 + k, float(w)) for k, w in enumerate(_lagrange(t))]


@lru_cache(maxsize=64)
def _layer_at(tau: float, T: float, n: float) -> OpalLayer:
    u = round(math.log(max(tau, 1e-300)) / math.log(DEPTH_STEP), 9)
    i0 = math.floor(u)
    t = u - i0
    depths = [(i0, 1.0)] if t < 1e-9 else [(i0, 1.0 - t), (i0 + 1, t)]
    parts = [(_grid_layer(i, j, n), wi * wj) for i, wi in depths for j, wj in _asymmetry_weights(i, T, n)]
    parts = [(x, w) for x, w in parts if abs(w) > 1e-15]
    return parts[0][0] if len(parts) == 1 and parts[0][1] == 1.0 else OpalLayer.mixture(parts)


def _grid_layer(i: int, j: int, ior: float) -> OpalLayer:
    return _opal_layer(round(DEPTH_STEP ** i, 12), round(_node_g(j), 12), ior)


@lru_cache(maxsize=160)
def _opal_layer(tau: float, g: float, ior: float) -> OpalLayer:
    return OpalLayer(tau, g, ior)


def opal_layer(tau: float, g: float, ior: float) -> OpalLayer:
    """The :class:`OpalLayer` of optical depth ``tau``, asymmetry ``g`` and faces ``ior``, one per
    set of values (rounded to 1e-9)."""
    return _opal_layer(round(float(tau), 9), round(float(g), 9), round(float(ior), 9))
