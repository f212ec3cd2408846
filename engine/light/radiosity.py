"""
Inter-reflection between the booth's interior surfaces (the ``interreflection`` effect).

Classic radiosity on the IR's surfaces (floor, walls, ceiling, platform, and
the booth's meshes such as a luminaire cavity), cut into patches of about
``patch_size_mm``:

    B_i(λ) = ρ_i(λ) · (E0_i(λ) + Σ_j F_ij B_j(λ))

``E0`` is first-order light (lamps, with every enabled effect, plus diffuse
re-emitters) averaged over each patch (at Gauss points, more of them the closer a lamp:
:data:`NEAR_SUB`, :data:`MID_DIAGONALS`; patches are cut finer near the lamps, the mirrors and
the bodies of the lamps that are off, :func:`refine_near_lamps`); ``F_ij`` the form factor from patch
``i`` (averaged over 2×2 points of it) to polygon ``j`` (exact contour
integral); the system is solved per band (LU factors are cached for the
reflectance set).  A receiver then gets ``Σ_j F(x ← j)·B_j`` — exact
polygon form factors again, clipped to the receiver's hemisphere, so
vertical receivers near walls are right.

The transfer from a source spectrum to indirect light depends only on the
(smooth) surface reflectances, so it is solved at the band centres and
interpolated to 1 nm, where it multiplies the lamps' 1 nm spectra.

Visibility: the box interior is convex, so without meshes nothing is tested
(exact).  Meshes (``role: mesh``, e.g. the BYK's white luminaire cavity
around its lamp) take part when the effect's ``meshes`` is on (default):
both faces of every mesh triangle become patches (Cycles reflects on both
sides too), and the mesh blocks light on every path the solve uses — lamp
point → patch point (first-order light), patch centre → patch centre (form
factors, 0/1) and receiver → 36 low-discrepancy points of each patch, 144
where the receiver sees the patch only partly (gather: the light of a
cavity reaches the booth through its aperture's edges).  The gather tests
points only where it must: a (receiver, patch) pair whose pyramid misses
every mesh's convex hull is seen whole, one whose four corners a single
convex mesh face hides is hidden whole (both exact), and the rest are
tested as one matrix product per receiver (on the BYK's ~500 runtime
receivers × 2678 patches: 43 s → 8 s, the same fractions).  Leaving a white
cavity out overstated the booth's first-order light on walls and ceiling
(the lamp's back light reached them straight through the cavity) and left
out the light the cavity reflects through its aperture: on the BYK grid the
model gave +5 % for inter-reflection where Cycles gives +129 % (the model
with meshes: +129 %, per point within 2 % of a Cycles bake with 0.8 % noise).
Bodies in the way (:func:`transport_bodies`): the lamps' own bodies (a
tube's cylinder, a panel, a bulb; ``lamp_bodies``, default on) and, with the
``aperture_occlusion`` effect, the declared occluders block light on the
same paths as the meshes.  An occluder with a material also reflects: both its
faces are patches (:func:`occluder_patches`), as a mesh's are; one without a
material absorbs.  In the SpectraLight QC the white walls of the two D65 lamp
boxes and the masks' undersides reflect: the model had left them black, and
its inter-reflected light on the A3 grid was 7 % under a Cycles bake that
drew them with their materials.  A lamp's light
on the patches is tested against the other lamps' bodies, not its own.  Two
bare tubes 80 mm under a 45 % ceiling hide from the floor the strip of
ceiling they light most: without their bodies the model was 5 % above Mitsuba
3 over the floor (inter-reflected light 12 % too high); with them, within the
truth's 0.5 % noise.  The direct light at receivers is not tested against
meshes or bodies (the occluders' own effect does that).

Mirrors (the effects' ``transport_mirrors``: the reflector's plane mirrors and prism facets)
block like occluders and reflect: each adds its images of the patches, at its reflectance per
band (:func:`lbscene.engine.light.plate_mirror.face_image_factors`),

.. math:: B_i = ρ_i \\Bigl(E^0_i + \\sum_j \\bigl(F_{ij} + \\sum_m R_m F_{ij'_m}\\bigr) B_j\\Bigr),

and the receivers gather the images the same way.  Box patches are refined near a mirror as
near a lamp (:data:`MIRROR_REFINE_RATIO`).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np

from lbscene.engine.files.disk_cache import array_key, cached_array

from .geometry import (Patches, _breaks, _grid_quad, bodies_block, coplanar_convex_faces, hidden_from_apex, lamp_body,
                       lamp_surface_distance_mm, mesh_patches, mesh_triangles, pairs_near_bodies, plate_pieces,
                       polygon_form_factor,
                       pyramids_clear_of, quad_areas, quad_centroids, quad_r2_points, quad_subpoints,
                       segments_blocked, segments_blocked_by_polygon, visibility_matrix)

__all__ = ["RadiosityTransport", "radiosity_transport", "patch_form_factors", "interior_patches",
           "occluder_patches", "transport_bodies", "transport_occluders",
           "mesh_patch_size_mm", "BOX_ROLES", "WALL_ROLES", "surface_patch_scales"]

#: IR surface roles of the booth's box (and platform): a convex set, no visibility needed
BOX_ROLES = ("floor", "ceiling", "left_wall", "right_wall", "rear_wall", "front_wall", "platform")
#: points on a patch are moved this far (mm) along its normal before a visibility test,
#: so the patch's own face never blocks them
NUDGE_MM = 1e-3
#: receivers see a patch through GATHER_SUB² points of it, GATHER_FINE² where they see it only
#: partly (through an aperture's edge); 8² / 24² changed the BYK grid by 0.1 % RMS
GATHER_SUB = 6
GATHER_FINE = 12
#: first-order light on a patch close to a lamp (its centre within NEAR_DIAGONALS diagonals) is
#: the mean over NEAR_SUB² Gauss points of it …
NEAR_SUB = 3
NEAR_DIAGONALS = 1.5
#: … within MID_DIAGONALS over MID_SUB² Gauss points (beyond, the patch's centre).  The light of a
#: lamp falls off steeply across a patch beside it, and the centre misses that: a tube 30 mm
#: under a ceiling lights a 95 mm patch 1.5 to 8 diagonals away 11 % to 0.4 % above its centre's
#: value (2 × 2 Gauss points: 0.5 % to 0.01 %).  In the SpectraLight's white luminaire cavity the
#: centres left the ceiling's first-order light low and the TL84 light at the sample 0.4 % low
#: (with the ceiling cut at the dark UV tube, :func:`refine_near_lamps`: the sample's light on
#: 100 mm patches within 0.04 % of 50 mm ones, and 0.1 % from a Cycles bake at final quality)
MID_DIAGONALS = 8.0
MID_SUB = 2
#: box patches are split while their diagonal exceeds this times their distance to a lit lamp …
REFINE_RATIO = 1.5
#: box patches are split while their diagonal exceeds this times their distance to a mirror, down
#: to REFINE_MIN_MM: the mirror's shadow on the wall behind it and the view it hides from the
#: surfaces around it.  Two tubes with a 90 mm mirror strip 40 mm behind each, 120 mm from 45 %
#: side walls (hypothesis scene mirror-sides; the mirrors black, for the blocking alone): the
#: booth's 100 mm patches left the inter-reflected light 2.0 % under Mitsuba 3, refined at 1.5
#: (the lamps' rule) 0.8 %, at 0.5 0.35 %
MIRROR_REFINE_RATIO = 0.5
#: … down to this size (mm) …
REFINE_MIN_MM = 15.0
#: at the body of a lamp that is off, patches are split by the lamps' rule only while their
#: diagonal also exceeds this times their distance to a lit lamp (where the lit lamps' light
#: changes across the patch): the SpectraLight's dark UV tube 65 mm from a TL84 tube is cut, the
#: tubes and bulbs far from the D65 lamps in their boxes are not (cut there too, the D65 solve
#: took 1.8 times as long for 0.04 % at the sample)
DARK_LIT_RATIO = 0.5
#: … or, next to a tube or a bulb (bodies that light the surface behind them and hide it), down
#: to this size: a patch must be narrower than the gap between the body and the surface for the
#: strip the body lights most, which is the strip it hides, to come out as a strip.  Four tubes
#: with a 7 mm gap under an 85 % ceiling (validation scene ceiling-85): the 25 mm patches the
#: old floor left there put the model's A3 grid 3 % above Mitsuba 3 (inter-reflected light 6 %
#: high), 6 mm ones within the truth's noise; panels emit away from the surface behind them and
#: keep REFINE_MIN_MM
REFINE_MIN_BODY_MM = 5.0
#: points (tube slices, panel cells) per lamp for the light reaching the patches; the forward
#: model's near-field rule refines them for patches within a few spacings of the lamp (25 instead
#: of the shipped booths' 100 moved their grids by at most 0.02 %, every lighting)
TRANSPORT_LAMP_POINTS = 25
#: segments sampled between two patches whose mutual view a body (lamp, occluder) may cross
FF_BODY_PAIRS = 8
#: a mesh is cut into at least this many patches across its smallest extent, unless the
#: effect's ``mesh_patch_size_mm`` says otherwise (the BYK's white cavity, 120 mm deep around
#: two tube legs: 3 across put the grid 0.7 % above Mitsuba 3, 5 across 0.2 % under it)
MESH_PATCHES_ACROSS = 3


#: an occluder is cut into at least this many patches across its smaller side (3 instead
#: moved the SpectraLight's grid by 0.02 %, the white cavity validation scene by 0.1 %)
OCCLUDER_PATCHES_ACROSS = 2
#: … and sampled at this many points squared for their first-order light when near a lamp
#: (3 × 3 moved the SpectraLight's grid by 0.01 %; its lamp boxes' walls are all near their lamp)
OCCLUDER_NEAR_SUB = 2
#: occluder patches may be this many times longer along an occluder's longer side than across
#: its shorter one (a lamp box's 560 × 70 mm wall: 2 × 6 patches of 35 × 93 mm a face)
OCCLUDER_PATCH_ASPECT = 3.0


def mesh_patch_size_mm(ir, patch_size_mm: float, declared_mm: float | None = None) -> float:
    """Patch size for the booth's meshes: at most 1/:data:`MESH_PATCHES_ACROSS` of the smallest extent
    of any mesh, so a luminaire cavity is cut into several patches across however coarse the
    booth's patches (the diagnosis solves on 100 mm patches); ``declared_mm`` (the effect's
    ``mesh_patch_size_mm``) when the booth sets it."""
    if declared_mm is not None:
        return float(declared_mm)
    ext = [np.ptp(s.vertex_array, axis=0) for s in ir.surfaces if s.role == "mesh"]
    if not ext:
        return patch_size_mm
    smallest = min(float(np.min(e[e > 1e-6])) if np.any(e > 1e-6) else patch_size_mm for e in ext)
    return min(patch_size_mm, smallest / MESH_PATCHES_ACROSS)


def refine_near_lamps(ir, patches: Patches, ratio: float | None = None,
                      min_size_mm: float | None = None, lamps=None,
                      min_body_mm: float | None = None, mirrors=(), dark=()) -> Patches:
    """Split patches 2 × 2 (repeatedly) while their diagonal exceeds ``ratio`` times the
    distance from their centre to the nearest lamp surface (of ``lamps``, default every
    lamp), mirror (``mirrors``: rectangles) or body of a lamp that is off (``dark``, where the
    patch is also wider than :data:`DARK_LIT_RATIO` times its distance to a lit lamp), down to
    ``min_size_mm`` (``min_body_mm`` where a tube or a bulb of ``lamps`` is the nearest:
    :data:`REFINE_MIN_BODY_MM`).

    A lamp that is off lights nothing, but its body still hides the strip of surface behind it
    from the room.  Where the others' light on that strip is far from uniform, a coarse patch
    across the strip is wrong: the room sees it as if its light were spread evenly over it.  In
    the SpectraLight QC the UV tube (off at TL84) lies 65 mm from a TL84 tube, 17 mm under the
    white cavity's ceiling; the patch across its shadow was lit bright on the TL84 side and dim
    on the side the body hides, and the TL84 light at the sample came out 0.3 % low on 100 mm
    patches (refined at the dark bodies too: within 0.04 % of 50 mm patches).

    Radiosity takes each patch as uniform.  Next to a lamp its first-order light is
    not: a tube 17 mm under a ceiling lights a strip a few centimetres wide, and that
    strip is exactly what the tube's body hides from the booth below.  On coarse patches
    the hidden strip is averaged with its dim surroundings and the shadow comes out too
    weak (SpectraLight TL84: the A3 grid moved 3 % between 25 and 75 mm uniform patches);
    refined only there, the solution holds with coarse patches elsewhere: 100 mm patches
    refined at the defaults (1.5, 15 mm) are within 0.5 % RMS of 50 mm patches refined at
    (1.0, 10 mm) for every lighting of the SpectraLight QC, with a third of the patches.
    Closer still (a tube's surface 7 mm from a white ceiling), the bright strip is narrower
    than 15 mm: next to tubes and bulbs the ratio rule goes on to :data:`REFINE_MIN_BODY_MM`.
    """
    ratio = REFINE_RATIO if ratio is None else ratio
    min_size_mm = REFINE_MIN_MM if min_size_mm is None else min_size_mm
    min_body_mm = min(REFINE_MIN_BODY_MM if min_body_mm is None else min_body_mm, min_size_mm)
    lamps = list(ir.lamps if lamps is None else lamps)
    bodies = [lp for lp in lamps if lp.kind in ("tube", "bulb")]
    polys, normals, mats, surfs = [patches.polys], [patches.normals], [patches.material], [patches.surface]
    done_p, done_n, done_m, done_s = [], [], [], []
    for _ in range(8):
        P, N, M, S = polys[-1], normals[-1], mats[-1], surfs[-1]
        if not len(P):
            break
        c = quad_centroids(P)
        diag = np.maximum(np.linalg.norm(P[:, 2] - P[:, 0], axis=1), np.linalg.norm(P[:, 3] - P[:, 1], axis=1))
        dist = lamp_surface_distance_mm(lamps, c)
        d_mirror = _rect_distance_mm(mirrors, c)
        near = diag > ratio * dist
        d_dark = lamp_surface_distance_mm(dark, c) if dark else None
        # the floor: finer where a tube or a bulb is the nearest lamp (mirrors: min_size_mm)
        floor = np.where(lamp_surface_distance_mm(bodies, c) <= dist, min_body_mm, min_size_mm) if bodies \
            else min_size_mm
        # a split's quarters keep at least the floor's width (a square's diagonal: √2 × it)
        splittable = diag > min_size_mm * np.sqrt(2) * 2
        split = (near & (diag > floor * np.sqrt(2) * 2)) | ((diag > MIRROR_REFINE_RATIO * d_mirror) & splittable)
        if d_dark is not None:
            split |= (diag > ratio * d_dark) & (diag > DARK_LIT_RATIO * dist) & splittable
        keep = ~split
        done_p.append(P[keep]); done_n.append(N[keep]); done_m.append(M[keep]); done_s.append(S[keep])
        if not split.any():
            break
        kids = np.concatenate([_grid_quad(*q, 2, 2) for q in P[split]]) if split.sum() else P[:0]
        polys.append(kids)
        normals.append(np.repeat(N[split], 4, axis=0))
        mats.append(np.repeat(M[split], 4))
        surfs.append(np.repeat(S[split], 4))
    else:
        P = polys[-1]
        done_p.append(P); done_n.append(normals[-1]); done_m.append(mats[-1]); done_s.append(surfs[-1])
    Pall = np.concatenate(done_p)
    return Patches(Pall, np.concatenate(done_n), quad_areas(Pall), np.concatenate(done_m),
                   np.concatenate(done_s))


def _concat_patches(parts) -> Patches:
    parts = [x for x in parts if len(x)]
    return Patches(np.concatenate([x.polys for x in parts]), np.concatenate([x.normals for x in parts]),
                   np.concatenate([x.areas_mm2 for x in parts]),
                   np.concatenate([x.material for x in parts]),
                   np.concatenate([x.surface for x in parts]))


def _both_faces(m: Patches) -> Patches:
    """``m`` and its back faces (reversed winding, opposite normals, surface ids ``…:back``)."""
    back = Patches(m.polys[:, [0, 3, 2, 1]], -m.normals, m.areas_mm2, m.material,
                   np.array([f"{x}:back" for x in m.surface], object))
    return _concat_patches((m, back))


def occluder_patches(occluders, patch_size_mm: float) -> Patches:
    """Both faces of every occluder that has a material, as patches.

    ``occluders``: ``(IROccluder, Rectangle)`` pairs (:func:`transport_occluders`).  An
    aperture plate is the frame around its opening (four rectangles).  Each occluder is cut
    into patches of at most ``patch_size_mm`` and at least :data:`OCCLUDER_PATCHES_ACROSS`
    across its smaller side (a lamp box's 70 mm wall: 35 mm patches), up to
    :data:`OCCLUDER_PATCH_ASPECT` times longer along the other.  An occluder
    without a material absorbs: it blocks light (:func:`transport_bodies`) and is no patch.
    """
    polys, mats, surfs = [], [], []
    for o, r in occluders:
        if o.material is None:
            continue
        c, n, u, v = (np.asarray(x, float) for x in (r.centre, r.normal, r.u, r.v))
        hu, hv = r.half
        across = min(patch_size_mm, 2 * min(hu, hv) / OCCLUDER_PATCHES_ACROSS)
        along = min(patch_size_mm, OCCLUDER_PATCH_ASPECT * across)
        size_u, size_v = (along, across) if hu >= hv else (across, along)
        pieces = plate_pieces(r.half, r.hole_half)
        # cut along the planes of the occluders that stand on this one (a lamp box's wall on
        # its mask): no patch straddles them
        others = [x for x in occluders if x[0].id != o.id]
        cu, cv = [], []
        for pc, pn in _standing_on(others, _rect_corners(r), n):
            if abs(pn @ v) < 1e-6 and abs(pn @ u) > 1e-6:
                cu.append(float((pc - c) @ pn) / float(u @ pn))
            elif abs(pn @ u) < 1e-6 and abs(pn @ v) > 1e-6:
                cv.append(float((pc - c) @ pn) / float(v @ pn))
        for u0, u1, v0, v1 in pieces:
            # corners counter-clockwise seen from the normal's side (the face's normal is n)
            q = [c + a * u + b * v for a, b in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))]
            nu = _breaks(u1 - u0, size_u, [(x - u0) / (u1 - u0) for x in cu])
            nv = _breaks(v1 - v0, size_v, [(x - v0) / (v1 - v0) for x in cv])
            g = _grid_quad(*q, nu, nv)
            polys.append(g)
            mats += [o.material] * len(g)
            surfs += [f"occluder:{o.id}"] * len(g)
    if not polys:
        z = np.zeros((0, 4, 3))
        return Patches(z, np.zeros((0, 3)), np.zeros(0), np.array([], object), np.array([], object))
    P = np.concatenate(polys)
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    return _both_faces(Patches(P, nrm, quad_areas(P), np.array(mats, object), np.array(surfs, object)))


#: an occluder whose rectangle comes this close (mm) to a surface (a box surface or another
#: occluder) stands on it: the surface's patches are cut along the occluder's plane
TOUCH_MM = 10.0


def _rect_corners(r) -> np.ndarray:
    c, u, v = (np.asarray(x, float) for x in (r.centre, r.u, r.v))
    return np.array([c + a * r.half[0] * u + b * r.half[1] * v for a in (-1, 1) for b in (-1, 1)])


def _standing_on(occluders, corners: np.ndarray, normal: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Planes ``(point, normal)`` of the occluders that stand on the flat surface with
    ``corners`` (a corner of the occluder within :data:`TOUCH_MM` of the surface's plane and
    of its extent; occluders parallel to it do not cut it)."""
    out = []
    lo, hi = corners.min(axis=0) - TOUCH_MM, corners.max(axis=0) + TOUCH_MM
    for _, r in occluders:
        n = np.asarray(r.normal, float)
        if abs(float(n @ normal)) > 1 - 1e-6:
            continue
        oc = _rect_corners(r)
        near = np.abs((oc - corners[0]) @ normal) <= TOUCH_MM
        inside = np.all((oc >= lo) & (oc <= hi), axis=1)
        if np.any(near & inside):
            out.append((np.asarray(r.centre, float), n))
    return out


def _box_cut_planes(ir, occluders) -> list[tuple[np.ndarray, np.ndarray]]:
    """Planes of the occluders that stand on one of the box's surfaces."""
    planes = []
    for s in ir.surfaces:
        if s.role not in BOX_ROLES:
            continue
        v = s.vertex_array
        n = np.cross(v[1] - v[0], v[2] - v[0])
        planes += _standing_on(occluders, v, n / np.linalg.norm(n))
    return planes


#: material id of the diffuser plate's patches (its reflectance comes from the plate model,
#: :func:`lbscene.engine.light.plates.plate_hemispherical_reflectance`)
PLATE_MATERIAL = "diffuser-plate"


def plate_patches(ir, patch_size_mm: float) -> Patches:
    """Both faces of the diffuser plate as patches: the top face (normal +z, at the plate's
    mid-plane + half its thickness, facing the luminaire above) and the bottom face (normal
    −z, facing the booth).  They reflect with the plate's hemispherical reflectance; light
    crossing the plate between the two sides is the transport's plate transmittance
    (:class:`RadiosityTransport`)."""
    d = ir.diffuser
    (cx, cy), (sx, sy) = d.centre_mm, d.size_mm
    nu = max(1, int(np.ceil(sx / patch_size_mm)))
    nv = max(1, int(np.ceil(sy / patch_size_mm)))
    out = []
    for sign, name in ((1.0, "plate:top"), (-1.0, "plate:bottom")):
        z = d.z_mm + sign * d.thickness_mm / 2
        a, b = np.array([cx - sx / 2, cy - sy / 2, z]), np.array([cx + sx / 2, cy - sy / 2, z])
        c, e = np.array([cx + sx / 2, cy + sy / 2, z]), np.array([cx - sx / 2, cy + sy / 2, z])
        # counter-clockwise seen from the side the face looks at
        q = _grid_quad(a, b, c, e, nu, nv) if sign > 0 else _grid_quad(a, e, c, b, nv, nu)
        n = np.tile([0.0, 0.0, sign], (len(q), 1))
        out.append(Patches(q, n, quad_areas(q), np.array([PLATE_MATERIAL] * len(q), object),
                           np.array([name] * len(q), object)))
    return _concat_patches(out)


def _rect_distance_mm(rects, points: np.ndarray) -> np.ndarray:
    """Distance (mm) from each point to the nearest of ``rects`` (inf without any)."""
    out = np.full(len(points), np.inf)
    for r in rects:
        q = points - np.asarray(r.centre, float)
        u, v = np.asarray(r.u, float), np.asarray(r.v, float)
        x = np.clip(q @ u, -r.half[0], r.half[0])
        y = np.clip(q @ v, -r.half[1], r.half[1])
        out = np.minimum(out, np.linalg.norm(q - np.outer(x, u) - np.outer(y, v), axis=1))
    return out


def interior_patches(ir, patch_size_mm: float, meshes: bool = True, lamps=None, occluders=(),
                     mesh_patch_mm: float | None = None, plate: bool = False, mirrors=(),
                     dark=()) -> Patches:
    """Patches of the box surfaces, refined near ``lamps`` (default: every lamp; the
    transport passes the lamps a lighting turns on), near the bodies of the lamps ``dark`` (off,
    their bodies in the way) and near ``mirrors`` (rectangles: a
    mirror's shadow and the view it hides are as sharp as a lamp's), plus both faces of every
    mesh triangle when ``meshes`` (at :func:`mesh_patch_size_mm`) and of every occluder of ``occluders``
    that has a material (:func:`occluder_patches`), and both faces of the diffuser plate when
    ``plate`` (:func:`plate_patches`)."""
    # walls are cut at a diffuser plate's height, and surfaces along the plane of an occluder
    # that stands on them: no patch straddles a plate or a panel
    z_cuts = (ir.diffuser.z_mm,) if ir.diffuser is not None else ()
    parts = [refine_near_lamps(ir, mesh_patches(ir, patch_size_mm, roles=BOX_ROLES, z_cuts_mm=z_cuts,
                                                cut_planes=_box_cut_planes(ir, occluders)),
                               lamps=lamps, mirrors=mirrors, dark=dark)]
    m = None
    if meshes:
        m = mesh_patches(ir, mesh_patch_size_mm(ir, patch_size_mm, mesh_patch_mm), roles=("mesh",))
        m = _both_faces(m) if len(m) else None
    o = occluder_patches(occluders, patch_size_mm)
    o = o if len(o) else None
    if m is not None and o is not None:
        m, o = _coplanar_cover(m, o, occluders, mesh_triangles(ir))
    parts += [x for x in (m, o) if x is not None and len(x)]
    if plate and ir.diffuser is not None:
        parts.append(plate_patches(ir, patch_size_mm))
    return parts[0] if len(parts) == 1 else _concat_patches(parts)


#: a mesh face and an occluder closer than this (mm) are one plate
COPLANAR_MM = 0.5


def _keep(p: Patches, keep: np.ndarray) -> Patches:
    return Patches(p.polys[keep], p.normals[keep], p.areas_mm2[keep], p.material[keep], p.surface[keep])


def _coplanar_cover(m: Patches, o: Patches, occluders, tris: np.ndarray) -> tuple[Patches, Patches]:
    """Where an occluder lies on a mesh face (an aperture plate that is the cavity's bottom),
    the occluder is seen from its front (the side its normal points to) and the mesh from the
    other: mesh patches facing the occluder's way on its rectangle are covered by it, and the
    occluder's back-face patches on a mesh face are covered by the mesh (the Cycles bake draws
    the occluder a hair in front of the mesh, :data:`~lbscene.engine.light.geometry.OCCLUDER_OFFSET_MM`).
    Without this both would reflect the same light."""
    keep_m = np.ones(len(m), bool)
    cm = m.centres
    for _, r in occluders:
        c, n, u, v = (np.asarray(x, float) for x in (r.centre, r.normal, r.u, r.v))
        d = cm - c
        a, b = d @ u, d @ v
        on = (np.abs(d @ n) <= COPLANAR_MM) & (m.normals @ n > 1 - 1e-6) & \
            (np.abs(a) <= r.half[0]) & (np.abs(b) <= r.half[1])
        if r.hole_half is not None:
            on &= ~((np.abs(a) < r.hole_half[0]) & (np.abs(b) < r.hole_half[1]))
        keep_m &= ~on
    keep_o = np.ones(len(o), bool)
    back = np.array([str(x).endswith(":back") for x in o.surface], bool)
    if back.any() and len(tris):
        co = o.centres
        e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
        tn = np.cross(e1, e2)
        tn /= np.maximum(np.linalg.norm(tn, axis=1), 1e-12)[:, None]
        for i in np.nonzero(back)[0]:
            w = co[i] - tris[:, 0]
            plane = (np.abs(np.einsum("ij,ij->i", w, tn)) <= COPLANAR_MM) & \
                (np.abs(tn @ o.normals[i]) > 1 - 1e-6)
            if not plane.any():
                continue
            # barycentric coordinates of the patch centre in the coplanar triangles
            E1, E2, W = e1[plane], e2[plane], w[plane]
            d11, d12, d22 = (E1 * E1).sum(1), (E1 * E2).sum(1), (E2 * E2).sum(1)
            w1, w2 = (W * E1).sum(1), (W * E2).sum(1)
            den = d11 * d22 - d12 * d12
            s_ = (d22 * w1 - d12 * w2) / den
            t_ = (d11 * w2 - d12 * w1) / den
            if np.any((s_ >= -1e-9) & (t_ >= -1e-9) & (s_ + t_ <= 1 + 1e-9)):
                keep_o[i] = False
    return _keep(m, keep_m), _keep(o, keep_o)


def patch_form_factors(patches: Patches, sub: int = 2, near_factor: float = 3.0,
                       blockers: np.ndarray | None = None) -> np.ndarray:
    """(P, P) form factors F[i, j] from patch i to polygon j.

    Exact point-to-polygon form factors from the centre of patch i; pairs
    closer than ``near_factor`` patch diagonals (where the centre is not
    representative of the patch) are averaged over ``sub × sub`` points.
    ``blockers`` (T, 3, 3): triangles that hide patch j from patch i when
    they cross the segment between the patch centres (symmetric, 0/1).
    """
    from .geometry import polygon_form_factor_pairs

    c = patches.centres
    F = polygon_form_factor(c, patches.normals, patches.polys, patches.normals)
    diag = np.linalg.norm(patches.polys[:, 2] - patches.polys[:, 0], axis=1)
    dist = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2)
    near = dist < near_factor * np.maximum(diag[:, None], diag[None, :])
    np.fill_diagonal(near, False)
    ii, jj = np.nonzero(near)
    if ii.size:
        pts, w = quad_subpoints(patches.polys, sub)                   # (P, s, 3)
        k = sub * sub
        f = polygon_form_factor_pairs(pts[ii].reshape(-1, 3), np.repeat(patches.normals[ii], k, axis=0),
                                      np.repeat(patches.polys[jj], k, axis=0))
        F[ii, jj] = (f.reshape(-1, k) * w[ii]).sum(axis=1)
    np.fill_diagonal(F, 0.0)
    if blockers is not None and len(blockers):
        ii, jj = np.nonzero(np.triu((F > 0) | (F.T > 0), 1))
        a = c[ii] + NUDGE_MM * patches.normals[ii]
        b = c[jj] + NUDGE_MM * patches.normals[jj]
        hidden = segments_blocked(a, b, blockers)
        F[ii[hidden], jj[hidden]] = 0.0
        F[jj[hidden], ii[hidden]] = 0.0
    return F


def transport_bodies(ctx, p) -> list[tuple[str, object]]:
    """Bodies that block light between surfaces, as ``(owner, body)``.

    * ``lamp:<id>``: every lamp's body when ``lamp_bodies`` is on (a lamp that
      is off still casts its shadow): a tube's :class:`~lbscene.engine.light.geometry.Capsule`,
      a panel's rectangle, a bulb's :class:`~lbscene.engine.light.geometry.Ball`;
    * ``occluder:<id>``: every declared occluder when the ``aperture_occlusion`` effect is on
      (an aperture plate with its declared opening): real plates block
      inter-reflected light as well as the lamps' (an occluder declared for some lamps only
      still blocks all light between surfaces).

    Bodies block; occluders with a material also reflect, as patches of their own
    (:func:`occluder_patches`).  Platform-mounted ones are taken where the IR puts them (the
    platform at rotation 0), as platform-mounted meshes are: a luminaire that turns with the
    platform keeps its lamps, cavity and aperture together (the BYK's two tube legs absorb
    in its white cavity: leaving them out put the model's light on the grid 34 % above a
    Cycles bake, which draws them).
    """
    from .geometry import lamp_body

    ir = ctx.ir
    out = []
    if getattr(p, "lamp_bodies", True):
        for lp in ir.lamps:
            body = lamp_body(lp)
            if body is not None:
                out.append((f"lamp:{lp.id}", body))
    for o, rect in transport_occluders(ctx):
        out.append((f"occluder:{o.id}", rect))
    return out


def transport_occluders(ctx) -> list[tuple[object, object]]:
    """The occluders the transport sees, as ``(IROccluder, Rectangle)`` with
    their declared openings, when the ``aperture_occlusion`` effect is on (else none).

    A fitted ``opening_scale`` acts on the lamps' light (the effect's own path factors), not
    on the far weaker inter-reflected light, so a fit that moves it does not redo the
    transport's patches and visibility at every step."""
    if "aperture_occlusion" not in ctx.effects:
        return []
    from .plates import occluder_rects

    occ = ctx.params("aperture_occlusion").model_copy(update={"opening_scale": 1.0, "opening_scale_u": 1.0,
                                                                 "opening_scale_v": 1.0})
    return list(occluder_rects(ctx.ir, occ))


def transport_mirrors(model) -> list:
    """The plane mirrors the transport sees (:class:`~lbscene.engine.light.effects.physics.TransportMirror`),
    from the ``transport_mirrors`` hooks of ``model``'s enabled effects (the reflector's facets)."""
    out = []
    for _, p, fn in model._hooks("transport_mirrors"):
        out.extend(fn(model.ctx, p) or [])
    return out


def _mirror_groups(mirrors) -> list[tuple[np.ndarray, list]]:
    """``[(reflectance_bands, [face, …])]``: the mirrors grouped by reflectance (one image
    matrix per group)."""
    groups: dict[bytes, tuple[np.ndarray, list]] = {}
    for m in mirrors:
        R = np.round(np.asarray(m.reflectance_bands, float), 9)
        groups.setdefault(R.tobytes(), (R, []))[1].append(m.face)
    return list(groups.values())


def _body_signature(bodies) -> tuple:
    """Hashable content of ``(owner, body)`` pairs (cache keys)."""
    sig = []
    for owner, b in bodies:
        vals = [np.ravel(np.asarray(v, float)).tolist() if v is not None else None
                for v in vars(b).values()]
        sig.append((owner, type(b).__name__, repr(vals)))
    return tuple(sig)


def _hidden_points(P_rx, pts_all, rows, cols, first, count, tris) -> np.ndarray:
    """(pairs, count) flags: is point ``first … first+count`` of patch ``cols`` hidden by the mesh
    triangles ``tris`` from receiver ``rows``?  Pairs come sorted by receiver: each receiver
    tests its patches' points at once."""
    out = np.empty((len(rows), count), bool)
    pts = pts_all[:, first:first + count]
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]]) if rows.size else rows
    for s, e in zip(starts, np.r_[starts[1:], rows.size].astype(int)):
        c = cols[s:e]
        out[s:e] = hidden_from_apex(P_rx[rows[s]], pts[c].reshape(-1, 3), tris).reshape(len(c), count)
    return out


def _half_diagonals(polys: np.ndarray) -> np.ndarray:
    c = quad_centroids(polys)
    return np.linalg.norm(polys - c[:, None, :], axis=2).max(axis=1)


#: IR surface roles a ``surface_reflectance`` effect's ``walls_scale`` acts on
WALL_ROLES = ("left_wall", "right_wall", "rear_wall", "front_wall")


def surface_patch_scales(ir, p, surfaces) -> np.ndarray:
    """Reflectance multiplier per patch (``surfaces``: the patches' surface ids) from the
    ``surface_reflectance`` effect's parameters ``p``: ``ceiling_scale``, ``walls_scale`` (the
    roles of :data:`WALL_ROLES`), ``floor_scale``; 1 for meshes, occluders and the platform."""
    role = {s.id: s.role for s in ir.surfaces}
    by_role = {"ceiling": p.ceiling_scale, "floor": p.floor_scale, **{w: p.walls_scale for w in WALL_ROLES}}
    return np.array([by_role.get(role.get(str(s).split(":")[0]), 1.0) for s in surfaces], float)


def radiosity_transport(ctx, p, model) -> "RadiosityTransport":
    return RadiosityTransport(ctx, p, model)


class RadiosityTransport:
    """Radiosity solution for one forward model (one parameter set)."""

    def __init__(self, ctx, p, model):
        self.ctx, self.p, self.model = ctx, p, model
        ir = ctx.ir
        # patches are refined near the lamps this lighting turns on, and near the bodies of those
        # it leaves off (they light nothing, but hide the surface behind them: refine_near_lamps)
        lit = tuple(sorted({lp.id for lp, _ in ir.lamps_on(model.lighting)}))
        bodies_on = bool(getattr(p, "lamp_bodies", True))
        occluders = transport_occluders(ctx)
        # occluders cut the box's patches where they stand on it; with a material, they
        # reflect (both faces are patches), as the booth declares
        occ_key = _body_signature([(f"{o.id}:{o.material}", r) for o, r in occluders])
        # the diffuser plate reflects from both faces: a clear or rough plate specularly (its
        # images in the inter-reflection, :mod:`.plate_mirror`), an opal one diffusely (its
        # faces are patches)
        has_plate = "diffuser" in ctx.effects and ir.diffuser is not None
        from .plates import specular_plate

        self._mirror = has_plate and specular_plate(ir, ctx.params("diffuser"))
        plate = has_plate and not self._mirror
        # the plate as the diffuser effect's parameters make it (a fitted diffuse fraction or
        # transmittance moves an opal plate's layer: its reflectance, its transfer between faces)
        from .plates import plate_as_fitted

        self.plate_ir = plate_as_fitted(ctx, ctx.params("diffuser")) if has_plate else ir
        # the plate as fitted shapes the band form factors beyond its transmittance (its layer's
        # transfer between the faces, its exit shape): a low-rank update (:meth:`_lu`) starts only
        # from a factorisation of the same plate (a fitted diffuse fraction moves the plate's
        # reflectance alone, and an update from another plate's factors was 1.7 to 5.6 % off)
        self._plate_state = (json.dumps(self.plate_ir.diffuser.model_dump(mode="json"), sort_keys=True, default=str)
                             if has_plate else None)
        # the lamps' mirrors block the surfaces' mutual views and reflect their light (images)
        self.mirrors = transport_mirrors(self._transport_model())
        mirror_key = _body_signature([(m.owner, m.face) for m in self.mirrors])
        key = ("patches", p.patch_size_mm, p.mesh_patch_size_mm, p.meshes, lit, bodies_on, occ_key, plate,
               mirror_key)
        if key not in ctx.cache:
            lamps = [lp for lp in ir.lamps if lp.id in lit]
            dark = [lp for lp in ir.lamps if lp.id not in lit and lamp_body(lp) is not None] if bodies_on else []
            patches = interior_patches(ir, p.patch_size_mm, p.meshes, lamps=lamps, occluders=occluders,
                                       mesh_patch_mm=p.mesh_patch_size_mm, plate=plate,
                                       mirrors=[m.face for m in self.mirrors], dark=dark)
            from lbscene.engine.files.limits import check_work

            check_work("patches", len(patches.polys),
                       what=f"inter-reflection patches at patch_size_mm {p.patch_size_mm:g}")
            blockers = mesh_triangles(ir) if p.meshes else np.zeros((0, 3, 3))
            ctx.cache[key] = (patches, blockers)
        self.patches, self.blockers = ctx.cache[key]
        self._patch_key = key
        # lamp bodies and occluders (analytic shapes) block patch-to-patch exchange too, and so
        # do the lamps' mirrors
        self.bodies = transport_bodies(ctx, p) + [(m.owner, m.face) for m in self.mirrors]
        self._mirror_groups = _mirror_groups(self.mirrors)
        self._mirror_F = None
        self._body_sig = _body_signature(self.bodies)
        self._body_digest = np.frombuffer(hashlib.sha256(repr(self._body_sig).encode()).digest(), np.uint8)
        self._plate_faces = self.patches.material == PLATE_MATERIAL if plate else None
        self._F = None
        # each mesh's vertices: (receiver, patch) pairs whose pyramid misses every mesh's
        # convex hull need no visibility points
        self.hulls = [s.vertex_array for s in ir.surfaces if s.role == "mesh"] if p.meshes else []
        plate_R = None
        if plate:
            from .plates import diffuser_transmittance_1nm, plate_hemispherical_reflectance

            T_bands = ir.grid.integrate(diffuser_transmittance_1nm(ctx, ctx.params("diffuser")))
            plate_R = plate_hemispherical_reflectance(self.plate_ir, T_bands)           # (B,)
        # a surface_reflectance effect scales the ceiling's, walls' or floor's reflectance
        sr = ctx.params("surface_reflectance") if "surface_reflectance" in ctx.effects else None
        rk = key + ("rho", p.reflectance_scale, None if plate_R is None else tuple(np.round(plate_R, 9))) + (
            () if sr is None else (sr.ceiling_scale, sr.walls_scale, sr.floor_scale))
        if rk not in ctx.cache:
            mats = ir.materials
            is_plate = self.patches.material == PLATE_MATERIAL
            rho = np.array([plate_R if m == PLATE_MATERIAL else mats[m].reflectance.array_bands
                            for m in self.patches.material]).reshape(len(self.patches), -1)
            # the plate's reflectance is the plate model's, not a surface material's
            scale = np.where(is_plate, 1.0, p.reflectance_scale)
            if sr is not None:
                scale = scale * np.where(is_plate, 1.0, surface_patch_scales(ir, sr, self.patches.surface))
            ctx.cache[rk] = np.clip(rho * scale[:, None], 0.0, 0.99)                   # (P, B)
        self.rho = ctx.cache[rk]
        self._rho_key = rk
        # a diffuser plate between surfaces (the luminaire cavity above it, the booth below)
        # transmits inter-reflected light along each line between two patches with its directional
        # transmittance at that line's incidence (plate_directional_relative, times the declared
        # total): by reciprocity, the radiance seen through a plate along θ under a uniform sky is
        # T(θ) times the sky's, so each line's share is T(θ), and a Lambertian source's light
        # crosses with the hemispherical T_h in total.  (A constant T_h on every line, as before,
        # put the light of a white cavity that reaches the booth below through a rough PMMA
        # plate 14 % under Mitsuba 3: the lines to the floor are steep, where T(θ) > T_h.)
        self.plate_T = None
        self._cross_pp = None
        if "diffuser" in ctx.effects and ir.diffuser is not None:
            from .plates import diffuser_rect, diffuser_transmittance_1nm

            dp = ctx.params("diffuser")
            self.plate_rect = diffuser_rect(ir)
            self.plate_T = ir.grid.integrate(diffuser_transmittance_1nm(ctx, dp))       # (B,) declared
        self._B = None
        self._terms = None
        self._E0 = None
        self._images = None

    # ------------------------------------------------------------------ form factors
    @property
    def F(self) -> np.ndarray:
        """(P, P) patch-to-patch form factors past meshes and bodies (computed when first asked
        for: a solution read from the disk cache or the shipped tables needs none)."""
        if self._F is None:
            ctx, key = self.ctx, self._patch_key
            fk = key + ("F",)
            if fk not in ctx.cache:
                patches, blockers = self.patches, self.blockers
                # the booth's heaviest geometry (BYK: ~4000 patches, 10 s): kept on disk across runs
                ctx.cache[fk] = cached_array("form_factors", (patches.polys, patches.normals, blockers),
                                             (2, 3.0, NUDGE_MM),
                                             lambda: patch_form_factors(patches, blockers=blockers),
                                             shape=(len(patches.polys), len(patches.polys)))
            F = ctx.cache[fk]
            if self.bodies:
                bk = key + ("bodies", self._body_sig)
                if bk not in ctx.cache:
                    ctx.cache[bk] = self._F_past_bodies(F)
                F = ctx.cache[bk]
            # the plate's faces are seen only from the side they face: a polygon form factor does
            # not tell a face from its back, and the plate is no blocker (light crossing it is the
            # line factor below), so the ceiling would see the bottom face through the plate
            if self._plate_faces is not None:
                # kept with the form factors: every evaluation of a fit builds its transport anew
                sk = key + ("plate_faces_seen", self._body_sig if self.bodies else None,
                            self._plate_faces.tobytes())
                if sk not in ctx.cache:
                    ctx.cache[sk] = np.where(self._behind_plate_faces(self.patches.centres), 0.0, F)
                F = ctx.cache[sk]
            self._F = F
        return self._F

    @property
    def cross_pp(self) -> np.ndarray | None:
        """(P, P) plate line factors between patch centres (:meth:`_plate_line_factor`), or None
        without a plate."""
        if self.plate_T is None:
            return None
        if self._cross_pp is None:
            d = self.plate_ir.diffuser
            ck = self._patch_key + ("plate_cross", d.ior, json.dumps(d.scattering, sort_keys=True),
                                    float(np.mean(d.transmittance.array_1nm)))
            if ck not in self.ctx.cache:
                c = self.patches.centres
                self.ctx.cache[ck] = self._plate_line_factor(c, c)
            self._cross_pp = self.ctx.cache[ck]
        return self._cross_pp

    # ------------------------------------------------------------------ solve
    def _first_order_at_patches(self):
        patches = self.patches
        ir = self.ctx.ir
        c = patches.centres
        diag = np.linalg.norm(patches.polys[:, 2] - patches.polys[:, 0], axis=1)
        # patches close to a lamp (relative to their size) are averaged over more points
        dist = np.full(len(c), np.inf)
        for lp, _ in ir.lamps_on(self.model.lighting):
            o = np.asarray(lp.position_mm, float)
            ax = np.asarray(lp.axis, float)
            half = lp.length_mm / 2 if lp.kind in ("tube", "panel") else 0.0
            t = np.clip((c - o) @ ax, -half, half)
            dist = np.minimum(dist, np.linalg.norm(c - o - np.outer(t, ax), axis=1))
        near = dist < NEAR_DIAGONALS * diag
        mid = ~near & (dist < MID_DIAGONALS * diag)
        # occluders (a lamp box's walls, all of them near its lamp) at 2 × 2 points
        occ = np.char.startswith(patches.surface.astype(str), "occluder:")
        idx, pts_l, w_l, nrm_l = [], [], [], []
        for k, sel in ((1, ~near & ~mid), (MID_SUB, mid), (NEAR_SUB, near & ~occ), (OCCLUDER_NEAR_SUB, near & occ)):
            if not sel.any():
                continue
            pts, w = quad_subpoints(patches.polys[sel], k, gauss=True)
            ii = np.nonzero(sel)[0]
            idx.append(np.repeat(ii, k * k))
            pts_l.append(pts.reshape(-1, 3))
            w_l.append(w.ravel())
            nrm_l.append(np.repeat(patches.normals[sel], k * k, axis=0))
        idx = np.concatenate(idx)
        pts = np.concatenate(pts_l)
        w = np.concatenate(w_l)
        nrm = np.concatenate(nrm_l)
        # nudge off the surface so paths leaving a patch never count it as an occluder
        terms = self._transport_model().first_order_terms(pts + NUDGE_MM * nrm, nrm, False,
                                                          pair_factor=self._plate_directional(
                                                              self._lamp_visibility()))
        E0 = np.zeros((len(patches), len(terms)))
        for k, t in enumerate(terms):
            E0[:, k] = np.bincount(idx, weights=w * t.geo, minlength=len(patches))
        return terms, E0

    def _transport_model(self):
        """The model whose lamp light lights the patches: this one, its lamps integrated over at
        most :data:`TRANSPORT_LAMP_POINTS` points (the near-field rule refines them where a patch
        is close), not the readings' ``point_sources``.

        Its parameters are the fit's own, exact: the light reaching the patches, and through
        them the readings, is continuous in every fitted number.  (It followed them in 2 %
        steps once, to spare a fit re-evaluating it: an opal plate's fitted transmittance then
        stepped the readings by 0.18 % at a step's edge, so that on the aperture booth a forward
        difference of 0.01 % straddling one read 6.5 χ² units, and the plate's refits took half
        as many evaluations again and twice the time.)"""
        m = self.model
        opts = replace(m.options, lamp_points=TRANSPORT_LAMP_POINTS)
        if opts == m.options:
            return m
        from .forward import ForwardModel

        return ForwardModel(m.ir, m.lighting, effects=m.effects, lamp_overrides=m.ctx.lamp_overrides, options=opts,
                            cache=m.ctx.cache)

    def _F_past_bodies(self, F: np.ndarray) -> np.ndarray:
        """``F`` times the fraction of each pair's mutual view that no body crosses.

        A pair no segment between the two patches can bring near a body
        (:func:`swept_pairs_near_body`) is seen whole; the others are sampled with ``FF_BODY_PAIRS``
        segments between matched low-discrepancy points of the two patches (a thin tube
        a few centimetres from a ceiling hides part of a patch, not all or nothing).
        """
        polys, nrm = self.patches.polys, self.patches.normals
        c = self.patches.centres + NUDGE_MM * nrm
        hd = _half_diagonals(polys)
        ii, jj = np.nonzero(np.triu((F > 0) | (F.T > 0), 1))
        bodies = [b for _, b in self.bodies]

        def compute():
            n = FF_BODY_PAIRS
            V = np.ones(ii.size)
            hid = None
            pts = None
            # per body, only the pairs a segment between them may bring near it
            for b, k in zip(bodies, pairs_near_bodies(bodies, c[ii], c[jj], hd[ii], hd[jj])):
                if not k.size:
                    continue
                if pts is None:
                    pts = quad_r2_points(polys, n)[0] + NUDGE_MM * nrm[:, None, :]
                    hid = np.zeros((ii.size, n), bool)
                # patch j's points in reverse order: the pairs cover the two patches evenly
                A = pts[ii[k]].reshape(-1, 3)
                B = pts[jj[k]][:, ::-1].reshape(-1, 3)
                hid[k] |= bodies_block(A, B, [b]).reshape(-1, n)
            if hid is not None:
                V = 1.0 - hid.mean(axis=1)
            return V

        V = cached_array("body_form_factor_view", (c[ii], c[jj], hd), self._body_sig + (FF_BODY_PAIRS,),
                         compute, shape=ii.shape)
        F = F.copy()
        F[ii, jj] *= V
        F[jj, ii] *= V
        return F

    def _lamp_visibility(self):
        """``pair_factor`` for the lamps' light on patch points: 0 where a mesh or another
        lamp's body is in the way (occluders act on lamp light through their own effect).
        A lamp's quadrature points lie inside its own body, which is therefore left out for
        its own light."""
        tris = self.blockers
        if not len(tris) and not self.bodies:
            return None

        def factor(es, P):
            f = None
            if len(tris):
                f = self.ctx.memo("meshvis", (es.points_mm, P, tris),
                                  lambda: visibility_matrix(es.points_mm, P, tris), limit=64)
            others = [b for owner, b in self.bodies
                      if owner.startswith("lamp:") and owner != f"lamp:{es.lamp_id}"]
            if others:
                def compute():
                    M, N = len(P), len(es.points_mm)
                    A = np.broadcast_to(es.points_mm[None, :, :], (M, N, 3)).reshape(-1, 3)
                    B = np.broadcast_to(P[:, None, :], (M, N, 3)).reshape(-1, 3)
                    return (~bodies_block(A, B, others)).reshape(M, N).astype(float)

                fb = self.ctx.memo(f"bodyvis:{es.lamp_id}", (es.points_mm, P, self._body_digest), compute,
                                   limit=64)
                f = fb if f is None else f * fb
            return f

        return factor

    def _plate_directional(self, base):
        """``base`` (a pair factor, or None) times, on the plate's top face, the plate's
        directional reflectance relative to its hemispherical one, :math:`R(θ_i)/R_h`: the lamps'
        light reaches the plate at its own incidence, while the patch reflects with
        :math:`R_h` (:func:`lbscene.engine.light.plates.plate_reflectance`; at the bands' mean
        absorption).  A plate that reflects the lamps specularly (their images in it carry that
        light, :func:`lbscene.engine.light.plates.specular_plate`) re-emits none of it: 0 there."""
        ir = self.ctx.ir
        if not (self.patches.material == PLATE_MATERIAL).any():
            return base
        from .plates import (diffuser_transmittance_1nm, plate_hemispherical_reflectance, plate_reflectance,
                             plate_top_mm, specular_plate)

        d = ir.diffuser
        dp = self.ctx.params("diffuser")
        specular = specular_plate(ir, dp)
        T = float(np.mean(ir.grid.integrate(diffuser_transmittance_1nm(self.ctx, dp))))
        Rh = float(plate_hemispherical_reflectance(self.plate_ir, np.array([T]))[0])
        z_top = plate_top_mm(ir)
        lo = np.array([d.centre_mm[0] - d.size_mm[0] / 2, d.centre_mm[1] - d.size_mm[1] / 2])
        hi = np.array([d.centre_mm[0] + d.size_mm[0] / 2, d.centre_mm[1] + d.size_mm[1] / 2])

        def factor(es, P):
            f = None if base is None else base(es, P)
            on = (np.abs(P[:, 2] - z_top) < 10 * NUDGE_MM) & np.all((P[:, :2] >= lo - 1e-6) &
                                                                    (P[:, :2] <= hi + 1e-6), axis=1)
            if not on.any() or Rh <= 0:
                return f
            w = np.ones((len(P), len(es.points_mm)))
            if specular:
                w[on] = 0.0
            else:
                d_ = es.points_mm[None, :, :] - P[on][:, None, :]
                cos_i = np.clip(d_[..., 2] / np.maximum(np.linalg.norm(d_, axis=-1), 1e-12), 0.0, 1.0)
                w[on] = plate_reflectance(self.plate_ir, cos_i, np.array([T]))[..., 0] / Rh
            return w if f is None else f * w

        return factor

    def _gather_past_bodies(self, P_rx, G) -> np.ndarray | None:
        """(M, P) fraction of each patch a receiver sees past the bodies (where ``G`` > 0):
        ``GATHER_SUB``² low-discrepancy points of the patch, tested only for pairs whose
        segment to the patch may meet a body (:func:`swept_pairs_near_body`; others: seen
        whole); a pair seen partly (a tube across the patch) is sampled again with
        ``GATHER_FINE``² points, as the meshes' gather is (the BYK's two tube legs in front
        of its cavity's aperture: 36 points left a ±2 % ripple from row to row of the grid).
        With meshes, the fraction of the part the meshes leave visible (the two factors
        multiply in :meth:`terms`)."""
        if not self.bodies:
            return None
        polys = self.patches.polys
        nrm = self.patches.normals

        def compute():
            rows, cols = np.nonzero(G > 0)
            c = self.patches.centres + NUDGE_MM * nrm
            hd = _half_diagonals(polys)
            n_sub, n_fine = GATHER_SUB ** 2, GATHER_FINE ** 2
            # the R2 points are a sequence: the first n_sub of the fine set are the coarse set
            pts, w_fine = quad_r2_points(polys, n_fine)
            pts = pts + NUDGE_MM * nrm[:, None, :]
            w_sub = quad_r2_points(polys, n_sub)[1]
            # per body, only pairs whose centre line passes it closer than the patch's half
            # diagonal (plus the body's own bounding radius for a plate) can be partly hidden
            bl = [b for _, b in self.bodies]
            nears = pairs_near_bodies(bl, P_rx[rows], c[cols], np.zeros(rows.size), hd[cols])
            hid = np.zeros((rows.size, n_fine), bool)
            tested = np.zeros(rows.size, bool)

            def test(first, count, select):
                for b, near in zip(bl, nears):
                    k = near[select[near]] if near.size else near
                    if not k.size:
                        continue
                    tested[k] = True
                    h = bodies_block(np.repeat(P_rx[rows[k]], count, axis=0),
                                     pts[cols[k], first:first + count].reshape(-1, 3), [b])
                    hid[k, first:first + count] |= h.reshape(-1, count)

            test(0, n_sub, np.ones(rows.size, bool))
            coarse = hid[:, :n_sub]
            part = tested & coarse.any(axis=1) & ~coarse.all(axis=1)
            test(n_sub, n_fine - n_sub, part)
            k = np.nonzero(tested & hid.any(axis=1))[0]
            n_pts = np.where(part[k], n_fine, n_sub)
            w = np.where(part[k][:, None], w_fine[cols[k]],
                         np.c_[w_sub[cols[k]], np.zeros((k.size, n_fine - n_sub))])
            seen = np.ones((k.size, n_fine), bool)
            tris = self.blockers
            if len(tris) and k.size:
                # the receiver's view of the patch is also cut by the meshes
                # (_gather_visibility): what a body hides counts only where the meshes do not
                # hide it already (an aperture plate on a cavity's face would otherwise hide
                # the cavity twice)
                for nn in (n_sub, n_fine):
                    sel = np.nonzero(n_pts == nn)[0]
                    if sel.size:
                        seen[sel, :nn] = ~_hidden_points(P_rx, pts, rows[k[sel]], cols[k[sel]], 0, nn, tris)
            den = (seen * w).sum(axis=1)
            num = ((seen & ~hid[k]) * w).sum(axis=1)
            V = np.ones(G.shape)
            V[rows[k], cols[k]] = np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0)
            return V

        return self.ctx.memo("bodyvis_rx", (P_rx, G > 0, polys, self._body_digest, self.blockers),
                             lambda: cached_array("gather_past_bodies", (P_rx, G > 0, polys, self.blockers),
                                                  self._body_sig + (GATHER_SUB, GATHER_FINE, NUDGE_MM),
                                                  compute, shape=G.shape, shipped=True), limit=32)

    def _gather_visibility(self, P_rx, G) -> np.ndarray | None:
        """(M, P) fraction of each patch a receiver sees past the meshes (where ``G`` > 0).

        ``GATHER_SUB``² low-discrepancy points per patch first; a (receiver, patch) pair
        seen partly (some points hidden, some not: a patch seen through an aperture's
        edge) is sampled again with ``GATHER_FINE``² points, since the light a receiver
        gets from a cavity comes through such partial views.
        """
        if not len(self.blockers):
            return None
        tris = self.blockers
        polys = self.patches.polys
        nrm = self.patches.normals
        seen = G > 0
        n_sub, n_fine = GATHER_SUB ** 2, GATHER_FINE ** 2

        def compute():
            faces = coplanar_convex_faces(tris)
            # the R2 points are a sequence: the first n_sub of the fine set are the coarse set,
            # so the fine pass tests only the points it adds
            pts_all, w_fine = quad_r2_points(polys, n_fine)
            pts_all = pts_all + NUDGE_MM * nrm[:, None, :]
            w_sub = quad_r2_points(polys, n_sub)[1]
            V = np.ones(G.shape)
            rows, cols = np.nonzero(seen)
            quads = polys + NUDGE_MM * nrm[:, None, :]
            # 1. pairs whose pyramid (receiver + patch) misses every mesh's hull: seen whole
            clear = np.ones(rows.size, bool)
            for hull in self.hulls:
                clear &= pyramids_clear_of(P_rx[rows], quads[cols], hull)
            rows, cols = rows[~clear], cols[~clear]
            # 2. pairs whose four corners one convex face hides: hidden whole (what a convex
            #    face hides from a point is convex)
            dark = np.zeros(rows.size, bool)
            for f in faces:
                h = np.ones(rows.size, bool)
                for q in range(4):
                    live = np.nonzero(h)[0]
                    h[live] = segments_blocked_by_polygon(P_rx[rows[live]], quads[cols[live], q], f)
                dark |= h
            V[rows[dark], cols[dark]] = 0.0
            rows, cols = rows[~dark], cols[~dark]
            # 3. the rest point by point; pairs seen partly get the fine set
            hid = _hidden_points(P_rx, pts_all, rows, cols, 0, n_sub, tris)
            V[rows, cols] = ((~hid) * w_sub[cols]).sum(axis=1)
            part = hid.any(axis=1) & ~hid.all(axis=1)
            if part.any():
                r, c = rows[part], cols[part]
                more = _hidden_points(P_rx, pts_all, r, c, n_sub, n_fine - n_sub, tris)
                V[r, c] = ((~np.c_[hid[part], more]) * w_fine[c]).sum(axis=1)
            return V

        def on_disk():
            return cached_array("gather_visibility", (P_rx, seen, polys, nrm, tris),
                                (GATHER_SUB, GATHER_FINE, NUDGE_MM), compute,
                                shape=seen.shape, shipped=True)

        return self.ctx.memo("meshvis_rx", (P_rx, seen, polys, tris, (GATHER_SUB, GATHER_FINE)), on_disk,
                             limit=32)

    def _first_order(self):
        """First-order light on the patches, once per model (parameters fixed), and shared by
        models whose lamp light is the same: a fit that moves only a meter's response, or
        repeats a point, reuses it (keyed by the parameters of every effect that changes
        lamp light, the lamp overrides and the lighting)."""
        if self._terms is None:
            tm = self._transport_model()
            k = (self._patch_key, self._body_sig, *tm.ctx.lamp_light_key())
            store = self.ctx.cache.setdefault("_rad_first", {})
            hit = store.get(k)
            if hit is None:
                hit = self._first_order_at_patches()
                if len(store) >= 16:
                    store.pop(next(iter(store)))
                store[k] = hit
            self._terms, self._E0 = hit
        return self._terms, self._E0

    def _band_classes(self):
        """Bands whose reflectances (and plate transmittance) coincide share one solve:
        ``(unique rows (U, P[+1]), band → row index (B,), cache key)``."""
        Rm = [np.broadcast_to(R, (self.rho.shape[1],)) for R, _ in self._mirror_groups]
        ck = self._rho_key + ("classes", None if self.plate_T is None else array_key(self.plate_T),
                              tuple(array_key(R) for R in Rm))
        hit = self.ctx.cache.get(ck)
        if hit is None:        # np.unique over (B, P) rows: ~20 ms, once per reflectance set
            sig = np.c_[(self.rho.T,) + (() if self.plate_T is None else (self.plate_T,)) + tuple(Rm)]
            uniq, inv = np.unique(np.round(sig, 9), axis=0, return_inverse=True)
            # the patches (with the occluders that cut them) and the bodies that shape F
            hit = self.ctx.cache[ck] = (uniq, inv.ravel(),
                                        (self._rho_key, self._body_digest.tobytes(), self.p.max_bounces,
                                         array_key(uniq)))
        return hit

    def _neumann_terms(self, u) -> int | None:
        """Jacobi sweeps for a 1e-9 relative residual when the series converges fast, else None."""
        r, T, Rm = self._class_parts(u)
        F_sum = self.F.sum(axis=1) + (self.images[0].sum(axis=1) if self._mirror else 0.0)
        for R, Fm in zip(Rm, self.mirror_images):
            F_sum = F_sum + R * Fm.sum(axis=1)
        pairs = self.plate_pairs
        if pairs is not None and T is not None:           # an opal plate's faces pass light on
            k = self._coupling_ratio(T)
            S, F_sum = F_sum, F_sum.copy()
            F_sum[pairs[:, 0]] += k * S[pairs[:, 1]]
            F_sum[pairs[:, 1]] += k * S[pairs[:, 0]]
        q = float(np.max(r * F_sum))                       # bound on the spectral radius of ρF
        if self.p.max_bounces > 0:
            return self.p.max_bounces - 1
        if q >= 1:
            return None
        return int(np.ceil(np.log(1e-9) / np.log(max(q, 1e-12))))

    def _form_factor_signature(self, T, Rm) -> tuple:
        """What :meth:`_F_band` builds a band class's form factors from: the patches (with the
        occluders that cut them), the bodies, the plate as fitted (its layer's transfer between its
        faces and its exit shape) and its transmittance ``T``, the mirrors' reflectances ``Rm``.  A
        factorisation is kept under it and an update starts only from one with the same."""
        return (self._patch_key, self._body_digest.tobytes(), self._plate_state,
                None if T is None else float(T), np.asarray(Rm, float).tobytes())

    def _lu(self, u) -> "_LUSolver | _LowRankSolver":
        """A solver of :math:`(I - \\mathrm{diag}(ρ) F_u)` for band class ``u`` (its reflectances
        and plate transmittance): the LU factors of the matrix, or — when an earlier class with
        the same form factors (:meth:`_form_factor_signature`) differs from it in the reflectance
        of at most :data:`LOW_RANK_MAX_FRACTION` of the patches (a fit moving the ceiling's or the
        walls' reflectance) — that class's factors with the
        difference as a low-rank update (:class:`_LowRankSolver`), exact to rounding."""
        from scipy.linalg import lu_factor

        store = self.ctx.cache.setdefault("_rad_lu", {})
        r, T, Rm = self._class_parts(u)
        bk = self._form_factor_signature(T, Rm)
        k = (bk, r.tobytes())
        if k not in store:
            P = len(self.patches)
            # the last few factored classes an update may start from, those with these form
            # factors among them (each holds an n × n factorisation: bounded apart from the store)
            bases = self.ctx.cache.setdefault("_rad_lu_bases", {})
            base = None
            for (bk_, k_), b in bases.items():
                if bk_ != bk:
                    continue
                n_diff = int(np.count_nonzero(b.r != r))
                if n_diff <= LOW_RANK_MAX_FRACTION * P and (base is None or n_diff < base[1]):
                    base = (b, n_diff, (bk_, k_))
            if len(store) >= 64:
                store.pop(next(iter(store)))
            if base is not None:
                # the base's rows of these form factors are kept with it: the band's form factors
                # (past the plate, its images) are built only for a new patch set
                store[k] = _LowRankSolver(base[0], r, lambda: self._F_band(T, Rm))
                bases[base[2]] = bases.pop(base[2])          # the least recently used go first
            else:
                Fu = self._F_band(T, Rm)
                store[k] = _LUSolver(lu_factor(np.eye(P) - r[:, None] * Fu), r)
                if len(bases) >= LOW_RANK_BASES:
                    bases.pop(next(iter(bases)))
                bases[(bk, k)] = store[k]
        return store[k]

    def _solution_params(self) -> tuple:
        """What the patch radiosity is computed from, as plain values (the key of its disk cache
        entry and shipped table): the booth's content (:attr:`~lbscene.engine.scene.ir.SceneIR.light_hash`:
        not the colour data derived from it, whose last digit is the machine's), the lighting,
        every effect's parameters
        and the lamp overrides of the model lighting the patches, its options, and the light
        model's code.  All of it reproducible from the booth file on any machine."""
        from .code_digest import light_code_digest

        tm = self._transport_model()
        return ("patch_radiosity-1", self.ctx.ir.light_hash, tm.lighting,
                json.dumps(tm.effects, sort_keys=True, default=str),
                json.dumps(tm.ctx.lamp_overrides, sort_keys=True, default=str),
                repr(tm.options), light_code_digest(self.ctx.ir))

    def _solve(self, compute: bool = True) -> bool:
        """Patch radiosity B (bands, patches, terms): for :meth:`patch_radiosity`.

        The solution is kept in the disk cache (and shipped for the shipped booths), so a later
        process — another view, the web export, a compare of the same booth — reads it instead of
        the form factors and the solve.  ``compute=False``: only look it up; returns whether B is
        known."""
        if self._B is not None:
            return True
        terms, E0 = self._first_order()
        shape = (self.ctx.ir.grid.count, len(self.patches), len(terms))
        params = self._solution_params()
        if not compute:
            from lbscene.engine.files.disk_cache import peek_array

            hit = peek_array("patch_radiosity", (), params, shape)
            if hit is None:
                return False
            self._B = hit
            return True
        self._B = cached_array("patch_radiosity", (), params, self._solve_now, shape=shape, shipped=True)
        return True

    def _solve_now(self) -> np.ndarray:
        terms, E0 = self._first_order()
        uniq, inv, _ = self._band_classes()
        P = len(self.patches)
        sol = []
        for j, u in enumerate(uniq):
            r, T, Rm = self._class_parts(u)
            n_it = self._neumann_terms(u)
            if n_it is not None and (self.p.max_bounces > 0 or n_it * E0.shape[1] < P / 3):
                Fu = self._F_band(T, Rm)
                x = r[:, None] * E0
                acc = x.copy()
                for _ in range(n_it):
                    x = r[:, None] * (Fu @ x)
                    acc += x
                sol.append(acc)
            else:
                sol.append(self._lu(u).solve(r[:, None] * E0))
        return np.stack([sol[i] for i in inv])

    def _in_front(self, P) -> np.ndarray:
        """(len(P), patches): is point ``P[i]`` on the side patch ``j`` faces?"""
        c, n = self.patches.centres, self.patches.normals
        return ((P[:, None, :] - c[None, :, :]) * n[None, :, :]).sum(-1) > 0

    def _behind_plate_faces(self, P) -> np.ndarray:
        """(len(P), patches): patch ``j`` is a face of the plate that point ``P[i]`` sees from
        behind (geometry, kept for the last :data:`PLATE_LINE_SETS` point sets)."""
        c, n = self.patches.centres, self.patches.normals
        return self.ctx.memo("plate_faces_behind", (P, self._plate_faces, c, n),
                             lambda: self._plate_faces[None, :] & ~self._in_front(P), limit=PLATE_LINE_SETS)

    def _plate_lines(self, A, B) -> tuple[np.ndarray, np.ndarray]:
        """``(flat indices, cosines)``: the lines between points ``B[j]`` and ``A[i]`` that cross
        the plate (entries of an ``(len(A), len(B))`` array) and their cosines with its normal.
        Geometry: kept for the last :data:`PLATE_LINE_SETS` point sets, as a fit moving the
        plate's transmittance or diffuse fraction asks for the same lines at every step."""
        from .geometry import segment_hits_rectangle

        r = self.plate_rect

        def compute():
            flat = np.flatnonzero(segment_hits_rectangle(B, A, r))
            d = A[flat // len(B)] - B[flat % len(B)]
            return flat, np.abs(d[:, 2]) / np.maximum(np.linalg.norm(d, axis=-1), 1e-12)

        hole = np.asarray(r.hole_half if r.hole_half is not None else (), float)
        return self.ctx.memo("plate_lines", (A, B, r.centre, r.normal, r.u, np.asarray(r.half, float), hole),
                             compute, limit=PLATE_LINE_SETS)

    def _plate_line_factor(self, A, B) -> np.ndarray:
        """(len(A), len(B)): 1 where the line between points ``A[i]`` and ``B[j]`` misses the plate,
        else minus the plate's directional transmittance at the line's incidence relative to
        normal incidence (the sign bit marks a crossing, −0 where nothing crosses along lines:
        :meth:`_F_band` multiplies those by the
        declared total transmittance); an opal plate's regular part only
        (:func:`~lbscene.engine.light.plates.plate_line_relative`: its scattered part goes from
        face to face, :meth:`_plate_coupling`)."""
        from .plates import plate_line_relative

        flat, cos = self._plate_lines(A, B)
        out = np.ones((len(A), len(B)))
        out.flat[flat] = -plate_line_relative(self.plate_ir, cos)
        return out

    def _crossed(self, M, S, T):
        """``M`` with the entries whose lines cross the plate (``S`` negative or −0) times ``T·|S|``."""
        # the sign bit marks a crossing: a line the plate lets nothing through (an opal plate with
        # no regular part) is −0, not a line that misses it
        return np.where(np.signbit(S), M * (-S) * T, M)

    def _F_crossed(self, T):
        """The form factors past the plate at transmittance ``T`` (:meth:`_crossed`), the last
        band class's kept (the gather of the patches and of the receivers both read it)."""
        if self.cross_pp is None:
            return self.F
        hit = getattr(self, "_F_crossed_last", None)
        if hit is not None and hit[0] == float(T):
            return hit[1]
        F = self._crossed(self.F, self.cross_pp, T)
        self._F_crossed_last = (float(T), F)
        return F

    def _F_crossed_rows(self, rows, T):
        """Rows ``rows`` of :meth:`_F_crossed` at ``T``, without forming the others."""
        if self.cross_pp is None:
            return self.F[rows]
        hit = getattr(self, "_F_crossed_last", None)
        if hit is not None and hit[0] == float(T):
            return hit[1][rows]
        return self._crossed(self.F[rows], self.cross_pp[rows], T)

    def _exit_cosines(self, points) -> list[np.ndarray]:
        """Per side of the plate (bottom faces seen from below, top from above), ``(len(points),
        n)`` cosines of the directions from the face patches to ``points`` (0 behind a face):
        geometry, kept for the last few point sets (a fit moves the plate's light, not them)."""
        pairs = self.plate_pairs
        store = self.__dict__.setdefault("_exit_cos", {})
        key = array_key(points)
        if key in store:
            return store[key]
        c = self.patches.centres
        out = []
        for face, sign in ((pairs[:, 1], -1.0), (pairs[:, 0], 1.0)):
            d = np.asarray(points, float)[:, None, :] - c[face][None, :, :]
            out.append(np.clip(sign * d[..., 2] / np.maximum(np.linalg.norm(d, axis=-1), 1e-12), 0.0, 1.0))
        if len(store) >= 8:
            store.pop(next(iter(store)))
        store[key] = out
        return out

    def _F_band(self, T, Rm=()):
        """The form factors of one band class: past the plate at its transmittance ``T`` (its
        images at :math:`R(θ)` for a specular plate) and with the mirrors' images at their
        reflectances ``Rm`` (one per group)."""
        F = self.F if T is None else self._F_crossed(T)
        if T is not None and self.plate_pairs is not None:
            F = self._plate_coupling(F, T) + self._exit_shape_correction(F, self.patches.centres, T)
        if self._mirror and T is not None:
            F = F + self._reflected(*self.images, T)
        for R, Fm in zip(Rm, self.mirror_images):
            if R > 0:
                F = F + R * Fm
        return F

    @property
    def plate_pairs(self) -> np.ndarray | None:
        """(n, 2) indices of the plate's top and bottom face patches over the same part of it, or
        None when the plate scatters nothing diffusely
        (:func:`~lbscene.engine.light.plates.plate_scatters_diffusely`)."""
        from .plates import plate_scatters_diffusely

        if self._plate_faces is None or not plate_scatters_diffusely(self.plate_ir):
            return None
        if getattr(self, "_pairs", None) is None:
            idx = np.nonzero(self._plate_faces)[0]
            c = np.round(self.patches.centres[idx, :2], 6)
            up = self.patches.normals[idx, 2] > 0
            top, bottom = idx[up], idx[~up]
            order_t = np.lexsort((c[up, 1], c[up, 0]))
            order_b = np.lexsort((c[~up, 1], c[~up, 0]))
            self._pairs = np.c_[top[order_t], bottom[order_b]]
        return self._pairs

    def _coupling_ratio(self, T: float) -> float:
        """:math:`τ_d / R_h`: the light an opal plate's face sends on scattered from the other face
        (:func:`~lbscene.engine.light.plates.plate_diffuse_transfer` times the transmittance ``T``)
        over what it reflects (the plate patches' reflectance at ``T``)."""
        from .plates import plate_diffuse_transfer, plate_hemispherical_reflectance

        ir = self.plate_ir
        Rh = float(plate_hemispherical_reflectance(ir, np.array([float(T)]))[0])
        return plate_diffuse_transfer(ir) * float(T) / max(Rh, 1e-9)

    def _plate_coupling(self, F, T):
        """``F`` with an opal plate's scattered transmission: the row of each plate face gets
        the other face's row times :meth:`_coupling_ratio`, so that :math:`\\mathrm{diag}(ρ) F`
        carries, besides what the face reflects, :math:`τ_d` times the light arriving on the
        other face (the layer scatters it out of this face, from where it arrived; its light
        crossing along straight lines is the regular part only, :meth:`_plate_line_factor`).
        The lamps' own light through the plate is not in it (the direct light's plate cells
        carry that): the coupling acts on inter-reflected light only."""
        pairs = self.plate_pairs
        if pairs is None:
            return F
        k = self._coupling_ratio(T)
        if k <= 0:
            return F
        F = F.copy()
        top, bottom = pairs[:, 0], pairs[:, 1]
        add_top, add_bottom = k * F[bottom], k * F[top]
        F[top] += add_top
        F[bottom] += add_bottom
        return F

    def _exit_shape_correction(self, M, points, T):
        """What an opal plate's scattered transmission adds to a gather ``M`` (rows: viewers at
        ``points``; columns: patches; the plate's lines already crossed) beyond the Lambertian
        emission of the face patches: the layer sends the light it scatters through with the
        shape :math:`s(θ_o) = t(θ_o)/t_h` (:meth:`~lbscene.engine.light.opal_layer.OpalLayer.exit_shape`:
        more toward the normal), so a viewer of face :math:`b` gets
        :math:`M_{ib}\\,(s(θ_{ib}) - 1)\\,τ_d\\,H_{b'}` more, :math:`H_{b'} = F_{b'} B` the light on
        the other face.  ``(len(points), P)``; zero without such a plate."""
        pairs = self.plate_pairs
        if pairs is None:
            return 0.0
        from .plates import opal_plate_layer, plate_diffuse_transfer

        ir = self.plate_ir
        tau = plate_diffuse_transfer(ir) * float(T)
        if tau <= 0:
            return 0.0
        # the plate's layer as the diffuser effect's parameters make it (plates.fitted_plate)
        layer = opal_plate_layer(ir)
        out = 0.0
        sides = zip((pairs[:, 1], pairs[:, 0]), (pairs[:, 0], pairs[:, 1]), self._exit_cosines(points))
        for face, other, cos in sides:
            delta = M[:, face] * (layer.exit_shape(cos) - 1.0)
            out = out + delta @ (tau * self._F_crossed_rows(other, T))
        return out

    def _class_parts(self, u) -> tuple[np.ndarray, float | None, np.ndarray]:
        """A band class's row split into ``(reflectances (P,), plate transmittance or None,
        mirror reflectances (groups,))``."""
        P = len(self.patches)
        k = P + (self.plate_T is not None)
        return u[:P], (u[P] if self.plate_T is not None else None), u[k:]

    @property
    def mirror_images(self) -> list[np.ndarray]:
        """(P, P) per mirror group: the form factors from each patch to the others' images in the
        group's mirrors, past bodies and meshes
        (:func:`lbscene.engine.light.plate_mirror.face_image_factors`)."""
        if self._mirror_F is None:
            from .plate_mirror import IMAGE_NEAR_FACTOR, IMAGE_PAIR_POINTS, face_image_factors

            out = []
            for R, faces in self._mirror_groups:
                geo = np.array([np.r_[f.centre, f.normal, f.u, f.half] for f in faces], float)
                ck = self._patch_key + ("mirror_images", self._body_sig, geo.tobytes())
                if ck not in self.ctx.cache:
                    self.ctx.cache[ck] = cached_array(
                        "mirror_image_factors", (self.patches.polys, self.patches.normals, self.blockers, geo),
                        self._body_sig + ("mirror-images-1", IMAGE_PAIR_POINTS, IMAGE_NEAR_FACTOR),
                        lambda: self._face_images(
                            lambda f, others: face_image_factors(self.patches, [f], others, self.blockers)[0],
                            faces, (len(self.patches), len(self.patches))),
                        shape=(len(self.patches), len(self.patches)))
                out.append(self.ctx.cache[ck])
            self._mirror_F = out
        return self._mirror_F

    def _face_images(self, factors, faces, shape) -> np.ndarray:
        """``factors(face, bodies)`` summed over ``faces``, each past every body but itself (a
        mirror does not hide its own images)."""
        F = np.zeros(shape)
        for f in faces:
            F += factors(f, [b for _, b in self.bodies if b is not f])
        return F

    @property
    def images(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F', cos)`` (P, P): the form factors from each patch to the others' images in the
        plate's faces, past bodies and meshes, and their lines' cosines with the plate's normal
        (:func:`lbscene.engine.light.plate_mirror.patch_image_factors`; a specular plate only)."""
        if self._images is None:
            from .plate_mirror import IMAGE_NEAR_FACTOR, IMAGE_PAIR_POINTS, patch_image_factors, plate_geometry_key

            plate = plate_geometry_key(self.ctx.ir)
            ck = self._patch_key + ("plate_images", self._body_sig, tuple(plate))
            if ck not in self.ctx.cache:
                P = len(self.patches)
                both = cached_array(
                    "plate_image_factors", (self.patches.polys, self.patches.normals, self.blockers, plate),
                    self._body_sig + ("plate-images-1", IMAGE_PAIR_POINTS, IMAGE_NEAR_FACTOR),
                    lambda: np.stack(patch_image_factors(self.patches, self.ctx.ir, [b for _, b in self.bodies],
                                                         self.blockers)),
                    shape=(2, P, P))
                self.ctx.cache[ck] = (both[0], both[1])
            self._images = self.ctx.cache[ck]
        return self._images

    def _reflected(self, F_img, cos, T) -> np.ndarray:
        """``F_img`` times the plate's directional reflectance :math:`R(θ)` at ``cos`` for the
        declared transmittance ``T`` (one band class)."""
        from .plates import plate_reflectance

        out = np.zeros_like(F_img)
        nz = F_img > 0
        if nz.any():
            out[nz] = F_img[nz] * plate_reflectance(self.plate_ir, cos[nz], np.array([float(T)]))[:, 0]
        return out

    # ------------------------------------------------------------------ receivers
    def patch_radiosity(self) -> np.ndarray:
        """(B, P, K) radiosity per band, patch and first-order term (W·m⁻² per unit spectrum)."""
        self._solve()
        return self._B

    def _receiver_gather(self, G, P_rx):
        """``(cross, S_rx)``: the plate line factors between receivers and patches (None without a
        plate)."""
        if self.plate_T is None:
            return None
        return self._plate_line_factor(P_rx, self.patches.centres)

    def _use_solution(self, P_rx) -> bool:
        """Whether the receivers ``P_rx`` get their light from the patch radiosity (solved here, or
        read from the disk cache or a shipped table) rather than from receiver operators.

        The first evaluation at a set of receivers uses the solution: one solve with the lamps'
        terms as right-hand sides, kept on disk for the next process (another view, the web
        export, a compare).  A fit evaluates the same receivers again and again with other lamp
        parameters: from the second evaluation on, the operators (built once, a few matrix
        products per evaluation) are cheaper, unless the solution is known already."""
        from lbscene.engine.files.disk_cache import array_key

        calls = self.ctx.cache.setdefault("_rad_rx_calls", {})
        k = (self._patch_key, array_key(P_rx))
        n = calls.get(k, 0)
        if len(calls) < 4096:
            calls[k] = n + 1
        if self._B is not None or n == 0:
            return self._solve()
        return self._solve(compute=False)

    def _G_band(self, G, S_rx, img, T, mimg=(), Rm=(), P_rx=None):
        """The receivers' gather for one band class: ``G`` with the plate's line factors at
        transmittance ``T`` and, for a specular plate, the patches' images (``img``: ``(G', cos)``
        of :func:`lbscene.engine.light.plate_mirror.receiver_image_factors`) times :math:`R(θ)`,
        and the patches' images in the mirrors (``mimg``, one per group) times their reflectances
        ``Rm``."""
        Gj = G if S_rx is None or T is None else self._crossed(G, S_rx, T)
        if T is not None and P_rx is not None:
            Gj = Gj + self._exit_shape_correction(Gj, P_rx, T)
        if img is not None and T is not None:
            Gj = Gj + self._reflected(img[0], img[1], T)
        for R, Gm in zip(Rm, mimg):
            if R > 0:
                Gj = Gj + R * Gm
        return Gj

    def _gather_solution(self, G, P_rx, img=None, mimg=()) -> np.ndarray:
        """(K, M, B) inter-reflected light at the receivers from the patch radiosity:
        :math:`G_b B_b` per band (G with the plate's line factors of the band's class, and the
        patches' images in a specular plate, ``img``)."""
        uniq, inv, _ = self._band_classes()
        S_rx = self._receiver_gather(G, P_rx)
        B = self._B
        out = np.empty((B.shape[2], len(G), B.shape[0]))
        for j, u in enumerate(uniq):
            bands = np.nonzero(inv == j)[0]
            _, T, Rm = self._class_parts(u)
            Gj = self._G_band(G, S_rx, img, T, mimg, Rm, P_rx)
            out[:, :, bands] = np.einsum("mp,bpk->kmb", Gj, B[bands], optimize=True)
        return out

    def _receiver_operators(self, G, P_rx, img=None, mimg=()) -> np.ndarray:
        """(B, M, P) operators R_b = G_b·(I − ρ_b F_b)⁻¹·diag(ρ_b): patch first-order light →
        inter-reflected light at the receivers.

        They depend on geometry, reflectances and the receivers only, not on the lamps or any
        lamp parameter, so a fit that varies intensities, σ, apertures… reuses them and each
        evaluation is a few small matrix products (the solve is done once, transposed, with
        the receivers as right-hand sides).
        """
        from lbscene.engine.files.disk_cache import array_key

        uniq, inv, key = self._band_classes()
        ck = key + (array_key(G, P_rx, *(() if img is None else img), *mimg),)
        store = self.ctx.cache.setdefault("_rad_ops", {})
        hit = store.get(ck)
        if hit is not None:
            return hit
        Pn = len(self.patches)
        S_rx = self._receiver_gather(G, P_rx)
        ops = []
        for j, u in enumerate(uniq):
            r, T, Rm = self._class_parts(u)
            Gj = self._G_band(G, S_rx, img, T, mimg, Rm, P_rx)
            n_it = self._neumann_terms(u)
            if n_it is not None and (self.p.max_bounces > 0 or n_it * len(G) < Pn / 3):
                A = r[:, None] * self._F_band(T, Rm)
                y = Gj
                acc = y * r[None, :]
                for _ in range(n_it):
                    y = y @ A
                    acc += y * r[None, :]
                ops.append(acc)
            else:
                x = self._lu(u).solve(Gj.T, trans=1)          # (I − ρF)⁻ᵀ Gᵀ
                ops.append((r[:, None] * x).T)
        out = np.stack([ops[i] for i in inv])
        if len(store) >= 32:
            store.pop(next(iter(store)))
        store[ck] = out
        return out

    def _receiver_images(self, P, N, meter):
        """``(G', cos)`` (M, P): the receivers' view of the patches' images in a specular plate
        (:func:`lbscene.engine.light.plate_mirror.receiver_image_factors`, with the meter's
        response), memoised per receiver set."""
        from .plate_mirror import plate_geometry_key, receiver_image_factors

        m = np.broadcast_to(np.asarray(meter, bool), (len(P),))
        return self.ctx.memo(
            "plate_images_rx", (P, N, m, self.patches.polys, self._body_digest, plate_geometry_key(self.ctx.ir)),
            lambda: receiver_image_factors(
                self.patches, self.ctx.ir, P, N,
                lambda polys, normals, rows: self.model.lambertian_gather(polys, normals, P[rows], N[rows], m[rows]),
                [b for _, b in self.bodies], self.blockers),
            limit=32)

    def _receiver_mirror_images(self, P, N, meter) -> list[np.ndarray]:
        """(M, P) per mirror group: the receivers' view of the patches' images in the group's
        mirrors (:func:`lbscene.engine.light.plate_mirror.face_receiver_factors`, with the
        meter's response), memoised per receiver set."""
        if not self._mirror_groups:
            return []
        from .plate_mirror import face_receiver_factors

        m = np.broadcast_to(np.asarray(meter, bool), (len(P),))

        def gather(polys, normals, rows):
            return self.model.lambertian_gather(polys, normals, P[rows], N[rows], m[rows])

        out = []
        for R, faces in self._mirror_groups:
            geo = np.array([np.r_[f.centre, f.normal, f.u, f.half] for f in faces], float)

            def compute(faces=faces):
                return self._face_images(
                    lambda f, others: face_receiver_factors(self.patches, [f], P, N, gather, others,
                                                            self.blockers)[0],
                    faces, (len(P), len(self.patches)))

            out.append(self.ctx.memo("mirror_images_rx", (P, N, m, self.patches.polys, self._body_digest, geo),
                                     compute, limit=32))
        return out

    def terms(self, P, N, meter):
        from .forward import Term

        terms, E0 = self._first_order()
        G = self.model.lambertian_gather(self.patches.polys, self.patches.normals, P, N, meter)
        V = self._gather_visibility(P, G)
        if V is not None:
            G = G * V
        Vb = self._gather_past_bodies(P, G)
        if Vb is not None:
            G = G * Vb
        if self._plate_faces is not None:
            G = np.where(self._behind_plate_faces(P), 0.0, G)
        img = self._receiver_images(P, N, meter) if self._mirror else None
        mimg = self._receiver_mirror_images(P, N, meter)
        if self._use_solution(P):
            ind = self._gather_solution(G, P, img, mimg)
        else:
            R = self._receiver_operators(G, P, img, mimg)
            ind = np.einsum("bmp,pk->kmb", R, E0, optimize=True)
        return [Term(t.group, t.lamp_id, t.key + ("indirect",), t.spectrum_1nm, None, ind[k],
                     "indirect") for k, t in enumerate(terms)]


#: the largest share of the patches whose reflectance may differ from an already factored band
#: class for :class:`_LowRankSolver` to take its place.  On 1305 patches (the SpectraLight; one
#: thread, 40 right-hand sides) an update's later steps took 12, 25, 36 and 53 ms at a share of
#: 0.3, 0.5, 0.75 and 0.9 against 80 to 105 ms for a new LU, its first step 1.2 to 2.3 times a new
#: LU (its k solves): a refit's tens of steps gain up to 0.75 (the SpectraLight's ceiling and its
#: cavity's: 0.51 of the patches)
LOW_RANK_MAX_FRACTION = 0.75
#: factored band classes kept as starting points of low-rank updates (besides the solver store)
LOW_RANK_BASES = 16
#: point sets whose lines across the plate are kept (:meth:`RadiosityTransport._plate_lines`)
PLATE_LINE_SETS = 16
#: base solutions kept per factorisation (:meth:`_LUSolver.solve_kept`): each step of a fit moving
#: a surface's reflectance asks the base for the same receivers' solution again (the SpectraLight's
#: ceiling refit, 11 band classes: 144 solves of 56 right-hand sides; the refit 6.5 → 5.8 s)
KEPT_SOLVES = 4


class _LUSolver:
    """:math:`A = I - \\mathrm{diag}(r) F` by its LU factors."""

    def __init__(self, lu, r):
        self.lu, self.r = lu, np.asarray(r, float)
        #: patch sets S → {"F_S": rows S of F, "P": A⁻¹ E_S, "Q": A⁻ᵀ F_Sᵀ, "FSP": F_S A⁻¹ E_S},
        #: for :class:`_LowRankSolver` (each made once, when first needed)
        self._updates = {}
        #: (trans, right-hand sides' content) → solution, for :meth:`solve_kept`
        self._kept: dict = {}

    def solve(self, b, trans: int = 0):
        from scipy.linalg import lu_solve

        return lu_solve(self.lu, b, trans=trans)

    def solve_kept(self, b, trans: int = 0):
        """:meth:`solve`, the last :data:`KEPT_SOLVES` solutions kept by the right-hand sides'
        content: every update of these factors (:class:`_LowRankSolver`: a fit's steps moving a
        surface's reflectance) starts from the base's solution for the same receivers."""
        from lbscene.engine.files.disk_cache import array_key

        k = (trans, array_key(b))
        hit = self._kept.get(k)
        if hit is None:
            if len(self._kept) >= KEPT_SOLVES:
                self._kept.pop(next(iter(self._kept)))
            hit = self._kept[k] = self.solve(b, trans=trans)
            hit.flags.writeable = False
        else:
            self._kept[k] = self._kept.pop(k)                # the least recently used go first
        return hit


class _LowRankSolver:
    """:math:`A' = I - \\mathrm{diag}(r') F` from the factors of :math:`A = I - \\mathrm{diag}(r) F`
    (``base``, a :class:`_LUSolver`) where :math:`r'` differs from :math:`r` on the patches
    :math:`S` only (:math:`k = |S|`, :math:`d = r'_S - r_S`): :math:`A' = A - E_S D F_S` with
    :math:`E_S` the identity's columns :math:`S`, :math:`D = \\mathrm{diag}(d)`, :math:`F_S` the
    rows :math:`S` of :math:`F`.  By the Woodbury identity

    .. math::

        A'^{-1} b = y + P (I_k - D F_S P)^{-1} D F_S y, \\quad y = A^{-1} b,\\ P = A^{-1} E_S,

        A'^{-T} b = y + Q (I_k - D Q_S)^{-1} D y_S, \\quad y = A^{-T} b,\\ Q = A^{-T} F_S^T,

    with :math:`Q_S` the rows :math:`S` of :math:`Q`.  :math:`F_S`, :math:`P`, :math:`Q` and
    :math:`F_S P` depend on :math:`S` only (kept with the base; ``form_factors``, a callable
    returning :math:`F`, is called only for a patch set the base has not kept): a fit that moves
    one surface's reflectance pays
    :math:`k` solves once, then a :math:`k \\times k` system per step, instead of a new LU of
    the :math:`n \\times n` matrix each time (the SpectraLight's ceiling: 25 factorisations per
    refit)."""

    def __init__(self, base: _LUSolver, r, form_factors):
        self.base = base
        self.r = np.asarray(r, float)
        S = np.nonzero(self.r != base.r)[0]
        self.S = S
        self.d = (self.r - base.r)[S]
        self._skey = S.tobytes()
        upd = base._updates.setdefault(self._skey, {})
        if "F_S" not in upd:              # a new patch set: its rows of the form factors
            upd["F_S"] = np.ascontiguousarray(np.asarray(form_factors())[S])
        self._upd = upd
        self.F_S = upd["F_S"]
        self._small = {}

    def _PQ(self, trans: int):
        name = "Q" if trans else "P"
        if name not in self._upd:
            if trans:
                self._upd["Q"] = self.base.solve(self.F_S.T, trans=1)          # (n, k)
            else:
                E = np.zeros((len(self.base.r), self.S.size))
                E[self.S, np.arange(self.S.size)] = 1.0
                self._upd["P"] = self.base.solve(E)                            # (n, k)
        return self._upd[name]

    def solve(self, b, trans: int = 0):
        from scipy.linalg import lu_factor, lu_solve

        y = self.base.solve_kept(b, trans=trans)
        if not self.S.size:
            return y.copy()
        W = self._PQ(trans)
        if trans not in self._small:
            k = self.S.size
            if trans:
                K = W[self.S]
            else:
                # F_S A⁻¹ E_S depends on the patch set only: kept with the base (k² n once)
                if "FSP" not in self._upd:
                    self._upd["FSP"] = self.F_S @ W
                K = self._upd["FSP"]
            self._small[trans] = lu_factor(np.eye(k) - self.d[:, None] * K)
        v = y[self.S] if trans else self.F_S @ y
        rhs = (self.d[:, None] if v.ndim == 2 else self.d) * v
        return y + W @ lu_solve(self._small[trans], rhs)
