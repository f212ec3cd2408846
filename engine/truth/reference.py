"""
A brute-force Monte Carlo reference for the forward model ("truth" engine).

Same physical definitions as the built-in effects, computed a different way,
so a test that fits :mod:`lbscene.engine.light.forward` to data made here cannot
pass by symmetry:

==================  ====================================  ===========================================
                    forward model                         this reference
==================  ====================================  ===========================================
lamp                N = 100 midpoints (+ refined near)    thousands of jittered stratified samples
occluders/mirrors   vectorised segment tests              per-sample ray/plane tests (own code; a
                                                          prism's facets turned about its apex)
diffuser, diffuse   polygon form factors of plate cells   point-to-point Monte Carlo over the plate
inter-reflection    patches ~100 mm, exact polygon        finer patches, form factors by cosine-
                    form factors, LU per band             weighted ray casting, Jacobi iteration,
                                                          receivers gather by stratified ray casting
meter response      per path, correction at centroid      per ray
==================  ====================================  ===========================================

It reads only the IR (spectra, geometry, effect parameters) and never calls
the forward model's code; a ``roughness`` plate's directional transmittance
comes from the rough slab tables (:mod:`lbscene.engine.light.rough_slab`, the
model of the plate both share; its regular path only: a plate whose lobe
is wide is not represented beyond that), and an opal plate's scattering layer from
:mod:`lbscene.engine.light.opal_layer` (the plate model both share).  It only supports box interiors (parametric
booths).  Other truth providers (e.g. a Cycles bake) register with
:func:`register_truth_provider` and are looked up by name.

Examples
--------
>>> from lbscene.engine.scene.compile import compile_booth                   # doctest: +SKIP
>>> ref = ReferenceEngine(compile_booth("tests/data/minimal-booth"), "A")  # doctest: +SKIP
>>> ref.illuminance_lx([[0, 0, 0]])                                     # doctest: +SKIP
array([2040.8...])
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from lbscene.engine.light.plates import diffuser_fraction, fitted_plate, opal_depth, opal_regular_relative

__all__ = ["ReferenceEngine", "TRUTH_PROVIDERS", "register_truth_provider", "get_truth_provider"]

K_M = 683.0

#: name → factory(ir, lighting, **kw) returning an object with ``illuminance_lx(points, normals,
#: meter)`` and ``spectral_irradiance_1nm(points, normals)``.
TRUTH_PROVIDERS: dict[str, Callable] = {}


def register_truth_provider(name: str, factory: Callable) -> None:
    """Register a truth provider: another engine that synthetic measurements can come from
    (this module registers ``'reference'``, the brute-force Monte Carlo engine)."""
    TRUTH_PROVIDERS[name] = factory


def get_truth_provider(name: str) -> Callable:
    """The factory registered as ``name``; ``KeyError`` naming the registered ones otherwise."""
    try:
        return TRUTH_PROVIDERS[name]
    except KeyError:
        raise KeyError(f"no truth provider {name!r}; registered: {sorted(TRUTH_PROVIDERS)}") from None


# ----------------------------------------------------------------------------- small helpers

def _norm(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _profile_factor(src: dict, u: np.ndarray):
    """Emission profile of ``src`` toward directions ``u`` (source → receiver).  A mirror
    image emits the mirrored directions of its lamp, so the angle is taken after reflecting
    ``u`` in the mirror plane.  1 where the source has no profile."""
    if src["prof"] is None:
        return 1.0
    if src["image_of"] is not None:
        nn = src["image_of"].n
        u = u - 2 * (u @ nn)[..., None] * nn
    if getattr(src["prof"], "two_d", False):      # IES: γ from aim, C from the lamp's axis
        from lbscene.engine.spectra.profiles import ies_angles

        return src["prof"](*ies_angles(u, src["axis"], src["aim"]))
    return src["prof"](np.arccos(np.clip(u @ src["aim"], -1, 1)))


def _profile(profile: dict):
    t = profile.get("type")
    if t == "gaussian":
        s = float(profile["sigma_deg"])
        return lambda th: np.exp(-(np.degrees(th) / (2.0 * s)) ** 2)
    if t == "cosine_power":
        e = float(profile["exponent"])
        return lambda th: np.where(th < np.pi / 2, np.cos(np.minimum(th, np.pi / 2)) ** e, 0.0)
    if t == "isotropic" or t is None:
        return None
    from lbscene.engine.spectra.profiles import \
        profile_shape  # IES tables: reuse the reader, nothing to compute

    return profile_shape(profile)


def _fresnel_plate(cos_i, n):
    """Transmittance of a clear plate: sum of the multiply-reflected series, both polarisations."""
    ci = np.clip(cos_i, 1e-9, 1.0)
    st = np.sqrt(1 - ci ** 2) / n
    ct = np.sqrt(1 - st ** 2)
    tot = 0.0
    for r in (((ci - n * ct) / (ci + n * ct)) ** 2, ((n * ci - ct) / (n * ci + ct)) ** 2):
        # T = (1-r)^2 * (1 + r^2 + r^4 + ...), summed explicitly
        r2 = r * r
        series, term = 1.0, 1.0
        for _ in range(12):
            term = term * r2
            series = series + term
        tot = tot + 0.5 * (1 - r) ** 2 * series
    return tot


class _Rect:
    def __init__(self, centre, normal, u, half, hole=None):
        self.c = np.asarray(centre, float)
        self.n = _norm(np.asarray(normal, float))
        u = np.asarray(u, float)
        u = u - self.n * (u @ self.n)
        self.u = _norm(u)
        self.v = np.cross(self.n, self.u)
        self.half = half
        self.hole = hole

    def crosses(self, a, b):
        """a (N,3) sources, b (M,3) targets → (M,N) bool: segment crosses the rectangle."""
        ha = (a - self.c) @ self.n
        hb = (b - self.c) @ self.n
        out = np.zeros((len(b), len(a)), bool)
        sign_change = (ha[None, :] * hb[:, None]) < 0
        if not sign_change.any():
            return out
        mi, ni = np.nonzero(sign_change)
        t = ha[ni] / (ha[ni] - hb[mi])
        p = a[ni] + t[:, None] * (b[mi] - a[ni]) - self.c
        pu, pv = p @ self.u, p @ self.v
        hit = (np.abs(pu) <= self.half[0]) & (np.abs(pv) <= self.half[1])
        if self.hole is not None:
            hit &= ~((np.abs(pu) < self.hole[0]) & (np.abs(pv) < self.hole[1]))
        out[mi[hit], ni[hit]] = True
        return out


class _Cylinder:
    """A tube's body: the solid cylinder of radius ``r`` about the segment ``p0 → p1``."""

    def __init__(self, p0, p1, r):
        self.p0 = np.asarray(p0, float)
        d = np.asarray(p1, float) - self.p0
        self.length = float(np.linalg.norm(d))
        self.k = d / self.length
        self.r = float(r)

    def crosses(self, a, b):
        """a (N,3) sources, b (M,3) targets → (M,N) bool: the segment passes through the body.

        With s(t) = a + t (b − a): the part of t ∈ [0, 1] inside the infinite cylinder (a
        quadratic in t, across the axis) meets the part whose axial coordinate lies on the tube."""
        A = (a - self.p0)[None, :, :] + np.zeros((len(b), 1, 1))
        D = b[:, None, :] - a[None, :, :]
        ak, dk = A @ self.k, D @ self.k
        Ap, Dp = A - ak[..., None] * self.k, D - dk[..., None] * self.k
        qa = (Dp * Dp).sum(-1)
        qb = 2.0 * (Ap * Dp).sum(-1)
        qc = (Ap * Ap).sum(-1) - self.r ** 2
        disc = qb * qb - 4.0 * qa * qc
        ok = (disc > 0) & (qa > 1e-12)
        sq = np.sqrt(np.where(ok, disc, 0.0))
        qa_ = np.where(ok, qa, 1.0)
        lo = np.maximum((-qb - sq) / (2 * qa_), 0.0)
        hi = np.minimum((-qb + sq) / (2 * qa_), 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            s0, s1 = (0.0 - ak) / dk, (self.length - ak) / dk
        ax_lo = np.where(dk != 0, np.minimum(s0, s1), np.where((ak >= 0) & (ak <= self.length), -np.inf, np.inf))
        ax_hi = np.where(dk != 0, np.maximum(s0, s1), np.where((ak >= 0) & (ak <= self.length), np.inf, -np.inf))
        return ok & (np.maximum(lo, ax_lo) < np.minimum(hi, ax_hi))


class _Sphere:
    """A bulb's body: the solid sphere of radius ``r`` about ``c``."""

    def __init__(self, c, r):
        self.c = np.asarray(c, float)
        self.r = float(r)

    def crosses(self, a, b):
        A = (a - self.c)[None, :, :] + np.zeros((len(b), 1, 1))
        D = b[:, None, :] - a[None, :, :]
        qa = (D * D).sum(-1)
        qb = 2.0 * (A * D).sum(-1)
        qc = (A * A).sum(-1) - self.r ** 2
        disc = qb * qb - 4.0 * qa * qc
        ok = disc > 0
        sq = np.sqrt(np.where(ok, disc, 0.0))
        lo = np.maximum((-qb - sq) / (2 * qa), 0.0)
        hi = np.minimum((-qb + sq) / (2 * qa), 1.0)
        return ok & (lo < hi)


def _own_body(lamp):
    """The lamp's body that stands in the way of its mirror image (None: a point lamp)."""
    p = np.asarray(lamp.position_mm, float)
    if lamp.kind == "tube" and lamp.radius_mm > 0:
        ax = _norm(np.asarray(lamp.axis, float))
        return _Cylinder(p - ax * lamp.length_mm / 2, p + ax * lamp.length_mm / 2, lamp.radius_mm)
    if lamp.kind == "bulb" and lamp.radius_mm > 0:
        return _Sphere(p, lamp.radius_mm)
    if lamp.kind == "panel":
        return _Rect(p, lamp.aim, lamp.axis, (lamp.length_mm / 2, lamp.width_mm / 2))
    return None


# ----------------------------------------------------------------------------- the engine

class ReferenceEngine:
    """Monte Carlo reference of one booth, lighting and set of effects.

    Parameters
    ----------
    ir, lighting
        Compiled booth and lighting configuration.
    effects
        Effects the truth includes ``{id: params}`` (default: the booth's).
        Only the built-in effect ids are understood.
    samples_per_lamp
        Jittered stratified samples per lamp (tubes along their length).
    patch_mm
        Radiosity patch size of the reference (finer than the model's).
    gather_rays
        Stratified rays per receiver for inter-reflected light.
    """

    def __init__(self, ir, lighting: str, effects: dict | None = None, *, samples_per_lamp=4000,
                 patch_mm: float = 50.0, gather_rays: int = 16384, form_factor_rays: int = 4096,
                 plate_samples: int = 2500, seed: int = 12345, lamp_overrides: dict | None = None):
        from lbscene.engine.light.effects.registry import get_effect

        self.ir = ir
        self.lighting = lighting
        raw = dict(ir.effects if effects is None else effects)
        # fill defaults through the registry's parameter models (data only, no physics)
        self.fx = {k: get_effect(k).Params.model_validate(v or {}) for k, v in raw.items()}
        self.rng = np.random.default_rng(seed)
        self.n_samples = samples_per_lamp
        self.patch_mm = patch_mm
        self.gather_rays = gather_rays
        self.ff_rays = form_factor_rays
        self.plate_samples = plate_samples
        self.lamp_overrides = lamp_overrides or {}
        from lbscene.engine.spectra.evaluate import photopic_1nm

        self.V = photopic_1nm()
        self._sources = None
        self._radiosity = None

    # ------------------------------------------------------------------ sources
    def _lamp_samples(self, lamp, n):
        """Jittered stratified samples ON the lamp's emitting surface:
        positions (n,3), Lambertian normals (n,3) or None (a point), weights (n,).

        The intensity of sample ``i`` toward ``u`` is ``w_i · max(0, n_i·u) · I_ref``
        (:mod:`lbscene.engine.light.emitters`): a tube is sampled over its lateral surface (and
        caps), a panel over its area, a bulb over its sphere.  Nothing here shares the
        forward model's axis quadrature or far-field law.
        """
        from lbscene.engine.light.emitters import emitter_from_lamp

        em = emitter_from_lamp(lamp)
        if lamp.kind == "tube":
            n_around = 16
            n_along = max(1, n // n_around)
            pos, nrm, w, s = em.surface_points(n_along, n_around, rng=self.rng)
            # around-major order: the solvers thin samples with [::stride], which then keeps
            # every azimuth (a random subset would let the share of down-facing normals vary)
            o = np.arange(len(pos)).reshape(n_along, n_around).T.ravel()
            pos, nrm, w, s = pos[o], nrm[o], w[o], s[o]
            fo = self.fx.get("tube_end_falloff")
            if fo is not None and (fo.lamps is None or lamp.id in fo.lamps):
                dist_end = lamp.length_mm * (0.5 - np.abs(s))
                ramp = np.minimum(dist_end / fo.falloff_length_mm, 1.0)
                w = w * (fo.end_level + (1 - fo.end_level) * ramp)
            caps = em.cap_points()
            if caps is not None:
                # each cap: a disc of radius r, sampled uniformly over its area
                k = max(1, n // 64)
                cp, cn, cw = [], [], []
                for c0, nn, wc in zip(*caps[:3]):
                    rr = lamp.radius_mm * np.sqrt((np.arange(k) + self.rng.random(k)) / k)
                    ph = 2 * np.pi * self.rng.random(k)
                    e1 = _norm(np.cross(nn, [0.0, 0.0, 1.0] if abs(nn[2]) < 0.9 else [1.0, 0.0, 0.0]))
                    e2 = np.cross(nn, e1)
                    cp.append(c0 + np.outer(rr * np.cos(ph), e1) + np.outer(rr * np.sin(ph), e2))
                    cn.append(np.tile(nn, (k, 1)))
                    cw.append(np.full(k, wc / k))
                pos, nrm, w = np.r_[pos, *cp], np.r_[nrm, *cn], np.r_[w, *cw]
            return pos, nrm, w
        if lamp.kind == "panel" or (lamp.kind == "bulb" and lamp.radius_mm > 0):
            # a sphere is smooth and convex: fewer samples reach the same noise as a tube's
            k = n if lamp.kind == "panel" else max(64, n // 16)
            pos, nrm, w, _ = em.surface_points(k, 1, rng=self.rng)
            o = self.rng.permutation(len(pos))
            return pos[o], nrm[o], w[o]
        return np.asarray(lamp.position_mm, float)[None, :], None, np.ones(1)

    def _mirror(self, lamp):
        refl = self.ir.reflectors[lamp.reflector]
        n = np.asarray(refl.normal, float)
        centre = np.asarray(lamp.position_mm, float) - refl.distance_mm * n
        u = np.asarray(lamp.axis, float)
        if np.linalg.norm(u - n * (u @ n)) < 1e-9:
            u = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        along = lamp.length_mm / 2 if lamp.kind in ("tube", "panel") else refl.width_mm / 2
        if refl.type != "prism":
            return refl, [_Rect(centre, n, u, (along, refl.width_mm / 2))]
        # a prism: each half of the plane mirror turned about the apex line (through ``centre``,
        # along the lamp's axis) toward the lamp by (180° − apex angle) / 2
        u = _norm(u - n * (u @ n))
        v = np.cross(n, u)
        beta = np.radians((180.0 - float(refl.apex_angle_deg)) / 2.0)

        def turn(x, a):                     # Rodrigues: x about u by the angle a
            return x * np.cos(a) + np.cross(u, x) * np.sin(a) + u * (u @ x) * (1.0 - np.cos(a))

        facets = []
        for s in (1.0, -1.0):
            e = turn(s * v, s * beta)
            facets.append(_Rect(centre + e * refl.width_mm / 4, turn(n, s * beta), u,
                                (along, refl.width_mm / 4)))
        return refl, facets

    def _occluders(self, lamp_id):
        occ = self.fx.get("aperture_occlusion")
        if occ is None:
            return []
        out = []
        for o in self.ir.occluders:
            if occ.occluders is not None and o.id not in occ.occluders:
                continue
            if o.lamps is not None and lamp_id not in o.lamps:
                continue
            half = (o.size_mm[0] / 2, o.size_mm[1] / 2)
            hole = None
            if o.type == "aperture_plate" and o.opening_mm is not None:
                hole = (min(o.opening_mm[0] * occ.opening_scale * occ.opening_scale_u, o.size_mm[0]) / 2,
                        min(o.opening_mm[1] * occ.opening_scale * occ.opening_scale_v, o.size_mm[1]) / 2)
            out.append(_Rect(o.centre_mm, o.normal, o.u_axis, half, hole))
        return out

    def sources(self):
        """List of source bundles: dict(group, pos, w, aim, prof, spectrum, mirror, blockers)."""
        if self._sources is not None:
            return self._sources
        out = []
        ap = self.fx.get("angular_profile")
        rf = self.fx.get("reflector")
        for lamp_id in self.ir.lighting[self.lighting].lamps:
            lamp = self.ir.lamp(lamp_id)
            level = float(self.ir.lighting[self.lighting].dimming.get(lamp_id, 1.0))
            pos, nrm, w = self._lamp_samples(lamp, self.n_samples if lamp.kind != "point" else 1)
            prof = None
            if ap is not None and (ap.lamps is None or lamp.id in ap.lamps):
                sig = self.lamp_overrides.get(lamp.id, {}).get("sigma_deg")
                if sig is not None:
                    prof = _profile({"type": "gaussian", "sigma_deg": sig})
                elif lamp.profile.get("type") != "isotropic":
                    prof = _profile(lamp.profile)
                elif ap.sigma_deg is not None:
                    prof = _profile({"type": "gaussian", "sigma_deg": ap.sigma_deg})
            # shifted and filtered as the forward model's emitters are (one definition)
            from lbscene.engine.light.lamp_spectrum import lamp_spectrum_1nm

            spec = lamp_spectrum_1nm(self.ir, lamp, {k: v.model_dump() for k, v in self.fx.items()}) * level
            blockers = self._occluders(lamp.id)
            mirror = None
            if rf is not None and lamp.reflector and (rf.lamps is None or lamp.id in rf.lamps):
                refl, mirror = self._mirror(lamp)
                for rect in mirror:
                    # image: reflect every sample through the mirror's (or the facet's) plane
                    h = (pos - rect.c) @ rect.n
                    ipos = pos - 2 * h[:, None] * rect.n[None, :]
                    inrm = None if nrm is None else nrm - 2 * (nrm @ rect.n)[:, None] * rect.n[None, :]
                    R = np.clip(refl.reflectance.array_1nm * rf.reflectance_scale, 0, 1)
                    # the lamp itself stands between its image and what lies beyond it
                    body = _own_body(lamp)
                    out.append(dict(group=lamp.group, lamp=lamp.id, pos=ipos, nrm=inrm, w=w,
                                    aim=np.asarray(lamp.aim), axis=np.asarray(lamp.axis),
                                    prof=prof, spectrum=spec * R, image_of=rect,
                                    blockers=blockers + ([body] if body is not None else []),
                                    mirror=None))
            out.append(dict(group=lamp.group, lamp=lamp.id, pos=pos, nrm=nrm, w=w,
                            aim=np.asarray(lamp.aim), axis=np.asarray(lamp.axis),
                            prof=prof, spectrum=spec, image_of=None, blockers=blockers, mirror=mirror))
        self._sources = out
        return out

    # ------------------------------------------------------------------ meter
    def _meter(self, cos_i):
        d = self.fx.get("detector_cosine_error")
        if d is None:
            return np.ones_like(cos_i)
        if d.model == "power":
            return np.where(cos_i > 0, np.clip(cos_i, 1e-12, 1) ** (d.exponent - 1.0), 0.0)
        # f2_linear: calibrate the slope so that the CIE f2 integral is f2_percent
        e = np.linspace(0, np.radians(85), 20001)
        de = e[1] - e[0]
        unit = float(np.sum((e / (np.pi / 2)) * np.sin(2 * e)) * de)
        k = d.f2_percent / 100.0 / unit
        return np.clip(1 - k * np.arccos(np.clip(cos_i, -1, 1)) / (np.pi / 2), 0, None)

    # ------------------------------------------------------------------ direct light
    def _direct(self, P, N, meter, chunk=64, stride=1):
        """list of (group, spectrum (471,), geo (M,)) for the straight paths.

        ``stride`` > 1 uses every stride-th lamp sample (weights scaled): for
        the many far receivers of the radiosity solve.
        """
        diff = self.fx.get("diffuser")
        plate = None
        if diff is not None and self.ir.diffuser is not None:
            d = self.ir.diffuser
            plate = _Rect((d.centre_mm[0], d.centre_mm[1], d.z_mm), (0, 0, 1), (1, 0, 0),
                          (d.size_mm[0] / 2, d.size_mm[1] / 2))
            fd = self._diffuse_fraction()
            T = np.clip(d.transmittance.array_1nm * diff.transmittance_scale, 0, 1)
            t0 = _fresnel_plate(np.ones(1), d.ior)[0]
        out = []
        for src in self.sources():
            if stride > 1 and len(src["pos"]) > stride:
                src = dict(src, pos=src["pos"][::stride], w=src["w"][::stride] * stride,
                           nrm=None if src["nrm"] is None else src["nrm"][::stride])
            geo_t = np.zeros(len(P))
            geo_n = np.zeros(len(P))
            for a in range(0, len(P), chunk):
                p, n, m = P[a:a + chunk], N[a:a + chunk], meter[a:a + chunk]
                d_ = p[:, None, :] - src["pos"][None]
                r = np.linalg.norm(d_, axis=2)
                u = d_ / r[..., None]
                cos_r = np.maximum(-(u * n[:, None, :]).sum(-1), 0)
                val = src["w"][None] * cos_r / (r * 1e-3) ** 2
                if src["nrm"] is not None:       # Lambertian surface sample: its own cosine
                    val = val * np.maximum((u * src["nrm"][None]).sum(-1), 0.0)
                val = val * _profile_factor(src, u)
                if m.any():
                    val = np.where(m[:, None], val * self._meter(cos_r), val)
                if src["image_of"] is not None:
                    val = val * src["image_of"].crosses(src["pos"], p)
                for m in src["mirror"] or ():
                    val = val * ~m.crosses(src["pos"], p)
                for b in src["blockers"]:
                    val = val * ~b.crosses(src["pos"], p)
                if plate is not None:
                    through = plate.crosses(src["pos"], p)
                    ang = self._plate_angular(np.abs(u[..., 2]), t0)
                    geo_t[a:a + chunk] = (val * through * ang * (1 - fd)).sum(1)
                    geo_n[a:a + chunk] = (val * ~through).sum(1)
                else:
                    geo_n[a:a + chunk] = val.sum(1)
            out.append((src["group"], src["spectrum"], geo_n))
            if plate is not None:
                out.append((src["group"], src["spectrum"] * T, geo_t))
        return out

    def _plate_angular(self, cos_i, t0):
        """Regular transmittance of the plate at incidence ``cos_i`` relative to its own at normal
        incidence: the clear plate's Fresnel series, or for a ``roughness`` plate the rough
        slab's directional transmittance (:mod:`lbscene.engine.light.rough_slab`: two GGX faces,
        light scattered within its narrow lobe kept on the straight path)."""
        d = self.ir.diffuser
        if d.scattering.get("type") == "roughness":
            from lbscene.engine.light.rough_slab import rough_slab

            # the declared transmittance is the plate's total at normal incidence: relative to
            # the non-absorbing rough slab's own T(0°)
            slab = rough_slab(float(d.scattering["roughness"]) ** 2, float(d.ior))
            return slab.transmittance(cos_i) / float(slab.transmittance(np.ones(1))[0])
        if d.scattering.get("type") == "lambertian":
            # an opal plate's unscattered light: Beer–Lambert along the refracted path
            return opal_regular_relative(cos_i, d.ior, opal_depth(self._plate_ir(), self._diffuse_fraction()))
        return _fresnel_plate(cos_i, d.ior) / t0

    def _plate_ir(self):
        """The booth with its plate as the diffuser effect's parameters make it
        (:func:`~lbscene.engine.light.plates.fitted_plate`); made once (the parameters are the
        engine's, fixed), not per chunk of receivers."""
        if getattr(self, "_fitted_plate_ir", None) is None:
            diff = self.fx["diffuser"]
            self._fitted_plate_ir = fitted_plate(self.ir, diff.transmittance_scale, diff.diffuse_fraction)
        return self._fitted_plate_ir

    def _diffuse_fraction(self):
        return diffuser_fraction(self.ir, self.fx["diffuser"])

    def _plate_light(self, P, N, meter, chunk=32):
        """Scattered light of the diffuser plate, Monte Carlo over the plate area: each sample
        point of the top face gathers the lamps' light by direction, the bottom face under it
        sends it on with the scattering layer's bidirectional law
        (:func:`~lbscene.engine.light.plates.opal_plate_layer`, the plate model both share),
        :math:`f_d T_\\text{decl}` of a beam along the normal."""
        diff = self.fx.get("diffuser")
        if diff is None or self.ir.diffuser is None or self._diffuse_fraction() <= 0:
            return []
        from lbscene.engine.light.plates import opal_plate_layer

        d = self.ir.diffuser
        fd = self._diffuse_fraction()
        layer = opal_plate_layer(self._plate_ir(), fd)
        key = "_plate"
        if getattr(self, key, None) is None:
            k = int(np.sqrt(self.plate_samples))
            su = (np.repeat(np.arange(k), k) + self.rng.random(k * k)) / k - 0.5
            sv = (np.tile(np.arange(k), k) + self.rng.random(k * k)) / k - 0.5
            pts = np.c_[d.centre_mm[0] + su * d.size_mm[0], d.centre_mm[1] + sv * d.size_mm[1],
                        np.full(k * k, d.z_mm)]
            area = d.size_mm[0] * d.size_mm[1] * 1e-6 / (k * k)
            top = self._top_light(pts + [0.0, 0.0, d.thickness_mm / 2], layer)
            setattr(self, key, (pts - [0.0, 0.0, d.thickness_mm / 2], area, top))
        pts, area, top = getattr(self, key)
        T = np.clip(d.transmittance.array_1nm * diff.transmittance_scale, 0, 1)
        scale = fd / float(layer.scattered_total(np.ones(1))[0])
        out = []
        for group, spec, coef in top:
            G = layer.exit_modes(coef)                             # (S, M+1, N)
            geo = np.zeros(len(P))
            for a in range(0, len(P), chunk):
                p, n, m = P[a:a + chunk], N[a:a + chunk], meter[a:a + chunk]
                v = pts[None] - p[:, None, :]
                r = np.linalg.norm(v, axis=2)
                u = v / r[..., None]
                cos_r = np.maximum((u * n[:, None, :]).sum(-1), 0)
                cos_s = np.maximum(u[..., 2], 0)           # plate emits downward (-z)
                # toward the receiver: −u; its azimuth
                L = layer.radiance_at(G, cos_s.T, np.arctan2(-u[..., 1], -u[..., 0]).T).T
                val = scale * L * cos_s * cos_r / (r * 1e-3) ** 2 * area
                if m.any():
                    val = np.where(m[:, None], val * self._meter(cos_r), val)
                geo[a:a + chunk] = val.sum(1)
            out.append((group, spec * T, geo))
        return out

    def _top_light(self, pts, layer, chunk=256):
        """Per lamp group: the light arriving on the plate's top face at ``pts`` binned by
        direction (:meth:`~lbscene.engine.light.opal_layer.OpalLayer.histogram`, its Fourier
        coefficients, ``(S, N, M + 1)``): irradiance of an ideal cosine receiver from each
        lamp sample (subsampled to about 500), with the azimuth it travels toward."""
        saved = self.fx.pop("diffuser")
        n_phi = 2 * layer.modes + 32
        out = []
        try:
            for src in self.sources():
                st = max(1, len(src["pos"]) // 500)
                src = dict(src, pos=src["pos"][::st], w=src["w"][::st] * st,
                           nrm=None if src["nrm"] is None else src["nrm"][::st])
                coef = np.zeros((len(pts), len(layer.cos_nodes), layer.modes + 1), complex)
                for a in range(0, len(pts), chunk):
                    q = pts[a:a + chunk] + [0, 0, 1e-3]
                    d_ = q[:, None, :] - src["pos"][None]
                    r = np.linalg.norm(d_, axis=2)
                    u = d_ / r[..., None]
                    cos_r = np.maximum(-u[..., 2], 0)
                    val = src["w"][None] * cos_r / (r * 1e-3) ** 2
                    if src["nrm"] is not None:       # Lambertian surface sample: its own cosine
                        val = val * np.maximum((u * src["nrm"][None]).sum(-1), 0.0)
                    val = val * _profile_factor(src, u)
                    if src["image_of"] is not None:
                        val = val * src["image_of"].crosses(src["pos"], q)
                    for m in src["mirror"] or ():
                        val = val * ~m.crosses(src["pos"], q)
                    for b in src["blockers"]:
                        val = val * ~b.crosses(src["pos"], q)
                    H = layer.histogram(cos_r, np.arctan2(u[..., 1], u[..., 0]), val, n_phi)
                    coef[a:a + chunk] = layer.histogram_modes(H, layer.modes)
                out.append((src["group"], src["spectrum"], coef))
        finally:
            self.fx["diffuser"] = saved
        return out

    # ------------------------------------------------------------------ inter-reflection
    def _box(self):
        it = self.ir.interior
        return it.width_mm / 2, it.depth_mm / 2, it.height_mm

    def _faces(self):
        """Box faces present in the IR: role → (axis, bound value, inward normal sign, material)."""
        w, d, h = self._box()
        spec = {"left_wall": (0, -w, 1), "right_wall": (0, w, -1), "front_wall": (1, -d, 1),
                "rear_wall": (1, d, -1), "floor": (2, 0.0, 1), "ceiling": (2, h, -1)}
        out = {}
        for s in self.ir.surfaces:
            if s.role in spec:
                out[s.role] = spec[s.role] + (s.material,)
            elif s.role not in ("platform", "mesh"):
                raise NotImplementedError("the reference engine supports box interiors only")
        return out

    def _fine_patches(self):
        w, d, h = self._box()
        ext = {0: (-w, w), 1: (-d, d), 2: (0.0, h)}
        cells = []
        for role, (axis, val, sgn, mat) in self._faces().items():
            a1, a2 = [i for i in range(3) if i != axis]
            n1 = max(1, int(round((ext[a1][1] - ext[a1][0]) / self.patch_mm)))
            n2 = max(1, int(round((ext[a2][1] - ext[a2][0]) / self.patch_mm)))
            cells.append((role, axis, val, sgn, mat, a1, a2, n1, n2))
        return cells, ext

    def _locate(self, hit_face, hit_pt, cells, ext, offsets):
        """Patch index of hit points (-1: open face)."""
        idx = np.full(len(hit_face), -1)
        for ci, (role, axis, val, sgn, mat, a1, a2, n1, n2) in enumerate(cells):
            sel = hit_face == (axis * 2 + (0 if sgn > 0 else 1))
            if not sel.any():
                continue
            f1 = (hit_pt[sel, a1] - ext[a1][0]) / (ext[a1][1] - ext[a1][0])
            f2 = (hit_pt[sel, a2] - ext[a2][0]) / (ext[a2][1] - ext[a2][0])
            i1 = np.clip((f1 * n1).astype(int), 0, n1 - 1)
            i2 = np.clip((f2 * n2).astype(int), 0, n2 - 1)
            idx[sel] = offsets[ci] + i1 * n2 + i2
        return idx

    def _plate_cross(self, o, dirs, hit_pt):
        """Bool: does the ray o→hit cross the diffuser plate (when the diffuser effect is on)?"""
        if "diffuser" not in self.fx or self.ir.diffuser is None:
            return None
        d = self.ir.diffuser
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (d.z_mm - o[:, 2]) / dirs[:, 2]
        t_hit = np.linalg.norm(hit_pt - o, axis=1)
        p = o + t[:, None] * dirs
        ok = (t > 1e-9) & (t < t_hit - 1e-9)
        ok &= np.abs(p[:, 0] - d.centre_mm[0]) <= d.size_mm[0] / 2
        ok &= np.abs(p[:, 1] - d.centre_mm[1]) <= d.size_mm[1] / 2
        return ok

    def _plate_T(self):
        diff = self.fx["diffuser"]
        return np.clip(self.ir.diffuser.transmittance.array_1nm * diff.transmittance_scale, 0, 1)

    def _trace(self, o, dirs):
        """Exit face code (axis*2 + 0 for the low bound, 1 for the high) and hit point."""
        w, d, h = self._box()
        lo = np.array([-w, -d, 0.0])
        hi = np.array([w, d, h])
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hi = np.where(dirs > 0, (hi - o) / dirs, np.inf)
            t_lo = np.where(dirs < 0, (lo - o) / dirs, np.inf)
        t = np.minimum(t_hi, t_lo)
        axis = np.argmin(t, axis=1)
        tt = t[np.arange(len(o)), axis]
        high = dirs[np.arange(len(o)), axis] > 0
        return axis * 2 + high.astype(int), o + tt[:, None] * dirs

    def _cos_dirs(self, n, count, rng):
        """Stratified cosine-weighted directions around each normal: (len(n), count, 3)."""
        k = int(np.sqrt(count))
        u1 = (np.repeat(np.arange(k), k)[None] + rng.random((len(n), k * k))) / k
        u2 = (np.tile(np.arange(k), k)[None] + rng.random((len(n), k * k))) / k
        r = np.sqrt(u1)
        phi = 2 * np.pi * u2
        local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1 - u1, 0, 1))], -1)
        t1 = np.where(np.abs(n[:, 0:1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
        t1 = _norm(t1 - n * (t1 * n).sum(1, keepdims=True))
        t2 = np.cross(n, t1)
        return local[..., 0:1] * t1[:, None] + local[..., 1:2] * t2[:, None] + local[..., 2:3] * n[:, None]

    def _solve_radiosity(self):
        if self._radiosity is not None:
            return self._radiosity
        cells, ext = self._fine_patches()
        offsets = np.cumsum([0] + [c[7] * c[8] for c in cells])
        npatch = offsets[-1]
        normals, mats, corners = [], [], []
        for role, axis, val, sgn, mat, a1, a2, n1, n2 in cells:
            e1 = np.linspace(ext[a1][0], ext[a1][1], n1 + 1)
            e2 = np.linspace(ext[a2][0], ext[a2][1], n2 + 1)
            for i in range(n1):
                for j in range(n2):
                    lo = np.zeros(3)
                    hi = np.zeros(3)
                    lo[axis] = hi[axis] = val
                    lo[a1], hi[a1], lo[a2], hi[a2] = e1[i], e1[i + 1], e2[j], e2[j + 1]
                    corners.append((lo, hi))
                    nrm = np.zeros(3)
                    nrm[axis] = sgn
                    normals.append(nrm)
                    mats.append(mat)
        lo = np.array([c[0] for c in corners])
        hi = np.array([c[1] for c in corners])
        normals = np.array(normals)
        rng = np.random.default_rng(777)
        # form factors by cosine-weighted ray casting from jittered points on each patch
        F = np.zeros((npatch, npatch))
        Fx = np.zeros((npatch, npatch))       # the part of F whose rays cross the diffuser plate
        R = self.ff_rays
        for a in range(0, npatch, 64):
            b = min(npatch, a + 64)
            org = lo[a:b, None, :] + rng.random((b - a, R, 3)) * (hi[a:b] - lo[a:b])[:, None, :]
            dirs = self._cos_dirs(normals[a:b], R, rng)
            org = org + 1e-6 * normals[a:b, None, :]
            o_flat, d_flat = org.reshape(-1, 3), dirs.reshape(-1, 3)
            face, pt = self._trace(o_flat, d_flat)
            idx = self._locate(face, pt, cells, ext, offsets).reshape(b - a, -1)
            crs = self._plate_cross(o_flat, d_flat, pt)
            crs = None if crs is None else crs.reshape(b - a, -1)
            for i in range(b - a):
                ok = idx[i] >= 0
                if crs is None:
                    F[a + i] = np.bincount(idx[i][ok], minlength=npatch) / idx.shape[1]
                else:
                    nc = ok & ~crs[i]
                    cc = ok & crs[i]
                    F[a + i] = np.bincount(idx[i][nc], minlength=npatch) / idx.shape[1]
                    Fx[a + i] = np.bincount(idx[i][cc], minlength=npatch) / idx.shape[1]
        # first-order light on each patch: average of 3×3 jittered stratified points
        k = 3
        su = (np.repeat(np.arange(k), k)[None] + rng.random((npatch, k * k))) / k
        sv = (np.tile(np.arange(k), k)[None] + rng.random((npatch, k * k))) / k
        pts = np.repeat(lo[:, None, :], k * k, axis=1)
        for i in range(npatch):
            a1, a2 = [j for j in range(3) if normals[i, j] == 0]
            pts[i, :, a1] = lo[i, a1] + su[i] * (hi[i, a1] - lo[i, a1])
            pts[i, :, a2] = lo[i, a2] + sv[i] * (hi[i, a2] - lo[i, a2])
        pts = pts + 1e-3 * normals[:, None, :]
        flatp = pts.reshape(-1, 3)
        flatn = np.repeat(normals, k * k, axis=0)
        first = self._direct(flatp, flatn, np.zeros(len(flatp), bool), stride=8) + \
            self._plate_light(flatp, flatn, np.zeros(len(flatp), bool))
        # reflectance at spectral nodes (10 nm) — flat materials need one node
        WL = np.arange(360.0, 831.0)
        refl = np.array([self.ir.materials[m].reflectance.array_1nm for m in mats])
        scale = self.fx["interreflection"].reflectance_scale
        refl = np.clip(refl * scale, 0, 0.99)
        plate = self._plate_T() if Fx.any() else np.ones(WL.size)
        flat = np.allclose(refl, refl[:, :1]) and np.allclose(plate, plate[0])
        nodes = np.array([550.0]) if flat else np.arange(380.0, 741.0, 10.0)
        rho = np.stack([np.interp(nodes, WL, r) for r in refl])            # (P, W)
        plate_n = np.interp(nodes, WL, plate)
        E0 = np.stack([g.reshape(npatch, k * k).mean(1) for _, _, g in first], 1)  # (P, K)
        B = np.zeros((len(nodes), npatch, E0.shape[1]))
        for wi in range(len(nodes)):
            r = rho[:, wi][:, None]
            Fw = F + plate_n[wi] * Fx
            x = r * E0
            for _ in range(500):  # Jacobi iteration to convergence
                nx = r * (E0 + Fw @ x)
                if np.max(np.abs(nx - x)) <= 1e-10 * max(np.max(np.abs(nx)), 1e-30):
                    x = nx
                    break
                x = nx
            B[wi] = x
        self._radiosity = dict(cells=cells, ext=ext, offsets=offsets, B=B, nodes=nodes, first=first,
                               plate_n=plate_n)
        return self._radiosity

    def _indirect(self, P, N, meter):
        if "interreflection" not in self.fx:
            return []
        rad = self._solve_radiosity()
        rng = np.random.default_rng(4242)
        out_geo = np.zeros((len(rad["first"]), len(P), len(rad["nodes"])))
        for a in range(len(P)):
            dirs = self._cos_dirs(N[a:a + 1], self.gather_rays, rng)[0]
            org = np.repeat(P[a:a + 1] + 1e-6 * N[a:a + 1], len(dirs), axis=0)
            face, pt = self._trace(org, dirs)
            idx = self._locate(face, pt, rad["cells"], rad["ext"], rad["offsets"])
            ok = idx >= 0
            wgt = np.ones(len(dirs))
            if meter[a]:
                wgt = self._meter(dirs @ N[a])
            crs = self._plate_cross(org, dirs, pt)
            # cosine-weighted estimator: E = mean(B_hit · response [· plate transmittance])
            for k in range(len(rad["first"])):
                if crs is None:
                    out_geo[k, a] = (rad["B"][:, idx[ok], k] * wgt[ok]).sum(1) / len(dirs)
                else:
                    nc, cc = ok & ~crs, ok & crs
                    out_geo[k, a] = ((rad["B"][:, idx[nc], k] * wgt[nc]).sum(1)
                                     + rad["plate_n"] * (rad["B"][:, idx[cc], k] * wgt[cc]).sum(1)) / len(dirs)
        WL = np.arange(360.0, 831.0)
        out = []
        for k, (group, spec, _) in enumerate(rad["first"]):
            if len(rad["nodes"]) == 1:
                g1 = np.repeat(out_geo[k], len(WL), axis=1)
            else:
                g1 = np.stack([np.interp(WL, rad["nodes"], row) for row in out_geo[k]])
            out.append((group, spec, g1))
        return out

    def _first_order(self, P, N, meter):
        return self._direct(P, N, meter) + self._plate_light(P, N, meter)

    # ------------------------------------------------------------------ public
    def spectral_irradiance_1nm(self, points, normals=None, meter=False, by_group=False):
        P = np.atleast_2d(np.asarray(points, float))
        if P.shape[1] == 2:
            P = np.c_[P, np.zeros(len(P))]
        N = np.tile([0, 0, 1.0], (len(P), 1)) if normals is None else _norm(
            np.broadcast_to(np.asarray(normals, float), P.shape).copy())
        m = np.broadcast_to(np.asarray(meter, bool), (len(P),))
        groups: dict = {}
        for group, spec, geo in self._first_order(P, N, m):
            groups[group] = groups.get(group, 0) + np.outer(geo, spec)
        for group, spec, g1 in self._indirect(P, N, m):
            groups[group] = groups.get(group, 0) + g1 * spec[None, :]
        if by_group:
            return groups
        return sum(groups.values())

    def illuminance_lx(self, points, normals=None, meter=True):
        return K_M * self.spectral_irradiance_1nm(points, normals, meter) @ self.V

    def white_tile_radiance_1nm(self, point=None, normal=(0, 0, 1.0), reflectance_1nm=1.0):
        p = self.ir.sample_position_mm if point is None else point
        return np.asarray(reflectance_1nm) * self.spectral_irradiance_1nm([p], [normal], False)[0] / np.pi


register_truth_provider("reference", lambda ir, lighting, **kw: ReferenceEngine(ir, lighting, **kw))


def _mitsuba_truth(ir, lighting, **kw):
    # imported on first use: `import lbscene` must not import mitsuba (an optional extra)
    from .mitsuba import MitsubaTruth

    return MitsubaTruth(ir, lighting, **kw)


register_truth_provider("mitsuba", _mitsuba_truth)
