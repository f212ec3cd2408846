"""
Plates as the light transport sees them: the diffuser plate and the occluders.

The diffuser effect's paths, the inter-reflection between surfaces
(:mod:`lbscene.engine.light.radiosity`), the Cycles bake job and the realtime graph all
need the same plate: its rectangle, its transmittance at an incidence angle (the clear
slab's Fresnel law, or the rough slab's :math:`T(θ)` for a ``roughness`` plate, see
:mod:`lbscene.engine.light.rough_slab`), its transmittance for diffuse light, and the
occluders' rectangles with their openings.  They are defined here, once, below the effect
plugins that use them.

The declared ``transmittance`` :math:`T_\\text{decl}(λ)` is what a datasheet or a
spectrophotometer gives: the plate's *total* transmittance at normal incidence (regular and
scattered light together).  Each plate type has its own non-absorbing model (the clear slab,
the rough GGX slab, the opal plate below) with total normal transmittance :math:`T_\\text{ref}`
(:func:`reference_transmittance`); the bulk absorption is what is left,

.. math:: a^2(λ) = T_\\text{decl}(λ) / T_\\text{ref},

and the transmittances here are relative to :math:`T_\\text{ref}`: times :math:`T_\\text{decl}`
they are the plate's.  (A rough slab transmits less than the clear one at normal incidence,
0.81 instead of 0.925 for PMMA with GGX α 0.3: dividing a declared 0.81 by the clear slab's
value would apply the rough slab's own losses twice.)

An opal (``lambertian``) plate is a scattering layer behind two faces of index :math:`n`
(:math:`n = 1`: faces matched to the air, no Fresnel boundary), declared by its total normal
transmittance :math:`T_\\text{decl}` and diffuse fraction :math:`f_d`.  Its regular part
:math:`(1 - f_d) T_\\text{decl}` is the light that crosses the layer unscattered; with the faces'
Fresnel reflectance :math:`F` and the layer's optical depth :math:`τ` it is

.. math:: T_\\text{reg}(θ_i) = \\frac{(1 - F)^2 e^{-τ/\\cos θ_t}}{1 - F^2 e^{-2τ/\\cos θ_t}},

which gives :math:`τ` from the declaration (:func:`opal_optical_depth`) and the regular part's
angular law (:func:`opal_regular_relative`).  The layer is a Henyey–Greenstein medium whose
asymmetry makes the non-absorbing plate transmit :math:`T_\\text{decl}` in total
(:func:`opal_plate_layer`; the medium Mitsuba 3 and the bake draw): its scattered light, every
incoming and outgoing direction, is the plane-parallel solution of
:mod:`lbscene.engine.light.opal_layer` (adding–doubling; no constant fitted).  The forward
model's direct light through the plate uses it whole (bidirectional, every azimuth); the
inter-reflection takes its directional-hemispherical parts: the scattered transmittance at
incidence :math:`θ_i` relative to normal incidence :math:`t(θ_i) = T_s(θ_i)/T_s(0)`
(:meth:`~lbscene.engine.light.opal_layer.OpalLayer.entry_relative`), by reciprocity the shape of
the radiance it sends on under diffuse light, :math:`L(θ_o) = \\frac{M}{π}\\,t(θ_o)/t_h`,
:math:`t_h = 2\\int_0^1 t(μ)\\,μ\\,dμ`, and what does not leave through the far face (nor is
absorbed, in the same proportion) comes back: :math:`R(θ_i) = 1 - T(θ_i) - A_0\\,t(θ_i)`, with
:math:`A_0 = 1 - T_\\text{decl} - R_\\text{decl}` and the declared normal reflectance
:math:`R_\\text{decl}` (default :math:`1 - T_\\text{decl}`: a plate that does not absorb).
Measured in Mitsuba 3 (a non-absorbing Henyey–Greenstein medium between smooth or index-matched
faces, ``tests/data/validation/plate-optics/``) five plates follow these laws within 1 % to 70°.

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

from .geometry import Rectangle, gauss_legendre
from .rough_slab import fresnel_slab_transmittance, rough_slab

__all__ = [
    "reference_transmittance",
    "absorption_squared",
    "interface_fresnel",
    "plate_reflectance",
    "plate_hemispherical_reflectance",
    "opal_declared_reflectance",
    "diffuser_rect",
    "diffuser_fraction",
    "diffuser_transmittance_1nm",
    "fitted_plate",
    "plate_as_fitted",
    "is_rough",
    "plate_slab",
    "specular_plate",
    "plate_top_mm",
    "slab_relative",
    "slab_crossing",
    "fresnel_relative",
    "FresnelWeight",
    "opal_optical_depth",
    "opal_depth",
    "opal_plate_layer",
    "plate_scatters_diffusely",
    "plate_line_relative",
    "plate_diffuse_transfer",
    "opal_regular_relative",
    "plate_lobe_footprint_mm",
    "plate_diffuse_light_factor",
    "plate_directional_relative",
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


def fitted_plate(ir, transmittance_scale: float = 1.0, diffuse_fraction: float | None = None):
    """The booth ``ir`` with its plate as the diffuser effect's parameters make it: the declared
    transmittance times ``transmittance_scale`` (clipped to [0, 1]) and, for an opal
    (``lambertian``) plate, the diffuse fraction ``diffuse_fraction`` where given.

    The plate functions of this module read the plate from the booth: an opal plate's optical
    depth (:func:`opal_depth`) and the asymmetry of its layer (:func:`opal_plate_layer`) follow
    from its declared total and diffuse fraction.  A fit that varies either (the diagnosis' plate
    hypothesis fits both) hands them this booth, so that the plate's angular law, its
    reflectance and its transfer between faces move with its level, everywhere the plate is
    read: the lamps' light through it and the inter-reflection alike.  ``ir`` itself when
    nothing changes.

    Examples
    --------
    >>> from lbscene.engine.scene.compile import compile_booth
    >>> ir = compile_booth("tests/data/validation/opal-grey")          # doctest: +SKIP
    >>> ir.diffuser.transmittance.array_1nm[0]                          # doctest: +SKIP
    0.65
    >>> fitted_plate(ir, 0.5).diffuser.transmittance.array_1nm[0]      # doctest: +SKIP
    0.325
    """
    d = ir.diffuser
    if d is None:
        return ir
    upd = {}
    if transmittance_scale != 1.0:
        # a spectrum of the declaration's own type (the scene layer's, above this one)
        T = np.clip(d.transmittance.array_1nm * float(transmittance_scale), 0.0, 1.0)
        upd["transmittance"] = type(d.transmittance).from_1nm(T, ir.grid)
    sc = d.scattering
    if diffuse_fraction is not None and sc.get("type") == "lambertian" and \
            float(diffuse_fraction) != float(sc.get("diffuse_fraction", 0.0)):
        upd["scattering"] = {**sc, "diffuse_fraction": float(diffuse_fraction)}
    return ir.model_copy(update={"diffuser": d.model_copy(update=upd)}) if upd else ir


def plate_as_fitted(ctx, p):
    """:func:`fitted_plate` of the forward context's booth at the diffuser effect's parameters
    ``p`` (``ctx.ir`` when ``p`` is None), kept in the context's cache."""
    if p is None or ctx.ir.diffuser is None:
        return ctx.ir
    key = (float(p.transmittance_scale), None if p.diffuse_fraction is None else float(p.diffuse_fraction))
    store = ctx.cache.setdefault("_fitted_plate", {})
    hit = store.get(key)
    if hit is None or hit[0] is not ctx.ir:
        hit = store[key] = (ctx.ir, fitted_plate(ctx.ir, *key))
    return hit[1]


def is_rough(ir) -> bool:
    """Whether the booth's diffuser is a ``roughness`` plate (rough glass)."""
    return ir.diffuser is not None and ir.diffuser.scattering.get("type") == "roughness"


def specular_plate(ir, p) -> bool:
    """Does the plate reflect the lamps' light as mirror images (a clear or rough plate with
    ``plate_reflection: specular``)?"""
    d = ir.diffuser
    return d is not None and p.plate_reflection == "specular" and d.scattering.get("type") != "lambertian"


def plate_top_mm(ir) -> float:
    """Height of the plate's top face (mm)."""
    return float(ir.diffuser.z_mm + ir.diffuser.thickness_mm / 2)


def plate_slab(ir):
    """The plate's :class:`~lbscene.engine.light.rough_slab.RoughSlab` (GGX, α = roughness²)."""
    d = ir.diffuser
    return rough_slab(float(d.scattering["roughness"]) ** 2, float(d.ior))


def slab_relative(ir, cos_i, fd: float | None = None) -> np.ndarray:
    """The plate's directional transmittance at incidence ``cos_i`` relative to its own at
    normal incidence, :math:`T(θ_i)/T_\\text{ref}`: the rough slab's
    (:mod:`~lbscene.engine.light.rough_slab`) for a ``roughness`` plate, an opal plate's regular
    part (:func:`opal_regular_relative`, its optical depth from the diffuse fraction ``fd``,
    default the declared one), the clear slab's Fresnel law otherwise.  Times the declared total
    transmittance :math:`T_\\text{decl}(λ) = a^2 T_\\text{ref}` it is the plate's."""
    if is_rough(ir):
        return plate_slab(ir).transmittance(cos_i) / reference_transmittance(ir)
    if ir.diffuser.scattering.get("type") == "lambertian":
        return opal_regular_relative(cos_i, ir.diffuser.ior, opal_depth(ir, fd))
    return fresnel_relative(cos_i, ir.diffuser.ior)


#: Newton steps of :func:`slab_crossing` (monotone from below: 1e-12 relative after 5 for any
#: plate thinner than the path)
_CROSSING_STEPS = 6


def slab_crossing(src_mm, rx_mm, z_mid_mm: float, thickness_mm: float, ior: float):
    """How a plate of finite thickness bends the straight path from a source point to a
    receiver: ``(cos_theta, spread)``, each of shape ``(len(rx), len(src))``.

    A ray crosses the slab (faces at :math:`z_\\text{mid} ± t/2`, index :math:`n`) refracted
    toward the normal and leaves it parallel to its entry, so the path from a source a height
    :math:`h_s` above its near face to a receiver :math:`h_r` beyond its far face, a horizontal
    distance :math:`ρ` apart, has :math:`u = \\tan θ` with

    .. math:: ρ(u) = (h_s + h_r)\\,u + \\frac{t\\,u}{\\sqrt{n^2 + (n^2 - 1)u^2}},

    (solved by Newton from :math:`u_0 = ρ/(h_s + h_r + t/n)`, below the root of this concave
    function).  The receiver sees the source through a ray tube that spreads less inside the
    plate: per unit area across the ray it receives

    .. math:: \\frac{dΩ}{dA_⊥} = \\frac{u}{(1 + u^2)\\,ρ\\,ρ'(u)}

    of the source's intensity instead of the straight line's :math:`1/r^2 = 1/(D^2(1 + u'^2))`,
    :math:`D = h_s + h_r + t`, :math:`u' = ρ/D`.  ``spread`` is their ratio (near the normal
    :math:`(D/(h_s + h_r + t/n))^2`: a 3 mm PMMA plate between a tube 50 mm above it and a floor
    600 mm below brightens the floor by 0.3 %, the apparent source being 1 mm closer); ``cos_theta``
    is :math:`\\cos θ` of the refracted path's outer legs (the incidence on the plate).  Pairs not
    on opposite sides of the plate (or inside it) get the straight line's values and spread 1.
    The source's intensity and the receiver's cosine are left at the straight line's direction
    (it differs from the path's by about :math:`t(1 - 1/n)/D` relative in :math:`\\tan θ`)."""
    S = np.asarray(src_mm, float)
    P = np.asarray(rx_mm, float)
    d = P[:, None, :] - S[None, :, :]
    rho = np.hypot(d[..., 0], d[..., 1])
    r = np.sqrt(rho * rho + d[..., 2] ** 2)
    cos_line = np.abs(d[..., 2]) / np.maximum(r, 1e-12)
    zs = S[None, :, 2] - z_mid_mm
    zr = P[:, None, 2] - z_mid_mm
    half = 0.5 * float(thickness_mm)
    crosses = (zs * zr < 0) & (np.abs(zs) > half) & (np.abs(zr) > half)
    n = float(ior)
    if half <= 0 or n <= 1.0 or not np.any(crosses):
        return cos_line, np.ones_like(cos_line)
    t = 2.0 * half
    h = np.where(crosses, np.abs(zs) + np.abs(zr) - t, 1.0)
    k = n * n - 1.0
    u = rho / (h + t / n)
    for _ in range(_CROSSING_STEPS):
        q = n * n + k * u * u
        f = h * u + t * u / np.sqrt(q) - rho
        u = u - f / (h + t * n * n / q ** 1.5)
    q = n * n + k * u * u
    drho = h + t * n * n / q ** 1.5
    # u/ρ at ρ → 0 is 1/ρ'(0) = 1/(h + t/n)
    u_over_rho = np.where(rho > 1e-9, u / np.maximum(rho, 1e-300), 1.0 / (h + t / n))
    D = h + t
    spread = u_over_rho / ((1.0 + u * u) * drho) * (D * D + rho * rho)
    cos_path = 1.0 / np.sqrt(1.0 + u * u)
    return np.where(crosses, cos_path, cos_line), np.where(crosses, spread, 1.0)


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
        d = ir.diffuser
        if d.scattering.get("type") != "lambertian":
            return _hemispherical(lambda mu: fresnel_relative(mu, d.ior))
        fd = float(d.scattering["diffuse_fraction"])
        tau = opal_depth(ir, fd)
        layer = opal_plate_layer(ir, fd)
        return (1.0 - fd) * _hemispherical(lambda mu: opal_regular_relative(mu, d.ior, tau)) + \
            fd * _hemispherical(layer.entry_relative)
    return float(plate_slab(ir).hemispherical_transmittance()) / reference_transmittance(ir)


def plate_directional_relative(ir, cos_i) -> np.ndarray:
    """The plate's total directional transmittance at ``cos_i`` relative to its own at normal
    incidence (regular and scattered parts): the rough slab's :math:`T(θ)/T_\\text{ref}`, an opal
    plate's :math:`(1 - f_d) T_\\text{reg}(θ)/T_\\text{reg}(0) + f_d\\,t(θ)`, the clear slab's
    law.  By reciprocity it is also the radiance seen through the plate along ``cos_i`` under a
    uniform sky on its other side, relative to normal incidence: the factor, times the declared
    total transmittance, of inter-reflected light crossing the plate along a line."""
    d = ir.diffuser
    if is_rough(ir) or d.scattering.get("type") != "lambertian":
        return slab_relative(ir, cos_i)
    fd = float(d.scattering["diffuse_fraction"])
    tau = opal_depth(ir, fd)
    return (1.0 - fd) * opal_regular_relative(cos_i, d.ior, tau) + fd * opal_plate_layer(ir, fd).entry_relative(cos_i)


def plate_scatters_diffusely(ir) -> bool:
    """Does the plate scatter part of its light through its layer (an opal plate with a diffuse
    fraction), so that the inter-reflection carries that part from face to face rather than
    along straight lines?"""
    d = ir.diffuser
    return (d is not None and d.scattering.get("type") == "lambertian"
            and float(d.scattering.get("diffuse_fraction", 0.0)) > 0.0)


def plate_line_relative(ir, cos_i) -> np.ndarray:
    """The part of :func:`plate_directional_relative` that crosses the plate along a straight
    line: all of it for a clear or rough plate, the regular part
    :math:`(1 - f_d) T_\\text{reg}(θ)/T_\\text{reg}(0)` for an opal plate (its scattered part
    leaves the far face from where it arrived: :func:`plate_diffuse_transfer`)."""
    if not plate_scatters_diffusely(ir):
        return plate_directional_relative(ir, cos_i)
    d = ir.diffuser
    fd = float(d.scattering["diffuse_fraction"])
    return (1.0 - fd) * opal_regular_relative(cos_i, d.ior, opal_depth(ir, fd))


def plate_diffuse_transfer(ir) -> float:
    """The part of diffuse (Lambertian) light arriving on one face of an opal plate that leaves
    the other face scattered, relative to the declared total normal transmittance:
    :math:`f_d\\,t_h`, :math:`t_h = 2\\int_0^1 t(μ)\\,μ\\,dμ` (0 for other plates)."""
    if not plate_scatters_diffusely(ir):
        return 0.0
    fd = float(ir.diffuser.scattering["diffuse_fraction"])
    return fd * _hemispherical(opal_plate_layer(ir, fd).entry_relative)


def _hemispherical(f) -> float:
    """:math:`2\\int_0^1 f(μ)\\,μ\\,dμ` (Gauss–Legendre)."""
    x, w = gauss_legendre(64)
    mu = 0.5 * (x + 1.0)
    return float(np.sum(w * f(mu) * mu))


def reference_transmittance(ir) -> float:
    """:math:`T_\\text{ref}`: the plate model's own total transmittance at normal incidence
    without absorption — the rough slab's :math:`T(0°)` for a ``roughness`` plate, 1 for the
    others (their laws, :func:`fresnel_relative`, :func:`opal_regular_relative` and the opal
    layer's :math:`t(θ)`, are already
    relative to normal incidence).  The declared transmittance over it is the absorption
    :math:`a^2` (:func:`absorption_squared`)."""
    if is_rough(ir):
        return float(plate_slab(ir).transmittance(np.ones(1))[0])
    return 1.0


def absorption_squared(ir, transmittance) -> np.ndarray:
    """:math:`a^2 = T_\\text{decl}/T_\\text{ref}` clipped to [0, 1] (``transmittance``: the
    declared total normal transmittance, any shape)."""
    return np.clip(np.asarray(transmittance, float) / reference_transmittance(ir), 0.0, 1.0)


def interface_fresnel(cos_i, ior: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of one smooth face (from air, index ``ior``)."""
    c = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    st = np.sqrt(np.clip(1.0 - c * c, 0.0, None)) / ior
    ct = np.sqrt(np.clip(1.0 - st * st, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = ((c - ior * ct) / (c + ior * ct)) ** 2
        rp = ((ior * c - ct) / (ior * c + ct)) ** 2
    return np.where(c > 0, 0.5 * (rs + rp), 1.0)


def opal_optical_depth(regular: float, ior: float) -> float:
    """The optical depth :math:`τ` of an opal layer whose unscattered light through both faces
    is ``regular`` at normal incidence: the root of
    :math:`(1 - R_0)^2 e^{-τ} / (1 - R_0^2 e^{-2τ}) = T_\\text{reg}`, a quadratic in
    :math:`e^{-τ}` (``inf`` when nothing passes unscattered).

    >>> round(opal_optical_depth(float(np.exp(-2.0)), 1.0), 9)
    2.0
    """
    reg = float(regular)
    r0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    if reg <= 0.0:
        return float("inf")
    b = (1.0 - r0) ** 2
    if r0 < 1e-12:
        e = reg
    else:
        e = (-b + np.sqrt(b * b + 4.0 * reg * reg * r0 * r0)) / (2.0 * reg * r0 * r0)
    return float(-np.log(min(max(e, 1e-300), 1.0)))


def opal_depth(ir, fd: float | None = None) -> float:
    """The booth's opal plate's optical depth (:func:`opal_optical_depth`) from its regular part
    :math:`(1 - f_d)\\,\\bar T_\\text{decl}`: ``fd`` (default the declared diffuse fraction) and
    the mean of the declared transmittance over 380–780 nm."""
    d = ir.diffuser
    if fd is None:
        fd = float(d.scattering.get("diffuse_fraction", 0.0))
    T = np.asarray(d.transmittance.array_1nm, float)
    T_mean = float(np.mean(T[20:421])) if T.size == 471 else float(np.mean(T))
    return opal_optical_depth((1.0 - float(fd)) * T_mean, d.ior)


#: an opal layer's optical depth at most (a plate declared with no regular part: :math:`e^{-τ}`
#: below 1e-5 of any transmittance; the asymmetry then makes up its total)
OPAL_MAX_DEPTH = 12.0
#: and at least (a fitted diffuse fraction near 0: the thin layer's law, which scatters along
#: the path, :math:`∝ 1/\cos θ_t`, is its limit)
OPAL_MIN_DEPTH = 1e-6


def opal_plate_layer(ir, fd: float | None = None):
    """The scattering layer of the booth's plate's diffuse part
    (:class:`~lbscene.engine.light.opal_layer.OpalLayer`): optical depth :func:`opal_depth`
    (``fd``: default the declared diffuse fraction; at most :data:`OPAL_MAX_DEPTH`) and the
    Henyey–Greenstein asymmetry for which the non-absorbing layer transmits the declared total
    (its mean over 380–780 nm) at normal incidence
    (:func:`~lbscene.engine.light.opal_layer.opal_layer_at`: between layers solved on a grid of
    depths, continuous in the depth).  A total no asymmetry in :math:`[0, G_\\text{max}]` reaches
    (a plate that absorbs, or a very thin one) takes the nearer end: the layer's shape of light
    then, its level the declaration's (the callers scale the scattered light to
    :math:`f_d T_\\text{decl}` at normal incidence)."""
    from .opal_layer import opal_layer_at

    d = ir.diffuser
    T = np.asarray(d.transmittance.array_1nm, float)
    T_mean = float(np.mean(T[20:421])) if T.size == 471 else float(np.mean(T))
    tau = min(max(opal_depth(ir, fd), OPAL_MIN_DEPTH), OPAL_MAX_DEPTH)
    return opal_layer_at(tau, min(max(T_mean, 1e-6), 1.0), float(d.ior))


def _cos_t(c, ior):
    return np.sqrt(np.clip(1.0 - (1.0 - c * c) / (ior * ior), 0.0, 1.0))


def opal_regular_relative(cos_i, ior: float, tau: float) -> np.ndarray:
    """An opal plate's unscattered transmittance at incidence ``cos_i`` relative to normal
    incidence, :math:`T_\\text{reg}(θ_i)/T_\\text{reg}(0)` (module docstring) for a layer of
    optical depth ``tau``; the clear slab's Fresnel law when nothing passes unscattered at any
    angle (``tau`` infinite: the regular part is zero anyway)."""
    c = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    if not np.isfinite(tau):
        return fresnel_relative(c, ior)

    def reg(cc):
        ct = np.maximum(_cos_t(cc, ior), 1e-9)
        F = interface_fresnel(cc, ior)
        e = np.exp(-tau / ct)
        # at grazing incidence on a layer of no depth (F = e = 1) the limit (1 - F)/(1 + F) is 0
        den = 1.0 - F * F * e * e
        return np.divide((1.0 - F) ** 2 * e, den, out=np.zeros_like(den), where=den > 0)

    return reg(c) / reg(np.ones(1))[0]


def plate_reflectance(ir, cos_i, transmittance) -> np.ndarray:
    """Directional-hemispherical reflectance of the plate (either face) at incidence ``cos_i``
    (shape ``S``) for a declared total normal transmittance ``transmittance`` (shape ``B``);
    shape ``S + B``.

    * ``roughness``: the rough slab's :math:`R_\\text{top}(μ) + a^2 R_\\text{int}(μ)`;
    * ``lambertian`` (opal): :math:`1 - T(μ) - A_0\\,t(μ)`, :math:`T(μ)` its total
      transmittance (regular part :func:`opal_regular_relative`, scattered part the layer's
      :math:`t(μ)`, :func:`opal_plate_layer`) and
      :math:`A_0 = 1 - T_\\text{decl} - R_\\text{decl}` what it absorbs at normal incidence, with
      the declared ``reflectance`` (default :math:`1 - T_\\text{decl}`: no absorption);
    * a clear plate: :math:`1 - T_\\text{slab}(μ)` (its absorption neglected).
    """
    d = ir.diffuser
    mu = np.asarray(cos_i, float)[..., None]
    T = np.asarray(transmittance, float)
    if is_rough(ir):
        a2 = absorption_squared(ir, T)
        s = plate_slab(ir)
        return s.reflectance(mu, np.sqrt(a2))
    clear = 1.0 - fresnel_slab_transmittance(mu, d.ior) + 0.0 * T
    if d.scattering.get("type") != "lambertian":
        return clear
    fd = float(d.scattering["diffuse_fraction"])
    tau = opal_depth(ir, fd)
    t = opal_plate_layer(ir, fd).entry_relative(mu)
    T_theta = T * ((1.0 - fd) * opal_regular_relative(mu, d.ior, tau) + fd * t)
    A0 = np.clip(1.0 - T - opal_declared_reflectance(ir, T), 0.0, 1.0)      # absorbed at 0°
    return np.clip(1.0 - T_theta - A0 * t, 0.0, 1.0)


def opal_declared_reflectance(ir, transmittance) -> np.ndarray:
    """An opal plate's total normal reflectance: the declared ``reflectance`` of its
    ``scattering`` when given, else :math:`1 - T_\\text{decl}` (a plate that does not absorb)."""
    R = ir.diffuser.scattering.get("reflectance")
    if R is None:
        return 1.0 - np.asarray(transmittance, float)
    return np.broadcast_to(np.asarray(R, float), np.shape(transmittance))


def plate_hemispherical_reflectance(ir, transmittance) -> np.ndarray:
    """Reflectance of the plate for diffuse (Lambertian) light, :math:`2\\int_0^1 R(μ) μ\\,dμ`,
    per value of ``transmittance``."""
    x, w = gauss_legendre(64)
    mu = 0.5 * (x + 1.0)
    R = plate_reflectance(ir, mu, transmittance)              # (64, B)
    return np.einsum("k,kb->b", w * mu, R.reshape(len(mu), -1)).reshape(np.shape(transmittance))


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
