"""
Mitsuba 3 as an independent truth: the compiled booth rendered by a spectral path tracer.

The forward model, the Monte Carlo :mod:`~lbscene.engine.truth.reference` engine
and the Cycles bake all start from lbscene's own lamp and transport code; a test
that compares two of them can pass while both share one wrong assumption.  This
provider hands the *declared physics* of a :class:`~lbscene.engine.scene.ir.SceneIR` to
Mitsuba 3 (``scalar_spectral`` variant, ``path`` integrator, unbounded depth with
Russian roulette) and measures illuminance there.

What the booth becomes
----------------------
===================  ==========================================================
booth element        Mitsuba 3
===================  ==========================================================
interior surfaces    triangle meshes, ``twosided`` ``diffuse`` with the material's
                     1 nm reflectance (black when ``interreflection`` is off)
tube                 ``cylinder`` (open, no end caps) with an ``area`` emitter of
                     radiance :math:`L(λ) = I(λ) / (2 r ℓ)`
panel                ``rectangle`` (length along ``axis`` × width along
                     ``aim × axis``) emitting toward ``aim``, :math:`L = I / (ℓ w)`
bulb                 ``sphere``, :math:`L = I / (π r^2)`
point                ``point`` emitter of intensity :math:`I(λ)`
lamp bodies          tube, panel and bulb shapes are black (absorbing), as in the
                     forward model; a lamp that is off stays as a black body;
                     under ``volpath`` the emitting shape is ``null`` with the
                     black body :data:`LAMP_BODY_INSET_MM` inside it (below)
occluders            black (or declared-material) ``twosided`` rectangles; an
                     aperture plate is the frame around its opening
                     (``aperture_occlusion`` on)
mirror (reflector)   a one-sided ``rectangle`` (the lamp's mirror:
                     facing ``normal``, ``distance_mm`` behind the lamp,
                     ``width_mm`` across its axis) of ``conductor``
                     ``material: none`` whose ``specular_reflectance``
                     is the declared reflectance (``reflector`` on;
                     plane mirrors, and prisms as their two facets);
                     its back absorbs
diffuser plate       a closed box of ``roughdielectric`` (GGX,
                     :math:`α = \\text{roughness}^2` as in Blender's Glass BSDF,
                     the declared ``ior`` and ``thickness_mm``; mid-plane at
                     ``z_mm``) (``diffuser`` on)
opal plate           a closed box of smooth ``dielectric`` (declared ``ior``,
                     ``thickness_mm``; ``null`` for ior 1) filled with a
                     non-absorbing ``homogeneous`` medium (Henyey–Greenstein
                     phase), rendered with ``volpath`` (``diffuser`` on;
                     scattering ``lambertian``)
===================  ==========================================================

:math:`I(λ)` is the lamp's peak spectral intensity from the IR
(``intensity_scale_W_sr_nm × spd``, times its dimming level and its filter when
``spectral_filter`` is on), perpendicular to a tube's axis and along a panel's
normal; lengths in metres in these formulas.  Scene coordinates stay in
millimetres: radiance-driven emitters do not depend on the length unit, the
point emitter's intensity is multiplied by 10⁶ (mm² → m²).

A declared diffuser transmittance is the plate's *total* transmittance at normal
incidence, as a datasheet gives it.  The rough plate's own transmittance without
absorption :math:`T_\\text{mi}` is measured here, in Mitsuba
(:func:`plate_optics`), and the rest is bulk absorption, a factor
:math:`\\sqrt{T/T_\\text{mi}}` on each refraction (``specular_transmittance``); a
transmittance above :math:`T_\\text{mi}` is refused (no such slab transmits it).

An opal plate is built from what its datasheet gives: the total normal
transmittance :math:`T` (constant over wavelength) and the diffuse fraction
:math:`f_d`.  The unscattered light crosses the medium with
:math:`e^{-τ}`, so the optical depth follows from the regular part,
:math:`(1-f_d)\\,T = (1-R_0)^2 e^{-τ} / (1 - R_0^2 e^{-2τ})`; the phase function's
asymmetry :math:`g` is then found (bisection on Mitsuba's own :func:`plate_optics`)
so that the non-absorbing plate transmits :math:`T` in total.

:func:`plate_optics` measures a plate by reciprocity: a radiance meter looks at
the (infinitely wide) plate from direction :math:`θ` under a uniform sky of
radiance 1 above it, a black ground below; what it sees through the plate is
the directional-hemispherical transmittance :math:`T(θ)`, what it sees reflected
from above the reflectance :math:`R(θ)`.

Measurement
-----------
Each receiver (point :math:`p`, unit normal :math:`n`) is a disc of radius
``DISC_RADIUS_MM`` with a white Lambertian BSDF at :math:`p + δ n`, seen by a
``radiancemeter`` just above it looking along :math:`-n`.  Its exitance gives the
irradiance :math:`E(λ) = π L(λ)` with next-event estimation reaching the lamps.
The film is a ``specfilm`` whose band is :math:`V(λ)`, so

.. math:: E_v = 683\\,\\mathrm{lm/W} \\cdot π \\int L(λ) V(λ)\\, dλ .

Opal plates behind a smooth dielectric are expensive in a booth: next-event estimation cannot
reach a lamp through a refracting face, so the lamps above the plate are found only when a sampled
direction hits them.  A plate declared with ``ior: 1.0`` (a scattering layer whose faces are
matched to the air) is a ``null`` box: ``volpath`` traces shadow rays through it and its medium,
and every scattering event inside sees the lamps.

Two float32 effects of Mitsuba 3.9.1 bias a layer this thin in booth coordinates.  A ray leaving
a surface starts about :math:`10^{-4}` of the point's largest coordinate off it (0.05 mm at
600 mm), so a ray entering the ``null`` box skips that much of the medium: a 0.3 mm layer at
z 600 mm transmitted 1.5 times what the plane-parallel layer does, a 3 mm one a few per cent
more.  An opal booth is therefore rendered with the plate's centre at the origin
(:meth:`MitsubaTruth.render_shift_mm`; the scene translated as a whole, the exported scene keeps
the booth's coordinates); 0.04 mm remain at the corners of an 880 mm plate.  And ``volpath``'s shadow ray from a scattering event overshoots the
point sampled on a lamp by the same offsets: a lamp whose emitting shape is its black body
stopped it (mitsuba-renderer/mitsuba3 pull request 678 reports black emitters in ``volpath``);
the opal-black booth read 7 to 9 % low.  Under ``volpath`` a lamp's emitting shape is therefore
``null`` (transparent, still emitting) and its black body the same shape
:data:`LAMP_BODY_INSET_MM` inside it (a thinner cylinder, a smaller sphere, a rectangle behind
a panel): light still ends on the lamp as on a black body.  ``tests/engine/test_truth_mitsuba.py``
holds a small lamp over such a layer to an adding–doubling solution of the plane-parallel layer.

Booths render in ``scalar_spectral`` or in its
vectorised twin ``llvm_ad_spectral`` (``variant``: the same path tracer as a wavefront on the
CPU, several times faster per sample for the volumetric plate; it needs libLLVM, found through
``DRJIT_LIBLLVM_PATH``); plates are always measured and their media fitted in the scalar variant.

Mitsuba accumulates film samples in float32, so each call renders at most
``MAX_SPP_PER_CALL`` samples and ``passes`` calls with their own seeds are
averaged; the spread of the passes gives the Monte Carlo standard error.

Effects Mitsuba cannot represent (end falloff, reflectors, non-isotropic angular
profiles, meter cosine error, per-lamp occluders, a Lambertian diffuse-fraction
plate, glossy materials) are refused with ``LB603``: the provider never
approximates silently.

Examples
--------
>>> from lbscene.engine.truth.synthetic import truth_engine          # doctest: +SKIP
>>> truth = truth_engine(ir, "FL", {"interreflection": {}}, provider="mitsuba", spp=4096)  # doctest: +SKIP
>>> E_lx, se_lx = truth.illuminance_with_error_lx([[0, 0, 0]])          # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lbscene.engine.files.diagnostics import LbsceneUserError

__all__ = ["MitsubaTruth", "MitsubaResult", "MAX_SPP_PER_CALL", "DISC_RADIUS_MM", "mitsuba_version",
           "SUPPORTED_EFFECTS", "plate_optics", "plate_bsdf", "opal_medium"]

K_M = 683.0
#: float32 film accumulation loses small samples beyond this (see the module docstring)
MAX_SPP_PER_CALL = 65536
#: measuring disc: small enough not to shade the booth, large enough for float32 at booth scale
DISC_RADIUS_MM = 0.05
#: disc lifted off the receiver point so that it never coincides with a booth surface
DISC_LIFT_MM = 0.02
VARIANT = "scalar_spectral"
#: variants a booth may be rendered in: the scalar one (default) and its vectorised twin, the
#: same spectral path tracer run as a wavefront on the CPU (LLVM; several times faster per
#: sample for the volumetric opal plates).  Plates are always measured and fitted in
#: :data:`VARIANT`, so that a booth's opal medium does not depend on the variant it renders in.
VARIANTS = ("scalar_spectral", "llvm_ad_spectral")

#: effects the provider represents (with the restrictions checked in ``_refusals``)
SUPPORTED_EFFECTS = frozenset({"interreflection", "diffuser", "aperture_occlusion", "spectral_filter",
                               "reflector",
                               "lamp_spectrum_shift",
                               "angular_profile", "detector_cosine_error"})


def _mi(variant: str = VARIANT):
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


def mitsuba_version() -> str:
    import mitsuba as mi

    return mi.__version__


def _spectrum(values_1nm) -> dict:
    """A 1 nm array on 360–830 nm as a Mitsuba ``regular`` spectrum."""
    v = np.clip(np.broadcast_to(np.asarray(values_1nm, float), (471,)), 0.0, None)
    if np.ptp(v) == 0.0:
        # a constant (zero included: a 'regular' spectrum needs probability mass to sample from)
        return {"type": "uniform", "value": float(v[0])}
    return {"type": "regular", "wavelength_min": 360.0, "wavelength_max": 830.0,
            "values": ", ".join(f"{x:.9g}" for x in v)}


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _translate(scene: dict, t, mi) -> None:
    """Translate the shapes, lamps and meters of a scene dict by ``t`` (mm) in place (meshes are
    translated where they are built, :meth:`MitsubaTruth._surfaces`)."""
    T = np.eye(4)
    T[:3, 3] = t
    for v in scene.values():
        if not isinstance(v, dict):
            continue
        if "to_world" in v:
            v["to_world"] = mi.ScalarTransform4f((T @ np.asarray(v["to_world"].matrix, float)).tolist())
        for key in ("p0", "p1", "center", "position", "origin"):
            if key in v:
                v[key] = (np.asarray(v[key], float) + t).tolist()


def _frame(x, y, z, origin, sx, sy, sz):
    """4×4 to_world: local (±1, ±1, ±1) → origin + sx·x + sy·y + sz·z."""
    m = np.eye(4)
    m[:3, 0] = np.asarray(x) * sx
    m[:3, 1] = np.asarray(y) * sy
    m[:3, 2] = np.asarray(z) * sz
    m[:3, 3] = origin
    return m


#: samples per pass and passes of a plate measurement (:func:`plate_optics`): the rough slab's
#: T(0°) to about ±0.0002
PLATE_SPP = 65536
PLATE_PASSES = 4
#: half-width of the measured plate (mm): 40 times the meter's distance, so that it fills the
#: meter's view; far wider plates lose float32 precision in their faces (a 10⁵ mm plate of GGX
#: α 0.01 transmitted 1.5 % less than a 10³ mm one, a smooth one the same)
PLATE_HALF_WIDTH_MM = 2000.0
#: the opal medium's phase asymmetry is searched in [0, OPAL_G_MAX]
OPAL_G_MAX = 0.95
#: samples per pass of the opal medium's search (:func:`opal_medium`, :data:`PLATE_PASSES` passes):
#: the plate's total normal transmittance to about ±0.001, the accuracy its booth truth inherits
OPAL_FIT_SPP = 65536
_PLATE_CACHE: dict = {}
#: under ``volpath``, a lamp's black body lies this far inside its null emitting shape (module
#: docstring: a shadow ray ending on the emitter must not be stopped by the lamp's own surface)
LAMP_BODY_INSET_MM = 0.01


def plate_bsdf(scattering: dict, ior: float) -> dict:
    """The plate's faces: ``roughdielectric`` (GGX, α = roughness²) for a ``roughness``
    plate, smooth ``dielectric`` for an opal one (``null``, no interface, for ior 1)."""
    if scattering.get("type") == "roughness":
        return {"type": "roughdielectric", "distribution": "ggx",
                "alpha": max(float(scattering["roughness"]) ** 2, 1e-4), "int_ior": float(ior), "ext_ior": 1.0}
    if ior <= 1.0 + 1e-9:
        # index-matched faces: no interface, the medium alone (lamps are reached by next-event
        # estimation through it)
        return {"type": "null"}
    return {"type": "dielectric", "int_ior": float(ior), "ext_ior": 1.0}


def plate_optics(bsdf: dict, thickness_mm: float, cos_theta, *, medium: dict | None = None,
                 spp: int = PLATE_SPP, passes: int = PLATE_PASSES, seed: int = 0) -> dict:
    """Directional-hemispherical transmittance and reflectance of a plate, measured in Mitsuba.

    The plate (faces ``bsdf``, optional interior ``medium``) is a slab of ``thickness_mm``,
    2 :data:`PLATE_HALF_WIDTH_MM` wide, under a uniform sky of radiance 1 (a ``constant`` emitter) with a black
    ground 200 mm below; a ``radiancemeter`` 50 mm from it along direction θ
    (``cos_theta``) looks at its centre, from below for :math:`T(θ)` and from above for
    :math:`R(θ)` (reciprocity: what the meter sees is the plate's response to light from the
    whole hemisphere into the meter's direction).  Returns ``{'T', 'R', 'T_se', 'R_se'}``
    arrays (standard errors over ``passes``)."""
    mi = _mi()
    cos_theta = np.atleast_1d(np.asarray(cos_theta, float))
    cube = {"type": "cube", "bsdf": bsdf,
            "to_world": mi.ScalarTransform4f(np.diag([PLATE_HALF_WIDTH_MM, PLATE_HALF_WIDTH_MM,
                                                      thickness_mm / 2, 1.0]).tolist())}
    if medium is not None:
        cube["interior"] = medium
    out = {"T": [], "R": [], "T_se": [], "R_se": []}
    for mode in ("T", "R"):
        for c in cos_theta:
            s_ = np.sqrt(max(0.0, 1.0 - c * c))
            d = np.array([s_, 0.0, c]) if mode == "R" else np.array([s_, 0.0, -c])
            o = 50.0 * d
            scene = mi.load_dict({
                "type": "scene",
                "integrator": {"type": "volpath" if medium is not None else "path", "max_depth": -1},
                "sky": {"type": "constant", "radiance": {"type": "uniform", "value": 1.0}},
                "plate": cube,
                "ground": {"type": "rectangle", "bsdf": {"type": "diffuse",
                                                          "reflectance": {"type": "uniform", "value": 0.0}},
                           "to_world": mi.ScalarTransform4f(
                               [[1e7, 0, 0, 0], [0, 1e7, 0, 0], [0, 0, 1, -200.0], [0, 0, 0, 1]])},
                "meter": {"type": "radiancemeter", "origin": o.tolist(), "direction": (-d).tolist(),
                          "film": {"type": "specfilm", "width": 1, "height": 1, "rfilter": {"type": "box"},
                                   "band": {"type": "regular", "wavelength_min": 360.0,
                                            "wavelength_max": 830.0, "values": "1, 1"}},
                          "sampler": {"type": "independent", "sample_count": spp}}})
            v = np.array([float(np.asarray(mi.render(scene, spp=spp, seed=seed + 7919 * k)).ravel()[0])
                          for k in range(passes)])
            out[mode].append(v.mean())
            out[mode + "_se"].append(v.std(ddof=1) / np.sqrt(passes))
    res = {k: np.asarray(v) for k, v in out.items()}
    return res


def _normalised_optics(bsdf, thickness_mm, cos_theta, medium=None, **kw) -> dict:
    """:func:`plate_optics` divided by what the meter sees with no plate (the sky, 1 by
    construction, times the film band's normalisation)."""
    key = (repr(bsdf), float(thickness_mm), tuple(np.atleast_1d(cos_theta)), repr(medium),
           tuple(sorted(kw.items())))
    hit = _PLATE_CACHE.get(key)
    if hit is None:
        ref = plate_optics({"type": "null"}, thickness_mm, [1.0], spp=64, passes=2)["T"][0]
        res = plate_optics(bsdf, thickness_mm, cos_theta, medium=medium, **kw)
        hit = _PLATE_CACHE[key] = {k: v / ref for k, v in res.items()}
    return hit


def _opal_optical_depth(T: float, fd: float, ior: float) -> float:
    """τ such that the unscattered light through the slab, (1−R₀)² e^{−τ}/(1 − R₀² e^{−2τ}), is
    the regular part (1 − f_d)·T of the total transmittance ``T``."""
    from scipy.optimize import brentq

    r0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    reg = (1.0 - fd) * T

    def f(tau):
        e = np.exp(-tau)
        return (1 - r0) ** 2 * e / (1 - r0 * r0 * e * e) - reg

    return float(brentq(f, 0.0, 60.0))


def opal_medium(T: float, fd: float, ior: float, thickness_mm: float, *, asymmetry: str = "layer",
                iterations: int = 12) -> dict:
    """The opal plate's interior: a non-absorbing ``homogeneous`` medium whose extinction
    gives the regular part (:func:`_opal_optical_depth`) and whose Henyey–Greenstein
    asymmetry :math:`g` makes the plate transmit ``T`` in total at normal incidence.

    ``asymmetry``: ``"layer"`` (default) takes :math:`g` from the deterministic plane-parallel
    solution of the slab (:func:`lbscene.engine.light.opal_layer.fit_asymmetry`; its T(θ) and
    R(θ) are held to Mitsuba's own measurement of such plates in
    ``tests/bakers/test_opal_slab.py``); ``"bisection"`` bisects Mitsuba's Monte Carlo
    measurement (:func:`plate_optics`, ``iterations`` steps), whose noise leaves the plate's
    total up to 0.3 % off the declaration (g 0.5498 instead of 0.5473 for 0.55, f_d 0.95,
    3 mm: 0.5516).  Raises ``ValueError`` when no :math:`g` in [0, :data:`OPAL_G_MAX`] does."""
    if asymmetry not in ("layer", "bisection"):
        raise ValueError(f"asymmetry must be 'layer' or 'bisection', not {asymmetry!r}")
    if asymmetry == "layer":
        from lbscene.engine.light.opal_layer import fit_asymmetry

        tau = _opal_optical_depth(T, fd, ior)
        g = fit_asymmetry(T, tau, ior)
        return {"type": "homogeneous", "albedo": {"type": "uniform", "value": 1.0},
                "sigma_t": {"type": "uniform", "value": tau / thickness_mm},
                "phase": {"type": "hg", "g": float(g)}}
    key = ("opal", round(T, 6), round(fd, 6), round(ior, 6), round(thickness_mm, 6), iterations)
    hit = _PLATE_CACHE.get(key)
    if hit is not None:
        return hit
    sigma_t = _opal_optical_depth(T, fd, ior) / thickness_mm
    bsdf = plate_bsdf({"type": "lambertian"}, ior)

    def medium(g):
        return {"type": "homogeneous", "albedo": {"type": "uniform", "value": 1.0},
                "sigma_t": {"type": "uniform", "value": sigma_t},
                "phase": {"type": "hg", "g": float(g)}}

    def total(g):
        return float(_normalised_optics(bsdf, thickness_mm, [1.0], medium=medium(g), spp=OPAL_FIT_SPP)["T"][0])

    lo, hi = 0.0, OPAL_G_MAX
    t_lo, t_hi = total(lo), total(hi)
    if not t_lo <= T <= t_hi:
        raise ValueError(f"an opal plate of total transmittance {T:g} and diffuse fraction {fd:g} "
                         f"(ior {ior:g}, {thickness_mm:g} mm) is out of reach: a non-absorbing "
                         f"scattering layer gives {t_lo:.3f} to {t_hi:.3f}")
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if total(mid) < T:
            lo = mid
        else:
            hi = mid
    hit = _PLATE_CACHE[key] = medium(0.5 * (lo + hi))
    return hit


@dataclass(frozen=True)
class MitsubaResult:
    """Illuminance at receivers with its Monte Carlo standard error (both lx)."""

    illuminance_lx: np.ndarray
    std_error_lx: np.ndarray
    spp: int                       # samples per pass
    passes: np.ndarray             # passes averaged, per receiver


def _coplanar_groups(P, N, tol_mm: float = 1e-6) -> list[np.ndarray]:
    """Receivers split into groups that share one plane and normal.

    The measuring discs of one group lie in one plane and face the same way, so no disc can
    shade another's view of the booth; receivers in different planes (a disc above another,
    say) are rendered in separate scenes.
    """
    keys: dict = {}
    for i, (p, n) in enumerate(zip(P, N)):
        k = (tuple(np.round(n, 9)), round(float(p @ n) / tol_mm) * tol_mm)
        keys.setdefault(k, []).append(i)
    return [np.asarray(v) for v in keys.values()]


class MitsubaTruth:
    """Illuminance of a booth rendered by Mitsuba 3.

    Parameters
    ----------
    ir
        The compiled booth.
    lighting
        Lighting configuration (default: the booth's first).
    effects
        The physics to include ``{id: params}`` (default: the booth's ``effects:``).
    spp
        Samples per receiver and pass (at most :data:`MAX_SPP_PER_CALL`).
    passes
        Independent passes (own seeds) averaged; their spread gives the standard error.
    seed
        Seed of the first pass.
    allow_lamp_specific_occluders
        An occluder declared for some lamps only cannot exist physically; by default
        it is refused, with ``True`` it blocks every lamp (and inter-reflected light).
    variant
        The Mitsuba variant that renders (one of :data:`VARIANTS`, default :data:`VARIANT`).
    """

    def __init__(self, ir, lighting: str | None = None, *, effects: dict | None = None,
                 spp: int = 16384, passes: int = 4, seed: int = 0,
                 allow_lamp_specific_occluders: bool = False, variant: str | None = None):
        if not 1 <= spp <= MAX_SPP_PER_CALL:
            raise ValueError(f"spp must be in 1..{MAX_SPP_PER_CALL} (float32 film), got {spp}")
        if passes < 2:
            raise ValueError("passes must be >= 2 (the standard error comes from their spread)")
        self.ir = ir
        self.lighting = lighting or next(iter(ir.lighting))
        self.effects = dict(ir.effects if effects is None else effects)
        self.spp, self.passes, self.seed = int(spp), int(passes), int(seed)
        self.allow_lamp_specific_occluders = allow_lamp_specific_occluders
        self.variant = variant or VARIANT
        if self.variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {self.variant!r}")
        self._refuse(self._refusals(meter=False))

    def _plates_measured(self) -> None:
        """Measure the rough plate and fit the opal medium (in the scalar variant, cached) before
        a scene is built: building must not switch variants half-way."""
        d = self.ir.diffuser
        if "diffuser" in self.effects and d is not None and d.scattering.get("type") == "roughness":
            self._rough_plate_T(d)
        if self._has_opal():
            self._opal_interior()

    # ------------------------------------------------------------------ what cannot be said
    def _refusals(self, meter: bool) -> list[str]:
        ir, fx = self.ir, self.effects
        out = []
        for eid in sorted(fx):
            if eid not in SUPPORTED_EFFECTS:
                out.append(f"effect {eid!r} has no Mitsuba representation")
        if meter and "detector_cosine_error" in fx:
            out.append("effect 'detector_cosine_error' (a meter response) has no Mitsuba "
                       "representation: ask for meter=False")
        if "angular_profile" in fx:
            set_params = sorted(k for k, v in (fx["angular_profile"] or {}).items() if v not in (None, {}, [], ()))
            if set_params:
                out.append(f"angular_profile parameters {set_params} have no Mitsuba representation "
                           "(emitters are Lambertian shapes)")
        for lamp, _ in ir.lamps_on(self.lighting):
            ptype = (lamp.profile or {}).get("type", "isotropic")
            if "angular_profile" in fx and ptype != "isotropic":
                out.append(f"lamp {lamp.id!r}: angular profile {ptype!r} has no Mitsuba representation "
                           "(emitters are Lambertian shapes)")
            if lamp.kind == "tube" and (lamp.length_mm <= 0 or lamp.radius_mm <= 0):
                out.append(f"lamp {lamp.id!r}: a tube needs length_mm > 0 and radius_mm > 0")
            if lamp.kind == "panel" and (lamp.length_mm <= 0 or lamp.width_mm <= 0):
                out.append(f"lamp {lamp.id!r}: a panel needs length_mm > 0 and width_mm > 0")
            if lamp.kind == "bulb" and lamp.radius_mm <= 0:
                out.append(f"lamp {lamp.id!r}: a bulb needs radius_mm > 0")
        for s in ir.surfaces:
            m = ir.materials[s.material]
            if m.type != "diffuse" and "interreflection" in fx:
                out.append(f"surface {s.id!r}: material {m.id!r} is {m.type!r}; only diffuse "
                           "materials have a Mitsuba representation here")
        if "aperture_occlusion" in fx and not self.allow_lamp_specific_occluders:
            on = {lp.id for lp, _ in ir.lamps_on(self.lighting)}
            for o in ir.occluders:
                if o.lamps is not None and not on <= set(o.lamps):
                    out.append(f"occluder {o.id!r} blocks only lamps {list(o.lamps)}: real geometry "
                               "blocks every lamp (pass allow_lamp_specific_occluders=True to accept that)")
        if "aperture_occlusion" in fx:
            for k in ("opening_scale", "opening_scale_u", "opening_scale_v"):
                if float(fx["aperture_occlusion"].get(k, 1.0) or 1.0) != 1.0:
                    out.append(f"aperture_occlusion {k} != 1 has no Mitsuba representation")
        if "reflector" in fx:
            p = fx["reflector"] or {}
            if float(p.get("reflectance_scale", 1.0) or 1.0) != 1.0:
                out.append("reflector reflectance_scale != 1 has no Mitsuba representation")
            if p.get("lamps") not in (None, [], ()):
                out.append("reflector 'lamps' (mirrors of some lamps only) has no Mitsuba representation")
            for lamp, _ in ir.lamps_on(self.lighting):
                refl = ir.reflectors.get(lamp.reflector) if lamp.reflector else None
                if refl is not None and refl.type not in ("plane", "prism"):
                    out.append(f"lamp {lamp.id!r}: reflector {lamp.reflector!r} is a {refl.type!r}; only "
                               "plane and prism mirrors have a Mitsuba representation here")
        if "diffuser" in fx and ir.diffuser is not None:
            d, p = ir.diffuser, fx["diffuser"]
            sc = d.scattering
            if sc.get("type") not in ("roughness", "lambertian"):
                out.append(f"diffuser scattering {sc.get('type')!r} has no Mitsuba representation")
            if p.get("diffuse_fraction"):
                out.append("diffuser diffuse_fraction override has no Mitsuba representation")
            T = d.transmittance.array_1nm * float(p.get("transmittance_scale", 1.0) or 1.0)
            if sc.get("type") == "lambertian":
                if np.ptp(T) > 1e-9:
                    out.append("an opal diffuser's transmittance must be constant over wavelength "
                               "for its Mitsuba representation (one scattering medium)")
                if sc.get("reflectance") is not None:
                    out.append("an opal diffuser's declared reflectance has no Mitsuba representation "
                               "(the medium does not absorb: R = 1 - T)")
                if not 0.0 < float(sc["diffuse_fraction"]) < 0.999:
                    out.append("an opal diffuser's diffuse_fraction must be in (0, 0.999) for its Mitsuba "
                               "representation (the regular part sets the medium's optical depth)")
            elif sc.get("type") == "roughness":
                t0 = self._rough_plate_T(d)
                if np.max(T) > t0 + 0.005:
                    out.append(f"diffuser transmittance {np.max(T):.3f} exceeds the non-absorbing rough "
                               f"plate's {t0:.3f} (ior {d.ior:g}, roughness {sc['roughness']:g}): no such "
                               f"plate transmits that")
        return out

    @staticmethod
    def _refuse(problems: list[str]) -> None:
        if problems:
            raise LbsceneUserError.single(
                "LB603", "the Mitsuba truth cannot represent this booth: " + "; ".join(problems))

    # ------------------------------------------------------------------ scene
    def _lamp_shapes(self) -> dict:
        ir, fx = self.ir, self.effects
        out = {}
        on = dict((lp.id, level) for lp, level in ir.lamps_on(self.lighting))
        black = {"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.0}}
        for lamp in ir.lamps:
            level = on.get(lamp.id, 0.0)
            if level <= 0.0:
                # a lamp that is off is still a body in the way (black, as the model's)
                from lbscene.engine.light.geometry import lamp_body

                if lamp.mount != "booth" or lamp_body(lamp) is None:
                    continue
                shape = self._lamp_shape(lamp, np.zeros(471))
                shape.pop("emitter")
                out[f"body_{lamp.id}"] = dict(shape, bsdf=black)
                continue
            from lbscene.engine.light.lamp_spectrum import lamp_spectrum_1nm

            I = level * lamp_spectrum_1nm(ir, lamp, fx)  # W/sr/nm, shifted and filtered as declared
            shape = self._lamp_shape(lamp, I)
            if lamp.kind == "point":
                out[f"lamp_{lamp.id}"] = shape
            elif self._has_opal():
                # volpath: a null emitter with its black body just inside (module docstring)
                out[f"lamp_{lamp.id}"] = dict(shape, bsdf={"type": "null"})
                out[f"body_{lamp.id}"] = dict(self._lamp_body_inset(lamp), bsdf=black)
            else:
                out[f"lamp_{lamp.id}"] = dict(shape, bsdf=black)
        return out

    def _lamp_body_inset(self, lamp) -> dict:
        """The lamp's black body :data:`LAMP_BODY_INSET_MM` inside its emitting shape (no emitter):
        a thinner cylinder, a smaller sphere, a rectangle behind a panel."""
        p = np.asarray(lamp.position_mm, float)
        ax = _unit(lamp.axis)
        e = LAMP_BODY_INSET_MM
        if lamp.kind == "tube":
            return {"type": "cylinder", "p0": (p - ax * lamp.length_mm / 2).tolist(),
                    "p1": (p + ax * lamp.length_mm / 2).tolist(), "radius": float(lamp.radius_mm) - e}
        if lamp.kind == "bulb":
            return {"type": "sphere", "center": p.tolist(), "radius": float(lamp.radius_mm) - e}
        aim = _unit(lamp.aim)
        wdir = _unit(np.cross(aim, ax))
        return {"type": "rectangle", "to_world": _mi(self.variant).ScalarTransform4f(
                    _frame(ax, wdir, aim, p - e * aim, lamp.length_mm / 2, lamp.width_mm / 2, 1.0).tolist())}

    def _lamp_shape(self, lamp, I) -> dict:
        """The Mitsuba shape (with its area emitter) of one lamp of peak intensity ``I`` (W/sr/nm)."""
        p = np.asarray(lamp.position_mm, float)
        ax = _unit(lamp.axis)
        if lamp.kind == "tube":
            r_m, l_m = lamp.radius_mm * 1e-3, lamp.length_mm * 1e-3
            return {
                "type": "cylinder", "p0": (p - ax * lamp.length_mm / 2).tolist(),
                "p1": (p + ax * lamp.length_mm / 2).tolist(), "radius": float(lamp.radius_mm),
                "emitter": {"type": "area", "radiance": _spectrum(I / (2 * r_m * l_m))}}
        if lamp.kind == "panel":
            aim = _unit(lamp.aim)
            wdir = _unit(np.cross(aim, ax))
            l_m, w_m = lamp.length_mm * 1e-3, lamp.width_mm * 1e-3
            return {
                "type": "rectangle",
                "to_world": _mi(self.variant).ScalarTransform4f(
                    _frame(ax, wdir, aim, p, lamp.length_mm / 2, lamp.width_mm / 2, 1.0).tolist()),
                "emitter": {"type": "area", "radiance": _spectrum(I / (l_m * w_m))}}
        if lamp.kind == "bulb":
            r_m = lamp.radius_mm * 1e-3
            return {
                "type": "sphere", "center": p.tolist(), "radius": float(lamp.radius_mm),
                "emitter": {"type": "area", "radiance": _spectrum(I / (np.pi * r_m ** 2))}}
        return {"type": "point", "position": p.tolist(), "intensity": _spectrum(I * 1e6)}

    def _bsdf(self, reflectance_1nm) -> dict:
        return {"type": "twosided", "material": {"type": "diffuse",
                                                  "reflectance": _spectrum(reflectance_1nm)}}

    def surface_meshes(self) -> dict:
        """``{name: (vertices (V, 3) float32 mm, triangles (T, 3) uint32, bsdf dict)}`` of the booth's
        surfaces, as :meth:`scene_dict` turns them into meshes (``lbscene export-mitsuba`` writes
        them as PLY files or inline arrays)."""
        ir = self.ir
        black = np.zeros(471)
        out = {}
        for s in ir.surfaces:
            refl = ir.materials[s.material].reflectance.array_1nm if "interreflection" in self.effects \
                else black
            out[f"surface_{s.id}"] = (s.vertex_array.astype(np.float32), s.triangle_array.astype(np.uint32),
                                      self._bsdf(refl))
        return out

    def _surfaces(self, shift_mm=None) -> dict:
        mi = _mi(self.variant)
        out = {}
        for name, (v, t, bsdf) in self.surface_meshes().items():
            if shift_mm is not None:
                v = (v.astype(float) + np.asarray(shift_mm, float)).astype(np.float32)
            props = mi.Properties()
            props["bsdf"] = mi.load_dict(bsdf)
            mesh = mi.Mesh(name, len(v), len(t), props=props)
            params = mi.traverse(mesh)
            # the buffers' own types: scalar variants use dynamic drjit arrays, not mi.Float
            params["vertex_positions"] = type(params["vertex_positions"])(v.ravel())
            params["faces"] = type(params["faces"])(t.ravel())
            params.update()
            out[name] = mesh
        return out

    def _occluders(self) -> dict:
        if "aperture_occlusion" not in self.effects:
            return {}
        from lbscene.engine.light.geometry import OCCLUDER_OFFSET_MM, plate_pieces

        ir = self.ir
        out = {}
        for o in ir.occluders:
            n = _unit(o.normal)
            u = np.asarray(o.u_axis, float)
            u = _unit(u - n * (u @ n))
            v = np.cross(n, u)
            # a hair to the side the normal points to, as the Cycles bake draws it
            c = np.asarray(o.centre_mm, float) + OCCLUDER_OFFSET_MM * n
            # black without inter-reflection, as the booth's surfaces (the model's direct light has
            # no light reflected by an occluder)
            refl = ir.materials[o.material].reflectance.array_1nm \
                if o.material and "interreflection" in self.effects else np.zeros(471)
            hole = (o.opening_mm[0] / 2, o.opening_mm[1] / 2) \
                if o.type == "aperture_plate" and o.opening_mm is not None else None
            for k, (u0, u1, v0, v1) in enumerate(plate_pieces((o.size_mm[0] / 2, o.size_mm[1] / 2), hole)):
                cu, cv, su, sv = (u0 + u1) / 2, (v0 + v1) / 2, (u1 - u0) / 2, (v1 - v0) / 2
                out[f"occluder_{o.id}_{k}"] = {
                    "type": "rectangle",
                    "to_world": _mi(self.variant).ScalarTransform4f(_frame(u, v, n, c + cu * u + cv * v, su, sv, 1.0)
                                                       .tolist()),
                    "bsdf": self._bsdf(refl)}
        return out

    def _mirrors(self) -> dict:
        """One conductor rectangle per facet of the mirror of every lamp that is on and has a
        reflector (``reflector`` on): one for a plane mirror, two for a prism
        (:func:`~lbscene.engine.light.effects.builtin.reflector.mirror_facets`)."""
        if "reflector" not in self.effects:
            return {}
        from lbscene.engine.light.effects.builtin.reflector import mirror_facets

        ir = self.ir
        out = {}
        for lamp, _ in ir.lamps_on(self.lighting):
            refl = ir.reflectors.get(lamp.reflector) if lamp.reflector else None
            if refl is None:
                continue
            facets = mirror_facets(ir, lamp, refl)
            for k, r in enumerate(facets):
                n, u = _unit(r.normal), _unit(r.u)
                key = f"mirror_{lamp.id}" if len(facets) == 1 else f"mirror_{lamp.id}_facet{k}"
                out[key] = {
                    "type": "rectangle",
                    "to_world": _mi(self.variant).ScalarTransform4f(
                        _frame(u, np.cross(n, u), n, np.asarray(r.centre, float), r.half[0], r.half[1],
                               1.0).tolist()),
                    "bsdf": {"type": "conductor", "material": "none",
                             "specular_reflectance": _spectrum(np.clip(refl.reflectance.array_1nm, 0.0, 1.0))}}
        return out

    @staticmethod
    def _rough_plate_T(d) -> float:
        """The non-absorbing rough plate's total normal transmittance, measured in Mitsuba."""
        return float(_normalised_optics(plate_bsdf(d.scattering, d.ior), d.thickness_mm, [1.0])["T"][0])

    def _has_opal(self) -> bool:
        d = self.ir.diffuser
        return "diffuser" in self.effects and d is not None and d.scattering.get("type") == "lambertian"

    def _opal_interior(self) -> dict:
        """The opal plate's medium (:func:`opal_medium`, fitted in :data:`VARIANT`); ``LB603`` when
        no non-absorbing layer has the declared transmittance and diffuse fraction."""
        d = self.ir.diffuser
        p = self.effects["diffuser"]
        T = np.clip(d.transmittance.array_1nm * float(p.get("transmittance_scale", 1.0) or 1.0), 0, 1)
        try:
            return opal_medium(float(T[0]), float(d.scattering["diffuse_fraction"]), d.ior, d.thickness_mm)
        except ValueError as exc:
            self._refuse([str(exc)])

    def _diffuser(self) -> dict:
        d = self.ir.diffuser
        if "diffuser" not in self.effects or d is None:
            return {}
        p = self.effects["diffuser"]
        T = np.clip(d.transmittance.array_1nm * float(p.get("transmittance_scale", 1.0) or 1.0), 0, 1)
        centre = (d.centre_mm[0], d.centre_mm[1], d.z_mm)
        bsdf = plate_bsdf(d.scattering, d.ior)
        plate = {"type": "cube",
                 "to_world": _mi(self.variant).ScalarTransform4f(
                     _frame((1, 0, 0), (0, 1, 0), (0, 0, 1), centre, d.size_mm[0] / 2, d.size_mm[1] / 2,
                            d.thickness_mm / 2).tolist())}
        if d.scattering.get("type") == "lambertian":
            plate["interior"] = self._opal_interior()
        else:
            # the declared total normal transmittance over the non-absorbing plate's: bulk absorption,
            # a factor on each of the two refractions
            per_interface = np.sqrt(np.clip(T / self._rough_plate_T(d), 0.0, 1.0))
            if np.any(per_interface < 0.9999):
                bsdf["specular_transmittance"] = _spectrum(per_interface)
        plate["bsdf"] = bsdf
        return {"diffuser": plate}

    def render_shift_mm(self) -> np.ndarray | None:
        """The translation a ``volpath`` (opal) scene is rendered under: the plate's centre to the
        origin (module docstring, float offsets); None for other scenes (rendered as declared)."""
        if not self._has_opal():
            return None
        d = self.ir.diffuser
        return -np.array([d.centre_mm[0], d.centre_mm[1], d.z_mm], float)

    def scene_dict(self, points, normals, film_bands: dict | None = None, *, shift_mm=None) -> dict:
        """The Mitsuba scene (dict) with one measuring disc and radiancemeter per receiver.

        ``film_bands``: name → 1 nm sensitivity of the film's channels (default: ``{'V': V(λ)}``).
        ``shift_mm``: translate the whole scene by this vector (the booth's coordinates when None;
        rendering uses :meth:`render_shift_mm`).
        """
        from lbscene.engine.spectra.evaluate import photopic_1nm

        if film_bands is None:
            film_bands = {"V": photopic_1nm()}
        self._plates_measured()
        P = np.asarray(points, float)
        N = np.asarray(normals, float)
        # an opal plate's scattering medium needs the volumetric path tracer
        scene = {"type": "scene", "integrator": {"type": "volpath" if self._has_opal() else "path",
                                                 "max_depth": -1}}
        scene.update(self._surfaces(shift_mm))
        scene.update(self._lamp_shapes())
        scene.update(self._occluders())
        scene.update(self._mirrors())
        scene.update(self._diffuser())
        film = {"type": "specfilm", "width": 1, "height": 1, "rfilter": {"type": "box"}}
        for k, (name, sens) in enumerate(film_bands.items()):
            # a sensitivity must be a sampled spectrum (specfilm refuses a uniform one)
            film[f"band_{k:03d}_{name}"] = {"type": "regular", "wavelength_min": 360.0, "wavelength_max": 830.0,
                                            "values": ", ".join(f"{x:.9g}" for x in np.clip(sens, 0, None))}
        for i, (p, n) in enumerate(zip(P, N)):
            a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
            u = _unit(a - n * (a @ n))
            v = np.cross(n, u)
            scene[f"meter_disc_{i:05d}"] = {
                "type": "disk",
                "to_world": _mi(self.variant).ScalarTransform4f(
                    _frame(u, v, n, p + DISC_LIFT_MM * n, DISC_RADIUS_MM, DISC_RADIUS_MM, 1.0).tolist()),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 1.0}}}
            scene[f"meter_{i:05d}"] = {
                "type": "radiancemeter", "origin": (p + 2 * DISC_LIFT_MM * n).tolist(),
                "direction": (-n).tolist(), "film": film,
                "sampler": {"type": "independent", "sample_count": self.spp}}
        if shift_mm is not None:
            _translate(scene, np.asarray(shift_mm, float), _mi(self.variant))
        return scene

    # ------------------------------------------------------------------ measurement
    def _receivers(self, points, normals):
        P = np.atleast_2d(np.asarray(points, float))
        if P.shape[1] == 2:
            P = np.c_[P, np.zeros(len(P))]
        N = np.tile([0, 0, 1.0], (len(P), 1)) if normals is None else np.broadcast_to(
            np.asarray(normals, float), P.shape).copy()
        return P, N / np.linalg.norm(N, axis=1, keepdims=True)

    def _render(self, P, N, film_bands: dict, scale, target_rel_error, max_passes):
        """Per receiver and film channel: mean × ``scale``, its standard error, passes used.
        The stopping rule looks at the worst channel."""
        mi = _mi(self.variant)
        C = len(film_bands)
        mean, se = np.zeros((len(P), C)), np.zeros((len(P), C))
        used = np.zeros(len(P), int)
        scale = np.broadcast_to(np.asarray(scale, float), (C,))
        for group in _coplanar_groups(P, N):
            scene = mi.load_dict(self.scene_dict(P[group], N[group], film_bands, shift_mm=self.render_shift_mm()))
            for i, sensor in zip(group, scene.sensors()):
                vals = []
                while True:
                    k = len(vals)
                    img = mi.render(scene, sensor=sensor, spp=self.spp, seed=self.seed + 7919 * k + int(i))
                    vals.append(scale * np.asarray(img, float).ravel()[:C])
                    if len(vals) < self.passes:
                        continue
                    v = np.asarray(vals)
                    m, s = v.mean(0), v.std(0, ddof=1) / np.sqrt(len(v))
                    if target_rel_error is None or np.all(s <= target_rel_error * np.abs(m)) \
                            or len(v) >= max_passes:
                        break
                mean[i], se[i], used[i] = m, s, len(v)
        return mean, se, used

    def illuminance_with_error_lx(self, points, normals=None, *, target_rel_error: float | None = None,
                                  max_passes: int = 64) -> MitsubaResult:
        """Illuminance (lx) at ``points`` (mm) on surfaces facing ``normals`` (default +z), with
        the standard error of its Monte Carlo estimate.

        ``target_rel_error``: keep adding passes (each ``spp`` samples, own seed) to a receiver
        until its standard error is at most this fraction of its value, or ``max_passes``.
        """
        from lbscene.engine.spectra.evaluate import photopic_1nm

        P, N = self._receivers(points, normals)
        m, s, used = self._render(P, N, {"V": photopic_1nm()}, K_M * np.pi, target_rel_error, max_passes)
        return MitsubaResult(m[:, 0], s[:, 0], self.spp, used)

    def spectral_irradiance_bands(self, points, normals=None, *, target_rel_error: float | None = None,
                                  max_passes: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """Band-mean spectral irradiance (W·m⁻²·nm⁻¹) on the IR's band grid, shape (M, B), and its
        standard error: film channels are the bands' box functions, E_b = π ∫_b L dλ / Δλ_b."""
        from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

        P, N = self._receivers(points, normals)
        edges = self.ir.grid.edges_nm
        bands = {}
        for k in range(len(edges) - 1):
            # 1 nm samples inside the band; the edge samples count half, as a box integrated on 1 nm
            w = ((WL > edges[k]) & (WL < edges[k + 1])).astype(float)
            w[(WL == edges[k]) | (WL == edges[k + 1])] = 0.5
            bands[f"b{k:02d}"] = w
        width = np.diff(edges)
        m, s, _ = self._render(P, N, bands, np.pi / width, target_rel_error, max_passes)
        return m, s

    def white_tile_radiance_bands(self, point=None, normal=(0.0, 0.0, 1.0), reflectance_bands=1.0):
        """Band-mean spectral radiance (W·sr⁻¹·m⁻²·nm⁻¹) of a Lambertian tile: ρ_b E_b / π."""
        p = self.ir.sample_position_mm if point is None else point
        E, _ = self.spectral_irradiance_bands([p], [normal])
        return np.asarray(reflectance_bands) * E[0] / np.pi

    def illuminance_lx(self, points, normals=None, meter: bool = True) -> np.ndarray:
        """Illuminance (lx); ``meter`` is accepted for the truth-provider interface (an ideal
        cosine meter: a booth with ``detector_cosine_error`` is refused)."""
        self._refuse(self._refusals(meter=bool(np.any(meter))))
        return self.illuminance_with_error_lx(points, normals).illuminance_lx

    def spectral_irradiance_1nm(self, points, normals=None, meter=False):
        raise NotImplementedError(
            "the Mitsuba truth measures illuminance (V(λ)-weighted); spectral irradiance at 1 nm "
            "needs one film band per nanometre and is not provided")
