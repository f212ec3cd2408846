"""
Outlying readings: a reading far from both its neighbours and the model.

A mistyped reading (a dropped decimal point, a sensor in a shadow, a value from
another lamp setting) pulls a least-squares fit and can make the diagnosis name an
effect that is not there.  A reading is flagged when its log-residual against the
booth model as declared,

    r_i = ln(E_measured,i / E_model,i),

is far from **both** the median residual of the whole set (the model cannot
explain it: a constant lamp-level factor is removed by the median) **and** the
median residual of its nearest neighbours facing the same way (its neighbours do
not share it: a real effect, such as a shadow edge or a missing diffuser, moves a
whole region together).  "Far" is

    |r_i − m| > max(Z · 1.4826 · MAD, K · σ_noise)

with Z = 6 robust standard deviations and K = 8 noise standard deviations (at 1 %
meter noise a reading must be off by more than 8 %).  At most a fifth of the
readings can be outliers: beyond that the data, not single readings, disagree with
the model.

Examples
--------
>>> import numpy as np
>>> pts = np.array([[x, y, 0.0] for x in range(0, 500, 100) for y in range(0, 400, 100)])
>>> model = 1000.0 + pts[:, 0]
>>> meas = model * 1.02
>>> meas[7] *= 10                                   # one mistyped reading
>>> [o.index for o in find_outliers(pts, np.tile([0, 0, 1.0], (len(pts), 1)), meas, model, 1.0)]
[7]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Outlier", "find_outliers", "Z_ROBUST", "K_NOISE", "NEIGHBOURS"]

#: Robust standard deviations a reading must be off by.
Z_ROBUST = 6.0
#: Meter-noise standard deviations a reading must be off by.
K_NOISE = 8.0
#: Neighbours each reading is compared with.
NEIGHBOURS = 4


@dataclass(frozen=True)
class Outlier:
    """One flagged reading."""

    index: int
    measured_lx: float
    model_lx: float
    deviation_percent: float          # from what the model and the neighbours expect
    neighbours_percent: float         # the neighbours' median residual

    def to_json(self) -> dict:
        return {"index": self.index, "measured_lx": round(self.measured_lx, 4),
                "model_lx": round(self.model_lx, 4),
                "deviation_percent": round(self.deviation_percent, 3),
                "neighbours_percent": round(self.neighbours_percent, 3)}


def find_outliers(points_mm: np.ndarray, normals: np.ndarray, measured_lx: np.ndarray,
                  model_lx: np.ndarray, noise_percent: float) -> list[Outlier]:
    """Readings far from both the model and their neighbours (see the module docstring).

    Parameters
    ----------
    points_mm, normals : (M, 3) reading positions and sensor normals.
    measured_lx, model_lx : (M,) readings and the model's prediction at them.
    noise_percent : the meter's relative noise (one standard deviation).
    """
    P = np.asarray(points_mm, float)
    N = np.asarray(normals, float)
    E = np.asarray(measured_lx, float)
    M = np.asarray(model_lx, float)
    n = len(E)
    if n < 6:
        return []
    ok = (E > 0) & (M > 0) & np.isfinite(E) & np.isfinite(M)
    r = np.full(n, np.nan)
    r[ok] = np.log(E[ok] / M[ok])
    if ok.sum() < 6:
        return []
    med = np.nanmedian(r)
    mad = 1.4826 * np.nanmedian(np.abs(r - med))
    sigma = max(noise_percent, 0.1) / 100.0
    limit = max(Z_ROBUST * mad, K_NOISE * sigma)
    far = ok & (np.abs(r - med) > limit)
    if not far.any():
        return []
    out = []
    for i in np.flatnonzero(far):
        same = ok & (np.abs(N @ N[i] - 1.0) < 1e-6)
        same[i] = False
        idx = np.flatnonzero(same)
        if idx.size < 2:
            continue
        d = np.linalg.norm(P[idx] - P[i], axis=1)
        near = idx[np.argsort(d)[:NEIGHBOURS]]
        m_nb = float(np.median(r[near]))
        if abs(r[i] - m_nb) > limit:
            out.append(Outlier(int(i), float(E[i]), float(M[i]),
                               100.0 * float(np.expm1(r[i] - m_nb)), 100.0 * float(np.expm1(m_nb - med))))
    if len(out) > n // 5:
        return []
    return out
