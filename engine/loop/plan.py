"""
Plan the next measurements: where do the tied candidates disagree most?

When the diagnosis cannot tell effects apart (``ambiguous``), each tied
candidate has its own fitted model.  A pool of feasible extra readings —
a wider floor grid, points beyond the tube ends, near the walls, vertical
and tilted meter orientations, a downward-facing meter — is predicted with
every candidate's model; points are picked greedily until every pair of
candidates is separated by at least :data:`TARGET_SEPARATION` in accumulated
χ² (in units of the meter noise), or :data:`MAX_POINTS` points are chosen.

The result lists each point (position, orientation) with the reading every
candidate predicts, and a CSV template (``illuminance_lx`` left for the user).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

__all__ = ["PlannedPoint", "Plan", "candidate_pool", "plan_measurements", "illuminance_upper_bound_lx", "TARGET_SEPARATION",
           "MIN_POINTS", "MAX_POINTS"]

#: Accumulated χ² between every pair of candidates that the plan aims for (6σ: the refit of
#: each candidate absorbs part of the difference the fixed models predict).
TARGET_SEPARATION = 36.0
MIN_POINTS = 4
MAX_POINTS = 8


@dataclass
class PlannedPoint:
    position_mm: tuple[float, float, float]
    normal: tuple[float, float, float]
    kind: str                                  # floor, tube_end, wall, vertical, tilted, down
    predicted_lx: dict[str, float]             # candidate → reading
    spread_percent: float                      # max relative difference between candidates

    def orientation(self) -> str:
        from lbscene.schemas.measurement import ORIENTATIONS

        for k, v in ORIENTATIONS.items():
            if np.allclose(self.normal, v, atol=1e-6):
                return k
        return "(" + ", ".join(f"{c:.3g}" for c in self.normal) + ")"

    def to_json(self) -> dict:
        return {"x_mm": self.position_mm[0], "y_mm": self.position_mm[1], "z_mm": self.position_mm[2],
                "normal": list(self.normal), "orientation": self.orientation(), "kind": self.kind,
                "predicted_lx": {k: round(v, 3) for k, v in self.predicted_lx.items()},
                "spread_percent": round(self.spread_percent, 3)}


@dataclass
class Plan:
    candidates: list[str]
    points: list[PlannedPoint]
    separation: dict[str, float]               # "a|b" → accumulated χ² after the plan
    noise_percent: float
    notes: list[str] = field(default_factory=list)

    def csv_template(self) -> str:
        lines = ["x_mm,y_mm,z_mm,normal_x,normal_y,normal_z,illuminance_lx"]
        for p in self.points:
            x, y, z = p.position_mm
            nx, ny, nz = p.normal
            lines.append(f"{x:g},{y:g},{z:g},{nx:.6g},{ny:.6g},{nz:.6g},")
        return "\n".join(lines) + "\n"

    def to_json(self) -> dict:
        return {"candidates": self.candidates, "points": [p.to_json() for p in self.points],
                "separation_chi2": {k: round(v, 2) for k, v in self.separation.items()},
                "noise_percent": self.noise_percent, "notes": self.notes}


def candidate_pool(ir, lighting: str, margin_mm: float = 30.0) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Feasible extra readings: (points (K,3), normals (K,3), kinds)."""
    it = ir.interior
    w, d = it.width_mm / 2 - margin_mm, it.depth_mm / 2 - margin_mm
    pts, nrm, kinds = [], [], []

    def add(p, n, k):
        pts.append(p)
        nrm.append(np.asarray(n, float) / np.linalg.norm(n))
        kinds.append(k)

    for x in np.linspace(-w, w, 9):
        for y in np.linspace(-d, d, 7):
            add((x, y, 0.0), (0, 0, 1), "floor")
    for lp, _ in ir.lamps_on(lighting):
        if lp.kind != "tube":
            continue
        c = np.asarray(lp.position_mm, float)
        ax = np.asarray(lp.axis, float)
        for s in (-1, 1):
            for off in (-60.0, 0.0, 60.0, 120.0):
                q = c + ax * s * (lp.length_mm / 2 + off)
                q = (float(np.clip(q[0], -w, w)), float(np.clip(q[1], -d, d)), 0.0)
                add(q, (0, 0, 1), "tube_end")
    wall = 40.0 - margin_mm
    for x, y in ((-w - wall, 0), (w + wall, 0), (0, d + wall), (-w - wall, d + wall), (w + wall, d + wall),
                 (0, -d - wall)):
        add((x, y, 0.0), (0, 0, 1), "wall")
    for z in (100.0, 300.0):
        for cx, cy in ((0, 0), (-w / 2, 0), (w / 2, 0), (0, d / 2), (0, -d / 2)):
            for n in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)):
                add((cx, cy, z), n, "vertical")
    for n in ((1, 0, 1), (-1, 0, 1), (0, 1, 1), (0, -1, 1)):
        add((0.0, 0.0, 50.0), n, "tilted")
    for cx, cy in ((0, 0), (-w / 2, 0), (w / 2, 0)):
        add((cx, cy, 300.0), (0, 0, -1), "down")
    return np.array(pts), np.array(nrm), kinds


def illuminance_upper_bound_lx(ir, lighting: str, points_mm: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """An upper bound on the illuminance any sane model can give at ``points_mm`` (any normal).

    Direct light: every lamp at its peak intensity as if all of it came from the lamp's point
    nearest the reading, Σ s·I_peak / d_min² (cos θ ≤ 1, the profile ≤ its peak).  Inter-reflected
    light: the interior returns at most ρ_max/(1 − ρ_max) of the flux it receives, spread over its
    area, with a factor 4 for non-uniformity: 4·ρ_max/(1 − ρ_max)·Σ s·Φ / A.  ``scale`` is the
    largest fitted lamp-level factor.
    """
    P = np.asarray(points_mm, float)
    direct = np.zeros(len(P))
    flux = 0.0
    for lp, dim in ir.lamps_on(lighting):
        c = np.asarray(lp.position_mm, float)
        ax = np.asarray(lp.axis, float)
        half = lp.length_mm / 2 if lp.kind in ("tube", "panel") else 0.0
        t = np.clip((P - c) @ ax, -half, half)
        d_m = np.maximum(np.linalg.norm(P - (c + t[:, None] * ax), axis=1), max(lp.radius_mm, 1.0)) / 1000.0
        direct += dim * lp.peak_luminous_intensity_cd / d_m ** 2
        flux += dim * lp.luminous_flux_lm
    it = ir.interior
    area_m2 = 2 * (it.width_mm * it.depth_mm + it.width_mm * it.height_mm + it.depth_mm * it.height_mm) / 1e6
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM

    vis = (REFERENCE_WAVELENGTHS_NM >= 380) & (REFERENCE_WAVELENGTHS_NM <= 780)
    rho = 0.0
    for mid in {sf.material for sf in ir.surfaces}:
        rho = max(rho, float(np.max(np.asarray(ir.materials[mid].reflectance.array_1nm)[vis])))
    rho = min(rho, 0.95)
    return scale * (direct + 4.0 * rho / (1.0 - rho) * flux / max(area_m2, 1e-6))


def plan_measurements(meas, fits: dict, noise_percent: float, *, max_points: int = MAX_POINTS,
                      target: float = TARGET_SEPARATION) -> Plan:
    """Choose extra readings that separate the candidate models ``fits`` (name → FitResult)."""
    from lbscene.engine.light.forward import ForwardModel

    names = list(fits)
    P, N, kinds = candidate_pool(meas.ir, meas.lighting)
    if meas.illuminance is not None and len(meas.illuminance):
        old = meas.illuminance
        dist = np.linalg.norm(P[:, None, :] - old.points_mm[None], axis=2)
        same = np.abs(N @ old.normals.T - 1) < 1e-6
        keep = ~np.any((dist < 20.0) & same, axis=1)
        P, N, kinds = P[keep], N[keep], [k for k, f in zip(kinds, keep) if f]
    pred = {}
    for name, fit in fits.items():
        # an explanation that adds hardware (a hypothesis) predicts with its own booth
        fm = ForwardModel(getattr(fit, "ir", None) or meas.ir, meas.lighting, effects=fit.effects,
                          lamp_overrides=fit.lamp_overrides)
        pred[name] = fm.illuminance_lx(P, N, True, scales=fit.scales)
    # a reading no candidate can predict sanely is never proposed (a fitted parameter far outside
    # what the data span can extrapolate wildly off the measured grid)
    bound = illuminance_upper_bound_lx(meas.ir, meas.lighting, P,
                                       max((max(f.scales.values(), default=1.0) for f in fits.values()),
                                           default=1.0))
    stack = np.stack(list(pred.values()))
    sane = np.all(np.isfinite(stack) & (stack >= 0) & (stack <= bound), axis=0)
    insane = int((~sane).sum())
    sigma = noise_percent / 100.0
    pairs = list(combinations(names, 2))
    z2 = {}
    for a, b in pairs:
        mean = 0.5 * (pred[a] + pred[b])
        with np.errstate(divide="ignore", invalid="ignore"):
            z2[(a, b)] = np.where(mean > 1e-6 * max(mean.max(), 1e-30),
                                  ((pred[a] - pred[b]) / (sigma * mean)) ** 2, 0.0)
    acc = {pr: 0.0 for pr in pairs}
    chosen = []
    usable = np.ones(len(P), bool)
    # readings below 5 % of the median are impractical (noise is not 1 % there, and stray light
    # the model may lack dominates them)
    med = np.median(stack, axis=0)
    usable &= med > 0.05 * np.median(med)
    usable &= sane
    for _ in range(max_points):
        if not pairs or (min(acc.values()) >= target and len(chosen) >= MIN_POINTS):
            break
        best, best_val = None, (-1.0, -1.0)
        for i in np.nonzero(usable)[0]:
            vals = [min(acc[pr] + z2[pr][i], target) for pr in pairs]
            if min(acc.values()) >= target:  # targets met: keep adding the most informative
                vals = [acc[pr] + z2[pr][i] for pr in pairs]
            key = (min(vals), sum(vals))
            if key > best_val:
                best, best_val = i, key
        if best is None:
            break
        chosen.append(best)
        # spread the readings: no second one within 60 mm in the same orientation
        near = (np.linalg.norm(P - P[best], axis=1) < 60.0) & (np.abs(N @ N[best] - 1) < 1e-6)
        usable[near] = False
        for pr in pairs:
            acc[pr] += z2[pr][best]
    points = []
    for i in chosen:
        vals = {n: float(pred[n][i]) for n in names}
        m = np.mean(list(vals.values()))
        spread = 100.0 * (max(vals.values()) - min(vals.values())) / m if m > 0 else 0.0
        points.append(PlannedPoint(tuple(float(c) for c in P[i]), tuple(float(c) for c in N[i]),
                                   kinds[i], vals, spread))
    plan = Plan(names, points, {f"{a}|{b}": float(acc[(a, b)]) for a, b in pairs}, noise_percent)
    if insane:
        plan.notes.append(f"{insane} candidate reading(s) left out: a candidate predicts more than the "
                          "physical bound there (every lamp at its peak intensity from its nearest point, "
                          "plus the most the interior can inter-reflect)")
    if pairs and min(acc.values()) < target:
        worst = min(acc, key=acc.get)
        plan.notes.append(f"{worst[0]} and {worst[1]} stay close everywhere a meter can go "
                          f"(χ² {acc[worst]:.1f} < {target:g}): repeat readings or a white-tile "
                          "spectrum may be needed")
    return plan
