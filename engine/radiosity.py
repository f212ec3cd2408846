"""
Inter-reflection between the booth's interior surfaces (the ``interreflection`` effect).

Classic radiosity on the IR's surfaces (floor, walls, ceiling, platform),
cut into patches of about ``patch_size_mm``:

    B_i(λ) = ρ_i(λ) · (E0_i(λ) + Σ_j F_ij B_j(λ))

``E0`` is first-order light (lamps, with every enabled effect, plus diffuse
re-emitters) averaged over each patch; ``F_ij`` the form factor from patch
``i`` (averaged over 2×2 points of it) to polygon ``j`` (exact contour
integral); the system is solved per band (LU factors are cached for the
reflectance set).  A receiver then gets ``Σ_j F(x ← j)·B_j`` — exact
polygon form factors again, clipped to the receiver's hemisphere, so
vertical receivers near walls are right.

The transfer from a source spectrum to indirect light depends only on the
(smooth) surface reflectances, so it is solved at the band centres and
interpolated to 1 nm, where it multiplies the lamps' 1 nm spectra.

Visibility between patches is not tested: exact for the convex box
interior; meshes inside the booth (``role: mesh``) are left out.
"""

from __future__ import annotations

import numpy as np

from .forward_geometry import Patches, mesh_patches, polygon_form_factor, quad_subpoints

__all__ = ["RadiosityTransport", "radiosity_transport", "patch_form_factors"]


def patch_form_factors(patches: Patches, sub: int = 2, near_factor: float = 3.0) -> np.ndarray:
    """(P, P) form factors F[i, j] from patch i to polygon j.

    Exact point-to-polygon form factors from the centre of patch i; pairs
    closer than ``near_factor`` patch diagonals (where the centre is not
    representative of the patch) are averaged over ``sub × sub`` points.
    """
    from .forward_geometry import polygon_form_factor_pairs

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
    return F


def radiosity_transport(ctx, p, model) -> "RadiosityTransport":
    return RadiosityTransport(ctx, p, model)


class RadiosityTransport:
    """Radiosity solution for one forward model (one parameter set)."""

    def __init__(self, ctx, p, model):
        self.ctx, self.p, self.model = ctx, p, model
        ir = ctx.ir
        key = ("patches", p.patch_size_mm)
        if key not in ctx.cache:
            patches = mesh_patches(ir, p.patch_size_mm)
            ctx.cache[key] = (patches, patch_form_factors(patches))
        self.patches, self.F = ctx.cache[key]
        mats = ir.materials
        rho = np.array([mats[m].reflectance.array_bands for m in self.patches.material]).reshape(
            len(self.patches), -1)
        self.rho = np.clip(rho * p.reflectance_scale, 0.0, 0.99)          # (P, B)
        # a diffuser plate between surfaces (the luminaire cavity above it, the booth below)
        # transmits inter-reflected light with its regular transmittance
        self.plate_T = None
        self.cross_pp = None
        if "diffuser" in ctx.effects and ir.diffuser is not None:
            from .effects.catalog import DiffuserEffect, _diffuser_rect
            from .forward_geometry import segment_hits_rectangle

            dp = ctx.params("diffuser")
            self.plate_rect = _diffuser_rect(ir)
            self.plate_T = ir.grid.integrate(DiffuserEffect._spectrum(ctx, dp))       # (B,)
            ck = ("plate_cross", p.patch_size_mm)
            if ck not in ctx.cache:
                c = self.patches.centres
                ctx.cache[ck] = segment_hits_rectangle(c, c, self.plate_rect)
            self.cross_pp = ctx.cache[ck]
        self._B = None
        self._terms = None
        self._E0 = None

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
        near = dist < 1.5 * diag
        idx, pts_l, w_l, nrm_l = [], [], [], []
        for k, sel in ((1, ~near), (3, near)):
            if not sel.any():
                continue
            pts, w = quad_subpoints(patches.polys[sel], k)
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
        terms = self.model.first_order_terms(pts + 1e-3 * nrm, nrm, False)
        E0 = np.zeros((len(patches), len(terms)))
        for k, t in enumerate(terms):
            E0[:, k] = np.bincount(idx, weights=w * t.geo, minlength=len(patches))
        return terms, E0

    def _first_order(self):
        """First-order light on the patches, once per model (parameters fixed)."""
        if self._terms is None:
            self._terms, self._E0 = self._first_order_at_patches()
        return self._terms, self._E0

    def _band_classes(self):
        """Bands whose reflectances (and plate transmittance) coincide share one solve:
        ``(unique rows (U, P[+1]), band → row index (B,), cache key)``."""
        from .forward import array_key

        sig = self.rho.T if self.plate_T is None else np.c_[self.rho.T, self.plate_T]
        uniq, inv = np.unique(np.round(sig, 9), axis=0, return_inverse=True)
        return uniq, inv.ravel(), (self.p.patch_size_mm, self.p.max_bounces, array_key(uniq))

    def _neumann_terms(self, u) -> int | None:
        """Jacobi sweeps for a 1e-9 relative residual when the series converges fast, else None."""
        P = len(self.patches)
        r = u[:P]
        q = float(np.max(r * self.F.sum(axis=1)))        # bound on the spectral radius of ρF
        if self.p.max_bounces > 0:
            return self.p.max_bounces - 1
        if q >= 1:
            return None
        return int(np.ceil(np.log(1e-9) / np.log(max(q, 1e-12))))

    def _lu(self, key, j, u):
        from scipy.linalg import lu_factor

        store = self.ctx.cache.setdefault("_rad_lu", {})
        k = key + (j,)
        if k not in store:
            P = len(self.patches)
            r = u[:P]
            Fu = self._F_band(u[P] if u.size > P else None)
            if len(store) >= 64:
                store.pop(next(iter(store)))
            store[k] = lu_factor(np.eye(P) - r[:, None] * Fu)
        return store[k]

    def _solve(self):
        """Patch radiosity B (bands, patches, terms): for :meth:`patch_radiosity`."""
        if self._B is not None:
            return
        from scipy.linalg import lu_solve

        terms, E0 = self._first_order()
        uniq, inv, key = self._band_classes()
        P = len(self.patches)
        sol = []
        for j, u in enumerate(uniq):
            r = u[:P]
            n_it = self._neumann_terms(u)
            if n_it is not None and (self.p.max_bounces > 0 or n_it * E0.shape[1] < P / 3):
                Fu = self._F_band(u[P] if u.size > P else None)
                x = r[:, None] * E0
                acc = x.copy()
                for _ in range(n_it):
                    x = r[:, None] * (Fu @ x)
                    acc += x
                sol.append(acc)
            else:
                sol.append(lu_solve(self._lu(key, j, u), r[:, None] * E0))
        self._B = np.stack([sol[i] for i in inv])

    def _F_band(self, T):
        if T is None or self.cross_pp is None:
            return self.F
        return np.where(self.cross_pp, self.F * T, self.F)

    # ------------------------------------------------------------------ receivers
    def patch_radiosity(self) -> np.ndarray:
        """(B, P, K) radiosity per band, patch and first-order term (W·m⁻² per unit spectrum)."""
        self._solve()
        return self._B

    def _receiver_operators(self, G, P_rx) -> np.ndarray:
        """(B, M, P) operators R_b = G_b·(I − ρ_b F_b)⁻¹·diag(ρ_b): patch first-order light →
        inter-reflected light at the receivers.

        They depend on geometry, reflectances and the receivers only, not on the lamps or any
        lamp parameter, so a fit that varies intensities, σ, apertures… reuses them and each
        evaluation is a few small matrix products (the solve is done once, transposed, with
        the receivers as right-hand sides).
        """
        from scipy.linalg import lu_solve

        from .forward import array_key

        uniq, inv, key = self._band_classes()
        ck = key + (array_key(G, P_rx),)
        store = self.ctx.cache.setdefault("_rad_ops", {})
        hit = store.get(ck)
        if hit is not None:
            return hit
        Pn = len(self.patches)
        if self.plate_T is not None:
            from .forward_geometry import segment_hits_rectangle

            cross = segment_hits_rectangle(self.patches.centres, P_rx, self.plate_rect)   # (M, P)
        ops = []
        for j, u in enumerate(uniq):
            r = u[:Pn]
            Gj = G if self.plate_T is None else np.where(cross, G * u[Pn], G)
            n_it = self._neumann_terms(u)
            if n_it is not None and (self.p.max_bounces > 0 or n_it * len(G) < Pn / 3):
                A = r[:, None] * self._F_band(u[Pn] if u.size > Pn else None)
                y = Gj
                acc = y * r[None, :]
                for _ in range(n_it):
                    y = y @ A
                    acc += y * r[None, :]
                ops.append(acc)
            else:
                x = lu_solve(self._lu(key, j, u), Gj.T, trans=1)        # (I − ρF)⁻ᵀ Gᵀ
                ops.append((r[:, None] * x).T)
        out = np.stack([ops[i] for i in inv])
        if len(store) >= 32:
            store.pop(next(iter(store)))
        store[ck] = out
        return out

    def terms(self, P, N, meter):
        from .forward import Term

        terms, E0 = self._first_order()
        G = self.model.lambertian_gather(self.patches.polys, self.patches.normals, P, N, meter)
        R = self._receiver_operators(G, P)
        ind = np.einsum("bmp,pk->kmb", R, E0, optimize=True)
        return [Term(t.group, t.lamp_id, t.key + ("indirect",), t.spectrum_1nm, None, ind[k],
                     "indirect") for k, t in enumerate(terms)]
