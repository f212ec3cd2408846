"""
``reflector``: a mirror behind a lamp adds mirror images and blocks what is behind it.

Kind ``geometric``.  The image method: a lamp's emitters mirrored across a mirror's plane,
times its reflectance, shining only through the mirror's extent and past the lamp's own
body.  A plane mirror reflects whatever reaches it, so every lamp of the lighting has an
image in every mirror, its own and the other lamps' (there the mirror's lamp also stands in
the way, before the mirror and after it); every mirror's back stops the lamps' straight
light.  Two tubes with their mirrors side by side on a rear wall (validation scene
``mirror-behind``), or two bulbs under mirrors that tile one plane: a model that mirrored each
lamp in its own mirror only missed up to 17 % of the light far to the side.

The inter-reflection sees the mirrors too (``transport_mirrors``): the walls' and ceiling's
light reflects in them, each a one-sided plane whose images of the surfaces join the radiosity
(:func:`lbscene.engine.light.plate_mirror.face_image_factors`), and their backs hide what lies
behind them.  Mirrors in a grey room that acted on the lamps' light only put the validation
scene ``mirror-room-45`` 1.4 % (A3) and 1.6 % (floor) RMS off Mitsuba 3 (1.3 % high on the
mean), the hypothesis scene ``mirror-sides`` 1.7 % and 1.6 % (1.5 % low on the A3 sheet); with
them in the inter-reflection, 0.3 / 0.6 % and 0.5 / 0.6 %.

Mirror shapes (:func:`mirror_facets`):

``plane``
    one rectangle facing ``normal``, ``distance_mm`` behind the lamp's axis, ``width_mm``
    across it and as long as the lamp.
``prism``
    two plane facets meeting at an apex parallel to the lamp's axis, ``distance_mm`` behind it,
    each ``width_mm / 2`` wide from the apex and folded toward the lamp (a V reflector): with
    apex angle :math:`α` (``apex_angle_deg``), facet :math:`s = ±1` leaves the apex along

    .. math:: e_s = s \\cos β\\, c + \\sin β\\, n, \\qquad β = (180° - α) / 2,

    (:math:`n` the declared ``normal``, toward the lamp; :math:`c` across the lamp's axis) and
    faces :math:`n_s = -s \\sin β\\, c + \\cos β\\, n`.  A lamp at distance :math:`d` on the axis
    has one image per facet, at :math:`d` from the apex and :math:`α` from the lamp seen from
    it: :math:`d(s \\sin 2β\\, c - \\cos 2β\\, n)` (apex 120°: 0.87 d to the side and 0.5 d behind
    the apex), so the tube's own body hides it only in part, where a plane mirror's image
    lies straight behind the tube.  At 180° the two facets are the plane mirror.
``parabolic_trough``
    drawn as the plane mirror (the linter says so, ``LB314``).

First order only: each image is seen through its facet's rectangle and past the lamp's body.
Light reflected twice — facet to facet — is omitted (the light of an image that meets the other
facet is counted as if it went on).  For a point of the
lamp at polar angle :math:`φ` from the prism's axis (seen from the apex, toward facet
:math:`s`), its image in facet :math:`s` lies at :math:`α - φ`, and light from that image
can reach the other facet only if the image is on the wedge's side of that facet's plane:

.. math:: α - φ < 180° - α/2 \\iff α < 120° + \\tfrac{2}{3} φ .

A lamp on the axis (φ = 0) therefore meets no facet twice for :math:`α ≥ 120°`; a tube of
radius :math:`r` at :math:`d` adds points up to :math:`φ = \\arcsin(r/d)`, so a fringe of
double reflections remains up to :math:`α = 120° + \\tfrac23 \\arcsin(r/d)` (a 6 mm tube 35 mm
from the apex: 126.6°).  At 120° a 2D ray trace (``tests/engine/test_prism_mirror.py``)
finds 2.5 % of the rays leaving a 13 mm tube 35 mm from the apex meeting both facets (1.2 % for
a 6 mm tube); below 120° the share grows with the lamp on the axis too (the linter warns,
``LB314``).  The validation scene ``mirror-prism`` (apex 120°) holds the
first-order model to Mitsuba 3, which draws every order.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from lbscene.engine.light.effects.physics import (EmitterSet, LampSelection, PathChannel, PhysicalEffect,
                                                  lamp_selected, lamps_on)
from lbscene.engine.light.effects.registry import register_effect

__all__ = ["ReflectorEffect", "mirror_rect", "mirror_facets", "MIRROR_RING"]

#: lines around a tube's image for the share of it a mirror's edge lets through: the image of a
#: tube 40 mm in front of a 120 mm mirror is cut by the edge for receivers across a whole row of
#: the floor (validation scene mirror-behind): six lines, each in or out, put that row 6 % under
#: Mitsuba 3, 24 lines within 0.5 % (now 24 arc elements' footprints)
MIRROR_RING = 24


def mirror_rect(ir, lamp, refl):
    """The mirror of ``lamp`` (reflector ``refl``) as a :class:`~lbscene.engine.light.geometry.Rectangle`:
    facing ``refl.normal``, ``refl.distance_mm`` behind the lamp's centre, as long as the lamp
    (``width_mm`` for a bulb or a point) along its axis and ``width_mm`` across it."""
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


def mirror_facets(ir, lamp, refl) -> list:
    """The mirror of ``lamp`` (reflector ``refl``) as the plane rectangles it is made of: one for a
    ``plane`` (and a ``parabolic_trough``, drawn as a plane), :func:`mirror_rect`; two for a
    ``prism`` (the module docstring): each ``width_mm / 2`` wide from the apex, as long as the
    plane mirror, facing the lamp."""
    rect = mirror_rect(ir, lamp, refl)
    if refl.type != "prism":
        return [rect]
    from lbscene.engine.light.geometry import Rectangle

    alpha = float(refl.apex_angle_deg if getattr(refl, "apex_angle_deg", None) is not None else 120.0)
    beta = np.radians((180.0 - alpha) / 2.0)
    n, ax = np.asarray(rect.normal, float), np.asarray(rect.u, float)
    c = np.cross(n, ax)                              # across the lamp's axis, in the apex plane
    apex = np.asarray(rect.centre, float)
    fw = refl.width_mm / 2.0
    out = []
    for s in (-1.0, 1.0):
        e = s * np.cos(beta) * c + np.sin(beta) * n
        ns = -s * np.sin(beta) * c + np.cos(beta) * n
        out.append(Rectangle(apex + e * (fw / 2.0), ns, ax, (rect.half[0], fw / 2.0)))
    return out


@register_effect
class ReflectorEffect(PhysicalEffect):
    id = "reflector"
    summary = "Mirrors behind lamps send back-emitted light forward."
    kind = "geometric"
    order = 60
    fit_parameters = {"reflectance_scale": (0.05, 1.5)}
    fit_initial = {"reflectance_scale": 1.0}

    class Params(LampSelection):
        reflectance_scale: float = Field(1.0, gt=0, le=1.5)

    @classmethod
    def applicable(cls, ir, lighting):
        if not any(lp.reflector for lp in lamps_on(ir, lighting)):
            return "no lamp that is on has a reflector:"
        return None

    @staticmethod
    def extra_emitters(ctx, p, lamp, es: EmitterSet) -> list[EmitterSet]:
        """The lamp's image in every mirror of the lighting (its own and the other lamps'):
        a plane mirror reflects whatever light reaches it."""
        from functools import partial

        from lbscene.engine.light.geometry import mirror_directions, mirror_points

        out = []
        for owner, refl, rect, facet in _mirrors(ctx, p):
            n = rect.normal
            pts = mirror_points(es.points_mm, rect.centre, n)
            # the mirror's plane, its normal toward the lamp's side (the image's light comes from
            # that side: aperture_occlusion mirrors what stands there on the image's path)
            c = np.asarray(rect.centre, float)
            toward = np.asarray(n, float) * (1.0 if float(np.mean((es.points_mm - c) @ n)) >= 0 else -1.0)
            R = np.clip(refl.reflectance.array_1nm * p.reflectance_scale, 0.0, 1.0)
            reflect = partial(mirror_directions, normal=n)
            half = None if es.half_step is None else mirror_directions(es.half_step, n)
            tag = f"image:{lamp.reflector}" if owner.id == lamp.id else f"image:{owner.reflector}@{owner.id}"
            if facet is not None:
                tag += f"/facet{facet}"
            out.append(es.with_(points_mm=pts, spectrum_1nm=es.spectrum_1nm * R, half_step=half,
                                spectral_key=es.spectral_key + (f"reflector:{owner.reflector}@{owner.id}",),
                                direction_map=reflect, tag=tag,
                                meta={**es.meta, "mirror": rect, "mirror_owner": owner.id,
                                      "mirror_facet": facet, "mirror_plane": (c, toward)}))
        return out

    @staticmethod
    def path_factors(ctx, p, es, rx):
        mirrors = _mirrors(ctx, p)
        if not mirrors:
            return None
        from lbscene.engine.light.geometry import lamp_body, mirrored_body

        lamp = ctx.ir.lamp(es.lamp_id)
        if es.tag.startswith("image:"):
            # the image shines only through the mirror's extent, and past the lamp itself: light
            # the mirror sends back toward the lamp's own body is stopped there (below a tube
            # under its mirror the image is hidden entirely).  In another lamp's mirror, that
            # lamp's body also stands in the way, after the mirror (as itself) and before it
            # (its mirror image on the image's side of the plane)
            rect = es.meta["mirror"]
            f = _fraction_through_facet(ctx, es, rx, rect)
            body = lamp_body(lamp) if lamp.mount == "booth" else None
            if body is not None:
                f = f * ctx.fraction_past_body(es, rx, body)
            owner = ctx.ir.lamp(es.meta.get("mirror_owner", lamp.id))
            if owner.id != lamp.id and owner.mount == "booth":
                ob = lamp_body(owner)
                if ob is not None:
                    f = f * ctx.fraction_past_body(es, rx, ob) * \
                        ctx.fraction_past_body(es, rx, mirrored_body(ob, *es.meta["mirror_plane"]))
            return [PathChannel(f)]
        # the lamp's straight light: every mirror (its back absorbs) stops what meets it
        f = None
        for _, _, rect, _ in mirrors:
            blocked = _fraction_through_facet(ctx, es, rx, rect)
            if blocked.any():
                f = (1.0 - blocked) if f is None else f * (1.0 - blocked)
        return None if f is None else [PathChannel(f)]


    @staticmethod
    def transport_mirrors(ctx, p) -> list:
        """Every facet of every mirror of the lighting, for the inter-reflection: a mirror
        reflects the walls' and ceiling's light as it does the lamps' (its images of the
        surfaces), and its back hides what lies behind it from the room."""
        from lbscene.engine.light.effects.physics import TransportMirror

        out = []
        for owner, refl, rect, facet in _mirrors(ctx, p):
            R = np.clip(np.asarray(refl.reflectance.array_bands, float) * p.reflectance_scale, 0.0, 1.0)
            name = f"mirror:{owner.reflector}@{owner.id}" + ("" if facet is None else f"/facet{facet}")
            out.append(TransportMirror(name, rect, R))
        return out


def _mirrors(ctx, p) -> list:
    """``(owner lamp, reflector, Rectangle, facet)`` of every facet of every lamp the lighting
    switches on that has a mirror (and that the effect's ``lamps`` selects): ``facet`` None for a
    mirror of one rectangle, else its index."""
    ir = ctx.ir
    out = []
    for lamp in lamps_on(ir, ctx.lighting):
        if lamp.reflector and lamp_selected(p, lamp.id) and lamp.reflector in ir.reflectors:
            refl = ir.reflectors[lamp.reflector]
            rects = mirror_facets(ir, lamp, refl)
            for k, rect in enumerate(rects):
                facet = None if len(rects) == 1 else k
                out.append((lamp, refl, rect, facet))
    return out


def _fraction_through_facet(ctx, es, rx, rect) -> np.ndarray:
    """(M, N) share of each slice's light toward each receiver that passes through a mirror's
    rectangle ``rect`` (a plane mirror or a prism's facet): for an image, the light the mirror
    reflects; for the lamp itself, the light its back stops (the footprints of
    :data:`MIRROR_RING` arc elements at every distance,
    :meth:`~lbscene.engine.light.effects.physics.ForwardContext.fraction_hitting`; a 90 mm strip
    40 mm behind a tube, hypothesis scene ``mirror-sides``, stepped the A3 sheet by 4 % from
    column to column with 24 lines each in or out)."""
    return ctx.fraction_hitting(es, rx, rect, ring=MIRROR_RING)
