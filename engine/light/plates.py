"""
Plates as the light transport sees them: the diffuser plate and the occluders.

The diffuser effect's paths, the inter-reflection between surfaces
(:mod:`lbscene.engine.light.radiosity`), the Cycles bake job and the realtime graph all
need the same plate: its rectangle, its transmittance at an incidence angle (the clear
slab's Fresnel law, or the rough slab's :math:`T(θ)` for a ``roughness`` plate, see
:mod:`lbscene.engine.light.rough_slab`), its transmittance for diffuse light, and the
occluders' rectangles with their openings.  They are defined here, once, below the effect
plugins that use them.

Transmittances are relative to the clear slab's at normal incidence :math:`T_0`: times
the declared transmittance :math:`T_\\text{decl}(λ) = a^2 T_0` they are the plate's.

Examples
--------
>>> import numpy as np
>>> round(float(fresnel_relative(np.array([1.0]), 1.5)[0]), 6)      # normal incidence
1.0
>>> bool(fresnel_relative(np.array([0.5]), 1.5)[0] < 1.0)          # 60°: less light through
True
"""

from __future__ import annotations

import numpy as np

from .geometry import Rectangle
from .rough_slab import clear_slab_normal_transmittance, fresnel_slab_transmittance, rough_slab

__all__ = [
    "diffuser_rect",
    "diffuser_fraction",
    "diffuser_transmittance_1nm",
    "is_rough",
    "plate_slab",
    "slab_relative",
    "fresnel_relative",
    "FresnelWeight",
    "plate_lobe_footprint_mm",
    "plate_diffuse_light_factor",
    "occluder_rects",
]


# --------------------------------------------------------------------------- the diffuser plate

def diffuser_rect(ir) -> Rectangle:
    """The booth's diffuser plate as a horizontal :class:`~lbscene.engine.light.geometry.Rectangle`."""
    d = ir.diffuser
    return Rectangle(np.array([d.centre_mm[0], d.centre_mm[1], d.z_mm]), np.array([0.0, 0.0, 1.0]),
                     np.array([1.0, 0.0, 0.0]), (d.size_mm[0] / 2, d.size_mm[1] / 2))


def diffuser_fraction(ir, p) -> float:
    """The part of the plate's light it re-emits diffusely: the diffuser effect's override
    ``p.diffuse_fraction``, else a ``lambertian`` plate's declared fraction, else 0."""
    if p.diffuse_fraction is not None:
        return float(p.diffuse_fraction)
    sc = ir.diffuser.scattering
    if sc.get("type") == "lambertian":
        return float(sc["diffuse_fraction"])
    # rough glass (GGX roughness) is no Lambertian scatterer: its transmission follows the rough
    # slab law (plate_slab), no diffuse part unless the booth overrides the fraction
    return 0.0


def diffuser_transmittance_1nm(ctx, p) -> np.ndarray:
    """The plate's declared spectral transmittance (1 nm) times the diffuser effect's
    ``transmittance_scale``, clipped to [0, 1]; cached in the forward context."""
    key = ("diffuser_T", p.transmittance_scale)
    t = ctx.cache.get(key)
    if t is None:
        t = ctx.cache[key] = np.clip(ctx.ir.diffuser.transmittance.array_1nm * p.transmittance_scale,
                                     0.0, 1.0)
    return t


def is_rough(ir) -> bool:
    """Whether the booth's diffuser is a ``roughness`` plate (rough glass)."""
    return ir.diffuser is not None and ir.diffuser.scattering.get("type") == "roughness"


def plate_slab(ir):
    """The plate's :class:`~lbscene.engine.light.rough_slab.RoughSlab` (GGX, α = roughness²)."""
    d = ir.diffuser
    return rough_slab(float(d.scattering["roughness"]) ** 2, float(d.ior))


def slab_relative(ir, cos_i) -> np.ndarray:
    """The plate's directional transmittance at incidence ``cos_i`` relative to the clear slab's
    at normal incidence, :math:`T(θ_i)/T_0`: the rough slab's (:mod:`~lbscene.engine.light.rough_slab`)
    for a ``roughness`` plate, the clear slab's Fresnel law otherwise.  Times the declared
    transmittance :math:`T_\\text{decl}(λ) = a^2 T_0` it is the plate's transmittance."""
    if is_rough(ir):
        return plate_slab(ir).transmittance(cos_i) / clear_slab_normal_transmittance(ir.diffuser.ior)
    return fresnel_relative(cos_i, ir.diffuser.ior)


def fresnel_relative(cos_i, ior: float) -> np.ndarray:
    """Slab transmittance at incidence ``cos_i`` relative to normal incidence."""
    return fresnel_slab_transmittance(cos_i, ior) / fresnel_slab_transmittance(np.ones(1), ior)[0]


class FresnelWeight:
    """Incidence weight of light entering the plate; ``cache_key`` lets the forward model reuse
    it across parameter changes (it depends on geometry and the refractive index only)."""

    def __init__(self, ior: float):
        self.ior = float(ior)
        self.cache_key = ("fresnel", self.ior)

    def __call__(self, cos_i):
        return fresnel_relative(cos_i, self.ior)


def _lamp_height_mm(ir, lighting) -> float:
    """Mean height of the lamps on above the plate (their centres), at least 1 mm."""
    z = [ir.lamp(i).position_mm[2] - ir.diffuser.z_mm for i in ir.lighting[lighting].lamps]
    z = [h for h in z if h > 0]
    return max(float(np.mean(z)) if z else 1.0, 1.0)


def plate_lobe_footprint_mm(ir, lighting) -> float:
    """Radius on the plate of the rough slab's transmitted lobe (90 % of its light, normal
    incidence) for light from the lamps on: :math:`h \\tan θ_{90}` with :math:`h` the lamps'
    mean height above the plate (0 for a plate that is not ``roughness``)."""
    if not is_rough(ir):
        return 0.0
    l90 = float(plate_slab(ir).lobe_deg(1.0, 0.9))
    return _lamp_height_mm(ir, lighting) * np.tan(np.deg2rad(min(l90, 89.0)))


def plate_diffuse_light_factor(ir) -> float:
    """Transmittance of the plate for diffuse (Lambertian) light relative to its declared
    normal-incidence transmittance: :math:`T_h/T_0` with :math:`T_h = 2\\int_0^1 T(μ) μ\\,dμ`
    of the rough slab; 1 for other plates (their declared transmittance is used as is)."""
    if not is_rough(ir):
        return 1.0
    return float(plate_slab(ir).hemispherical_transmittance()) / \
        clear_slab_normal_transmittance(ir.diffuser.ior)


# --------------------------------------------------------------------------- occluders

def occluder_rects(ir, p) -> list[tuple[object, Rectangle]]:
    """``(IROccluder, Rectangle)`` of the occluders the ``aperture_occlusion`` parameters ``p``
    select (``p.occluders``; all when None), an aperture plate's opening scaled by
    ``p.opening_scale`` (× ``opening_scale_u`` / ``_v``) and kept inside the plate."""
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
