r"""
An opal plate's scattering medium as the bake draws it.

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
in total at normal incidence.  Mitsuba finds :math:`g` by bisecting its own Monte Carlo
measurement; here :math:`T` comes from the deterministic solution of the plane-parallel layer
(:mod:`lbscene.engine.light.opal_layer`: adding–doubling, the same layer the forward model
takes the plate's scattered light from), so the bake does not need Mitsuba.

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

from dataclasses import dataclass

import numpy as np

from lbscene.engine.light.opal_layer import G_MAX, absorption_depth, fit_asymmetry, slab_optics

__all__ = ["OpalSlabMedium", "opal_slab_medium", "G_MAX"]


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
