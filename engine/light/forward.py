"""
The analytic forward model: spectral irradiance, illuminance and white-tile
radiance anywhere in a booth, straight from the :class:`~lbscene.engine.scene.ir.SceneIR`.

Base model: each lamp is what :mod:`lbscene.engine.light.emitters` says it is (a
Lambertian cylinder, rectangle or sphere, or a point), integrated by a
quadrature of ``N`` points (``IRLamp.point_sources``).  Each point carries a
weight ``w_i`` of the lamp's reference spectral intensity ``I_ref(λ)`` and the
emitter's own law ``b_i(u)``; a receiver at distance ``d`` whose normal makes
an angle θ_r with the direction ``u`` to a point gets

    E(λ) = Σ_i I_ref(λ) · w_i · b_i(u_i) · f(u_i) · cos θ_r,i / d_i²      (W·m⁻²·nm⁻¹)

with the modulation f ≡ 1 unless the ``angular_profile`` effect is on.  A tube
is ``N`` slices along its axis; at each receiver every slice's visible arc
(``|φ| < arccos(r/h)``) is integrated with the Lambertian law (Gauss–Legendre
in φ, :func:`_cylinder_slices`), so the radius counts at any distance (the
far-field ``sin`` law alone is 1.2 % low 700 mm under a 26 mm tube); close to
a tube the slices are refined.  A panel is a
grid of Lambertian points, refined close to it; a bulb equals a point at its
centre outside it.

Everything else is an effect plugin enabled by the booth's ``effects:``
section (see :mod:`lbscene.engine.light.effects.physics` for the hooks): nothing
is hard-wired here.

Spectral bookkeeping: each contribution is a *term* — a geometric transfer
times a 1 nm spectrum.  Direct terms have a spectrally flat transfer;
inter-reflected terms have a transfer that depends smoothly on wavelength
(surface reflectances), solved at the band centres and interpolated, then
multiplied by the (possibly spiky) 1 nm lamp spectrum.  Illuminance is
683·Σ E(λ)·V(λ)·1 nm, from the 1 nm spectra; band values are band means.

Examples
--------
>>> from lbscene.engine.scene.compile import compile_booth          # doctest: +SKIP
>>> ir = compile_booth("tests/data/minimal-booth")            # doctest: +SKIP
>>> fm = ForwardModel(ir, "A")                                # doctest: +SKIP
>>> fm.illuminance_lx([[0, 0, 0]])    # 1000 cd at 0.7 m: 1000/0.49 lx  # doctest: +SKIP
array([2040.81...])
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterable, Sequence

import numpy as np

from lbscene.engine.files.parallel import blas_single_thread
from lbscene.engine.files.disk_cache import array_key
from lbscene.engine.light.effects.physics import (DirectionalSource, EmitterSet, ForwardContext,
                                                  LambertianSource, PointLight, effect_params)

__all__ = [
    "ForwardOptions",
    "ForwardModel",
    "Prediction",
    "Term",
    "as_receivers",
    "K_M",
    "spectral_tables",
    "blas_single_thread",
]

#: Maximum luminous efficacy of radiation, lm/W.
K_M = 683.0


@dataclass(frozen=True)
class ForwardOptions:
    """Numerical options of the forward model (not physics: physics lives in effects)."""

    #: integrate tubes finely where a receiver is within ``near_field_factor`` point spacings
    near_field: bool = True
    near_field_factor: float = 4.0
    max_points: int = 4000
    #: at most this many points per lamp before the near-field refinement (None: the lamp's
    #: ``point_sources``); the inter-reflection's light on its patches uses fewer
    lamp_points: int | None = None


def _changing_overrides(ir, lamp_overrides: dict | None) -> dict:
    """The lamp overrides that change a lamp: a ``sigma_deg`` equal to that of the Gaussian
    profile the lamp declares is the lamp as declared, and is dropped, so that light stored for the
    declared booth (the disk cache, the shipped tables) is read under the same key (a fit starts
    at the declared values: its first evaluation is the declared booth's)."""
    out = {}
    for lid, over in (lamp_overrides or {}).items():
        lamp = next((lp for lp in ir.lamps if lp.id == lid), None)
        prof = dict(lamp.profile or {}) if lamp is not None else {}
        kept = {k: v for k, v in dict(over or {}).items()
                if not (k == "sigma_deg" and prof.get("type") == "gaussian" and v is not None
                        and float(prof.get("sigma_deg", float("nan"))) == float(v))}
        if kept:
            out[lid] = kept
    return out


@dataclass
class Term:
    """One contribution: transfer × spectrum.

    ``geo`` (M,) is a spectrally flat transfer (1/m², multiply by the
    spectrum in W·sr⁻¹·nm⁻¹); ``geo_bands`` (M, B) a transfer that varies
    smoothly with wavelength, given at the band centres.
    """

    group: str
    lamp_id: str
    key: tuple
    spectrum_1nm: np.ndarray
    geo: np.ndarray | None = None
    geo_bands: np.ndarray | None = None
    kind: str = "direct"

    def derived(self, *, spectral_key: str | None = None, spectrum_factor=None,
                kind: str | None = None) -> "Term":
        """A term descriptor for light that came from this one (no transfer yet)."""
        key = self.key + ((spectral_key,) if spectral_key else ())
        spec = self.spectrum_1nm if spectrum_factor is None else self.spectrum_1nm * spectrum_factor
        return Term(self.group, self.lamp_id, key, spec, None, None, kind or self.kind)


def _behind_receivers(points: np.ndarray, P: np.ndarray, N: np.ndarray) -> bool:
    """True when receivers sharing one normal all face away from every emitter point
    (:math:`n·(e - p) ≤ 0` for every pair; checked through the extremes, in O(M + N))."""
    if len(P) == 0 or len(points) == 0 or np.ptp(N, axis=0).max() > 0.0:
        return False
    n = N[0]
    return bool(float(np.max(points @ n)) <= float(np.min(P @ n)))


def as_receivers(points, normals=None, meter=None):
    """Normalise receiver arguments: points (M,3), unit normals (M,3), meter mask (M,).

    Points given as (M, 2) lie on the floor (z = 0).  What a caller of the public API can get
    wrong is a :class:`LbsceneUserError` (``LB104``: a shape other than (M, 2) or (M, 3), a
    coordinate or normal that is not finite, a zero normal, normals not one per point), or a
    ``TypeError`` for values that are not numbers.
    """
    P = np.atleast_2d(_numbers(points, "points"))
    if P.size == 0:
        P = np.zeros((0, 3))
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise _receiver_error(f"points must be an (M, 3) array of millimetres, got shape {P.shape}")
    if P.shape[1] == 2:
        P = np.c_[P, np.zeros(len(P))]
    if not np.isfinite(P).all():
        raise _receiver_error("points must be finite (no NaN or infinity)")
    if normals is None:
        N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    else:
        N = np.atleast_2d(_numbers(normals, "normals"))
        if N.shape[0] == 1 and len(P) > 1:
            N = np.repeat(N, len(P), axis=0)
        if N.shape != P.shape:
            raise _receiver_error(f"normals must be one (x, y, z) per point: shape {N.shape} for {len(P)} points")
        length = np.linalg.norm(N, axis=1, keepdims=True)
        if not (np.isfinite(length).all() and (length > 0).all()):
            raise _receiver_error("normals must be finite and non-zero")
        N = N / length
    if meter is None:
        m = np.ones(len(P), bool)
    else:
        m = np.broadcast_to(np.asarray(meter, bool), (len(P),)).copy()
    return P, N, m


def _numbers(values, what: str) -> np.ndarray:
    """``values`` as a float array; a ``TypeError`` when they are not numbers (a string, None …)."""
    if isinstance(values, (str, bytes)) or values is None:
        raise TypeError(f"{what} must be numbers (an array of coordinates), not {type(values).__name__}")
    try:
        return np.asarray(values, float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{what} must be numbers (an array of coordinates): {exc}") from None


def _receiver_error(message: str):
    from lbscene.engine.files.diagnostics import LbsceneUserError

    return LbsceneUserError.single("LB104", message, expected="points (M, 3) in mm and unit normals (M, 3)")


_TABLES: dict = {}


def spectral_tables(grid):
    """``(V (471,), band matrix (B, 471), interpolation matrix (471, B))`` for a band grid."""
    key = (grid.first_centre_nm, grid.width_nm, grid.count)
    t = _TABLES.get(key)
    if t is None:
        from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL
        from lbscene.engine.spectra.evaluate import photopic_1nm

        c = grid.centres_nm
        P = np.zeros((WL.size, c.size))
        if c.size == 1:
            P[:, 0] = 1.0
        else:
            j = np.clip(np.searchsorted(c, WL) - 1, 0, c.size - 2)
            t_ = np.clip((WL - c[j]) / (c[j + 1] - c[j]), 0.0, 1.0)
            P[np.arange(WL.size), j] = 1.0 - t_
            P[np.arange(WL.size), j + 1] += t_
        t = _TABLES[key] = (photopic_1nm(), grid.integration_matrix, P)
    return t


# --------------------------------------------------------------------------- prediction

@dataclass
class Prediction:
    """Result of :meth:`ForwardModel.predict`: terms at M receivers, by lamp group."""

    groups: list[str]
    terms: list[Term]
    n: int
    grid: object

    def _per_group(self, what: str) -> dict[str, np.ndarray]:
        V, Bm, P = spectral_tables(self.grid)
        B = Bm.shape[0]
        out = {g: (np.zeros(self.n) if what == "lux" else np.zeros((self.n, B))) for g in self.groups}
        for t in self.terms:
            S = t.spectrum_1nm
            if t.geo is not None:
                if what == "lux":
                    out[t.group] += t.geo * (K_M * float(S @ V))
                else:
                    out[t.group] += np.outer(t.geo, Bm @ S)
            if t.geo_bands is not None:
                if what == "lux":
                    out[t.group] += t.geo_bands @ (K_M * (P.T @ (S * V)))
                else:
                    out[t.group] += t.geo_bands @ ((P.T * S[None, :]) @ Bm.T)
        return out

    def lux_by_group(self) -> dict[str, np.ndarray]:
        """Illuminance (lx) per lamp group at unit intensity scale."""
        return self._per_group("lux")

    def bands_by_group(self) -> dict[str, np.ndarray]:
        """Band-mean spectral irradiance (W·m⁻²·nm⁻¹) per lamp group, (M, B)."""
        return self._per_group("bands")

    def lux(self, scales: dict[str, float] | None = None) -> np.ndarray:
        scales = scales or {}
        return sum((scales.get(g, 1.0) * v for g, v in self.lux_by_group().items()),
                   np.zeros(self.n))

    def bands(self, scales: dict[str, float] | None = None) -> np.ndarray:
        scales = scales or {}
        B = spectral_tables(self.grid)[1].shape[0]
        return sum((scales.get(g, 1.0) * v for g, v in self.bands_by_group().items()),
                   np.zeros((self.n, B)))

    def spectral_1nm(self, scales: dict[str, float] | None = None, rows=None) -> np.ndarray:
        """Spectral irradiance on the 1 nm reference grid, (M, 471); only ``rows`` (indices)
        if given."""
        scales = scales or {}
        _, _, P = spectral_tables(self.grid)
        sel = slice(None) if rows is None else np.asarray(rows, int)
        n = self.n if rows is None else len(sel)
        out = np.zeros((n, P.shape[0]))
        for t in self.terms:
            s = scales.get(t.group, 1.0)
            if not s:
                continue
            if t.geo is not None:
                out += s * np.outer(t.geo[sel], t.spectrum_1nm)
            if t.geo_bands is not None:
                out += s * (t.geo_bands[sel] @ P.T) * t.spectrum_1nm[None, :]
        return out


# --------------------------------------------------------------------------- the model

class ForwardModel:
    """Forward model of one booth and lighting configuration.

    Parameters
    ----------
    ir
        The compiled booth.
    lighting
        Lighting configuration name (default: the booth's first).
    effects
        Enabled effects ``{id: params}`` (default: the booth's ``effects:``).
    lamp_overrides
        Per-lamp overrides used by fits, e.g. ``{'tube1': {'sigma_deg': 40}}``.
    cache
        A dict shared between models of the same IR (a fit passes one), so
        geometry (form factors, LU factors) is computed once.
    """

    def __init__(self, ir, lighting: str | None = None, *, effects: dict | None = None,
                 lamp_overrides: dict | None = None, options: ForwardOptions | None = None,
                 cache: dict | None = None):
        from lbscene.engine.files.diagnostics import LbsceneUserError
        from lbscene.engine.light.effects.registry import available_effects, get_effect
        # a compiled booth (the scene layer's SceneIR, above this one: recognised by its fields)
        # (content_hash looked up on the class: the property hashes the whole booth)
        if not (all(hasattr(ir, a) for a in ("lighting", "lamps", "interior"))
                and hasattr(type(ir), "content_hash")):
            raise TypeError(f"ForwardModel needs a compiled booth (SceneIR, from lbscene.compile_booth), "
                            f"not {type(ir).__name__}")
        self.ir = ir
        self.lighting = lighting or next(iter(ir.lighting))
        if self.lighting not in ir.lighting:
            raise LbsceneUserError.single("LB202", f"the booth has no lighting configuration {self.lighting!r}",
                                          value=repr(self.lighting), expected=f"one of {', '.join(ir.lighting)}")
        self.effects = dict(ir.effects if effects is None else effects)
        registry = available_effects()
        unknown = [e for e in self.effects if e not in registry]
        if unknown:
            raise LbsceneUserError.single("LB106", f"unknown effect id {unknown[0]!r}", value=repr(unknown[0]),
                                          expected=f"one of {', '.join(registry)}")
        for eid, p in self.effects.items():
            if p is not None and not isinstance(p, dict):
                raise TypeError(f"effects[{eid!r}] must be a dict of parameters (or None), not {type(p).__name__}")
            try:
                effect_params(get_effect(eid), p)
            except ValueError as exc:          # pydantic's ValidationError
                err = exc.errors()[0] if hasattr(exc, "errors") else {"loc": (), "msg": str(exc)}
                where = ".".join(str(x) for x in err["loc"])
                raise LbsceneUserError.single(
                    "LB104", f"effects[{eid!r}]{'.' + where if where else ''}: {err['msg']}",
                    value=repr(p)[:80], expected=f"the parameters of effect {eid!r} (lbscene effects)") from None
        self.options = options or ForwardOptions()
        self.ctx = ForwardContext(ir, self.lighting, self.effects, _changing_overrides(ir, lamp_overrides),
                                  self.options, cache if cache is not None else {})
        self._enabled = sorted(((get_effect(eid), effect_params(get_effect(eid), p))
                                for eid, p in self.effects.items()),
                               key=lambda cp: (getattr(cp[0], "order", 100), cp[0].id))
        self._sets_cache: dict = {}
        self._global = None

    # ------------------------------------------------------------------ lamps
    @property
    def groups(self) -> list[str]:
        seen = []
        for lamp, _ in self.ir.lamps_on(self.lighting):
            if lamp.group not in seen:
                seen.append(lamp.group)
        return seen

    def _hooks(self, name: str, exclude: Iterable[str] = ()):
        ex = set(exclude)
        for cls, p in self._enabled:
            fn = getattr(cls, name, None)
            if fn is not None and cls.id not in ex:
                yield cls, p, fn

    def base_emitters(self, lamp, n: int, level: float = 1.0, *, n_around: int = 0) -> list[EmitterSet]:
        """The lamp's :class:`~lbscene.engine.light.emitters.Emitter` as point quadratures.

        Tubes: ``n`` points on the axis with the Lambertian cylinder's far-field law
        (sin of the angle to the axis), or, with ``n_around`` > 0, ``n × n_around`` points on
        the lateral surface with the Lambertian law (near field); end caps as two flat points.
        Panels: a grid of about ``n`` points with the Lambertian law of their normal.
        Bulbs (outside: a point) and points: one point.
        """
        from .emitters import TubeEmitter, emitter_from_lamp

        em = emitter_from_lamp(lamp)
        spec = lamp.peak_intensity_1nm * level
        aim, ax = em.aim, em.axis
        common = dict(lamp_id=lamp.id, group=lamp.group, kind=lamp.kind, aim=aim,
                      spectrum_1nm=spec, lamp_axis=ax)
        sets = []
        if isinstance(em, TubeEmitter):
            half = ax * lamp.length_mm / (2 * n)
            if n_around > 0:
                pts, nrm, w, s = em.surface_points(n, n_around)
                sets.append(EmitterSet(points_mm=pts, weights=w, s=s, normals=nrm, half_step=half,
                                       **common))
            else:
                pts, w, s = em.line_points(n)
                sets.append(EmitterSet(points_mm=pts, weights=w, s=s, line_axis=ax, half_step=half,
                                       line_radius_mm=float(lamp.radius_mm), **common))
            caps = em.cap_points()
            if caps is not None:
                sets.append(EmitterSet(points_mm=caps[0], weights=caps[2], s=caps[3], normals=caps[1],
                                       **common))
        elif lamp.kind == "panel":
            pts, w, s = em.line_points(n)
            sets.append(EmitterSet(points_mm=pts, weights=w, s=s, normals=np.tile(aim, (len(pts), 1)),
                                   **common))
        else:
            pts, w, s = em.line_points(1)
            sets.append(EmitterSet(points_mm=pts, weights=w, s=s, **common))
        return sets

    def emitter_sets(self, lamp, n: int | None = None, level: float = 1.0,
                     n_around: int = 0) -> list[EmitterSet]:
        """A lamp's emitters after every enabled effect's ``modify_emitters``/``extra_emitters``."""
        n = n or lamp.point_sources
        key = (lamp.id, n, level, n_around)
        hit = self._sets_cache.get(key)
        if hit is not None:
            return hit
        sets = []
        for es in self.base_emitters(lamp, n, level, n_around=n_around):
            for cls, p, fn in self._hooks("modify_emitters"):
                es = fn(self.ctx, p, lamp, es)
            sets.append(es)
            for cls, p, fn in self._hooks("extra_emitters"):
                sets.extend(fn(self.ctx, p, lamp, es))
        self._sets_cache[key] = sets
        return sets

    # ------------------------------------------------------------------ direct light
    def _response(self, cos_i: np.ndarray, meter: np.ndarray) -> np.ndarray | None:
        hooks = list(self._hooks("receiver_response"))
        if not hooks or not meter.any():
            return None
        f = np.ones_like(cos_i)
        for cls, p, fn in hooks:
            f = f * fn(self.ctx, p, cos_i)
        return np.where(meter[:, None] if f.ndim == 2 else meter, f, 1.0)

    def _pair_geometry(self, es: EmitterSet, P, N):
        """cos θ_r / d² (1/m²), cos θ_r and emission angle θ for every (receiver, point) pair.

        Depends on geometry only, so it is cached across parameter changes.
        """
        key = ("_pairs", array_key(es.points_mm), array_key(P, N), es.tag, es.lamp_id,
               es.shape is not None, getattr(es.shape, "two_d", False), es.normals is not None,
               es.line_axis is not None)
        store = self.ctx.cache.setdefault("_pairs", {})
        hit = store.get(key)
        if hit is not None:
            return hit
        d = P[:, None, :] - es.points_mm[None, :, :]
        r2 = np.maximum(np.einsum("mnc,mnc->mn", d, d), 1e-6)
        inv_r = 1.0 / np.sqrt(r2)
        cos_rx = np.clip(-np.einsum("mnc,mc->mn", d, N) * inv_r, 0.0, None)
        g0 = cos_rx / (r2 * 1e-6)
        theta = None
        if es.shape is not None or es.normals is not None or es.line_axis is not None:
            u = d * inv_r[..., None]
            ue = es.direction_map(u) if es.direction_map is not None else u
            if es.normals is not None:          # Lambertian surface element
                g0 = g0 * np.clip(np.einsum("mnc,nc->mn", ue, es.normals), 0.0, None)
            if es.line_axis is not None and es.line_radius_mm > 0:
                g0 = _cylinder_slices(d, N, es.line_axis if es.direction_map is None
                                      else es.direction_map(es.line_axis), es.line_radius_mm)
            elif es.line_axis is not None:      # far field of a Lambertian cylinder slice
                c = ue @ es.line_axis
                g0 = g0 * np.sqrt(np.clip(1.0 - c * c, 0.0, None))
            if es.shape is not None:
                if getattr(es.shape, "two_d", False):
                    from lbscene.engine.spectra.profiles import ies_angles

                    axis = es.lamp_axis if es.lamp_axis is not None else np.array([1.0, 0.0, 0.0])
                    theta = ies_angles(ue, axis, es.aim)
                else:
                    theta = np.arccos(np.clip(ue @ es.aim, -1.0, 1.0))
        out = (g0, cos_rx, theta)
        if not self.ctx.storing:
            return out
        if len(store) >= 128:
            store.pop(next(iter(store)))
        store[key] = out
        return out

    def _set_terms(self, es: EmitterSet, P, N, meter, exclude, incidence_weight, pair_factor=None,
                   per_point: bool = False):
        if _behind_receivers(es.points_mm, P, N):
            # every point lies behind every receiver (a lamp's image under a plate, seen from
            # the plate's top): no light, and no geometry or path factor worth computing
            zero = np.zeros((len(P), len(es.points_mm))) if per_point else np.zeros(len(P))
            return [(es.spectral_key, es.spectrum_1nm, zero)]
        g0, cos_rx, theta = self._pair_geometry(es, P, N)
        base = es.weights[None, :] * g0
        if pair_factor is not None:
            # caller's per-path transmission (the inter-reflection's mesh visibility)
            f = pair_factor(es, P)
            if f is not None:
                base = base * f
        if es.shape is not None:
            # declared profiles (cosⁿ, IES) never change during a fit: reuse their values; a fitted
            # σ makes a new shape at every step, hence the small bound
            data = getattr(es.shape, "data", None)        # IES tables: key by content, not repr
            name = f"shape:{type(es.shape).__name__}" if data is not None else f"shape:{es.shape!r}"
            extra = (data.vertical_deg, data.horizontal_deg, data.candela) if data is not None else ()
            base = base * self.ctx.memo(name, (es.points_mm, P, N, es.aim,
                                               es.lamp_axis if es.lamp_axis is not None else 0.0,
                                               *extra),
                                        lambda: es.shape(*theta) if isinstance(theta, tuple)
                                        else es.shape(theta), limit=16)
        resp = self._response(cos_rx, meter)
        if resp is not None:
            base = base * resp
        if incidence_weight is not None:
            ck = getattr(incidence_weight, "cache_key", None)
            if es.line_axis is not None and es.line_radius_mm > 0:
                # a tube slice's light arrives from the arc of its surface the receiver sees, not
                # from its axis: the weight averaged over that arc (_ArcMean)
                axis = es.line_axis if es.direction_map is None else es.direction_map(es.line_axis)

                cyl = (np.asarray(axis, float), np.array([es.line_radius_mm], float))

                def weight():
                    # the arcs' geometry is kept apart from the weight: a fit that changes the
                    # weight (an opal layer's depth) reuses it
                    arc = self.ctx.memo("arc", (es.points_mm, P, N, *cyl), lambda: _ArcMean(
                        P[:, None, :] - es.points_mm[None, :, :], N, axis, es.line_radius_mm), limit=32)
                    return arc(incidence_weight)
            else:
                def weight():
                    return incidence_weight(cos_rx)
                cyl = ()
            w = weight() if ck is None else self.ctx.memo(f"incidence:{ck!r}", (es.points_mm, P, N, *cyl), weight)
            base = base * w
        channels = [(1.0, (), None)]
        pk = None
        # receivers no emitter point reaches (facing away: an inter-reflection patch on the far
        # side of a lamp box's wall) need no path factors: they get none of this set's light
        live = np.any(base != 0.0, axis=1)
        if not live.any():
            return [(es.spectral_key, es.spectrum_1nm, base if per_point else np.zeros(len(P)))]
        sub = None if live.all() else np.nonzero(live)[0]
        Pp = P if sub is None else P[sub]
        for cls, p, fn in self._hooks("path_factors", exclude):
            # path factors depend on geometry only: cache them across parameter changes (a fit
            # varying σ or intensities never recomputes occlusion, mirrors or the diffuser)
            if pk is None:
                pk = (array_key(es.points_mm, es.half_step if es.half_step is not None else 0.0),
                      array_key(Pp), es.tag, es.lamp_id)
            ck = (cls.id, repr(p)) + pk
            store = self.ctx.cache.setdefault("_paths", {})
            if ck in store:
                chs = store[ck]
            else:
                chs = fn(self.ctx, p, es, Pp)
                if self.ctx.storing:
                    if len(store) >= 256:
                        store.pop(next(iter(store)))
                    store[ck] = chs
            if not chs:
                continue
            new = []
            for f, key, spec in channels:
                for ch in chs:
                    k = key + ((ch.spectral_key,) if ch.spectral_key else ())
                    s = spec if ch.spectrum_1nm is None else (
                        ch.spectrum_1nm if spec is None else spec * ch.spectrum_1nm)
                    fac = ch.factor
                    if sub is not None and isinstance(fac, np.ndarray) and fac.ndim >= 1 and \
                            fac.shape[0] == sub.size:
                        full = np.zeros((len(P),) + fac.shape[1:])
                        full[sub] = fac
                        fac = full
                    new.append((f * fac, k, s))
            channels = new
        out = []
        for f, key, spec in channels:
            if per_point:
                geo = base * f
            else:
                geo = (base * f).sum(axis=1) if isinstance(f, np.ndarray) else base.sum(axis=1) * f
            S = es.spectrum_1nm if spec is None else es.spectrum_1nm * spec
            out.append((es.spectral_key + key, S, geo))
        return out

    def _lamp_terms(self, lamp, level, P, N, meter, exclude, incidence_weight,
                    pair_factor=None) -> dict:
        """{key: [spectrum, geo (M,)]} of one lamp at the receivers (near field refined)."""
        acc: dict = {}

        def add(sets, rows):
            # sets of one quadrature add up; a finer quadrature replaces the coarse one on its rows
            local: dict = {}
            for es in sets:
                for key, S, geo in self._set_terms(es, P[rows], N[rows], meter[rows], exclude,
                                                   incidence_weight, pair_factor):
                    k = (es.tag,) + key
                    if k in local:
                        local[k][1] = local[k][1] + geo
                    else:
                        local[k] = [S, geo]
            for k, (S, geo) in local.items():
                if k not in acc:
                    acc[k] = [S, np.zeros(len(P))]
                acc[k][1][rows] = geo

        allrows = np.arange(len(P))
        opt = self.options
        n = lamp.point_sources if opt.lamp_points is None else max(1, min(lamp.point_sources, opt.lamp_points))
        add(self.emitter_sets(lamp, n, level), allrows)
        if opt.near_field and lamp.kind in ("tube", "panel") and lamp.length_mm > 0:
            spacing = lamp.length_mm / n
            c = np.asarray(lamp.position_mm, float)
            ax = np.asarray(lamp.axis, float)
            rel = P - c
            t = np.clip(rel @ ax, -lamp.length_mm / 2, lamp.length_mm / 2)
            dist = np.linalg.norm(rel - np.outer(t, ax), axis=1)
            if lamp.kind == "panel":
                # a rule of ~n nodes ~√(ℓw/n) apart: near receivers need nodes a fifth of their
                # distance apart
                dist = np.abs(rel @ np.asarray(lamp.aim, float))
                cell = np.sqrt(lamp.length_mm * lamp.width_mm / n)
                near = dist < opt.near_field_factor * cell
                need = lamp.length_mm * lamp.width_mm / (np.maximum(dist, 1.0) / 5.0) ** 2
            else:
                # slices finer than the distance to the surface (each slice's arc is exact already)
                dist = np.maximum(dist - lamp.radius_mm, 0.0)
                near = dist < opt.near_field_factor * spacing
                need = n * opt.near_field_factor * spacing / np.maximum(dist, max(0.05 * spacing, 1e-3))
            if near.any():
                # rows grouped by the resolution they need (powers of two of n): a few receivers
                # touching the lamp do not make every near receiver pay for the finest rule
                octave = np.ceil(np.log2(np.maximum(np.minimum(need, opt.max_points) / n, 1.0)))
                for k in np.unique(octave[near]):
                    n_fine = int(min(opt.max_points, n * 2 ** k))
                    rows = np.nonzero(near & (octave == k))[0]
                    if n_fine > n and rows.size:
                        add(self.emitter_sets(lamp, n_fine, level), rows)
        return acc

    def direct_terms(self, points, normals=None, meter=None, *, exclude: Sequence[str] = (),
                     incidence_weight=None, pair_factor=None) -> list[Term]:
        """Straight lamp→receiver light (with every enabled path/emitter/response effect).

        ``pair_factor(es, P)`` (optional) returns an extra ``(M, N)`` transmission of each
        receiver ← emitter point path (or None): the inter-reflection passes the
        visibility of its patches past the booth's meshes.
        """
        P, N, m = as_receivers(points, normals, meter)
        out = []
        for lamp, level in self.ir.lamps_on(self.lighting):
            for key, (S, geo) in self._lamp_terms(lamp, level, P, N, m, exclude,
                                                  incidence_weight, pair_factor).items():
                out.append(Term(lamp.group, lamp.id, key, S, geo, None, "direct"))
        return out

    def direct_per_point(self, points, normals=None, *, exclude: Sequence[str] = ()) -> list[PointLight]:
        """Direct light on physical surfaces (no meter response) emitter point by emitter point,
        with the direction it comes from: one :class:`PointLight` per emitter set and spectral
        channel (each lamp's own quadrature, no near-field refinement)."""
        P, N, m = as_receivers(points, normals, False)
        out = []
        for lamp, level in self.ir.lamps_on(self.lighting):
            for es in self.emitter_sets(lamp, None, level, n_around=PER_POINT_AROUND):
                d = es.points_mm[None, :, :] - P[:, None, :]
                u = d / np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-9)
                for key, S, geo in self._set_terms(es, P, N, m, exclude, None, per_point=True):
                    geo = np.broadcast_to(geo, u.shape[:2])
                    out.append(PointLight(Term(lamp.group, lamp.id, (es.tag,) + key, S, None, None, "direct"),
                                          geo, u))
        return out

    # ------------------------------------------------------------------ secondary emitters
    def secondary_sources(self) -> list[LambertianSource | DirectionalSource]:
        key = "_secondary"
        hit = getattr(self, key, None)
        if hit is not None:
            return hit
        out = []

        def direct(points, normals, exclude=(), incidence_weight=None):
            # light arriving on a physical surface (never read by the meter)
            return self.direct_terms(points, normals, False, exclude=exclude,
                                     incidence_weight=incidence_weight)

        direct.per_point = lambda points, normals, exclude=(): self.direct_per_point(
            points, normals, exclude=exclude)

        for cls, p, fn in self._hooks("secondary_sources"):
            out.extend(fn(self.ctx, p, direct))
        setattr(self, key, out)
        return out

    def lambertian_gather(self, src_polys, src_normals, P, N, meter) -> np.ndarray:
        """(M, S) form factors from receivers to Lambertian polygons, with meter response."""
        from .geometry import polygon_form_factor, quad_centroids

        ck = ("ff", array_key(src_polys, P, N))
        F = self.ctx.cache.get(ck)
        if F is None:
            F = polygon_form_factor(P, N, src_polys, src_normals)
            if len(self.ctx.cache) < 512:
                self.ctx.cache[ck] = F
        if list(self._hooks("receiver_response")) and meter.any():
            c = quad_centroids(src_polys)
            d = c[None, :, :] - P[:, None, :]
            cos_i = np.clip(np.einsum("msc,mc->ms", d, N) / np.maximum(np.linalg.norm(d, axis=2), 1e-9),
                            0.0, 1.0)
            F = F * self._response(cos_i, meter)
        return F

    def first_order_terms(self, points, normals=None, meter=None, *, pair_factor=None) -> list[Term]:
        """Direct light plus light from secondary (diffusely re-emitting) sources.

        ``pair_factor``: see :meth:`direct_terms` (applied to the lamps' direct light only).
        """
        P, N, m = as_receivers(points, normals, meter)
        terms = self.direct_terms(P, N, m, pair_factor=pair_factor)
        for src in self.secondary_sources():
            F = self.lambertian_gather(src.polys, src.normals, P, N, m)
            for cls, p, fn in self._hooks("source_path_factors"):
                f = fn(self.ctx, p, src.polys, P)
                if f is not None:
                    F = F * f
            if isinstance(src, DirectionalSource):
                from .geometry import quad_centroids

                # the radiance only toward receivers that see a polygon (a plate's light is
                # asked for at every patch of the room, the cavity above it and the walls' backs
                # included: the evaluation is the cost)
                seen = np.flatnonzero(F.any(axis=1))
                geo = np.zeros((len(P), len(src.terms)))
                if seen.size:
                    d = P[None, seen, :] - quad_centroids(src.polys)[:, None, :]   # (S, M', 3)
                    d = d / np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-9)
                    L = src.radiance(d)                                            # (S, M', K)
                    geo[seen] = np.pi * np.einsum("ms,smk->mk", F[seen], L)
            else:
                geo = F @ src.exitance                           # (M, K)
            for k, d in enumerate(src.terms):
                terms.append(replace(d, geo=geo[:, k], geo_bands=None))
        return terms

    # ------------------------------------------------------------------ global transport
    def global_transports(self) -> list:
        if self._global is None:
            self._global = [fn(self.ctx, p, self) for cls, p, fn in self._hooks("global_transport")]
        return self._global

    # ------------------------------------------------------------------ public API
    def predict(self, points, normals=None, meter=None) -> Prediction:
        """All light at the receivers: first-order and global terms."""
        P, N, m = as_receivers(points, normals, meter)
        with blas_single_thread():
            terms = self.first_order_terms(P, N, m)
            for gt in self.global_transports():
                terms.extend(gt.terms(P, N, m))
        return Prediction(self.groups, _merge_terms(terms), len(P), self.ir.grid)

    def illuminance_lx(self, points, normals=None, meter: bool = True, scales=None) -> np.ndarray:
        """Illuminance (lx) read by the meter (``meter=True``) or on a physical surface."""
        return self.predict(points, normals, meter).lux(scales)

    def spectral_irradiance_bands(self, points, normals=None, scales=None) -> np.ndarray:
        """Band-mean spectral irradiance (W·m⁻²·nm⁻¹) on physical surfaces, (M, B)."""
        return self.predict(points, normals, False).bands(scales)

    def spectral_irradiance_1nm(self, points, normals=None, scales=None) -> np.ndarray:
        """Spectral irradiance (W·m⁻²·nm⁻¹) at 1 nm on physical surfaces, (M, 471)."""
        return self.predict(points, normals, False).spectral_1nm(scales)

    def white_tile_radiance_1nm(self, point=None, normal=(0.0, 0.0, 1.0), reflectance_1nm=1.0,
                                scales=None) -> np.ndarray:
        """Radiance (W·sr⁻¹·m⁻²·nm⁻¹) of a Lambertian tile: ρ(λ)·E(λ)/π."""
        p = self.ir.sample_position_mm if point is None else point
        e = self.spectral_irradiance_1nm([p], [normal], scales)[0]
        return np.asarray(reflectance_1nm, float) * e / np.pi


_GAUSS_ARC = np.polynomial.legendre.leggauss(12)
#: points around a tube's circumference in :meth:`ForwardModel.direct_per_point`: light that a
#: surface near a tube receives comes from the tube's visible surface, a spread of directions
#: (±asin(r/d)) a direction-dependent receiver (a rough plate's BTDF) must see
PER_POINT_AROUND = 16


def _cylinder_arc(d, N, axis, radius_mm):
    """The quadrature over the arc of Lambertian cylinder slices a receiver sees.

    ``d`` (M, K, 3) receiver minus slice centre (mm), ``N`` (M, 3) receiver normals.  Returns
    ``φ₀`` (M, K), the half-angle of the visible arc (``|φ| < arccos(r/h)``, h the receiver's
    distance from the axis; 0 inside the tube), an iterator over the 12 Gauss–Legendre
    nodes φ = φ₀·t_k of ``(g_k · cos θ_s · max(0, cos θ_r) / ρ², cos θ_r)`` (1/mm², each
    (M, K)): θ_s from the surface normal at the node, θ_r at the receiver, ρ the distance
    from the node, and ``(N·d, |d|²)`` (M, K).  :func:`_cylinder_slices` and :class:`_ArcMean`
    sum over it.
    """
    t, g = _GAUSS_ARC
    a = np.asarray(axis, float)
    ax = d @ a
    perp = d - ax[..., None] * a
    h = np.maximum(np.linalg.norm(perp, axis=-1), 1e-9)
    e = perp / h[..., None]
    phi0 = np.arccos(np.clip(radius_mm / h, -1.0, 1.0))
    Ne = np.einsum("mkc,mc->mk", e, N)
    Ne2 = np.einsum("mkc,mc->mk", np.cross(a, e), N)
    Nd = np.einsum("mkc,mc->mk", d, N)
    d2 = np.einsum("mkc,mkc->mk", d, d)

    def nodes():
        for tk, gk in zip(t, g):
            phi = phi0 * tk
            c, s = np.cos(phi), np.sin(phi)
            rho2 = np.maximum(d2 - 2.0 * radius_mm * h * c + radius_mm ** 2, 1e-6)
            rho = np.sqrt(rho2)
            cos_s = (h * c - radius_mm) / rho
            cos_r = np.clip((radius_mm * (c * Ne + s * Ne2) - Nd) / rho, 0.0, None)
            yield gk * cos_s * cos_r / rho2, cos_r

    return phi0, nodes(), (Nd, d2)


def _cylinder_slices(d, N, axis, radius_mm):
    """Irradiance transfer of Lambertian cylinder slices, (M, K), per unit slice weight.

    ``d`` (M, K, 3) receiver minus slice centre (mm), ``N`` (M, 3) receiver normals.  A slice
    of radius r whose weight stands for ``I = L·2r·Δℓ`` gives at the receiver

        G = ½ ∫ cos θ_s · max(0, cos θ_r) / ρ² dφ      (1/m²)

    over the arc the receiver sees (:func:`_cylinder_arc`: n·(P − x) > 0, |φ| < arccos(r/h),
    h its distance from the axis), θ_s from the surface normal, ρ from the surface point.
    12-point Gauss–Legendre over the arc; far away G → sin θ_axis · cos θ_r / d².
    """
    phi0, nodes, _ = _cylinder_arc(d, N, axis, radius_mm)
    out = np.zeros(d.shape[:2])
    for f, _ in nodes:
        out += f
    return 0.5e6 * phi0 * out


#: cos θ_r samples of :class:`_ArcMean`'s table of an incidence weight and its derivatives
#: (uniform on [0, 1])
ARC_WEIGHT_TABLE = 2049


class _ArcMean:
    """Irradiance-weighted mean of an incidence weight ``w(cos θ_r)`` over the arc of a Lambertian
    cylinder slice a receiver sees, (M, K):

        W = ∫ w(cos θ_r) cos θ_s cos θ_r / ρ² dφ  /  ∫ cos θ_s cos θ_r / ρ² dφ

    (the quadrature of :func:`_cylinder_arc`).  An incidence weight evaluated along the slice's
    axis instead sees the light of a near tube from too steep a direction: an opal plate 48.5 mm
    under tubes of radius 13 mm took 1.5 % too much of it.

    The geometry is reduced once (``__init__``) to the weighted mean c̄ of cos θ_r over the arc and
    its central moments μ₂…μ₄; a smooth weight's mean is then its Taylor series about c̄,

        W = w(c̄) + w''(c̄)·μ₂/2 + w'''(c̄)·μ₃/6 + w''''(c̄)·μ₄/24,

    with the derivatives taken from the weight tabulated at :data:`ARC_WEIGHT_TABLE` values of
    cos θ_r (:meth:`__call__`).  A fit that changes the weight (an opal layer's optical depth)
    does not integrate the arcs again, and the store per geometry is four (M, K) arrays.  On the
    SpectraLight QC's diffuser (tubes 48.5 mm above it, the opal entry law at optical depths
    0.03–5) the series is within 2.3·10⁻⁶ of the arc's quadrature (w(c̄) alone: 9·10⁻⁴).
    Where no light arrives (the integral's denominator is 0) the weight along the axis is used;
    it multiplies nothing.
    """

    def __init__(self, d, N, axis, radius_mm):
        from math import factorial

        _, nodes, (Nd, d2) = _cylinder_arc(d, N, axis, radius_mm)
        nodes = list(nodes)
        den = np.zeros(d2.shape)
        mean = np.zeros(d2.shape)
        for f, c in nodes:
            den += f
            mean += f * c
        lit = den > 0
        inv = np.where(lit, 1.0 / np.where(lit, den, 1.0), 0.0)
        mean *= inv
        # the central moments by products (a power with an integer exponent above 2 is a pow())
        moments = [np.zeros(d2.shape) for _ in range(3)]
        for f, c in nodes:
            dc = c - mean
            t = f * dc * dc
            moments[0] += t
            t *= dc
            moments[1] += t
            t *= dc
            moments[2] += t
        moments = [mu * inv for mu in moments]
        axis_cos = np.clip(-Nd / np.sqrt(np.maximum(d2, 1e-12)), 0.0, None)
        mean = np.clip(np.where(lit, mean, axis_cos), 0.0, 1.0)
        # each c̄'s interval of the table and its place in it; the series' coefficients
        x = mean * (ARC_WEIGHT_TABLE - 1)
        self.index = np.minimum(np.floor(x).astype(np.intp), ARC_WEIGHT_TABLE - 2)
        self.frac = (x - self.index)[..., None]
        self.coef = np.stack([np.ones_like(mean)] + [mu / factorial(n) for n, mu in zip((2, 3, 4), moments)],
                             axis=-1)

    def __call__(self, weight) -> np.ndarray:
        c = np.linspace(0.0, 1.0, ARC_WEIGHT_TABLE)
        w0 = np.asarray(weight(c), float)
        w2 = np.gradient(np.gradient(w0, c), c)
        w3 = np.gradient(w2, c)
        T = np.stack([w0, w2, w3, np.gradient(w3, c)], axis=1)         # the weight, its 2nd–4th derivatives
        lo, hi = T[self.index], T[self.index + 1]
        return np.einsum("...j,...j->...", lo + self.frac * (hi - lo), self.coef)


def _merge_terms(terms: list[Term]) -> list[Term]:
    """Sum terms with the same group, lamp, spectral identity and kind of transfer."""
    out: dict = {}
    for t in terms:
        k = (t.group, t.lamp_id, t.key, t.geo is not None, t.geo_bands is not None)
        if k not in out:
            out[k] = replace(t, geo=None if t.geo is None else t.geo.copy(),
                             geo_bands=None if t.geo_bands is None else t.geo_bands.copy())
        else:
            if t.geo is not None:
                out[k].geo += t.geo
            if t.geo_bands is not None:
                out[k].geo_bands += t.geo_bands
    return list(out.values())
