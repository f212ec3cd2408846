"""
The model's texture metrics of a visual-test case: what the rendering of an effect coating shows
at one lighting and geometry, to set beside the panel's sparkle and graininess scores.

For the sample's centre, the booth's emitters (placed for the view) are integrated over their
extent (64 points along a tube, an 8 × 4 grid on a panel) as in the renderer
(``lib_coating.glsl``):

* ``glints_per_cm2``: expected glinting flakes per cm² of sample,
  :math:`ρ_A \\sum_{elements} p(\\mathbf h') dω_{h'}` (:mod:`~lbscene.engine.coatings.flakes`);
* ``glint_contrast``: the luminance one glint adds to a cell of the view (the renderer's flake
  cell, about one pixel of a 768-pixel-high view) over the coating's mean luminance under the
  lamps (the flop BRDF);
* ``grain_contrast_percent``: the relative standard deviation of the diffuse part per cell (the
  renderer's graininess);
* the instrument model's readings of the flakes (S_a, S_i at 15°, 45°, 75°; G), which do not
  depend on the booth.
"""

from __future__ import annotations

import numpy as np

__all__ = ["case_texture_metrics", "TEXTURE_COLUMNS"]

#: Columns of ``model-texture.csv`` (after lighting, geometry, sample).
TEXTURE_COLUMNS = ("glints_per_cm2", "glint_contrast", "grain_contrast_percent",
                   "S_a_15", "S_i_15", "S_a_45", "S_i_45", "S_a_75", "S_i_75", "G")

TUBE_POINTS = 64


def _elements(row: np.ndarray, P: np.ndarray):
    """(directions (k, 3), solid angles (k,), radiance per unit band intensity (scalar)) of one
    emitter row of the renderer's ``emitters`` texture (layout: runtimes/graph.py)."""
    c, kind = row[0, :3], int(round(row[0, 3]))
    ax, hl = row[1, :3], row[1, 3]
    aim, hw = row[2, :3], row[2, 3]
    wax = row[3, :3]
    prof = row[8:24].ravel()
    theta = np.arccos(np.clip(np.dot((P - c) / np.linalg.norm(P - c), aim), -1, 1))
    x = np.clip(theta / np.pi, 0, 1) * 63
    i = min(int(x), 62)
    f = prof[i] + (prof[i + 1] - prof[i]) * (x - i)
    if kind == 1:
        t = ((np.arange(TUBE_POINTS) + 0.5) / TUBE_POINTS * 2 - 1) * hl
        q = c + t[:, None] * ax
        d = q - P
        r = np.linalg.norm(d, axis=1)
        l = d / r[:, None]
        dom = 2 * hw * (2 * hl / TUBE_POINTS) * np.linalg.norm(np.cross(l, ax), axis=1) / r ** 2
        return l, dom, f / (4 * hl * hw * 1e-6)
    if kind == 2:
        u = ((np.arange(8) + 0.5) / 8 * 2 - 1) * hl
        v = ((np.arange(4) + 0.5) / 4 * 2 - 1) * hw
        U, W = np.meshgrid(u, v, indexing="ij")
        q = c + U.reshape(-1, 1) * ax + W.reshape(-1, 1) * wax
        d = q - P
        r = np.linalg.norm(d, axis=1)
        l = d / r[:, None]
        dom = np.clip(-(l @ aim), 0, None) * (4 * hl * hw / 32) / r ** 2
        return l, dom, f / (4 * hl * hw * 1e-6)
    d = c - P
    r = float(np.linalg.norm(d))
    return (d / r)[None], np.array([4 * hw * hw / r ** 2]), f / (4 * hw * hw * 1e-6)


def case_texture_metrics(appearance, emitters: np.ndarray, emitter_count: int, centre_mm, normal, eye_mm,
                         u_axis, xyz_weights: np.ndarray, cell_mm: float, grain_sigma: float,
                         visible_share: float) -> dict:
    """The metrics of the module docstring for one view (``emitters``: the view's ``emitters``
    texture, (rows, 24, 4); ``xyz_weights``: (bands, 3) of the view; ``cell_mm``,
    ``grain_sigma``, ``visible_share``: the renderer's values for the view)."""
    from .optics import fresnel_transmittance, half_vector, refract_into_coat

    fl, flop = appearance.flakes, appearance.flop
    nb = len(flop.diffuse)
    P = np.asarray(centre_mm, float)
    N = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.asarray(u_axis, float)
    u = (u - N * (u @ N)) / np.linalg.norm(u - N * (u @ N))
    frame = np.stack([u, np.cross(N, u), N])
    V = np.asarray(eye_mm, float) - P
    V /= np.linalg.norm(V)
    v = frame @ V
    vc = refract_into_coat(v, fl.n)
    Y = np.asarray(xyz_weights, float)[:nb, 1]
    smooth_y = 0.0
    lam_sum = 0.0
    glint_y = 0.0
    for k in range(emitter_count):
        row = emitters[k]
        I = row[4:8].ravel()[:nb]
        l_w, dom, rad = _elements(row, P)
        l = l_w @ frame.T
        ok = (l[:, 2] > 0) & (dom > 0)
        l, dom = l[ok], dom[ok]
        if not len(l):
            continue
        L_y = rad * (I @ Y)                                   # luminance factor of the lamp's radiance
        smooth_y += float(((flop.brdf(l, np.broadcast_to(v, l.shape)) @ (I * Y)) * rad * l[:, 2] * dom).sum())
        lc = refract_into_coat(l, fl.n)
        h = half_vector(lc, np.broadcast_to(vc, lc.shape))
        dom_h = dom * l[:, 2] / (fl.n ** 2 * lc[:, 2]) / (4 * (lc * h).sum(-1))
        lam = fl.density_per_mm2 * cell_mm ** 2 * fl.normal_pdf(h) * dom_h
        t = fresnel_transmittance(l[:, 2], fl.n) * fresnel_transmittance(v[2], fl.n)
        unit = t * fl.mean_area_um2 * 1e-6 * visible_share * (h @ vc) / (vc[2] * cell_mm ** 2)
        rho_y = float((np.asarray(fl.flake_reflectance, float)[:nb] * I * Y).sum() / max(I @ Y, 1e-30))
        lam_sum += float(lam.sum())
        glint_y += float((lam * unit).sum()) * L_y * rho_y
    pred = appearance.predicted
    out = {"glints_per_cm2": lam_sum / cell_mm ** 2 * 100.0,
           "glint_contrast": (glint_y / lam_sum) / smooth_y if lam_sum > 0 and smooth_y > 0 else 0.0,
           "grain_contrast_percent": 100.0 * grain_sigma}
    for a in (15, 45, 75):
        s = pred.sparkle.get(float(a), (float("nan"), float("nan"))) if pred is not None else (np.nan, np.nan)
        out[f"S_a_{a}"], out[f"S_i_{a}"] = float(s[0]), float(s[1])
    out["G"] = float(pred.graininess) if pred is not None else float("nan")
    return {k: round(float(v), 5) for k, v in out.items()}
