"""
The diffuser plate and the lamps' mirrors in the inter-reflection: image form factors.

A clear or rough plate (``plate_reflection: specular``, see
:func:`lbscene.engine.light.plates.specular_plate`) reflects the light that reaches its faces
specularly, with its directional reflectance :math:`R(θ)`
(:func:`lbscene.engine.light.plates.plate_reflectance`): the Fresnel law of both faces, the
rough slab's :math:`R_\\text{top}(μ) + a^2 R_\\text{int}(μ)`.  The lamps' light does so through
their mirror images (the diffuser effect's ``extra_emitters``); the light of the booth's
surfaces does so here.  Light leaving patch :math:`j` that a face of the plate reflects reaches
patch :math:`i` (on the same side) as if it came from :math:`j`'s image :math:`j'` in the face's
plane, so the inter-reflection gains an image term (Wallace, Cohen and Greenberg 1987, "A two-pass
solution to the rendering equation"; Sillion and Puech 1989, "A general two-pass method
integrating specular and diffuse reflection")

.. math:: B_i = ρ_i \\Bigl(E^0_i + \\sum_j \\bigl(F_{ij} + R(θ_{ij'})\\,F_{ij'}\\,V_{ij'}\\bigr) B_j\\Bigr),

with :math:`F_{ij'}` the exact polygon form factor from :math:`i` to the image polygon,
:math:`θ_{ij'}` the angle between the plate's normal and the line from :math:`i` to the image's
centre, and :math:`V_{ij'}` the share of the lines between the two (matched low-discrepancy
points) that meet the face inside the plate's rectangle and whose two legs, patch to plate and
plate to patch, no body (lamp, occluder) or mesh crosses.  A patch sees its own image (a
luminaire ceiling over the plate: :math:`i = j`).  Receivers gather the images the same way.

The same holds for any one-sided plane mirror (:func:`face_image_factors`,
:func:`face_receiver_factors`: a rectangle reflecting to the side its normal points to): the
plate's two faces (:func:`plate_face_rects`) and the lamps' mirrors, whose reflectance
:math:`R(λ)` does not depend on the angle.  Only the pairs whose centre line meets the face
grown by the larger patch's half diagonal can see each other in it, so the form factors are
computed for those alone (a mirror strip in a room: a few per cent of the pairs).

A plate that reflected its surfaces' light diffusely instead (its faces as Lambertian patches of
reflectance :math:`R_h`) sent the light a glass plate reflects at grazing incidence, which goes on
toward the cavity's walls, up to the ceiling above it: receivers under the ceiling of the
validation scene ``glass-cavity-45``'s cavity got 70 % too much of the ceiling's light back from
the plate against Mitsuba 3, and the booth below 2 % too much light.
"""

from __future__ import annotations

import numpy as np

from .geometry import (Patches, bodies_block, mirror_points, pairs_near_bodies, polygon_form_factor_pairs,
                       quad_centroids, quad_r2_points, quad_subpoints, segments_blocked)

__all__ = ["plate_faces_mm", "plate_face_rects", "plate_geometry_key", "face_image_factors",
           "face_receiver_factors", "patch_image_factors", "receiver_image_factors", "IMAGE_PAIR_POINTS",
           "IMAGE_GATHER_POINTS"]

#: matched point pairs per (patch, image) pair whose view may be cut by a body, a mesh or the
#: plate's edge
IMAGE_PAIR_POINTS = 8
#: points of an image a receiver's view of it is sampled at where it may be cut
IMAGE_GATHER_POINTS = 36
#: pairs closer than this many patch diagonals are averaged over 2 × 2 points of the receiving patch
IMAGE_NEAR_FACTOR = 3.0
#: points are kept this far (mm) off their surface and off the face's plane
_NUDGE_MM = 1e-3


def plate_faces_mm(ir) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((z_top, +1), (z_bottom, −1))``: the plate's two faces and the side each reflects to."""
    d = ir.diffuser
    return ((float(d.z_mm + d.thickness_mm / 2), 1.0), (float(d.z_mm - d.thickness_mm / 2), -1.0))


def plate_geometry_key(ir) -> np.ndarray:
    """What the images depend on of the plate, as one array (a cache key): its height, thickness,
    centre and size (mm)."""
    d = ir.diffuser
    return np.array([d.z_mm, d.thickness_mm, *d.centre_mm, *d.size_mm], float)


def plate_face_rects(ir) -> list:
    """The plate's two faces as one-sided mirrors (:class:`~lbscene.engine.light.geometry.Rectangle`
    whose normal points to the side it reflects to): the top face up, the bottom face down."""
    from .geometry import Rectangle

    d = ir.diffuser
    cx, cy = (float(v) for v in d.centre_mm)
    half = (float(d.size_mm[0]) / 2, float(d.size_mm[1]) / 2)
    return [Rectangle(np.array([cx, cy, z]), np.array([0.0, 0.0, sign]), np.array([1.0, 0.0, 0.0]), half)
            for z, sign in plate_faces_mm(ir)]


def _face_image(polys: np.ndarray, normals: np.ndarray, face) -> tuple[np.ndarray, np.ndarray]:
    """Quads ``polys`` (P, 4, 3) and their normals mirrored across the plane of ``face``."""
    n = np.asarray(face.normal, float)
    ip = mirror_points(polys, face.centre, n)
    nn = np.asarray(normals, float)
    return ip, nn - 2.0 * (nn @ n)[..., None] * n


def _cross_face(a: np.ndarray, b: np.ndarray, face) -> np.ndarray:
    """Where the segments ``a → b`` (on either side of the face's plane) cross that plane."""
    n = np.asarray(face.normal, float)
    den = (b - a) @ n
    ok = np.abs(den) > 1e-12
    t = np.where(ok, ((np.asarray(face.centre, float) - a) @ n) / np.where(ok, den, 1.0), 0.5)
    return a + t[..., None] * (b - a)


def _local(p: np.ndarray, face) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of points ``p`` (on the face's plane) along the face's ``u`` and ``v``."""
    q = p - np.asarray(face.centre, float)
    return q @ np.asarray(face.u, float), q @ np.asarray(face.v, float)


def _on_face(p: np.ndarray, face, margin=0.0) -> np.ndarray:
    """Bool per point ``p`` (on the face's plane): inside the face grown by ``margin``."""
    x, y = _local(p, face)
    return (np.abs(x) <= face.half[0] + margin) & (np.abs(y) <= face.half[1] + margin)


def _legs_clear(a: np.ndarray, b_real: np.ndarray, p: np.ndarray, bodies, tris, near=None) -> np.ndarray:
    """Bool per path ``a → p → b_real``: no body and no mesh triangle crosses either leg.
    ``near``: ``(near_a, near_b)``, per body a bool per path, False where that body certainly
    misses the leg ``a → p`` (``near_a``) or ``p → b_real`` (``near_b``): only the others are tested."""
    ok = np.ones(len(a), bool)
    if bodies and near is None:
        ok &= ~bodies_block(a, p, bodies)
        live = np.nonzero(ok)[0]
        ok[live] &= ~bodies_block(p[live], b_real[live], bodies)
    elif bodies:
        for start, end, masks in ((a, p, near[0]), (p, b_real, near[1])):
            for body, m in zip(bodies, masks):
                live = np.nonzero(ok & m)[0]
                if live.size:
                    ok[live] &= ~bodies_block(start[live], end[live], [body])
    if tris is not None and len(tris):
        live = np.nonzero(ok)[0]
        ok[live] &= ~segments_blocked(a[live], p[live], tris)
        live = np.nonzero(ok)[0]
        ok[live] &= ~segments_blocked(p[live], b_real[live], tris)
    return ok


def _uncertain(ca, r_a, cb_img, r_b, face, bodies, tris):
    """``(uncertain, near)``: bool per pair (receiving point/patch ``ca`` of radius ``r_a``, image
    centre ``cb_img`` of radius ``r_b``): may its lines meet the face's edge, a body or a mesh
    (then sampled), or is the centre line's verdict the whole pair's?  ``near``: ``(near_a,
    near_b)``, per body a bool per pair, False where no line of the pair can meet that body on
    its leg to the face or from the face (None with meshes: every body is tested)."""
    p = _cross_face(ca, cb_img, face)
    m = np.maximum(r_a, r_b)
    inner = _on_face(p, face, -m)
    outer = _on_face(p, face, m)
    unc = outer & ~inner
    if tris is not None and len(tris):
        return unc | outer, None
    near = None
    if bodies:
        cb = mirror_points(cb_img, face.centre, face.normal)
        near = ([], [])
        for legs, hits in ((near[0], pairs_near_bodies(bodies, ca, p, r_a, m)),
                           (near[1], pairs_near_bodies(bodies, p, cb, m, r_b))):
            for idx in hits:
                unc[idx] = True
                mask = np.zeros(len(p), bool)
                mask[idx] = True
                legs.append(mask)
    return unc & outer, near


def _visible_share(A, W, B_img, face, bodies, tris, near=None):
    """Weighted share (per pair) of matched lines ``A[k, s] → B_img[k, s]`` (weights ``W[k, s]``)
    that meet the face's plane on the face with both legs clear (``near``: per body and leg, the
    pairs whose lines may meet it, :func:`_uncertain`)."""
    k, s = A.shape[:2]
    a = A.reshape(-1, 3)
    b = B_img.reshape(-1, 3)
    p = _cross_face(a, b, face)
    ok = _on_face(p, face)
    real = mirror_points(b, face.centre, face.normal)
    live = np.nonzero(ok)[0]
    if live.size:
        pair = live // s                    # the pair of each line that meets the face
        lines = None if near is None else tuple([m[pair] for m in leg] for leg in near)
        ok[live] = _legs_clear(a[live], real[live], p[live], bodies, tris, lines)
    return (ok.reshape(k, s) * W).sum(axis=1)


def _candidates(ca: np.ndarray, r_a: np.ndarray, ic: np.ndarray, r_b: np.ndarray, face,
                chunk: int = 1 << 22) -> tuple[np.ndarray, np.ndarray]:
    """``(ii, jj)``: the pairs (point or patch ``ca[i]`` of radius ``r_a[i]``, image centre
    ``ic[j]`` of radius ``r_b[j]``) whose centre line crosses the face's plane within the face
    grown by the larger radius; no other pair's lines can meet the face."""
    out_i, out_j = [], []
    step = max(1, chunk // max(len(ic), 1))
    for s0 in range(0, len(ca), step):
        a = ca[s0:s0 + step]
        p = _cross_face(a[:, None, :], ic[None, :, :], face)
        m = np.maximum(r_a[s0:s0 + step, None], r_b[None, :])
        ii, jj = np.nonzero(_on_face(p, face, m))
        out_i.append(ii + s0)
        out_j.append(jj)
    if not out_i:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(out_i), np.concatenate(out_j)


def face_image_factors(patches: Patches, faces, bodies=(), tris=None) -> tuple[np.ndarray, np.ndarray]:
    """``(F, cos)`` (P, P): the form factor from patch ``i`` to patch ``j``'s images in the
    one-sided mirrors ``faces`` (rectangles reflecting to the side their normal points to),
    each times its visible share :math:`V_{ij'}`, summed over the faces, and the cosine of the
    centre line's angle with the (last) face's normal (for an angle-dependent reflectance).
    ``bodies``: ``[body]`` that block light
    (:func:`lbscene.engine.light.radiosity.transport_bodies`); ``tris``: mesh triangles."""
    bodies = list(bodies)
    polys, nrm = patches.polys, patches.normals
    c = patches.centres
    n = len(c)
    F = np.zeros((n, n))
    C = np.zeros((n, n))
    diag = np.linalg.norm(polys[:, 2] - polys[:, 0], axis=1)
    hd = 0.5 * diag
    for face in faces:
        fn = np.asarray(face.normal, float)
        side = np.nonzero((c - np.asarray(face.centre, float)) @ fn > _NUDGE_MM)[0]
        if not side.size:
            continue
        ip, inrm = _face_image(polys[side], nrm[side], face)
        ic = quad_centroids(ip)
        ii, jj = _candidates(c[side], hd[side], ic, hd[side], face)
        if not ii.size:
            continue
        vals = polygon_form_factor_pairs(c[side][ii] + _NUDGE_MM * nrm[side][ii], nrm[side][ii], ip[jj])
        keep = vals > 0
        ii, jj, vals = ii[keep], jj[keep], vals[keep]
        if not ii.size:
            continue
        # near pairs: the receiving patch averaged over 2 × 2 points
        dist = np.linalg.norm(c[side][ii] - ic[jj], axis=1)
        near = dist < IMAGE_NEAR_FACTOR * np.maximum(diag[side][ii], diag[side][jj])
        if near.any():
            pts, w = quad_subpoints(polys[side], 2)
            a, b = ii[near], jj[near]
            fp = polygon_form_factor_pairs(pts[a].reshape(-1, 3) + _NUDGE_MM * np.repeat(nrm[side][a], 4, axis=0),
                                           np.repeat(nrm[side][a], 4, axis=0), np.repeat(ip[b], 4, axis=0))
            vals[near] = (fp.reshape(-1, 4) * w[a]).sum(axis=1)
        # the share of each pair's lines that meet the face with both legs clear
        V = _on_face(_cross_face(c[side][ii], ic[jj], face), face).astype(float)
        unc, near = _uncertain(c[side][ii], hd[side][ii], ic[jj], hd[side][jj], face, bodies, tris)
        if unc.any():
            k = np.nonzero(unc)[0]
            m = IMAGE_PAIR_POINTS
            # each patch's points and each image's once (a patch is in many pairs)
            pts_a, w_a = quad_r2_points(polys[side], m)
            pts_b = quad_r2_points(ip, m)[0]
            pa = pts_a[ii[k]] + _NUDGE_MM * nrm[side][ii[k]][:, None, :]
            pb = pts_b[jj[k]][:, ::-1] + _NUDGE_MM * inrm[jj[k]][:, None, :]
            sub = None if near is None else tuple([msk[k] for msk in leg] for leg in near)
            V[k] = _visible_share(pa, w_a[ii[k]], pb, face, bodies, tris, sub)
        d = c[side][ii] - ic[jj]
        np.add.at(F, (side[ii], side[jj]), vals * V)
        C[side[ii], side[jj]] = np.abs(d @ fn) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    return F, C


def face_receiver_factors(patches: Patches, faces, P, N, gather, bodies=(), tris=None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """``(G, cos)`` (M, P): receivers ``P`` (normals ``N``) gathering patch ``j``'s images in the
    one-sided mirrors ``faces``, summed over the faces — ``gather(image_polys, image_normals,
    rows)`` the form factors from receivers ``rows`` (the model's, with its meter response) times
    the share of the image the receiver sees on the face past the bodies and meshes
    (:data:`IMAGE_GATHER_POINTS` points where it may be cut) — and the cosine of the line to the
    image's centre with the (last) face's normal."""
    bodies = list(bodies)
    P = np.asarray(P, float)
    N = np.asarray(N, float)
    polys, nrm = patches.polys, patches.normals
    c = patches.centres
    G = np.zeros((len(P), len(c)))
    C = np.zeros((len(P), len(c)))
    hd = 0.5 * np.linalg.norm(polys[:, 2] - polys[:, 0], axis=1)
    for face in faces:
        fc, fn = np.asarray(face.centre, float), np.asarray(face.normal, float)
        side = np.nonzero((c - fc) @ fn > _NUDGE_MM)[0]
        rx = np.nonzero((P - fc) @ fn > _NUDGE_MM)[0]
        if not side.size or not rx.size:
            continue
        ip, inrm = _face_image(polys[side], nrm[side], face)
        ic = quad_centroids(ip)
        # only the images some receiver's line to them can see on the face
        _, cols = _candidates(P[rx], np.zeros(rx.size), ic, hd[side], face)
        cols = np.unique(cols)
        if not cols.size:
            continue
        g = gather(ip[cols], inrm[cols], rx)                                 # (R, S')
        ii, jc = np.nonzero(g > 0)
        if not ii.size:
            continue
        jj = cols[jc]
        V = _on_face(_cross_face(P[rx][ii], ic[jj], face), face).astype(float)
        unc, near = _uncertain(P[rx][ii], np.zeros(ii.size), ic[jj], hd[side][jj], face, bodies, tris)
        if unc.any():
            k = np.nonzero(unc)[0]
            m = IMAGE_GATHER_POINTS
            pts_b, w_b = quad_r2_points(ip, m)              # each image's points once
            pb = pts_b[jj[k]] + _NUDGE_MM * inrm[jj[k]][:, None, :]
            pa = np.broadcast_to(P[rx][ii[k]][:, None, :], pb.shape)
            sub = None if near is None else tuple([msk[k] for msk in leg] for leg in near)
            V[k] = _visible_share(pa, w_b[jj[k]], pb, face, bodies, tris, sub)
        d = P[rx][ii] - ic[jj]
        np.add.at(G, (rx[ii], side[jj]), g[ii, jc] * V)
        C[rx[ii], side[jj]] = np.abs(d @ fn) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    return G, C


def patch_image_factors(patches: Patches, ir, bodies=(), tris=None) -> tuple[np.ndarray, np.ndarray]:
    """``(F, cos)`` (P, P): the form factor from patch ``i`` to patch ``j``'s image in the plate's
    face on their side, times the visible share :math:`V_{ij'}`, and the cosine of the centre
    line's angle with the plate's normal (for :math:`R(θ)`); 0 for pairs on different sides
    (:func:`face_image_factors` on :func:`plate_face_rects`)."""
    return face_image_factors(patches, plate_face_rects(ir), bodies, tris)


def receiver_image_factors(patches: Patches, ir, P, N, gather, bodies=(), tris=None
                           ) -> tuple[np.ndarray, np.ndarray]:
    """``(G, cos)`` (M, P): receivers ``P`` (normals ``N``) gathering patch ``j``'s image in the
    plate's face on their side (:func:`face_receiver_factors` on :func:`plate_face_rects`)."""
    return face_receiver_factors(patches, plate_face_rects(ir), P, N, gather, bodies, tris)
