"""
The physics interface between the forward model and effect plugins.

The analytic forward model (:mod:`lbscene.engine.light.forward`) builds each lamp
as a set of point emitters, traces straight lamp→receiver paths and adds
global transport.  Effects change that picture through *hooks*: optional
class methods an effect defines.  An effect implements only the hooks it
needs; the forward model calls the hooks of the effects a booth enables, in
``order``.  A third-party effect subclasses :class:`PhysicalEffect` (or just
:class:`~lbscene.engine.light.effects.registry.Effect` and defines the methods).

Hooks (``ctx`` is a :class:`ForwardContext`, ``p`` the validated ``Params``):

``modify_emitters(ctx, p, lamp, es) -> EmitterSet``
    Change a lamp's emitters: angular shape, per-point weights (tube ends),
    spectrum (filters).
``extra_emitters(ctx, p, lamp, es) -> list[EmitterSet]``
    Additional emitters derived from a lamp (mirror images behind it).
``path_factors(ctx, p, es, rx_points) -> list[PathChannel] | None``
    Per (receiver, emitter point) transmission of the straight path:
    occluders (0/1), mirrors, a diffuser plate (angle-dependent, with a
    spectral transmittance).  Several channels split the light into parts
    with different spectral multipliers.
``secondary_sources(ctx, p, direct) -> list[LambertianSource | DirectionalSource]``
    Surfaces that re-emit lamp light: diffusely (a Lambertian diffuser,
    :class:`LambertianSource`) or with a direction-dependent radiance (a
    rough glass plate, :class:`DirectionalSource`);
    ``direct(points, normals, exclude)`` evaluates direct lamp light and
    ``direct.per_point(points, normals, exclude)`` the same light emitter
    point by emitter point, with its directions (:class:`PointLight`).
``source_path_factors(ctx, p, polys, rx_points) -> (M, P) array | None``
    Per (receiver, polygon of a secondary source) share of the polygon's light that reaches the
    receiver: occluders between a diffuser plate and the room.  The factors of every enabled
    effect multiply.
``receiver_response(ctx, p, cos_incidence) -> factor``
    Meter response relative to an ideal cosine receiver (only applied to
    illuminance-meter receivers, never to physical surfaces).
``global_transport(ctx, p, model) -> GlobalTransport``
    Light exchanged between the booth's surfaces (inter-reflection).
``transport_mirrors(ctx, p) -> list[TransportMirror]``
    One-sided plane mirrors the inter-reflection sees: they block the surfaces' mutual views
    and reflect the surfaces' light (their images), as the effect's own hooks do the lamps'.

Diagnosis metadata (class attributes):

``fit_parameters``
    ``{param: (low, high)}`` freed when the diagnosis tries the effect.
``applicable(ir, lighting) -> str | None``
    ``None`` when the booth has what the effect needs, else the reason.
``channels``
    the residuals the effect may explain: ``("spatial",)`` by default, ``("spectral",)`` for
    ``kind = "spectral"``, both for an effect that does both (a diffuser's spectral
    transmittance).  A candidate that gains only on another channel is not chosen.
"""

from __future__ import annotations

import inspect
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any, Callable, ClassVar, Protocol

import numpy as np
from pydantic import Field

from lbscene.schemas.base import Identifier

from .registry import Effect, EffectParams

__all__ = [
    "PhysicalEffect",
    "EffectHooks",
    "HOOKS",
    "BACKENDS",
    "check_effect_class",
    "EmitterSet",
    "PathChannel",
    "LambertianSource",
    "DirectionalSource",
    "PointLight",
    "TransportMirror",
    "ForwardContext",
    "footprint_fraction",
    "effect_params",
    "LampSelection",
    "lamp_selected",
    "lamps_on",
    "lamps_on_ids",
]


@dataclass(frozen=True)
class EmitterSet:
    """Point emitters standing for one lamp (or an image of it): a quadrature of the lamp's
    :class:`~lbscene.engine.light.emitters.Emitter`.

    The spectral radiant intensity of point ``i`` toward a unit direction ``u``
    (after ``direction_map``) is ``weights[i] · b_i(u) · f(u) · spectrum_1nm``
    (W·sr⁻¹·nm⁻¹) with ``f`` the modulation ``shape`` (θ from ``aim``; IES: γ, C
    in the frame of ``lamp_axis``) and ``b_i`` the emitter's own law:
    ``max(0, normals[i]·u)`` for points on a Lambertian surface, ``sin`` of the
    angle to ``line_axis`` for a tube's line quadrature (the far field of a
    Lambertian cylinder slice; with ``line_radius_mm`` > 0 the forward model
    integrates the slice's visible arc at each receiver instead), 1 otherwise.
    """

    lamp_id: str
    group: str
    kind: str                                   # lamp kind: tube, bulb, panel, point
    points_mm: np.ndarray                       # (N, 3)
    weights: np.ndarray                         # (N,)
    s: np.ndarray                               # (N,) position along the lamp, -0.5..0.5
    aim: np.ndarray                             # (3,)
    spectrum_1nm: np.ndarray                    # (471,) W·sr⁻¹·nm⁻¹ at θ = 0, whole lamp
    spectral_key: tuple = ()                    # names of spectral factors applied (term identity)
    shape: Callable | None = None               # f(θ[, φ]) ; None: isotropic
    #: maps the direction *from this emitter* to the direction the real lamp emitted
    #: (mirror images reflect it); None: identity
    direction_map: Callable | None = None
    tag: str = "lamp"                           # 'lamp' or e.g. 'image:<reflector id>'
    #: half of the piece of lamp each point stands for (tubes), mm vector; None for points
    half_step: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    #: (N, 3) outward normals of surface points (Lambertian law); None: no surface law
    normals: np.ndarray | None = None
    #: tube axis of a line quadrature (sin law); None: none
    line_axis: np.ndarray | None = None
    #: tube radius of a line quadrature: > 0 integrates each slice's visible arc exactly
    line_radius_mm: float = 0.0
    #: the lamp's axis: C = 0 of a two-dimensional (IES) modulation
    lamp_axis: np.ndarray | None = None

    def with_(self, **kw) -> "EmitterSet":
        return replace(self, **kw)


@dataclass(frozen=True)
class PathChannel:
    """Part of the light on the straight paths: ``factor`` (M, N) and a spectral multiplier."""

    factor: np.ndarray | float
    spectral_key: str | None = None             # None: spectrally neutral
    spectrum_1nm: np.ndarray | None = None


@dataclass(frozen=True)
class LambertianSource:
    """Polygons that re-emit diffusely; exitance per term is ``exitance`` (P, K)."""

    polys: np.ndarray                           # (P, 4, 3)
    normals: np.ndarray                         # (P, 3) emitting side
    exitance: np.ndarray                        # (P, K) W/m² per unit term spectrum
    terms: list                                 # K term descriptors (group, spectrum_1nm, key)


@dataclass(frozen=True)
class DirectionalSource:
    """Polygons that re-emit with a direction-dependent radiance.

    ``radiance(directions)`` takes unit directions ``(P, M, 3)`` from each polygon's centroid
    toward ``M`` receivers and returns the radiance ``(P, M, K)`` leaving the polygon in those
    directions (W·sr⁻¹·m⁻² per unit term spectrum).  A receiver gets, per polygon,
    :math:`E = π L(ω)\\,F` with :math:`F` its form factor to the polygon (the radiance taken
    constant over the polygon toward one receiver).
    """

    polys: np.ndarray                           # (P, 4, 3)
    normals: np.ndarray                         # (P, 3) emitting side
    radiance: Callable[[np.ndarray], np.ndarray]
    terms: list                                 # K term descriptors (group, spectrum_1nm, key)


@dataclass(frozen=True)
class PointLight:
    """Direct light at receivers emitter point by emitter point (``direct.per_point``).

    ``geo`` (M, N) is what :meth:`~lbscene.engine.light.forward.ForwardModel.direct_terms` sums over
    the points (irradiance per unit term spectrum, path factors included) and ``from_dir``
    (M, N, 3) the unit direction from each receiver toward each point (where the light comes
    from).  ``term`` is the term descriptor (transfer empty).
    """

    term: Any
    geo: np.ndarray
    from_dir: np.ndarray


@dataclass(frozen=True)
class TransportMirror:
    """A plane mirror in the light exchanged between surfaces: ``face`` a
    :class:`~lbscene.engine.light.geometry.Rectangle` whose normal points to the side it reflects
    to (its back absorbs), ``reflectance_bands`` its reflectance per band of the IR's grid,
    ``owner`` a name for cache keys and messages."""

    owner: str
    face: Any
    reflectance_bands: np.ndarray


@dataclass
class ForwardContext:
    """What hooks see: the IR, the lighting, enabled effects and fit overrides."""

    ir: Any
    lighting: str
    effects: dict[str, dict]                    # effect id → params (validated JSON)
    lamp_overrides: dict[str, dict] = field(default_factory=dict)   # lamp id → {'sigma_deg': …}
    options: Any = None
    cache: dict = field(default_factory=dict)

    def params(self, effect_id: str):
        from .registry import get_effect

        return effect_params(get_effect(effect_id), self.effects.get(effect_id, {}))

    @contextmanager
    def transient(self):
        """Within it, results are computed and not kept: :meth:`memo` and the forward model's
        stores (pair geometry, path factors) skip storing, for light computed once at many
        points (a rough plate's sub-points) whose arrays would crowd out what a fit reuses."""
        before = self.cache.get("_transient", False)
        self.cache["_transient"] = True
        try:
            yield
        finally:
            self.cache["_transient"] = before

    @property
    def storing(self) -> bool:
        """False inside :meth:`transient`: computed results are not to be kept."""
        return not self.cache.get("_transient", False)

    def lamp_light_key(self, ignore: dict[str, tuple[str, ...]] | None = None) -> tuple:
        """What the lamps' light on surfaces depends on beyond the booth, as plain values: the
        lighting, the parameters of every effect that changes lamp light
        (:func:`~lbscene.engine.light.effects.registry.changes_lamp_light`; ``ignore`` names
        parameters per effect that do not matter to the caller) and the lamp overrides.  Keys
        the light stored on surfaces (the inter-reflection's patches, a rough plate's cells)."""
        import json

        from .registry import changes_lamp_light

        ignore = ignore or {}
        lamp_light = {eid: {k: v for k, v in dict(q or {}).items() if k not in ignore.get(eid, ())}
                      for eid, q in self.effects.items() if changes_lamp_light(eid)}
        return (self.lighting, json.dumps(lamp_light, sort_keys=True, default=str),
                json.dumps(self.lamp_overrides, sort_keys=True, default=str))

    def memo(self, name: str, key_arrays: tuple, compute, *, limit: int = 512):
        """``compute()`` cached under ``name`` + the content of ``key_arrays``.

        For geometry-only intermediate results (occlusion fractions, Fresnel factors): a
        fit changes intensities, σ, fractions… but never the geometry, so every model of
        the fit (they share ``cache``) computes them once.
        """
        from lbscene.engine.files.disk_cache import array_key

        # one store per kind, each with its own bound: arrays of (receivers × emitters) add up
        if not self.storing:
            return compute()
        store = self.cache.setdefault(("_memo", name.split(":", 1)[0]), {})
        k = (name, array_key(*[np.asarray(a, float) for a in key_arrays]))
        hit = store.get(k)
        if hit is None:
            hit = compute()
            if len(store) >= limit:
                store.pop(next(iter(store)))
            store[k] = hit
        return hit

    def fraction_hitting(self, es: "EmitterSet", rx: np.ndarray, rect, ring: int | None = None) -> np.ndarray:
        """Memoised :func:`~lbscene.engine.light.geometry.segment_fraction_hitting`.

        A tube slice of radius r > 0 is not its axis: its light toward a receiver leaves
        the arc it sees, so for a rectangle within :data:`TUBE_RING_REACH` radii the fraction
        is the share of that arc's light the rectangle meets (:func:`footprint_fraction`, the
        arc cut into :data:`FOOTPRINT_RING` elements).  With ``ring`` the footprints (of
        ``ring`` elements) are taken at every distance: a mirror's window, whose edge
        shapes the image however far from the tube it stands.
        """
        from lbscene.engine.light.geometry import apart_from_plane, segment_fraction_hitting

        if apart_from_plane(es.points_mm, es.half_step, rx, rect, es.line_radius_mm or 0.0):
            return np.zeros((len(rx), len(es.points_mm)))

        half = es.half_step if es.half_step is not None else np.zeros(3)
        key = (es.points_mm, half, rx, *rect.key_arrays)
        # the tube's width only shifts a shadow edge noticeably when the rectangle is within a
        # few radii of it (apertures, slots); farther away its axis stands for it
        tube = es.line_axis is not None and es.line_radius_mm > 0
        close = tube and (ring is not None or abs(float((es.points_mm.mean(axis=0) - rect.centre) @ rect.normal))
                          < TUBE_RING_REACH * es.line_radius_mm)
        if not close:
            return self.memo("hit", key,
                             lambda: segment_fraction_hitting(es.points_mm, es.half_step, rx, rect))
        lines = FOOTPRINT_RING if ring is None else int(ring)
        return self.memo("hit:footprint", key + (np.asarray([es.line_radius_mm, lines]),),
                         lambda: footprint_fraction(es, rx, rect, lines))

    def fraction_past_body(self, es: "EmitterSet", rx: np.ndarray, body) -> np.ndarray:
        """(M, N) share of each emitter point's light toward each receiver that ``body`` (a
        :class:`~lbscene.engine.light.geometry.Capsule`, ``Ball`` or ``Rectangle``) does not
        stop.  A tube slice of radius r > 0 is averaged over :data:`BODY_RING` lines on its
        surface, each weighted by its Lambertian ``max(0, n·u)`` toward the receiver, so a
        body close to it casts a penumbra, not a hard edge."""
        from lbscene.engine.light.geometry import Capsule, bodies_block

        rx = np.asarray(rx, float)
        M, N = len(rx), len(es.points_mm)

        def visible(P):
            A = np.broadcast_to(P[None, :, :], (M, N, 3)).reshape(-1, 3)
            B = np.broadcast_to(rx[:, None, :], (M, N, 3)).reshape(-1, 3)
            return (~bodies_block(A, B, [body])).reshape(M, N).astype(float)

        def compute():
            if es.line_axis is None or es.line_radius_mm <= 0:
                return visible(es.points_mm)
            a = es.line_axis if es.direction_map is None else es.direction_map(es.line_axis)
            a = a / np.linalg.norm(a)
            if isinstance(body, Capsule):
                b = np.asarray(body.p1, float) - np.asarray(body.p0, float)
                if np.linalg.norm(b) > 0 and abs(a @ b) / np.linalg.norm(b) > 1.0 - 1e-9:
                    return _parallel_cylinder_shadow(es.points_mm, a, es.line_radius_mm, body, rx)
            return _tube_ring_average(es, rx, BODY_RING, 1.0, visible)

        sig = [np.ravel(np.asarray(v, float)) for v in vars(body).values() if v is not None]
        return self.memo("pastbody", (es.points_mm, rx, np.asarray([es.line_radius_mm]), *sig), compute)


def _ring_normals(es: "EmitterSet", lines: int) -> tuple[np.ndarray, np.ndarray]:
    """``(axis, normals (lines, 3))``: a tube slice's unit axis (mirrored by
    ``es.direction_map`` for an image) and the outward normals of ``lines`` equally spaced lines
    on its surface."""
    a = es.line_axis if es.direction_map is None else es.direction_map(es.line_axis)
    a = np.asarray(a, float) / np.linalg.norm(a)
    e1 = np.cross(a, [0.0, 0.0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    phi = 2.0 * np.pi * (np.arange(lines) + 0.5) / lines
    return a, np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2


def footprint_fraction(es: "EmitterSet", rx: np.ndarray, rect, lines: int) -> np.ndarray:
    """(M, N) share of each tube slice's light toward each receiver that crosses ``rect``
    (outside its opening): a mirror's window for an image, an occluder for the lamp.

    A tube slice of radius :math:`r` sends light toward a receiver from the arc it sees, so which
    part of it a rectangle's edge cuts changes smoothly with the receiver; ``lines`` lines on
    the surface, each in or out, step it (24 lines put the far rows of the validation scene
    ``mirror-prism`` 3.5 % low, 384 still 0.9 %; six lines of an occluder 70 mm tall standing
    on the ceiling beside tubes, or of a mirror strip 35 mm above one, left the ceiling around
    it too dark: the inter-reflected light 1 to 4 % low).  Here each line stands for its arc
    element and its slice: the element's footprint where its rays cross the rectangle's plane,
    a box of half sizes :math:`w_u, w_v` around the crossing point :math:`(x_u, x_v)`, is the
    element's offset :math:`δ` (half the slice along the axis, half the arc :math:`π r / n`
    along the tangent) carried to the plane,

    .. math:: Δx = (1 - s)\\left(δ - D\\,\\frac{δ·n}{D·n}\\right),

    (:math:`D` from the line to the receiver, :math:`s` the crossing's fraction of it), and its
    share inside the rectangle is the product of the overlaps
    :math:`\\operatorname{clip}\\big((\\min(x+w, H) - \\max(x-w, -H)) / 2w, 0, 1\\big)` along
    :math:`u` and :math:`v`, less that of the opening.  The lines are weighted by their
    Lambertian :math:`\\max(0, n_k·D)`.  A point (no line radius) is tested by its segment
    (:func:`~lbscene.engine.light.geometry.segment_fraction_hitting`)."""
    from lbscene.engine.light.geometry import segment_fraction_hitting

    rx = np.asarray(rx, float)
    if es.line_axis is None or es.line_radius_mm <= 0:
        return segment_fraction_hitting(es.points_mm, es.half_step, rx, rect)
    half = np.zeros(3) if es.half_step is None else np.asarray(es.half_step, float)

    def overlap(x, w, H):
        with np.errstate(divide="ignore", invalid="ignore"):
            soft = np.clip((np.minimum(x + w, H) - np.maximum(x - w, -H)) / (2.0 * w), 0.0, 1.0)
        return np.where(w > 1e-9, soft, (np.abs(x) <= H).astype(float))

    a, ring = _ring_normals(es, lines)
    c, n = np.asarray(rect.centre, float), np.asarray(rect.normal, float)
    u, v = np.asarray(rect.u, float), np.asarray(rect.v, float)
    r = float(es.line_radius_mm)
    pts = np.asarray(es.points_mm, float)
    # everything in the rectangle's frame: each (M, N) quantity is a difference of the
    # receivers' and the line points' coordinates along n, u, v and the line's normal
    frame = np.stack([n, u, v])
    Rn, Ru, Rv = ((rx - c) @ frame.T).T
    Qn, Qu, Qv = ((pts - c) @ frame.T).T
    hn, hu, hv = frame @ half
    num = np.zeros((len(rx), len(pts)))
    den = np.zeros_like(num)
    for nk in ring:
        w = np.clip((rx @ nk)[:, None] - (pts @ nk)[None, :], 0.0, None)
        kn, ku, kv = r * (frame @ nk)
        tn, tu, tv = frame @ (np.cross(a, nk) * (np.pi * r / lines))
        hP = Qn + kn                                       # the line's height over the plane
        Dn = Rn[:, None] - hP[None, :]
        Du = Ru[:, None] - (Qu + ku)[None, :]
        Dv = Rv[:, None] - (Qv + kv)[None, :]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            s = np.where(np.abs(Dn) > 1e-12, -hP[None, :] / Dn, -1.0)
            ok = (s > 1e-9) & (s < 1.0 - 1e-9)
            xu = (Qu + ku)[None, :] + s * Du
            xv = (Qv + kv)[None, :] + s * Dv
            # the footprint's half sizes: the slice's and the arc's offsets carried to the plane
            g = 1.0 - s
            wu = g * (np.abs(hu - Du * (hn / Dn)) + np.abs(tu - Du * (tn / Dn)))
            wv = g * (np.abs(hv - Dv * (hn / Dn)) + np.abs(tv - Dv * (tn / Dn)))
            cov = overlap(xu, wu, rect.half[0]) * overlap(xv, wv, rect.half[1])
            if rect.hole_half is not None:
                cov = cov - overlap(xu, wu, rect.hole_half[0]) * overlap(xv, wv, rect.hole_half[1])
            cov = np.where(ok, np.clip(cov, 0.0, 1.0), 0.0)
        num += w * np.nan_to_num(cov)
        den += w
    return np.where(den > 0, num / np.maximum(den, 1e-300), 0.0)


def _tube_ring_average(es: "EmitterSet", rx: np.ndarray, lines: int, empty: float,
                       per_line: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """(M, N) average of ``per_line(points)`` over ``lines`` lines on a tube slice's surface
    (``es.line_radius_mm`` about its axis, mirrored by ``es.direction_map`` for an image),
    each weighted by its Lambertian ``max(0, n·u)`` toward the receiver (the common 1/|d|
    cancels); ``empty`` where no line faces the receiver."""
    _, ring = _ring_normals(es, lines)
    d = np.asarray(rx, float)[:, None, :] - es.points_mm[None, :, :]
    num = np.zeros(d.shape[:2])
    den = np.zeros(d.shape[:2])
    for nk in ring:
        w = np.clip(d @ nk, 0.0, None)
        num += w * per_line(es.points_mm + es.line_radius_mm * nk)
        den += w
    return np.where(den > 0, num / np.maximum(den, 1e-300), empty)


def _parallel_cylinder_shadow(points_mm, axis, radius_mm, body, rx) -> np.ndarray:
    """(M, N) visible share of the light of tube slices (axis points ``points_mm``, radius
    ``radius_mm``) at receivers ``rx``, past a parallel cylinder ``body`` (a Capsule).

    In the plane across the axis through the receiver R, a Lambertian cylinder is seen with
    uniform radiance over its angular width :math:`2\\arcsin(r/ρ)`; the body, when nearer to
    R than the slice and crossing the path within its length, hides the overlap of the two
    angular intervals.  The share is the uncovered part of the slice's interval (exact for
    parallel cylinders; the cosine at R is constant over a width of a few degrees)."""
    rx = np.asarray(rx, float)
    P = np.asarray(points_mm, float)
    p0 = np.asarray(body.p0, float)
    s0, s1 = sorted((float(p0 @ axis), float(np.asarray(body.p1, float) @ axis)))
    d_i = P[None, :, :] - rx[:, None, :]                           # receiver → slice (M, N, 3)
    d_t = (p0 - rx)[:, None, :] + np.zeros_like(d_i)               # receiver → body axis
    perp_i = d_i - (d_i @ axis)[..., None] * axis
    perp_t = d_t - (d_t @ axis)[..., None] * axis
    rho_i = np.linalg.norm(perp_i, axis=-1)
    rho_t = np.linalg.norm(perp_t, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        a_i = np.arcsin(np.clip(radius_mm / rho_i, 0.0, 1.0))
        a_t = np.arcsin(np.clip(body.radius_mm / rho_t, 0.0, 1.0))
        cosd = np.clip((perp_i * perp_t).sum(-1) / (rho_i * rho_t), -1.0, 1.0)
        delta = np.arccos(cosd)
        ov = np.clip(np.minimum(a_i, delta + a_t) - np.maximum(-a_i, delta - a_t), 0.0, None)
        # where along the axis the path slice → receiver passes the body's depth
        frac = np.clip(rho_t * cosd / rho_i, 0.0, 1.0)
    s_rx = rx @ axis
    s_cross = s_rx[:, None] + frac * ((P @ axis)[None, :] - s_rx[:, None])
    nearer = (rho_t * cosd < rho_i) & (cosd > 0)
    within = (s_cross >= s0 - body.radius_mm) & (s_cross <= s1 + body.radius_mm)
    share = 1.0 - np.where(nearer & within & (a_i > 0), ov / np.maximum(2.0 * a_i, 1e-300), 0.0)
    return np.where(np.isfinite(share), share, 1.0)


#: arc elements of a tube's surface whose footprints on a rectangle close to it are summed
#: (:func:`footprint_fraction`)
FOOTPRINT_RING = 24
#: lines around a tube's surface over which a lamp body's shadow on it is averaged (a body as
#: wide as the tube, close to it, casts a broad penumbra)
BODY_RING = 24
#: ... for rectangles closer to the tube than this many radii
TUBE_RING_REACH = 8.0


def effect_params(cls, params: dict | None):
    """Validated ``Params`` instance of an effect class (cached by value)."""
    key = (cls, repr(sorted((params or {}).items())))
    hit = _PARAMS_CACHE.get(key)
    if hit is None:
        hit = cls.Params.model_validate(params or {})
        if len(_PARAMS_CACHE) > 4096:
            _PARAMS_CACHE.clear()
        _PARAMS_CACHE[key] = hit
    return hit


_PARAMS_CACHE: dict = {}


class EffectHooks(Protocol):
    """Every hook an effect may define (all optional; see the module docstring)."""

    @staticmethod
    def modify_emitters(ctx: ForwardContext, p: Any, lamp: Any, es: EmitterSet) -> EmitterSet: ...

    @staticmethod
    def extra_emitters(ctx: ForwardContext, p: Any, lamp: Any, es: EmitterSet) -> list[EmitterSet]: ...

    @staticmethod
    def path_factors(ctx: ForwardContext, p: Any, es: EmitterSet,
                     rx_points: np.ndarray) -> list[PathChannel] | None: ...

    @staticmethod
    def secondary_sources(ctx: ForwardContext, p: Any,
                          direct: Callable) -> list[LambertianSource | DirectionalSource]: ...

    @staticmethod
    def source_path_factors(ctx: ForwardContext, p: Any, polys: np.ndarray,
                            rx_points: np.ndarray) -> np.ndarray | None: ...

    @staticmethod
    def receiver_response(ctx: ForwardContext, p: Any, cos_incidence: np.ndarray) -> np.ndarray: ...

    @staticmethod
    def global_transport(ctx: ForwardContext, p: Any, model: Any) -> Any: ...

    @staticmethod
    def transport_mirrors(ctx: ForwardContext, p: Any) -> list[TransportMirror]: ...


#: hook name → number of arguments (after the class, for classmethods)
HOOKS: dict[str, int] = {
    name: len(inspect.signature(getattr(EffectHooks, name)).parameters)
    for name in ("modify_emitters", "extra_emitters", "path_factors", "secondary_sources",
                 "source_path_factors", "receiver_response", "global_transport", "transport_mirrors")
}
#: backends that consume effects: the analytic forward model, the Monte Carlo reference engine,
#: Cycles bake jobs, the realtime render graph
BACKENDS = frozenset({"forward", "reference", "cycles", "realtime"})
#: public class members of an effect that are not hooks
_METADATA = frozenset({"Params", "applicable", "fit_parameters_for", "describe_params",
                       "diagnosis_params", "refit_cost_s", "check_class"})


def check_effect_class(cls) -> None:
    """Raise ``TypeError`` unless ``cls`` keeps to the hook interface.

    Every public callable it defines must be a hook of :class:`EffectHooks` with the hook's
    number of arguments, a metadata member, or named in its ``helpers``; ``backends`` must be
    a subset of :data:`BACKENDS` that includes ``'forward'``.
    """
    helpers = set(getattr(cls, "helpers", ()))
    for klass in cls.__mro__:
        if klass in (PhysicalEffect, Effect, object):
            continue
        for name, raw in vars(klass).items():
            if name.startswith("_") or name in _METADATA or name in helpers:
                continue
            fn = raw.__func__ if isinstance(raw, (staticmethod, classmethod)) else raw
            if not callable(fn) or isinstance(fn, type):
                continue
            if name not in HOOKS:
                raise TypeError(f"effect {getattr(cls, 'id', cls.__name__)!r}: {name!r} is not a hook "
                                f"(hooks: {', '.join(sorted(HOOKS))}); list helper methods in "
                                f"`helpers`")
            n = len(inspect.signature(fn).parameters) - (1 if isinstance(raw, classmethod) else 0)
            if n != HOOKS[name]:
                raise TypeError(f"effect {getattr(cls, 'id', cls.__name__)!r}: hook {name} takes "
                                f"{n} arguments, the interface {HOOKS[name]}")
    backends = getattr(cls, "backends", BACKENDS)
    if not set(backends) <= BACKENDS or "forward" not in backends:
        raise TypeError(f"effect {getattr(cls, 'id', cls.__name__)!r}: backends {sorted(backends)} "
                        f"must include 'forward' and be among {sorted(BACKENDS)}")


class PhysicalEffect(Effect):
    """Base class of effects with forward-model physics (see the module docstring).

    Hooks are the methods of :class:`EffectHooks`; registering a class that defines any other
    public method (not listed in ``helpers``) is an error.
    """

    #: backends that model this effect (see :data:`BACKENDS`)
    backends: ClassVar[frozenset[str]] = BACKENDS
    #: an effect with no hook of its own names the effect whose ``global_transport`` applies its
    #: parameters (``surface_reflectance``: the ``interreflection``'s radiosity scales the surfaces)
    applied_by: ClassVar[str | None] = None
    #: public methods that are not hooks
    helpers: ClassVar[tuple[str, ...]] = ()

    #: evaluation order among enabled effects (lower first)
    order: ClassVar[int] = 100
    #: parameters the diagnosis frees when it tries this effect: {param: (low, high)}
    fit_parameters: ClassVar[dict[str, tuple[float, float]]] = {}
    #: initial values for the diagnosis (default: the Params default)
    fit_initial: ClassVar[dict[str, float]] = {}

    @classmethod
    def check_class(cls) -> None:
        """The hook interface (:func:`check_effect_class`), checked when the class is registered."""
        check_effect_class(cls)

    @classmethod
    def applicable(cls, ir, lighting: str) -> str | None:
        """``None`` when the booth has what this effect needs, else why not."""
        return None

    @classmethod
    def fit_parameters_for(cls, ir, lighting: str) -> dict[str, tuple[float, float]]:
        """Parameters the diagnosis frees for this booth (default: :attr:`fit_parameters`)."""
        return dict(cls.fit_parameters)

    @classmethod
    def describe_params(cls) -> list[dict]:
        """Parameter table for ``lbscene effects``."""
        out = []
        for name, f in cls.Params.model_fields.items():
            out.append({"name": name, "default": f.default if f.default is not None else None,
                        "description": f.description or "",
                        "fit_bounds": list(cls.fit_parameters[name]) if name in cls.fit_parameters
                        else None})
        return out


def lamps_on_ids(ir, lighting: str) -> list[str]:
    """Ids of the lamps a lighting switches on."""
    return list(ir.lighting[lighting].lamps)


def lamps_on(ir, lighting: str) -> list:
    """The lamps (``IRLamp``) a lighting switches on."""
    return [ir.lamp(i) for i in ir.lighting[lighting].lamps]


class LampSelection(EffectParams):
    """Parameters of an effect that applies to some lamps (``lamps:``; default: every lamp on)."""

    lamps: list[Identifier] | None = Field(None, description="Lamps it applies to (default: all on).")


def lamp_selected(p, lamp_id: str) -> bool:
    """Whether the effect parameters ``p`` (a :class:`LampSelection`) select lamp ``lamp_id``."""
    return p.lamps is None or lamp_id in p.lamps
