"""
Built-in physical effects (ids are part of the file format: never rename).

Each effect declares the parameters a booth file may give it (``Params``),
its physics as forward-model hooks (see :mod:`lbscene.engine.light.effects.physics`)
and what the diagnosis may fit when it tries the effect (``fit_parameters``).

=====================  ==========  ============================================================
id                     kind        physics
=====================  ==========  ============================================================
angular_profile        geometric   lamps emit I0·f(θ) (declared profile, or Gaussian σ)
interreflection        global      radiosity between floor, walls, ceiling, meshes (spectral ρ)
diffuser               geometric   plate: spectral transmittance, Fresnel angular loss,
                                   Lambertian re-emission of a diffuse fraction; a
                                   ``roughness`` plate: the rough GGX slab's T(θ) on
                                   straight paths, or its BTDF on re-emitting cells when
                                   the lobe is wide (:mod:`lbscene.engine.light.rough_slab`)
aperture_occlusion     geometric   occluders (aperture plates, panels) block lamp→point paths
tube_end_falloff       geometric   tube emission falls linearly toward the ends
spectral_filter        spectral    a filter's transmittance multiplies a lamp's spectrum
detector_cosine_error  instrument  the meter reads cos^k or f2-type response instead of cos
reflector              geometric   a mirror behind the lamp adds a mirror image; blocks behind
=====================  ==========  ============================================================
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from lbscene.schemas.base import Identifier

from .physics import (DirectionalSource, EmitterSet, LambertianSource, PathChannel, PhysicalEffect,
                      fresnel_slab_transmittance)
from .registry import EffectParams, register_effect

__all__ = [
    "AngularProfileEffect",
    "InterreflectionEffect",
    "DiffuserEffect",
    "ApertureOcclusionEffect",
    "TubeEndFalloffEffect",
    "SpectralFilterEffect",
    "LampSpectrumShiftEffect",
    "shifted_spectrum_1nm",
    "lamp_spectrum_1nm",
    "DetectorCosineErrorEffect",
    "ReflectorEffect",
    "f2_linear_coefficient",
]


class _LampSelection(EffectParams):
    lamps: list[Identifier] | None = Field(None, description="Lamps it applies to (default: all on).")


def _selected(p, lamp_id: str) -> bool:
    return p.lamps is None or lamp_id in p.lamps


def _lamps_on(ir, lighting):
    return [ir.lamp(i) for i in ir.lighting[lighting].lamps]


# --------------------------------------------------------------------------- angular profile

@register_effect
class AngularProfileEffect(PhysicalEffect):
    id = "angular_profile"
    summary = "Lamps emit with their declared angular profile instead of isotropically."
    kind = "geometric"
    order = 10
    fit_parameters = {"sigma_deg": (5.0, 1000.0)}
    fit_initial = {"sigma_deg": 60.0}

    class Params(_LampSelection):
        sigma_deg: float | None = Field(
            None, gt=0, le=1000,
            description="Gaussian σ for lamps without a declared profile (seed: I0·exp(−(θ/2σ)²)).")

    @classmethod
    def fit_parameters_for(cls, ir, lighting) -> dict:
        # σ of the effect only matters for lamps that declare no profile of their own
        if any(lp.profile.get("type") == "isotropic" for lp in _lamps_on(ir, lighting)):
            return dict(cls.fit_parameters)
        return {}

    @staticmethod
    def modify_emitters(ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        from lbscene.engine.spectra.profiles import GaussianShape, profile_shape

        if not _selected(p, lamp.id):
            return es
        sigma = ctx.lamp_overrides.get(lamp.id, {}).get("sigma_deg")
        if sigma is not None:
            return es.with_(shape=GaussianShape(float(sigma)))
        if lamp.profile.get("type") != "isotropic":
            key = ("profile", lamp.id)
            shape = ctx.cache.get(key)
            if shape is None:
                shape = ctx.cache[key] = profile_shape(lamp.profile)
            return es.with_(shape=shape)
        if p.sigma_deg is not None:
            return es.with_(shape=GaussianShape(float(p.sigma_deg)))
        return es


# --------------------------------------------------------------------------- inter-reflection

@register_effect
class InterreflectionEffect(PhysicalEffect):
    id = "interreflection"
    summary = ("Light reflected between floor, walls, ceiling and meshes such as a luminaire cavity "
               "(radiosity with spectral reflectances).")
    kind = "global"
    order = 900
    fit_parameters = {"reflectance_scale": (0.05, 2.5)}
    fit_initial = {"reflectance_scale": 1.0}

    class Params(EffectParams):
        patch_size_mm: float = Field(100.0, gt=1, le=1000,
                                     description="Radiosity patch size (smaller: finer, slower).")
        max_bounces: int = Field(0, ge=0, le=100, description="0: solve to convergence.")
        reflectance_scale: float = Field(1.0, gt=0, le=3,
                                         description="Multiplier on all surface reflectances "
                                                     "(clipped at 0.99).")
        mesh_patch_size_mm: float | None = Field(None, gt=1, le=1000,
                                                 description="Patch size on the booth's meshes "
                                                             "(default: a third of the smallest "
                                                             "mesh's smallest extent, at most "
                                                             "patch_size_mm).")
        meshes: bool = Field(True, description="Include the booth's meshes (luminaire cavity, "
                                               "props): both faces reflect, and they block light "
                                               "between surfaces (visibility tested).")
        lamp_bodies: bool = Field(True, description="Lamp bodies (a tube's cylinder, a panel, a "
                                                    "bulb's sphere) block light between surfaces "
                                                    "and other lamps' light on them (absorbing).")

    @classmethod
    def applicable(cls, ir, lighting):
        return None if ir.surfaces else "the booth has no interior surfaces"

    #: the diagnosis refits every candidate: it solves radiosity on patches at least this coarse
    diagnosis_patch_mm: float = 100.0

    @classmethod
    def diagnosis_params(cls, params: dict) -> dict:
        """Parameters used for the diagnosis' many refits (coarser patches: ~0.2 % of the
        illuminance on the test booths, far below meter noise; 16× fewer unknowns than 50 mm)."""
        out = dict(params or {})
        out["patch_size_mm"] = max(float(out.get("patch_size_mm", 100.0)), cls.diagnosis_patch_mm)
        return out

    @classmethod
    def refit_cost_s(cls, ir, params: dict) -> float:
        """Rough seconds per forward evaluation when ``reflectance_scale`` changes (LU per band)."""
        ps = float((params or {}).get("patch_size_mm", 100.0))
        meshes = bool((params or {}).get("meshes", True))
        n = sum(s.area_mm2() for s in ir.surfaces if s.role != "mesh") / ps ** 2
        if meshes:
            from lbscene.engine.light.radiosity import mesh_patch_size_mm

            # both faces of a mesh are patches, at the (finer) mesh patch size
            n += sum(2.0 * s.area_mm2() for s in ir.surfaces if s.role == "mesh") / \
                mesh_patch_size_mm(ir, ps, (params or {}).get("mesh_patch_size_mm")) ** 2
        return 16 * 0.8 * (n / 1000.0) ** 3

    @staticmethod
    def global_transport(ctx, p, model):
        from lbscene.engine.light.radiosity import radiosity_transport

        return radiosity_transport(ctx, p, model)


# --------------------------------------------------------------------------- diffuser

def _diffuser_fraction(ir, p) -> float:
    if p.diffuse_fraction is not None:
        return float(p.diffuse_fraction)
    sc = ir.diffuser.scattering
    if sc.get("type") == "lambertian":
        return float(sc["diffuse_fraction"])
    # rough glass (GGX roughness) is no Lambertian scatterer: its transmission follows the rough
    # slab law (_rough_slab), no diffuse part unless the booth overrides the fraction
    return 0.0


def _is_rough(ir) -> bool:
    return ir.diffuser is not None and ir.diffuser.scattering.get("type") == "roughness"


def _rough_slab(ir):
    """The plate's :class:`~lbscene.engine.light.rough_slab.RoughSlab` (GGX, α = roughness²)."""
    from lbscene.engine.light.rough_slab import rough_slab

    d = ir.diffuser
    return rough_slab(float(d.scattering["roughness"]) ** 2, float(d.ior))


def _slab_relative(ir, cos_i) -> np.ndarray:
    """The plate's directional transmittance at incidence ``cos_i`` relative to the clear slab's
    at normal incidence, :math:`T(θ_i)/T_0`: the rough slab's (:mod:`~lbscene.engine.light.rough_slab`)
    for a ``roughness`` plate, the clear slab's Fresnel law otherwise.  Times the declared
    transmittance :math:`T_\\text{decl}(λ) = a^2 T_0` it is the plate's transmittance."""
    from lbscene.engine.light.rough_slab import clear_slab_normal_transmittance

    if _is_rough(ir):
        return _rough_slab(ir).transmittance(cos_i) / clear_slab_normal_transmittance(ir.diffuser.ior)
    return _fresnel_relative(cos_i, ir.diffuser.ior)


def _lamp_height_mm(ir, lighting) -> float:
    """Mean height of the lamps on above the plate (their centres), at least 1 mm."""
    z = [lp.position_mm[2] - ir.diffuser.z_mm for lp in _lamps_on(ir, lighting)]
    z = [h for h in z if h > 0]
    return max(float(np.mean(z)) if z else 1.0, 1.0)


def plate_lobe_footprint_mm(ir, lighting) -> float:
    """Radius on the plate of the rough slab's transmitted lobe (90 % of its light, normal
    incidence) for light from the lamps on: :math:`h \\tan θ_{90}` with :math:`h` the lamps'
    mean height above the plate (0 for a plate that is not ``roughness``)."""
    if not _is_rough(ir):
        return 0.0
    l90 = float(_rough_slab(ir).lobe_deg(1.0, 0.9))
    return _lamp_height_mm(ir, lighting) * np.tan(np.deg2rad(min(l90, 89.0)))


def plate_diffuse_light_factor(ir) -> float:
    """Transmittance of the plate for diffuse (Lambertian) light relative to its declared
    normal-incidence transmittance: :math:`T_h/T_0` with :math:`T_h = 2\\int_0^1 T(μ) μ\\,dμ`
    of the rough slab; 1 for other plates (their declared transmittance is used as is)."""
    from lbscene.engine.light.rough_slab import clear_slab_normal_transmittance

    if not _is_rough(ir):
        return 1.0
    return float(_rough_slab(ir).hemispherical_transmittance()) / \
        clear_slab_normal_transmittance(ir.diffuser.ior)


def _fresnel_relative(cos_i, ior: float) -> np.ndarray:
    """Slab transmittance at incidence ``cos_i`` relative to normal incidence."""
    return fresnel_slab_transmittance(cos_i, ior) / fresnel_slab_transmittance(np.ones(1), ior)[0]


class FresnelWeight:
    """Incidence weight of light entering the plate; ``cache_key`` lets the forward model reuse
    it across parameter changes (it depends on geometry and the refractive index only)."""

    def __init__(self, ior: float):
        self.ior = float(ior)
        self.cache_key = ("fresnel", self.ior)

    def __call__(self, cos_i):
        return _fresnel_relative(cos_i, self.ior)


def _diffuser_rect(ir):
    from lbscene.engine.light.geometry import Rectangle

    d = ir.diffuser
    return Rectangle(np.array([d.centre_mm[0], d.centre_mm[1], d.z_mm]), np.array([0.0, 0.0, 1.0]),
                     np.array([1.0, 0.0, 0.0]), (d.size_mm[0] / 2, d.size_mm[1] / 2))


@register_effect
class DiffuserEffect(PhysicalEffect):
    id = "diffuser"
    summary = "A plate below the lamps transmits and scatters their light."
    kind = "geometric"
    #: residuals it may explain in the diagnosis: its light's distribution and, through the
    #: plate's spectral transmittance, the spectrum
    channels = ("spatial", "spectral")
    order = 50
    fit_parameters = {"diffuse_fraction": (0.0, 1.0)}
    fit_initial = {"diffuse_fraction": 0.5}

    class Params(EffectParams):
        transmittance_scale: float = Field(1.0, gt=0, le=1.5,
                                           description="Multiplier on the plate's transmittance.")
        diffuse_fraction: float | None = Field(
            None, ge=0, le=1, description="Override of the booth diffuser's diffuse fraction.")
        cell_size_mm: float = Field(50.0, gt=1, le=1000,
                                    description="Cell size of the re-emitting plate (diffuse part; "
                                                "a rough plate's scattered light).")
        rough_transport: Literal["auto", "regular", "scattered"] = Field(
            "auto", description="A roughness plate's light: 'regular' (straight paths times the "
                                "rough slab's transmittance T(θ)), 'scattered' (plate cells "
                                "re-emit through the slab's BTDF), 'auto' (scattered when the "
                                "lobe's footprint on the plate exceeds the cell size).")

    @classmethod
    def applicable(cls, ir, lighting):
        return None if ir.diffuser is not None else "the booth has no diffuser: section"

    @staticmethod
    def _spectrum(ctx, p):
        key = ("diffuser_T", p.transmittance_scale)
        t = ctx.cache.get(key)
        if t is None:
            t = ctx.cache[key] = np.clip(ctx.ir.diffuser.transmittance.array_1nm * p.transmittance_scale,
                                         0.0, 1.0)
        return t

    @staticmethod
    def _scattered(ctx, p) -> bool:
        """Does a roughness plate's light go through the BTDF source (not straight paths)?"""
        if not _is_rough(ctx.ir) or p.rough_transport == "regular":
            return False
        if p.rough_transport == "scattered":
            return True
        return plate_lobe_footprint_mm(ctx.ir, ctx.lighting) > p.cell_size_mm

    @classmethod
    def path_factors(cls, ctx, p, es, rx):
        ir = ctx.ir
        if ir.diffuser is None:
            return None
        hit = ctx.fraction_hitting(es, rx, _diffuser_rect(ir))
        if not hit.any():
            return None
        if cls._scattered(ctx, p):
            # every path through the plate is the directional source's (secondary_sources)
            return [PathChannel(1.0 - hit, None, None)]

        def angular():
            d = rx[:, None, :] - es.points_mm[None, :, :]
            cos_i = np.abs(d[..., 2]) / np.maximum(np.linalg.norm(d, axis=-1), 1e-12)
            return _slab_relative(ir, cos_i)

        rough = float(ir.diffuser.scattering.get("roughness", -1.0)) if _is_rough(ir) else -1.0
        ang = ctx.memo("diffuser_fresnel", (es.points_mm, rx, [ir.diffuser.ior, rough]), angular)
        fd = _diffuser_fraction(ir, p)
        through = hit * (1.0 - fd) * ang
        return [PathChannel(through, "diffuser", cls._spectrum(ctx, p)),
                PathChannel(1.0 - hit, None, None)]

    @staticmethod
    def _cells(d, cell_size_mm):
        """The plate's cells as quads facing down (counter-clockwise seen from below)."""
        (cx, cy), (sx, sy) = d.centre_mm, d.size_mm
        nu = max(1, int(np.ceil(sx / cell_size_mm)))
        nv = max(1, int(np.ceil(sy / cell_size_mm)))
        xs = cx - sx / 2 + sx * np.arange(nu + 1) / nu
        ys = cy - sy / 2 + sy * np.arange(nv + 1) / nv
        X0, Y0 = np.meshgrid(xs[:-1], ys[:-1], indexing="ij")
        X1, Y1 = np.meshgrid(xs[1:], ys[1:], indexing="ij")
        z = d.z_mm
        return np.stack([np.stack([X0, Y0, np.full_like(X0, z)], -1),
                         np.stack([X0, Y1, np.full_like(X0, z)], -1),
                         np.stack([X1, Y1, np.full_like(X0, z)], -1),
                         np.stack([X1, Y0, np.full_like(X0, z)], -1)], axis=2).reshape(-1, 4, 3)

    @classmethod
    def _rough_source(cls, ctx, p, direct, fd):
        """The rough plate's cells as a :class:`DirectionalSource`: per cell and term

        .. math:: L(ω_o) = (1 - f_d)\\,\\frac{T_\\text{decl}(λ)}{T_0}
                  \\sum_{s} w_s \\sum_{e} f_T(ω_{i,se}, ω_o)\\, E_{se},

        the slab's non-absorbing BTDF :math:`f_T` (:mod:`~lbscene.engine.light.rough_slab`) over the
        irradiance :math:`E_{se}` of each emitter point ``e`` at each sub-point ``s`` (area
        weight :math:`w_s`) of the cell's top face, :math:`ω_i` its direction."""
        from lbscene.engine.light.geometry import quad_subpoints
        from lbscene.engine.light.rough_slab import clear_slab_normal_transmittance

        ir = ctx.ir
        d = ir.diffuser
        polys = cls._cells(d, p.cell_size_mm)
        k = 2
        pts, w = quad_subpoints(polys, k)
        top = pts.reshape(-1, 3) + np.array([0.0, 0.0, 1e-3])
        up = np.tile([0.0, 0.0, 1.0], (top.shape[0], 1))
        slab = _rough_slab(ir)
        spec = cls._spectrum(ctx, p) / clear_slab_normal_transmittance(d.ior)
        merged: dict = {}
        for pl in direct.per_point(top, up, exclude=(cls.id,)):
            if pl.term.key in merged:
                t, g, u = merged[pl.term.key]
                merged[pl.term.key] = (t, np.concatenate([g, pl.geo], 1), np.concatenate([u, pl.from_dir], 1))
            else:
                merged[pl.term.key] = (pl.term, np.asarray(pl.geo), pl.from_dir)
        if not merged:
            return None
        C = polys.shape[0]
        descr, E, cos_i, phi_p = [], [], [], []
        for t, g, u in merged.values():
            descr.append(t.derived(spectral_key="diffuser", spectrum_factor=spec, kind="diffuser"))
            # per cell: (C, k*k*N) irradiance × area weight, incidence cosine, azimuth of the
            # light's propagation (away from the emitter)
            E.append(((g.reshape(C, k * k, -1) * w[:, :, None]) * (1.0 - fd)).reshape(C, -1))
            cos_i.append(np.clip(u[..., 2], 0.0, 1.0).reshape(C, -1))
            phi_p.append(np.arctan2(-u[..., 1], -u[..., 0]).reshape(C, -1))

        def radiance(dirs):
            cos_o = np.clip(-dirs[..., 2], 0.0, 1.0)                         # (C, M)
            phi_o = np.arctan2(dirs[..., 1], dirs[..., 0])
            out = np.zeros(dirs.shape[:2] + (len(descr),))
            for j in range(len(descr)):
                f = slab.btdf(cos_i[j][:, None, :], cos_o[:, :, None],
                              phi_o[:, :, None] - phi_p[j][:, None, :])            # (C, M, n)
                out[:, :, j] = np.einsum("cmn,cn->cm", f, E[j])
            return out

        return DirectionalSource(polys, np.tile([0.0, 0.0, -1.0], (C, 1)), radiance, descr)

    @classmethod
    def secondary_sources(cls, ctx, p, direct):
        from lbscene.engine.light.geometry import quad_subpoints

        ir = ctx.ir
        if ir.diffuser is None:
            return []
        fd = _diffuser_fraction(ir, p)
        out = []
        if cls._scattered(ctx, p) and fd < 1:
            src = cls._rough_source(ctx, p, direct, fd)
            if src is not None:
                out.append(src)
        if fd <= 0:
            return out
        d = ir.diffuser
        polys = cls._cells(d, p.cell_size_mm)
        pts, w = quad_subpoints(polys, 2)
        top = pts.reshape(-1, 3) + np.array([0.0, 0.0, 1e-3])
        up = np.tile([0.0, 0.0, 1.0], (top.shape[0], 1))
        # light arriving on the top side: cos-weighted and reduced by the Fresnel angular factor
        terms = direct(top, up, exclude=(cls.id,), incidence_weight=FresnelWeight(d.ior))
        T = cls._spectrum(ctx, p)
        exit_, descr = [], []
        for t in terms:
            e = (t.geo.reshape(polys.shape[0], -1) * w).sum(axis=1)
            exit_.append(fd * e)
            descr.append(t.derived(spectral_key="diffuser", spectrum_factor=T, kind="diffuser"))
        if not exit_:
            return out
        return out + [LambertianSource(polys, np.tile([0.0, 0.0, -1.0], (polys.shape[0], 1)),
                                       np.stack(exit_, axis=1), descr)]


# --------------------------------------------------------------------------- occluders

def _occluder_rects(ir, p):
    from lbscene.engine.light.geometry import Rectangle

    out = []
    for o in ir.occluders:
        if p.occluders is not None and o.id not in p.occluders:
            continue
        n = np.asarray(o.normal, float)
        u = np.asarray(o.u_axis, float)
        u = u - n * (u @ n)
        u = u / np.linalg.norm(u)
        half = (o.size_mm[0] / 2, o.size_mm[1] / 2)
        hole = None
        if o.type == "aperture_plate" and o.opening_mm is not None:
            hole = (min(o.opening_mm[0] * p.opening_scale * p.opening_scale_u / 2, half[0]),
                    min(o.opening_mm[1] * p.opening_scale * p.opening_scale_v / 2, half[1]))
        out.append((o, Rectangle(np.asarray(o.centre_mm, float), n, u, half, hole)))
    return out


@register_effect
class ApertureOcclusionEffect(PhysicalEffect):
    id = "aperture_occlusion"
    summary = "The luminaire cavity, an aperture or another occluder blocks part of the lamp light."
    kind = "geometric"
    order = 40
    fit_parameters = {"opening_scale": (0.3, 3.0)}
    fit_initial = {"opening_scale": 1.0}

    class Params(EffectParams):
        occluders: list[Identifier] | None = Field(None, description="Occluders used (default: all).")
        opening_scale: float = Field(1.0, gt=0, le=5, description="Multiplier on aperture openings.")
        opening_scale_u: float = Field(1.0, gt=0, le=5, description="Further multiplier on the openings' "
                                       "u extent (fitted for an undeclared aperture, see hypotheses).")
        opening_scale_v: float = Field(1.0, gt=0, le=5, description="Further multiplier on the openings' "
                                       "v extent.")

    @classmethod
    def applicable(cls, ir, lighting):
        on = set(ir.lighting[lighting].lamps)
        if not any(o.lamps is None or on & set(o.lamps) for o in ir.occluders):
            return "the booth has no occluders: (apertures, cavity panels) for the lamps on"
        return None

    @staticmethod
    def path_factors(ctx, p, es, rx):
        key = ("occ", p.opening_scale, p.opening_scale_u, p.opening_scale_v, tuple(p.occluders or ()))
        rects = ctx.cache.get(key)
        if rects is None:
            rects = ctx.cache[key] = _occluder_rects(ctx.ir, p)
        blocked = None
        for o, rect in rects:
            if o.lamps is not None and es.lamp_id not in o.lamps:
                continue
            b = ctx.fraction_hitting(es, rx, rect)
            # several occluders on one path: the blocked fractions combine as independent
            blocked = b if blocked is None else 1.0 - (1.0 - blocked) * (1.0 - b)
        if blocked is None or not blocked.any():
            return None
        return [PathChannel(1.0 - blocked)]


# --------------------------------------------------------------------------- tube ends

@register_effect
class TubeEndFalloffEffect(PhysicalEffect):
    id = "tube_end_falloff"
    summary = "Emission of tubes falls toward their ends (cathodes, phosphor ageing)."
    kind = "geometric"
    order = 20
    fit_parameters = {"end_level": (0.0, 1.0), "falloff_length_mm": (5.0, 1000.0)}
    fit_initial = {"end_level": 0.5, "falloff_length_mm": 100.0}
    helpers = ("weight",)

    class Params(_LampSelection):
        falloff_length_mm: float = Field(100.0, gt=0, le=2000,
                                         description="Length over which emission falls at each end.")
        end_level: float = Field(0.5, ge=0, le=1, description="Relative emission at the very end.")

    @classmethod
    def applicable(cls, ir, lighting):
        if not any(lp.kind == "tube" for lp in _lamps_on(ir, lighting)):
            return "no tube lamp is on"
        return None

    @staticmethod
    def weight(distance_from_end_mm, p) -> np.ndarray:
        """Relative emission at a distance from the nearer tube end (linear ramp)."""
        t = np.clip(np.asarray(distance_from_end_mm, float) / p.falloff_length_mm, 0.0, 1.0)
        return p.end_level + (1.0 - p.end_level) * t

    @classmethod
    def modify_emitters(cls, ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        if lamp.kind != "tube" or not _selected(p, lamp.id):
            return es
        d_end = (0.5 - np.abs(es.s)) * lamp.length_mm
        return es.with_(weights=es.weights * cls.weight(d_end, p))


# --------------------------------------------------------------------------- spectral filter

@register_effect
class SpectralFilterEffect(PhysicalEffect):
    id = "spectral_filter"
    summary = "A spectral filter in front of a lamp changes its spectrum."
    kind = "spectral"
    order = 30

    class Params(EffectParams):
        filter: Identifier | None = Field(None, description="Filter id applied to `lamps` "
                                          "(default: each lamp's own `filter:`).")
        lamps: list[Identifier] | None = None

    @classmethod
    def applicable(cls, ir, lighting):
        if not ir.filters:
            return "the booth has no filters: section"
        if not any(lp.filter for lp in _lamps_on(ir, lighting)):
            return "no lamp that is on names a filter (give `filter:` and `lamps:` to the effect)"
        return None

    helpers = ("filter_for",)

    @staticmethod
    def filter_for(ir, p, lamp) -> str | None:
        """The filter in front of ``lamp``: the effect's ``filter`` (or the lamp's own) when the
        effect selects the lamp, and the booth defines it; else None."""
        if p.lamps is not None and lamp.id not in p.lamps:
            return None
        fid = p.filter if p.filter is not None else lamp.filter
        return fid if fid and fid in ir.filters else None

    @classmethod
    def modify_emitters(cls, ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        fid = cls.filter_for(ctx.ir, p, lamp)
        if fid is None:
            return es
        t = ctx.ir.filters[fid].transmittance.array_1nm
        return es.with_(spectrum_1nm=es.spectrum_1nm * t, spectral_key=es.spectral_key + (f"filter:{fid}",))


# --------------------------------------------------------------------------- lamp spectrum shift

def shifted_spectrum_1nm(values_1nm, shift_nm: float, tilt: float = 0.0) -> np.ndarray:
    """A 1 nm spectrum (360–830 nm) moved by ``shift_nm`` and tilted.

    .. math:: S'(λ) = S(λ − Δλ)\\,\\bigl(1 + t\\,(λ − 555)/200\\bigr)

    ``Δλ > 0`` moves every feature to longer wavelengths (linear interpolation; zero outside
    the sampled range); the tilt ``t`` (clipped so the factor stays ≥ 0) is the slow change of a
    lamp's colour with age.  Δλ = 0 and t = 0 return the spectrum unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> s = np.zeros(471); s[200] = 1.0                 # a line at 560 nm
    >>> int(np.argmax(shifted_spectrum_1nm(s, 3.0)))    # now at 563 nm
    203
    """
    v = np.asarray(values_1nm, float)
    wl = np.arange(360.0, 360.0 + v.size)
    out = np.interp(wl - shift_nm, wl, v, left=0.0, right=0.0) if shift_nm else v.copy()
    if tilt:
        out = out * np.clip(1.0 + tilt * (wl - 555.0) / 200.0, 0.0, None)
    return out


@register_effect
class LampSpectrumShiftEffect(PhysicalEffect):
    id = "lamp_spectrum_shift"
    summary = "The lamps' spectrum differs from the declared one: a wavelength shift and a tilt (ageing)."
    kind = "spectral"
    order = 29
    fit_parameters = {"shift_nm": (-15.0, 15.0), "tilt": (-0.5, 0.5)}
    fit_initial = {"shift_nm": 0.0, "tilt": 0.0}

    class Params(_LampSelection):
        shift_nm: float = Field(0.0, ge=-50, le=50, description="Wavelength shift of the whole spectrum "
                                "(positive: toward the red).")
        tilt: float = Field(0.0, ge=-1, le=1, description="Relative slope of a linear tilt per 200 nm, "
                            "around 555 nm (positive: redder).")

    @staticmethod
    def modify_emitters(ctx, p, lamp, es: EmitterSet) -> EmitterSet:
        if not _selected(p, lamp.id) or (p.shift_nm == 0.0 and p.tilt == 0.0):
            return es
        return es.with_(spectrum_1nm=shifted_spectrum_1nm(es.spectrum_1nm, p.shift_nm, p.tilt),
                        spectral_key=es.spectral_key + (f"shift:{p.shift_nm:.6g}:{p.tilt:.6g}",))


def lamp_spectrum_1nm(ir, lamp, effects: dict) -> np.ndarray:
    """Peak spectral intensity of ``lamp`` (W·sr⁻¹·nm⁻¹) after the lamp-spectrum effects enabled
    in ``effects`` — ``lamp_spectrum_shift``, then ``spectral_filter`` — exactly as the forward
    model's emitters carry it.  The backends that take a lamp's spectrum as a whole (reference
    engine, Cycles bake, realtime graph, USD stage, Mitsuba truth) read it here, so each effect
    means one thing everywhere."""
    from .physics import effect_params

    e = np.asarray(lamp.peak_intensity_1nm, float)
    if "lamp_spectrum_shift" in effects:
        p = effect_params(LampSpectrumShiftEffect, effects["lamp_spectrum_shift"])
        if _selected(p, lamp.id):
            e = shifted_spectrum_1nm(e, p.shift_nm, p.tilt)
    if "spectral_filter" in effects:
        p = effect_params(SpectralFilterEffect, effects["spectral_filter"])
        fid = SpectralFilterEffect.filter_for(ir, p, lamp)
        if fid is not None:
            e = e * ir.filters[fid].transmittance.array_1nm
    return e


# --------------------------------------------------------------------------- meter cosine error

def f2_linear_coefficient(f2_percent: float) -> float:
    """Coefficient c of the response cos ε·(1 − c·ε/(π/2)) whose CIE f2 error is ``f2_percent``.

    CIE 69 / ISO/CIE 19476: f2 = ∫₀^{85°} |Y(ε)/(Y(0)·cos ε) − 1| sin 2ε dε.
    """
    eps = np.linspace(0.0, np.radians(85.0), 2001)
    unit = np.trapz((eps / (np.pi / 2)) * np.sin(2 * eps), eps)
    return float(f2_percent / 100.0 / unit)


@register_effect
class DetectorCosineErrorEffect(PhysicalEffect):
    id = "detector_cosine_error"
    summary = "The illuminance meter's imperfect cosine response (f2 error)."
    kind = "instrument"
    order = 200
    # a meter's response: Cycles' sensors and the realtime view are ideal cosine receivers
    backends = frozenset({"forward", "reference"})
    fit_parameters = {"exponent": (0.5, 2.0)}
    fit_initial = {"exponent": 1.05}

    class Params(EffectParams):
        model: Literal["power", "f2_linear"] = "power"
        exponent: float = Field(1.1, gt=0, le=5,
                                description="Response ∝ cos(θ)^exponent (power model).")
        f2_percent: float = Field(3.0, ge=0, le=50, description="CIE f2 error (f2_linear model).")

    @classmethod
    def fit_parameters_for(cls, ir, lighting) -> dict:
        return dict(cls.fit_parameters)

    @staticmethod
    def receiver_response(ctx, p, cos_i: np.ndarray) -> np.ndarray:
        """Meter reading relative to an ideal cosine receiver, per incidence cosine."""
        c = np.clip(cos_i, 0.0, 1.0)
        if p.model == "power":
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(c > 0, c ** (p.exponent - 1.0), 0.0)
        k = f2_linear_coefficient(p.f2_percent)
        eps = np.arccos(c)
        return np.clip(1.0 - k * eps / (np.pi / 2), 0.0, None)


# --------------------------------------------------------------------------- reflector

def _mirror_rect(ir, lamp, refl):
    from lbscene.engine.light.geometry import Rectangle

    n = np.asarray(refl.normal, float)
    c = np.asarray(lamp.position_mm, float) - n * refl.distance_mm
    ax = np.asarray(lamp.axis, float)
    ax = ax - n * (ax @ n)
    if np.linalg.norm(ax) < 1e-9:                   # lamp axis along the mirror normal
        ax = np.cross(n, [1.0, 0.0, 0.0])
        if np.linalg.norm(ax) < 1e-9:
            ax = np.cross(n, [0.0, 1.0, 0.0])
    ax = ax / np.linalg.norm(ax)
    along = (lamp.length_mm if lamp.kind in ("tube", "panel") else refl.width_mm) / 2
    return Rectangle(c, n, ax, (along, refl.width_mm / 2))


@register_effect
class ReflectorEffect(PhysicalEffect):
    id = "reflector"
    summary = "Mirrors behind lamps send back-emitted light forward."
    kind = "geometric"
    order = 60
    fit_parameters = {"reflectance_scale": (0.05, 1.5)}
    fit_initial = {"reflectance_scale": 1.0}

    class Params(_LampSelection):
        reflectance_scale: float = Field(1.0, gt=0, le=1.5)

    @classmethod
    def applicable(cls, ir, lighting):
        if not any(lp.reflector for lp in _lamps_on(ir, lighting)):
            return "no lamp that is on has a reflector:"
        return None

    @staticmethod
    def extra_emitters(ctx, p, lamp, es: EmitterSet) -> list[EmitterSet]:
        if not lamp.reflector or not _selected(p, lamp.id) or lamp.reflector not in ctx.ir.reflectors:
            return []
        refl = ctx.ir.reflectors[lamp.reflector]
        rect = _mirror_rect(ctx.ir, lamp, refl)
        n = rect.normal
        pts = es.points_mm - 2.0 * ((es.points_mm - rect.centre) @ n)[:, None] * n[None, :]
        R = np.clip(refl.reflectance.array_1nm * p.reflectance_scale, 0.0, 1.0)

        def reflect(u, n=n):
            return u - 2.0 * (u @ n)[..., None] * n

        half = None if es.half_step is None else es.half_step - 2.0 * (es.half_step @ n) * n
        return [es.with_(points_mm=pts, spectrum_1nm=es.spectrum_1nm * R, half_step=half,
                         spectral_key=es.spectral_key + (f"reflector:{lamp.reflector}",),
                         direction_map=reflect, tag=f"image:{lamp.reflector}",
                         meta={**es.meta, "mirror": rect})]

    @staticmethod
    def path_factors(ctx, p, es, rx):
        lamp = ctx.ir.lamp(es.lamp_id)
        if not lamp.reflector or not _selected(p, lamp.id) or lamp.reflector not in ctx.ir.reflectors:
            return None
        if es.tag.startswith("image:"):
            # the image shines only through the mirror's extent, and past the lamp itself: light
            # the mirror sends back toward the lamp's own body is stopped there (below a tube
            # under its mirror the image is hidden entirely)
            rect = es.meta["mirror"]
            f = ctx.fraction_hitting(es, rx, rect)
            from lbscene.engine.light.geometry import lamp_body

            body = lamp_body(lamp) if lamp.mount == "booth" else None
            if body is not None:
                f = f * ctx.fraction_past_body(es, rx, body)
            return [PathChannel(f)]
        rect = _mirror_rect(ctx.ir, lamp, ctx.ir.reflectors[lamp.reflector])
        blocked = ctx.fraction_hitting(es, rx, rect)
        if not blocked.any():
            return None
        return [PathChannel(1.0 - blocked)]
