"""
Statistics of a visual test: STRESS, grey-scale scores as visual differences,
intra- and inter-observer repeatability.

STRESS (standardized residual sum of squares; García, Huertas, Melgosa and Cui,
J. Opt. Soc. Am. A 24, 2007) between computed differences ΔE and visual differences ΔV:

.. math::

    F_1 = \\frac{\\sum_i \\Delta E_i^2}{\\sum_i \\Delta E_i \\Delta V_i}, \\qquad
    \\mathrm{STRESS} = 100 \\sqrt{\\frac{\\sum_i (\\Delta E_i - F_1 \\Delta V_i)^2}
                                      {\\sum_i F_1^2 \\Delta V_i^2}}

0 is perfect agreement up to a scale factor (STRESS does not depend on the units of
ΔV), 100 is none.  It is the statistic the colour-difference literature, and the
visual validation of "Visual validation of the appearance of chromatic objects rendered
from spectrophotometric measurements", uses for observer variability: intra-observer
(one observer's repeats against that observer's mean) and inter-observer (one
observer's mean against the panel mean).

Grey-scale grades become visual differences with the CIELAB differences of the grey
scale for assessing change in colour (ISO 105-A02: grade 5 → 0, 4 → 1.7, 3 → 3.4,
2 → 6.8, 1 → 13.6, half grades in between), interpolated linearly.

Examples
--------
>>> round(stress([1.0, 2.0], [2.0, 1.0]), 6)      # F1 = 5/4; 100·√(2.8125/7.8125)
60.0
>>> stress([1, 2, 3], [2, 4, 6])                  # proportional: perfect agreement
0.0
>>> float(grey_scale_to_delta_e(4.5))
0.8
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

__all__ = [
    "GREY_SCALE_GRADES",
    "GREY_SCALE_DELTA_E",
    "stress",
    "grey_scale_to_delta_e",
    "delta_e_to_grey_scale",
    "visual_differences",
    "case_means",
    "intra_observer_stress",
    "inter_observer_stress",
]

#: ISO 105-A02 grey scale for assessing change in colour: grades and their CIELAB ΔE.
GREY_SCALE_GRADES = np.array([1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0])
GREY_SCALE_DELTA_E = np.array([13.6, 9.6, 6.8, 4.8, 3.4, 2.5, 1.7, 0.8, 0.0])


def stress(delta_e, delta_v) -> float:
    """STRESS (0–100) between computed ΔE and visual ΔV (same length, ≥ 2 pairs)."""
    e = np.asarray(delta_e, float)
    v = np.asarray(delta_v, float)
    if e.shape != v.shape or e.size < 2:
        raise ValueError("stress needs two arrays of the same length (at least 2 pairs)")
    ev = float(e @ v)
    if ev <= 0:
        return 100.0
    f1 = float(e @ e) / ev
    den = float(((f1 * v) ** 2).sum())
    return float(100.0 * np.sqrt(((e - f1 * v) ** 2).sum() / den)) if den > 0 else 100.0


def grey_scale_to_delta_e(grade):
    """Grey-scale grade(s) 1–5 → visual difference in CIELAB units (ISO 105-A02), linear
    between the grades; clipped to the scale."""
    g = np.clip(np.asarray(grade, float), 1.0, 5.0)
    return np.interp(g, GREY_SCALE_GRADES, GREY_SCALE_DELTA_E)


def delta_e_to_grey_scale(delta_e):
    """The inverse of :func:`grey_scale_to_delta_e` (continuous grades)."""
    d = np.clip(np.asarray(delta_e, float), 0.0, GREY_SCALE_DELTA_E[0])
    return np.interp(d, GREY_SCALE_DELTA_E[::-1], GREY_SCALE_GRADES[::-1])


def visual_differences(scores, response_type: str):
    """Answers → visual differences ΔV (grey-scale grades through ISO 105-A02, ΔE
    estimates as they are)."""
    s = np.asarray(scores, float)
    return grey_scale_to_delta_e(s) if response_type == "grey_scale" else s


def case_means(rows, value: str = "delta_v", by=("case",)) -> dict:
    """Mean of ``value`` over the rows sharing the key ``by`` (rows: dicts)."""
    acc = defaultdict(list)
    for r in rows:
        acc[tuple(r[k] for k in by)].append(r[value])
    return {k if len(by) > 1 else k[0]: float(np.mean(v)) for k, v in acc.items()}


def intra_observer_stress(rows) -> dict[str, float]:
    """Per observer: the mean over that observer's repeats of STRESS(repeat's ΔV, the
    observer's mean ΔV over repeats), case by case.  Observers with one repeat: NaN."""
    out = {}
    for obs in sorted({r["observer"] for r in rows}):
        mine = [r for r in rows if r["observer"] == obs]
        mean = case_means(mine)
        reps = sorted({r["repeat"] for r in mine})
        if len(reps) < 2:
            out[obs] = float("nan")
            continue
        vals = []
        for rep in reps:
            rr = [r for r in mine if r["repeat"] == rep]
            if len(rr) >= 2:
                vals.append(stress([mean[r["case"]] for r in rr], [r["delta_v"] for r in rr]))
        out[obs] = float(np.mean(vals)) if vals else float("nan")
    return out


def inter_observer_stress(rows) -> dict[str, float]:
    """Per observer: STRESS(the panel's mean ΔV, the observer's mean ΔV), case by case."""
    panel = case_means(rows)
    out = {}
    for obs in sorted({r["observer"] for r in rows}):
        mine = case_means([r for r in rows if r["observer"] == obs])
        cases = sorted(mine)
        out[obs] = stress([panel[c] for c in cases], [mine[c] for c in cases]) if len(cases) >= 2 \
            else float("nan")
    return out
