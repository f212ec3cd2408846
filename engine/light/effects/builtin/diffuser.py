"""
``diffuser``: a plate below the lamps transmits and scatters their light.

Kind ``geometric`` (and spectral: the plate's transmittance).  Straight paths through the
plate get its spectral transmittance and the Fresnel angular loss, and are refracted through its
thickness (:func:`lbscene.engine.light.plates.slab_crossing`: the lamps behind a plate look
:math:`t(1 - 1/n)` closer; ``thickness_refraction``); an opal plate's diffuse
fraction enters its top face and is re-emitted from its bottom face's cells with the scattering
layer's bidirectional law: the light of every emitter point on each cell binned by direction
and carried to every exit direction and azimuth (:mod:`lbscene.engine.light.opal_layer`).  The declared transmittance is the
plate's total at normal incidence (:func:`lbscene.engine.light.plates.reference_transmittance`).  A ``roughness`` plate (rough
glass) has the rough GGX slab's :math:`T(θ)` on straight paths, or its BTDF on re-emitting
cells when the lobe is wide (:mod:`lbscene.engine.light.rough_slab`).  A clear or rough plate
reflects the lamps above it specularly: each lamp gets a mirror image under the plate's top face
(``extra_emitters``), seen through the plate and past the lamp's body, times the plate's
directional reflectance :math:`R(θ)` at the path's incidence (``plate_reflection: specular``); the
inter-reflection then reflects the surfaces' light in the plate the same way, through their
images (:mod:`lbscene.engine.light.plate_mirror`), where ``diffuse`` makes both faces Lambertian
patches of the plate's hemispherical reflectance.  The plate itself
(rectangle, transmittances) is :mod:`lbscene.engine.light.plates`.
"""

from __future__ import annotations

import hashlib
import math
from typing import Literal

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import (DirectionalSource, PathChannel,
                                                  PhysicalEffect)
from lbscene.engine.light.effects.registry import EffectParams, register_effect
from lbscene.engine.light.plates import (absorption_squared, diffuser_fraction, diffuser_rect,
                                         diffuser_transmittance_1nm, is_rough, plate_as_fitted,
                                         plate_lobe_footprint_mm, plate_reflectance, plate_slab, plate_top_mm,
                                         reference_transmittance, slab_crossing, slab_relative,
                                         specular_plate)
from lbscene.engine.light.rough_slab import EXIT_PHI_STEPS, RoughSlab

__all__ = ["DiffuserEffect"]


#: rough plates' exit-radiance grids (per unit 1 − f_d) kept per forward-model cache: a fit
#: varying only the plate's diffuse fraction or transmittance asks for the same light again
ROUGH_RADIANCE_MEMO = 4
#: a rough plate whose transmitted lobe holds 90 % of its light beyond this angle (normal
#: incidence) re-emits through its cells (``rough_transport: auto``): straight paths with T(θ) keep
#: a grazing path's direction where a wide lobe turns light toward the plate's normal — under tubes
#: 14 mm above a plate of GGX α 0.3 (θ₉₀ 29°) 2.4 % / 3.1 % low against Mitsuba 3 (validation scene
#: ``aperture-diffuser``), through the cells 0.7 %; with α 0.09 (θ₉₀ 11°) straight paths are the
#: closer (0.5 % / 0.7 % against 0.7 % / 1.0 %, ``rough-diffuser-r030``)
SCATTERED_LOBE_DEG = 20.0
#: sub-points a side of a rough plate's re-emitting cell: at least, at most, and how many times
#: closer than the cell's distance to the nearest lamp surface they are spaced
ROUGH_SUB_MIN = 2
ROUGH_SUB_MAX = 8
ROUGH_SUB_DISTANCE_RATIO = 3.5
#: sub-points of a rough plate's cells whose incoming light is computed at once
ROUGH_CHUNK_POINTS = 1024
#: an opal plate's cells coarser than this (the diagnosis' 100 mm) send their light from sub-cells
#: no larger, each in proportion to the light its part of the cell gathered (the cell's angular
#: law shared): a 100 mm cell spreading the light peaked under a tube evenly put the A3 sheet
#: 600 mm below the plate 1.1 % low against Mitsuba 3 (``opal-black``; 0.3 % at 50 mm cells)
OPAL_EMIT_CELL_MM = 50.0


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
                                    description="Cell size of the re-emitting plate (an opal "
                                                "plate's diffuse part).")
        plate_reflection: Literal["specular", "diffuse"] = Field(
            "specular", description="How a clear or rough plate reflects light: 'specular' (the lamps' "
                                    "and the surfaces' mirror images in its faces, times its "
                                    "reflectance R(θ)), 'diffuse' (re-emitted by the inter-reflection's "
                                    "plate patches, Lambertian).  Opal plates reflect diffusely.")
        rough_transport: Literal["auto", "regular", "scattered"] = Field(
            "auto", description="A roughness plate's light: 'regular' (straight paths times the "
                                "rough slab's transmittance T(θ)), 'scattered' (plate cells "
                                "re-emit through the slab's BTDF), 'auto' (scattered when the "
                                "lobe's footprint on the plate exceeds scattered_cell_size_mm or "
                                "the lobe is wide, 90 % of its light beyond 20° of the straight "
                                "line).")
        cell_subpoints: int | None = Field(None, ge=1, le=16,
                                           description="Sub-points a side of each of an opal plate's cells at "
                                                       "which the lamps' light on the plate is gathered "
                                                       "(default: by the cell's distance to the lamps, 2 to 8).")
        opal_modes: int | None = Field(None, ge=0, le=48,
                                       description="Azimuthal modes of an opal plate's law kept for the "
                                                   "lamps' light through it (default: every mode the "
                                                   "layer's asymmetry needs, at most 48).")
        thickness_refraction: bool = Field(True, description="Paths through the plate are refracted through "
                                                             "its thickness_mm, so what lies behind it looks "
                                                             "closer; false: a plate of no thickness (as the "
                                                             "bake's thin sheet draws a clear or rough plate).")
        scattered_cell_size_mm: float = Field(25.0, gt=1, le=1000,
                                              description="Cell size of a roughness plate whose light "
                                                          "re-emits through the slab's BTDF.")

    @classmethod
    def applicable(cls, ir, lighting):
        return None if ir.diffuser is not None else "the booth has no diffuser: section"

    #: the diagnosis refits every candidate (and profiles a hypothesised plate's height): it
    #: gathers the light on an opal plate's cells at least this coarse, 2 × 2 points a cell
    diagnosis_cell_mm: float = 100.0
    #: … and keeps at most this many azimuthal modes of an opal plate's law
    diagnosis_opal_modes: int = 12

    @classmethod
    def diagnosis_params(cls, params: dict) -> dict:
        """Parameters used for the diagnosis' many refits: an opal plate's cells 100 mm, their
        light gathered at 2 × 2 points and its law's azimuthal series cut after
        :attr:`diagnosis_opal_modes` modes (a coarser plate, as the inter-reflection's 100 mm
        patches are: a forward-scattering layer, g 0.95, needs 48 modes, each a layer solve at
        every depth a fit visits)."""
        out = dict(params or {})
        out["cell_size_mm"] = max(float(out.get("cell_size_mm", 50.0)), cls.diagnosis_cell_mm)
        out["cell_subpoints"] = 2
        modes = out.get("opal_modes")
        cut = cls.diagnosis_opal_modes
        out["opal_modes"] = cut if modes is None else min(int(modes), cut)
        return out

    #: seconds per (plate sub-point × lamp emitter point) pair of an opal plate's light (gathered
    #: per emitter point, binned, sent through the layer to every receiver): a fit's forward
    #: evaluation redoes it whenever a lamp's light on the plate changes
    opal_pair_cost_s: float = 1.0e-6

    @classmethod
    def refit_cost_s(cls, ir, params: dict, lighting: str | None = None) -> float:
        """Rough seconds per forward evaluation of the light an opal part of the plate scatters
        (refitting ``diffuse_fraction`` gives a clear or rough plate one): the plate's cells at
        ``cell_size_mm`` times ``cell_subpoints``² sub-points (the default's smallest, 2 × 2,
        when not set) times the lamps' emitter points (a tube's line points times
        :data:`~lbscene.engine.light.forward.PER_POINT_AROUND` around it and its end caps, a
        panel's grid, one for a bulb; mirror images not counted), times :attr:`opal_pair_cost_s`
        (an order of magnitude: aperture masks and mirror images make a pair up to 3× dearer,
        bare tubes over a plate in a black box 5× cheaper);
        ``lighting`` None: the costliest lighting."""
        from lbscene.engine.light.forward import PER_POINT_AROUND

        d = ir.diffuser
        if d is None:
            return 0.0
        q = dict(params or {})
        cell = float(q.get("cell_size_mm") or 50.0)
        k = int(q.get("cell_subpoints") or 2)
        cells = math.ceil(d.size_mm[0] / cell) * math.ceil(d.size_mm[1] / cell)

        def points(lp):
            if lp.kind == "tube":
                return lp.point_sources * PER_POINT_AROUND + (2 if lp.end_caps else 0)
            return len(lp.point_positions_mm()) if lp.kind == "panel" else 1

        def emitters(name):
            return sum(points(lp) for lp, _ in ir.lamps_on(name))

        names = [lighting] if lighting in ir.lighting else list(ir.lighting)
        return cells * k * k * max((emitters(n) for n in names), default=0) * cls.opal_pair_cost_s

    @staticmethod
    def _scattered(ctx, p) -> bool:
        """Does a roughness plate's light go through the BTDF source (not straight paths)?"""
        if not is_rough(ctx.ir) or p.rough_transport == "regular":
            return False
        if p.rough_transport == "scattered":
            return True
        if plate_lobe_footprint_mm(ctx.ir, ctx.lighting) > p.scattered_cell_size_mm:
            return True
        return float(plate_slab(ctx.ir).lobe_deg(1.0, 0.9)) >= SCATTERED_LOBE_DEG

    @staticmethod
    def extra_emitters(ctx, p, lamp, es):
        """The lamp's mirror image in the plate's top face (``plate_reflection: specular``, a
        clear or rough plate, the lamp above it): light the plate reflects goes on as from the
        image, through the plate's extent, times :math:`R(θ)` (:func:`_image_channels`)."""
        from functools import partial

        from lbscene.engine.light.geometry import mirror_directions, mirror_points

        if not specular_plate(ctx.ir, p) or es.meta.get("plate_image"):
            return []
        z = plate_top_mm(ctx.ir)
        if es.points_mm[:, 2].min() <= z:
            return []
        up = np.array([0.0, 0.0, 1.0])
        pts = mirror_points(es.points_mm, [0.0, 0.0, z], up)
        half = None if es.half_step is None else mirror_directions(es.half_step, up)
        return [es.with_(points_mm=pts, half_step=half, direction_map=partial(mirror_directions, normal=up),
                         tag="plate-image",
                         spectral_key=es.spectral_key + ("plate-reflection",),
                         meta={**es.meta, "plate_image": True, "mirror_plane": (np.array([0.0, 0.0, z]), up)})]

    @classmethod
    def path_factors(cls, ctx, p, es, rx):
        ir = ctx.ir
        if ir.diffuser is None:
            return None
        if es.meta.get("plate_image"):
            return _image_channels(ctx, p, es, rx)
        hit = ctx.fraction_hitting(es, rx, diffuser_rect(ir))
        if not hit.any():
            return None
        if cls._scattered(ctx, p):
            # every path through the plate is the directional source's (secondary_sources)
            return [PathChannel(1.0 - hit, None, None)]

        fd = diffuser_fraction(ir, p)

        d = ir.diffuser

        thick = d.thickness_mm if p.thickness_refraction else 0.0

        def angular():
            # the path refracted through the plate's thickness: its incidence and the spread of
            # its ray tube (slab_crossing) times the plate's law at that incidence
            cos_i, spread = slab_crossing(es.points_mm, rx, d.z_mm, thick, d.ior)
            return spread * slab_relative(plate_as_fitted(ctx, p), cos_i, fd)

        rough = float(d.scattering.get("roughness", -1.0)) if is_rough(ir) else -1.0
        # an opal plate's regular part depends on its optical depth, i.e. on the diffuse fraction
        # and the total it is a part of
        opal = [fd, float(p.transmittance_scale)] if d.scattering.get("type") == "lambertian" else [-1.0, -1.0]
        ang = ctx.memo("diffuser_fresnel", (es.points_mm, rx, [d.ior, rough, *opal, d.z_mm, thick]),
                       angular)
        through = hit * (1.0 - fd) * ang
        return [PathChannel(through, "diffuser", diffuser_transmittance_1nm(ctx, p)),
                PathChannel(1.0 - hit, None, None)]

    @staticmethod
    def _cells(d, cell_size_mm, face: int = 0):
        """The plate's cells as quads facing down (counter-clockwise seen from below), in its
        mid-plane (``face`` 0), its top face (+1) or its bottom face (−1)."""
        (cx, cy), (sx, sy) = d.centre_mm, d.size_mm
        nu = max(1, int(np.ceil(sx / cell_size_mm)))
        nv = max(1, int(np.ceil(sy / cell_size_mm)))
        xs = cx - sx / 2 + sx * np.arange(nu + 1) / nu
        ys = cy - sy / 2 + sy * np.arange(nv + 1) / nv
        X0, Y0 = np.meshgrid(xs[:-1], ys[:-1], indexing="ij")
        X1, Y1 = np.meshgrid(xs[1:], ys[1:], indexing="ij")
        z = d.z_mm + face * d.thickness_mm / 2
        return np.stack([np.stack([X0, Y0, np.full_like(X0, z)], -1),
                         np.stack([X0, Y1, np.full_like(X0, z)], -1),
                         np.stack([X1, Y1, np.full_like(X0, z)], -1),
                         np.stack([X1, Y0, np.full_like(X0, z)], -1)], axis=2).reshape(-1, 4, 3)

    @staticmethod
    def _cell_subpoints(ctx, polys, cell_size_mm):
        """Per cell, how many sub-points a side (:data:`ROUGH_SUB_MIN` … :data:`ROUGH_SUB_MAX`):
        spaced at most :data:`ROUGH_SUB_DISTANCE_RATIO` times closer than the cell's distance to
        the nearest lamp surface (the irradiance under a tube varies over that distance)."""
        from lbscene.engine.light.geometry import lamp_surface_distance_mm, quad_centroids

        lamps = [lp for lp, _ in ctx.ir.lamps_on(ctx.lighting)]
        if not lamps:
            return np.full(len(polys), ROUGH_SUB_MIN)
        dist = lamp_surface_distance_mm(lamps, quad_centroids(polys))
        # the cell's nearest point may be half a cell closer than its centre
        near = np.maximum(dist - 0.5 * cell_size_mm, np.min(dist))
        k = np.ceil(ROUGH_SUB_DISTANCE_RATIO * cell_size_mm / np.maximum(near, 1e-6) - 1e-9)
        return np.clip(k, ROUGH_SUB_MIN, ROUGH_SUB_MAX).astype(int)

    @classmethod
    def _incoming(cls, ctx, p, direct, cell_size_mm: float, subpoints: int | None = None):
        """The light arriving on the plate's cells (``cell_size_mm``, on its top face:
        :meth:`_cells`), per emitter point, in
        chunks of cells: yields ``(idx, light)`` for cells ``idx`` (sampled at ``k × k``
        sub-points: ``subpoints``, or by distance, :meth:`_cell_subpoints`), ``light`` mapping each term (its group,
        key and spectrum) to
        ``(term, E, cos_i, phi, E_s)``: ``E`` (n, ·) the irradiance of each emitter point at each
        sub-point times its area weight (their sum over a cell is the cell's mean irradiance),
        ``cos_i`` its incidence cosine and ``phi`` the azimuth of its propagation (away from the
        emitter), ``E_s`` (n, k·k) the weighted irradiance of each sub-point (summed over the
        emitter points).  A chunk holds at most :data:`ROUGH_CHUNK_POINTS` sub-points: the
        (sub-point × emitter point) arrays of a large plate do not all exist at once.  Yields
        ``(idx, light, k)``."""
        from lbscene.engine.light.geometry import quad_subpoints

        polys = cls._cells(ctx.ir.diffuser, cell_size_mm, +1)
        if subpoints is not None:
            ks = np.full(len(polys), int(subpoints))
        else:
            ks = cls._cell_subpoints(ctx, polys, cell_size_mm)
        for k in np.unique(ks):
            k = int(k)
            cells = np.nonzero(ks == k)[0]
            step = max(1, ROUGH_CHUNK_POINTS // (k * k))
            for first in range(0, len(cells), step):
                idx = cells[first:first + step]
                n = len(idx)
                pts, w = quad_subpoints(polys[idx], k)
                top = pts.reshape(-1, 3) + np.array([0.0, 0.0, 1e-3])
                up = np.tile([0.0, 0.0, 1.0], (top.shape[0], 1))
                merged: dict = {}
                for pl in direct.per_point(top, up, exclude=(cls.id,)):
                    if not np.any(pl.geo):
                        continue            # a lamp's image under the plate: none reaches its top
                    E = np.asarray(pl.geo).reshape(n, k * k, -1) * w[:, :, None]
                    Es = E.sum(axis=2)
                    E = E.reshape(n, -1)
                    u = pl.from_dir
                    c = np.clip(u[:, :, 2], 0.0, 1.0).reshape(n, -1)
                    ph = np.arctan2(-u[:, :, 1], -u[:, :, 0]).reshape(n, -1)
                    # one term per group and spectrum: lamps of different groups (each scaled
                    # on its own when their outputs are fitted) or spectra stay apart
                    mk = (pl.term.group, pl.term.key, _spectrum_digest(pl.term.spectrum_1nm))
                    if mk in merged:
                        _, E0, c0, ph0, Es0 = merged[mk]
                        E, c, ph = (np.concatenate([E0, E], 1), np.concatenate([c0, c], 1),
                                    np.concatenate([ph0, ph], 1))
                        Es = Es0 + Es
                    merged[mk] = (pl.term, E, c, ph, Es)
                yield idx, merged, k

    @classmethod
    def _rough_exit(cls, ctx, p, direct):
        """``(polys, terms, grid)``: the rough plate's cells, the lamp terms lighting them and,
        per cell and term, the exit radiance per unit :math:`(1 - f_d)` toward every exit bin
        and grid azimuth (:meth:`~lbscene.engine.light.rough_slab.RoughSlab.exit_radiance_grid`,
        ``(C, n_θo, n_φ, K)``), summed over the cells' incoming light (:meth:`_incoming`)
        once; None when no light arrives.  Kept per forward-model cache under everything that
        changes the lamps' light on the plate (the booth, the lighting, the parameters of every
        effect that changes lamp light but the plate's diffuse fraction and transmittance scale,
        the lamp overrides; not the options: the light on the cells is each lamp's own
        quadrature): a fit varying only the plate's or a meter's parameters, and the
        inter-reflection's model of the same lamps, read it back."""
        ir = ctx.ir
        key = (ir.content_hash,
               *ctx.lamp_light_key({cls.id: ("diffuse_fraction", "transmittance_scale", "opal_modes")}))
        store = ctx.cache.setdefault("_rough_exit", {})
        if key in store:
            return store[key]
        # light arrives on the top face (_incoming) and leaves from the bottom one
        polys = cls._cells(ir.diffuser, p.scattered_cell_size_mm, -1)
        slab = plate_slab(ir)
        terms: dict = {}
        grids: dict = {}
        # the sub-points' light is used once, here: nothing of it is kept in the model's caches
        with ctx.transient():
            for idx, light, _k in cls._incoming(ctx, p, direct, p.scattered_cell_size_mm):
                for tk, (t, E, cos_i, phi, _Es) in light.items():
                    if tk not in terms:
                        terms[tk] = t
                        grids[tk] = np.zeros((polys.shape[0], slab.btdf_table.shape[1], EXIT_PHI_STEPS))
                    grids[tk][idx] = slab.exit_radiance_grid(cos_i, phi, E)
        hit = None
        if terms:
            hit = (polys, list(terms.values()), np.stack([grids[tk] for tk in terms], axis=-1))
        if len(store) >= ROUGH_RADIANCE_MEMO:
            store.pop(next(iter(store)))
        store[key] = hit
        return hit

    @classmethod
    def _rough_source(cls, ctx, p, direct, fd):
        """The rough plate's cells as a :class:`DirectionalSource`: per cell and term

        .. math:: L(ω_o) = (1 - f_d)\\,\\frac{T_\\text{decl}(λ)}{T_0}
                  \\sum_{s} w_s \\sum_{e} f_T(ω_{i,se}, ω_o)\\, E_{se},

        the slab's non-absorbing BTDF :math:`f_T` (:mod:`~lbscene.engine.light.rough_slab`) over the
        irradiance :math:`E_{se}` of each emitter point ``e`` at each sub-point ``s`` (area
        weight :math:`w_s`) of the cell's top face, :math:`ω_i` its direction, leaving from the bottom face
        (the slab shifts a path sideways by less than its thickness).  A cell close
        to a lamp gets more sub-points (:meth:`_cell_subpoints`): under a tube 14 mm above the
        plate, 2 × 2 points on 25 mm cells put the light 2–5 % off between and beyond the tubes
        against Mitsuba 3 (validation scene ``aperture-diffuser``), 6 × 6 within 1 %."""
        ir = ctx.ir
        hit = cls._rough_exit(ctx, p, direct)
        if hit is None:
            return None
        polys, terms, grid = hit
        C = polys.shape[0]
        spec = diffuser_transmittance_1nm(ctx, p) / reference_transmittance(ir)
        descr = [t.derived(spectral_key="diffuser", spectrum_factor=spec, kind="diffuser") for t in terms]

        def radiance(dirs):
            # linear in (1 − f_d)
            cos_o = np.clip(-dirs[..., 2], 0.0, 1.0)                             # (C, M)
            phi_o = np.arctan2(dirs[..., 1], dirs[..., 0])
            return (1.0 - fd) * RoughSlab.exit_radiance_at(grid, cos_o, phi_o)

        return DirectionalSource(polys, np.tile([0.0, 0.0, -1.0], (C, 1)), radiance, descr)

    @classmethod
    def secondary_sources(cls, ctx, p, direct):
        ir = ctx.ir
        if ir.diffuser is None:
            return []
        fd = diffuser_fraction(ir, p)
        out = []
        if cls._scattered(ctx, p) and fd < 1:
            src = cls._rough_source(ctx, p, direct, fd)
            if src is not None:
                out.append(src)
        if fd <= 0:
            return out
        src = cls._opal_source(ctx, p, direct, fd)
        return out + ([src] if src is not None else [])

    @classmethod
    def _opal_histograms(cls, ctx, p, direct, layer):
        """``(top, terms, B)``: an opal plate's cells on its top face, the lamp terms lighting
        them and per cell and term the Fourier coefficients of the light arriving, binned by
        incidence node and azimuth (:meth:`~lbscene.engine.light.opal_layer.OpalLayer.histogram`,
        ``(C, N, MAX_MODES + 1, K)``); None when no light arrives.  They do not depend on the
        layer's depth or asymmetry (only on its faces' index, through the nodes): kept per
        forward-model cache under everything that changes the lamps' light on the plate, as
        :meth:`_rough_exit`, a fit varying the plate's diffuse fraction or transmittance reads
        them back."""
        from lbscene.engine.light.opal_layer import MAX_MODES

        ir = ctx.ir
        # (the diffuser's own cell_size_mm and cell_subpoints are in lamp_light_key)
        key = (ir.content_hash,
               *ctx.lamp_light_key({cls.id: ("diffuse_fraction", "transmittance_scale", "opal_modes")}), "opal")
        store = ctx.cache.setdefault("_opal_light", {})
        if key in store:
            return store[key]
        n_phi = 2 * MAX_MODES + 32
        polys = cls._cells(ir.diffuser, p.cell_size_mm, +1)
        split = max(1, math.ceil(float(p.cell_size_mm) / OPAL_EMIT_CELL_MM - 1e-9))
        terms: dict = {}
        coef: dict = {}
        share: dict = {}
        with ctx.transient():
            for idx, light, k in cls._incoming(ctx, p, direct, p.cell_size_mm, p.cell_subpoints):
                member = _subcell_membership(k, split)                          # (k·k, s·s)
                for tk, (t, E, cos_i, phi, E_s) in light.items():
                    if tk not in terms:
                        terms[tk] = t
                        coef[tk] = np.zeros((polys.shape[0], len(layer.cos_nodes), MAX_MODES + 1), complex)
                        share[tk] = np.full((polys.shape[0], split * split), 1.0)
                    coef[tk][idx] = layer.histogram_modes(layer.histogram(cos_i, phi, E, n_phi), MAX_MODES)
                    Es = E_s @ member                                                 # (n, s·s)
                    tot = Es.sum(axis=1, keepdims=True)
                    share[tk][idx] = np.divide(Es * split * split, tot, out=np.ones_like(Es), where=tot > 0)
        hit = None
        if terms:
            hit = (polys, list(terms.values()), np.stack([coef[tk] for tk in terms], axis=-1),
                   np.stack([share[tk] for tk in terms], axis=-1), split)
        if len(store) >= ROUGH_RADIANCE_MEMO:
            store.pop(next(iter(store)))
        store[key] = hit
        return hit

    @classmethod
    def _opal_source(cls, ctx, p, direct, fd):
        """An opal plate's scattered light as a :class:`DirectionalSource` on its bottom face: per
        cell and term

        .. math:: L(ω_o) = f_d\\,\\frac{T_\\text{decl}(λ)}{T_s(0)}
                  \\sum_{s} w_s \\sum_{e} f(ω_{i,se}, ω_o)\\, E_{se},

        the layer's bidirectional law :math:`f` (:mod:`~lbscene.engine.light.opal_layer`: the
        scattering layer of the plate's declared total and diffuse fraction, every azimuth;
        :func:`~lbscene.engine.light.plates.opal_plate_layer`) over the irradiance
        :math:`E_{se}` of each emitter point ``e`` at each sub-point ``s`` of the cell's top
        face, :math:`T_s(0)` the layer's scattered total at normal incidence (so that the plate
        scatters :math:`f_d T_\\text{decl}` of a beam along its normal).  Light enters on the top
        face and leaves from the bottom one, a thickness apart: light that goes on sideways in
        a forward-scattering layer (a plate lit at a grazing angle from tubes close above)
        leaves it that way.  A cell coarser than :data:`OPAL_EMIT_CELL_MM` sends its light from
        ``s × s`` sub-cells, each with the cell's law times the share of the cell's light its part
        of the top face gathered (:math:`s^2 E_q / \\sum_q E_q`)."""
        from lbscene.engine.light.plates import opal_plate_layer

        ir = ctx.ir
        layer = opal_plate_layer(plate_as_fitted(ctx, p), fd)
        hit = cls._opal_histograms(ctx, p, direct, layer)
        if hit is None:
            return None
        top, terms, B, share, split = hit
        polys = top - np.array([0.0, 0.0, ir.diffuser.thickness_mm])
        C, S = polys.shape[0], split * split
        if split > 1:
            polys = _subcells(polys, split).reshape(C * S, 4, 3)
        G = layer.exit_modes(B, p.opal_modes)                               # (C, M+1, N, K)
        scale = fd / float(layer.scattered_total(np.ones(1))[0])
        T = diffuser_transmittance_1nm(ctx, p)
        descr = [t.derived(spectral_key="diffuser", spectrum_factor=T, kind="diffuser") for t in terms]

        def radiance(dirs):
            cos_o = np.clip(-dirs[..., 2], 0.0, 1.0)                             # (C·S, R)
            phi_o = np.arctan2(dirs[..., 1], dirs[..., 0])
            if split == 1:
                return scale * layer.radiance_at(G, cos_o, phi_o)
            R = cos_o.shape[1]
            L = layer.radiance_at(G, cos_o.reshape(C, S * R), phi_o.reshape(C, S * R))   # (C, S·R, K)
            L = L.reshape(C, S, R, -1) * share[:, :, None, :]
            return scale * L.reshape(C * S, R, -1)

        return DirectionalSource(polys, np.tile([0.0, 0.0, -1.0], (polys.shape[0], 1)), radiance, descr)


def _subcell_membership(k: int, split: int) -> np.ndarray:
    """``(k·k, split·split)``: the share of each of a cell's ``k × k`` sub-points
    (:func:`~lbscene.engine.light.geometry.quad_subpoints`' order) in each of its
    ``split × split`` sub-cells (:func:`_subcells`' order); a sub-point on a sub-cell boundary
    is shared equally."""
    t = (np.arange(k) + 0.5) / k
    edges = np.arange(split + 1) / split
    # per coordinate: (k, split) membership, boundaries split half and half
    m = np.zeros((k, split))
    for i, x in enumerate(t):
        on = np.isclose(x, edges)
        if on[1:-1].any():
            j = int(np.nonzero(on)[0][0])
            m[i, j - 1] = m[i, j] = 0.5
        else:
            m[i, min(int(x * split), split - 1)] = 1.0
    # sub-point (u_i, v_j) is index i·k + j; sub-cell (a, b) is index a·split + b
    return np.einsum("ia,jb->ijab", m, m).reshape(k * k, split * split)


def _subcells(polys: np.ndarray, split: int) -> np.ndarray:
    """``(P, split·split, 4, 3)``: each quad cut into ``split × split`` quads along its bilinear
    parameters (:func:`~lbscene.engine.light.geometry.quad_subpoints`' ``u``, ``v``), each wound
    as the quad is."""
    e = np.arange(split + 1) / split
    p0, p1, p2, p3 = (polys[:, i][:, None, :] for i in range(4))

    def at(u, v):
        u, v = np.asarray(u, float)[None, :, None], np.asarray(v, float)[None, :, None]
        return (1 - u) * (1 - v) * p0 + u * (1 - v) * p1 + u * v * p2 + (1 - u) * v * p3

    a, b = np.meshgrid(np.arange(split), np.arange(split), indexing="ij")
    a, b = a.ravel(), b.ravel()
    corners = [at(e[a], e[b]), at(e[a + 1], e[b]), at(e[a + 1], e[b + 1]), at(e[a], e[b + 1])]
    return np.stack(corners, axis=2)


def _spectrum_digest(spectrum) -> bytes:
    """A term spectrum's identity (lamps of one group merge only where their spectra are equal)."""
    return hashlib.sha1(np.ascontiguousarray(spectrum, float).tobytes()).digest()


def _image_channels(ctx, p, es, rx):
    """Path factors of a lamp's image in the plate's top face: its light leaves through the
    plate's rectangle (a receiver below the plate gets none) and past the lamp's body (light
    reflected straight back meets the tube), times the plate's directional reflectance at the
    path's incidence, :math:`R_\\text{top}(θ) + a^2(λ) R_\\text{int}(θ)` for a rough plate (the
    part reflected inside the plate crosses its absorbing bulk twice) and the clear slab's
    :math:`1 - T(θ)` otherwise."""
    from lbscene.engine.light.geometry import lamp_body

    ir = ctx.ir
    f = ctx.fraction_hitting(es, rx, diffuser_rect(ir))
    if not f.any():
        return [PathChannel(f)]
    lamp = ir.lamp(es.lamp_id)
    body = lamp_body(lamp) if lamp.mount == "booth" else None
    if body is not None:
        f = f * ctx.fraction_past_body(es, rx, body)
    d = rx[:, None, :] - es.points_mm[None, :, :]
    cos_i = np.clip(d[..., 2] / np.maximum(np.linalg.norm(d, axis=-1), 1e-12), 0.0, 1.0)
    if is_rough(ir):
        slab = plate_slab(ir)
        a2 = absorption_squared(ir, diffuser_transmittance_1nm(ctx, p))
        r_top = slab.reflectance(cos_i, 0.0)
        return [PathChannel(f * r_top),
                PathChannel(f * (slab.reflectance(cos_i, 1.0) - r_top), "plate-internal-reflection", a2)]
    # a clear plate's reflectance does not depend on its transmittance (its absorption neglected)
    return [PathChannel(f * plate_reflectance(plate_as_fitted(ctx, p), cos_i, np.ones(1))[..., 0])]
