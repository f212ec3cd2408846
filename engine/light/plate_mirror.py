"""
The diffuser plate as a mirror in the inter-reflection: image form factors.

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

A plate that reflected its surfaces' light diffusely instead (its faces as Lambertian patches of
reflectance :math:`R_h`) sent the light a glass plate reflects at grazing incidence, which goes on
toward the cavity's walls, up to the ceiling above it: receivers under the ceiling of the
validation scene ``glass-cavity-45``'s cavity got 70 % too much of the ceiling's light back from
the plate against Mitsuba 3, and the booth below 2 % too much light.
"""

from __future__ import annotations

import numpy as np

from .geometry import (Patches, bodies_block, pairs_near_bodies, polygon_form_factor, polygon_form_factor_pairs,
                       quad_centroids, quad_r2_points, quad_subpoints, segments_blocked)

__all__ = ["plate_faces_mm", "plate_geometry_key", "image_polys", "patch_image_factors", "receiver_image_factors",
           "IMAGE_PAIR_POINTS", "IMAGE_GATHER_POINTS"]

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


def _mirrored(q: np.ndarray, z_mm: float) -> np.ndarray:
    """Points ``q`` (..., 3) mirrored across the plane ``z = z_mm``."""
    out = np.array(q, float, copy=True)
    out[..., 2] = 2.0 * z_mm - out[..., 2]
    return out


def image_polys(polys: np.ndarray, normals: np.ndarray, z_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Quads ``polys`` (P, 4, 3) and their normals mirrored across the plane ``z = z_mm``."""
    ip = _mirrored(polys, z_mm)
    n = np.array(normals, float, copy=True)
    n[..., 2] = -n[..., 2]
    return ip, n


def _on_plate(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.all((p[..., :2] >= lo) & (p[..., :2] <= hi), axis=-1)


def _plate_bounds(ir) -> tuple[np.ndarray, np.ndarray]:
    d = ir.diffuser
    c = np.asarray(d.centre_mm, float)
    h = np.asarray(d.size_mm, float) / 2
    return c - h, c + h


def _cross_plane(a: np.ndarray, b: np.ndarray, z_mm: float) -> np.ndarray:
    """Where the segments ``a → b`` (on either side of ``z = z_mm``) cross that plane."""
    den = b[..., 2] - a[..., 2]
    t = np.where(np.abs(den) > 1e-12, (z_mm - a[..., 2]) / np.where(np.abs(den) > 1e-12, den, 1.0), 0.5)
    return a + t[..., None] * (b - a)


def _legs_clear(a: np.ndarray, b_real: np.ndarray, p: np.ndarray, bodies, tris) -> np.ndarray:
    """Bool per path ``a → p → b_real``: no body and no mesh triangle crosses either leg."""
    ok = np.ones(len(a), bool)
    if bodies:
        ok &= ~bodies_block(a, p, bodies)
        live = np.nonzero(ok)[0]
        ok[live] &= ~bodies_block(p[live], b_real[live], bodies)
    if tris is not None and len(tris):
        live = np.nonzero(ok)[0]
        ok[live] &= ~segments_blocked(a[live], p[live], tris)
        live = np.nonzero(ok)[0]
        ok[live] &= ~segments_blocked(p[live], b_real[live], tris)
    return ok


def _uncertain(ca, r_a, cb_img, r_b, z_mm, lo, hi, bodies, tris):
    """Bool per pair (receiving point/patch ``ca`` of radius ``r_a``, image centre ``cb_img`` of
    radius ``r_b``): may its lines meet the plate's edge, a body or a mesh (then sampled), or is
    the centre line's verdict the whole pair's?"""
    p = _cross_plane(ca, cb_img, z_mm)
    m = np.maximum(r_a, r_b)
    inner = np.all((p[:, :2] >= lo + m[:, None]) & (p[:, :2] <= hi - m[:, None]), axis=1)
    outer = np.all((p[:, :2] >= lo - m[:, None]) & (p[:, :2] <= hi + m[:, None]), axis=1)
    unc = outer & ~inner
    if tris is not None and len(tris):
        return unc | outer
    if bodies:
        cb = _mirrored(cb_img, z_mm)
        for near in pairs_near_bodies(bodies, ca, p, r_a, m):
            unc[near] = True
        for near in pairs_near_bodies(bodies, p, cb, m, r_b):
            unc[near] = True
    return unc & outer


def _visible_share(A, W, B_img, z_mm, lo, hi, bodies, tris):
    """Weighted share (per pair) of matched lines ``A[k, s] → B_img[k, s]`` (weights ``W[k, s]``)
    that meet the face plane on the plate with both legs clear."""
    k, s = A.shape[:2]
    a = A.reshape(-1, 3)
    b = B_img.reshape(-1, 3)
    p = _cross_plane(a, b, z_mm)
    ok = _on_plate(p, lo, hi)
    real = _mirrored(b, z_mm)
    live = np.nonzero(ok)[0]
    if live.size:
        ok[live] = _legs_clear(a[live], real[live], p[live], bodies, tris)
    return (ok.reshape(k, s) * W).sum(axis=1)


def patch_image_factors(patches: Patches, ir, bodies=(), tris=None) -> tuple[np.ndarray, np.ndarray]:
    """``(F, cos)`` (P, P): the form factor from patch ``i`` to patch ``j``'s image in the plate's
    face on their side, times the visible share :math:`V_{ij'}`, and the cosine of the centre
    line's angle with the plate's normal (for :math:`R(θ)`); 0 for pairs on different sides.
    ``bodies``: ``[body]`` that block light (:func:`lbscene.engine.light.radiosity.transport_bodies`);
    ``tris``: mesh triangles."""
    bodies = list(bodies)
    polys, nrm = patches.polys, patches.normals
    c = patches.centres
    n = len(c)
    F = np.zeros((n, n))
    C = np.zeros((n, n))
    lo, hi = _plate_bounds(ir)
    diag = np.linalg.norm(polys[:, 2] - polys[:, 0], axis=1)
    hd = 0.5 * diag
    for z, sign in plate_faces_mm(ir):
        side = np.nonzero(sign * (c[:, 2] - z) > _NUDGE_MM)[0]
        if not side.size:
            continue
        ip, inrm = image_polys(polys[side], nrm[side], z)
        ic = quad_centroids(ip)
        f = polygon_form_factor(c[side] + _NUDGE_MM * nrm[side], nrm[side], ip, inrm)      # (S, S)
        ii, jj = np.nonzero(f > 0)
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
            f[a, b] = (fp.reshape(-1, 4) * w[a]).sum(axis=1)
        vals = f[ii, jj]
        # the share of each pair's lines that meet the plate with both legs clear
        p = _cross_plane(c[side][ii], ic[jj], z)
        V = _on_plate(p, lo, hi).astype(float)
        unc = _uncertain(c[side][ii], hd[side][ii], ic[jj], hd[side][jj], z, lo, hi, bodies, tris)
        if unc.any():
            k = np.nonzero(unc)[0]
            m = IMAGE_PAIR_POINTS
            pa, wa = quad_r2_points(polys[side][ii[k]], m)
            pb = quad_r2_points(ip[jj[k]], m)[0][:, ::-1]
            pa = pa + _NUDGE_MM * nrm[side][ii[k]][:, None, :]
            pb = pb + _NUDGE_MM * inrm[jj[k]][:, None, :]
            V[k] = _visible_share(pa, wa, pb, z, lo, hi, bodies, tris)
        d = c[side][ii] - ic[jj]
        F[side[ii], side[jj]] = vals * V
        C[side[ii], side[jj]] = np.abs(d[:, 2]) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    return F, C


def receiver_image_factors(patches: Patches, ir, P, N, gather, bodies=(), tris=None
                           ) -> tuple[np.ndarray, np.ndarray]:
    """``(G, cos)`` (M, P): receivers ``P`` (normals ``N``) gathering patch ``j``'s image in the
    plate's face on their side — ``gather(image_polys, image_normals, rows)`` the form factors
    from receivers ``rows`` (the model's, with its meter response) times the share of the image the receiver sees
    on the plate past the bodies and meshes (:data:`IMAGE_GATHER_POINTS` points where it may be
    cut) — and the cosine of the line to the image's centre with the plate's normal."""
    bodies = list(bodies)
    P = np.asarray(P, float)
    N = np.asarray(N, float)
    polys, nrm = patches.polys, patches.normals
    c = patches.centres
    G = np.zeros((len(P), len(c)))
    C = np.zeros((len(P), len(c)))
    lo, hi = _plate_bounds(ir)
    hd = 0.5 * np.linalg.norm(polys[:, 2] - polys[:, 0], axis=1)
    for z, sign in plate_faces_mm(ir):
        side = np.nonzero(sign * (c[:, 2] - z) > _NUDGE_MM)[0]
        rx = np.nonzero(sign * (P[:, 2] - z) > _NUDGE_MM)[0]
        if not side.size or not rx.size:
            continue
        ip, inrm = image_polys(polys[side], nrm[side], z)
        ic = quad_centroids(ip)
        g = gather(ip, inrm, rx)                                             # (R, S)
        ii, jj = np.nonzero(g > 0)
        if not ii.size:
            continue
        p = _cross_plane(P[rx][ii], ic[jj], z)
        V = _on_plate(p, lo, hi).astype(float)
        unc = _uncertain(P[rx][ii], np.zeros(ii.size), ic[jj], hd[side][jj], z, lo, hi, bodies, tris)
        if unc.any():
            k = np.nonzero(unc)[0]
            m = IMAGE_GATHER_POINTS
            pb, wb = quad_r2_points(ip[jj[k]], m)
            pb = pb + _NUDGE_MM * inrm[jj[k]][:, None, :]
            pa = np.broadcast_to(P[rx][ii[k]][:, None, :], pb.shape)
            V[k] = _visible_share(pa, wb, pb, z, lo, hi, bodies, tris)
        d = P[rx][ii] - ic[jj]
        G[rx[ii], side[jj]] = g[ii, jj] * V
        C[rx[ii], side[jj]] = np.abs(d[:, 2]) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    return G, C
