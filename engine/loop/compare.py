"""
The measurement loop in one call: load → predict → fit → diagnose → plan → history.

:func:`run_compare` is what ``lbscene compare`` and ``lbscene plan`` run;
:class:`CompareResult` carries everything the text output, the JSON output
and the HTML report need.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .diagnose import Diagnosis, NoiseModel, diagnose, noise_model
from .diagnosis_cache import cached_diagnosis
from .fit import FitProblem, FitResult, resolve_free_parameters
from .measurements import Measurements, check_against_prediction, load_measurements

__all__ = ["CompareResult", "run_compare", "plan_for"]


def _r(x, nd=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return None
    return round(float(x), nd)


@dataclass
class CompareResult:
    meas: Measurements
    fit: FitResult
    noise: NoiseModel
    diagnosis: Diagnosis | None
    plan: object | None = None
    history_entry: dict | None = None
    timing_s: dict = field(default_factory=dict)
    booth_hash: str = ""
    #: readings far from both the model and their neighbours (file, line, values)
    outliers: list[dict] = field(default_factory=list)
    #: whether the fit and the verdict were computed without the outliers
    outliers_excluded: bool = False

    @property
    def outlier_note(self) -> str | None:
        """What the verdict was computed with, when there are outliers."""
        if not self.outliers:
            return None
        n = len(self.outliers)
        what = f"{n} outlying reading{'s' if n != 1 else ''}"
        return (f"fit and verdict computed without {what} (--keep-outliers to include them)"
                if self.outliers_excluded else f"fit and verdict computed with {what} included")

    @property
    def verdict(self):
        """The diagnosis' :class:`~lbscene.engine.loop.diagnose.Verdict` (compares equal to its short
        form, e.g. ``"missing:diffuser"``), or ``"not diagnosed"``."""
        return self.diagnosis.verdict if self.diagnosis else "not diagnosed"

    def residual_rows(self) -> list[dict]:
        ill = self.meas.illuminance
        if ill is None:
            return []
        labels = ill.orientation_labels()
        r = self.fit.residual_percent
        return [{"x_mm": float(ill.points_mm[i, 0]), "y_mm": float(ill.points_mm[i, 1]),
                 "z_mm": float(ill.points_mm[i, 2]), "orientation": labels[i],
                 "measured_lx": float(ill.lux[i]), "predicted_lx": round(float(self.fit.lux_pred[i]), 4),
                 "residual_percent": round(float(r[i]), 4), "file": ill.files[i], "line": int(ill.lines[i])}
                for i in range(len(ill))]

    def spectral_rows(self) -> list[dict]:
        f = self.fit
        if f.tile_bands_pred is None:
            return []
        centres = f.tile_centres_nm if f.tile_centres_nm is not None else self.meas.ir.grid.centres_nm
        res = f.spectral_residual_percent
        return [{"centre_nm": float(c), "measured": float(m), "predicted": float(p),
                 "residual_percent": None if not np.isfinite(x) else round(float(x), 4)}
                for c, m, p, x in zip(centres, f.tile_bands_meas, f.tile_bands_pred, res)]

    def to_json(self) -> dict:
        f = self.fit
        d = self.diagnosis
        out = {
            "measurements": str(self.meas.path), "name": self.meas.name,
            "booth": str(self.meas.booth_file), "booth_hash": self.booth_hash,
            "lighting": self.meas.lighting, "effects": f.effects,
            "fitted": f.fitted,
            "rmse_percent": _r(f.rmse_percent), "mean_abs_percent": _r(f.mean_abs_percent),
            "max_percent": _r(f.max_percent),
            "noise_percent_estimate": _r(self.noise.estimate_percent if self.noise.estimate_percent
                                         is not None else self.noise.percent),
            "noise_percent_used": _r(self.noise.percent), "noise_source": self.noise.source,
            "n_points": len(self.meas.illuminance) if self.meas.illuminance is not None else 0,
            "chi2_per_dof": _r(f.chi2 / f.dof),
            "parameters": [{**p, "value": _r(p["value"], 6), "stderr": _r(p["stderr"], 6)}
                           for p in f.parameters_table()],
            "known_output_groups": self.meas.known_output_groups,
            "warnings": f.warnings,
            "residuals": self.residual_rows(),
            "spectral": ({"rmse_percent": _r(f.spectral_rmse_percent), "bands": self.spectral_rows()}
                         if f.tile_bands_pred is not None else None),
            "verdict": str(self.verdict),
            "suspects": [{"effect": s.effect, "rmse_percent_after": _r(s.rmse_percent_after),
                          "score": _r(s.score, 3)} for s in (d.suspects if d else [])],
            "diagnosis": d.to_json() if d else None,
            "snippet": d.snippet if d else None,
            "plan": self.plan.to_json() if self.plan is not None else None,
            "history": ({"path": str(self.meas.history_path), "step": self.history_entry.get("step"),
                         "label": self.history_entry.get("label")} if self.history_entry else None),
            "timing_s": {k: round(v, 3) for k, v in self.timing_s.items()},
            "outliers": self.outliers,
            "outliers_excluded": self.outliers_excluded,
            "outlier_note": self.outlier_note,
        }
        return out


def plan_for(result: CompareResult, max_points: int | None = None):
    """Plan extra readings for the tied candidates (or the two best explanations)."""
    from .plan import MAX_POINTS, plan_measurements

    d = result.diagnosis
    if d is None or result.meas.illuminance is None:
        return None
    fits = {}
    by_name = {s.effects: s for s in d.suspects + d.pairs}
    if d.verdict.kind == "ambiguous":
        fits = {"+".join(a): by_name[a].fit for a in d.verdict.alternatives if a in by_name}
    else:
        top = [s for s in d.suspects if s.fit is not None][:2]
        if d.verdict.kind in ("none", "unexplained") or len(top) < 2:
            fits["(booth as is)"] = d.base
            top = top[:1]
        for s in top:
            fits[s.effect] = s.fit
    if len(fits) < 2:
        return None
    return plan_measurements(result.meas, fits, result.noise.percent,
                             max_points=max_points or MAX_POINTS)


def _flag_outliers(meas: Measurements, lux_pred, noise_percent: float) -> tuple[list[dict], np.ndarray]:
    """Outlying readings (see :mod:`lbscene.engine.loop.outliers`) and the indices of the others."""
    from .outliers import find_outliers

    ill = meas.illuminance
    if ill is None or lux_pred is None:
        return [], np.arange(0)
    found = find_outliers(ill.points_mm, ill.normals, ill.lux, lux_pred, noise_percent)
    rows = [{**o.to_json(), "file": ill.files[o.index], "line": int(ill.lines[o.index]),
             "x_mm": float(ill.points_mm[o.index, 0]), "y_mm": float(ill.points_mm[o.index, 1]),
             "z_mm": float(ill.points_mm[o.index, 2])} for o in found]
    keep = np.setdiff1d(np.arange(len(ill)), [o.index for o in found])
    return rows, keep


def run_compare(measurements, *, booth=None, fit: bool = True, do_diagnose: bool = True,
                do_plan: bool | None = None, history: bool = True, allowed_dirs=(),
                progress=None, keep_outliers: bool = False) -> CompareResult:
    """Run the measurement loop on a measurement-set file.

    Readings far from both the model and their neighbours are flagged; unless
    ``keep_outliers``, the fit and the diagnosis are computed without them (the result
    says which, and lists them).
    """
    from .history import append_history

    t = {}
    t0 = time.perf_counter()
    meas = measurements if isinstance(measurements, Measurements) else load_measurements(
        Path(measurements), booth, allowed_dirs)
    t["load"] = time.perf_counter() - t0
    if history:
        from .history import check_history_path

        check_history_path(meas.history_path)        # before the work, not after it
    noise = noise_model(meas)
    ir = meas.ir
    effects = {k: dict(v) for k, v in ir.effects.items()}
    free = resolve_free_parameters(ir, meas.lighting, effects, meas.known_output_groups,
                                   str(meas.booth_file))
    cache: dict = {}
    prob = FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, cache)
    t1 = time.perf_counter()
    declared = prob.evaluate()
    check_against_prediction(meas, declared.lux_pred, declared.tile_bands_pred, declared.tile_bands_meas)
    outliers, keep = _flag_outliers(meas, declared.lux_pred, noise.percent)
    if outliers and not keep_outliers:
        from dataclasses import replace

        meas = replace(meas, illuminance=meas.illuminance.subset(keep))
        noise = noise_model(meas)
        prob = FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, cache)
        declared = prob.evaluate()
    result_fit = prob.solve() if fit else declared
    t["fit"] = time.perf_counter() - t1
    res = CompareResult(meas, result_fit, noise, None, booth_hash=ir.content_hash, outliers=outliers,
                        outliers_excluded=bool(outliers) and not keep_outliers)
    if do_diagnose:
        t2 = time.perf_counter()
        # kept on disk: the same question in another format, or `plan` after `compare`, reads it
        res.diagnosis = cached_diagnosis(meas, prob, lambda: diagnose(meas, prob, progress=progress, cache=cache))
        t["diagnose"] = time.perf_counter() - t2
        if do_plan is None:
            do_plan = res.diagnosis.verdict.kind == "ambiguous"
        if do_plan:
            t3 = time.perf_counter()
            res.plan = plan_for(res)
            t["plan"] = time.perf_counter() - t3
    if history:
        f = res.fit
        entry = {
            "booth": str(meas.booth_file), "booth_hash": res.booth_hash, "lighting": meas.lighting,
            "effects": f.effects, "fitted": f.fitted,
            "parameters": {k: _r(v, 6) for k, v in f.values.items()} if f.fitted else {},
            "rmse_percent": _r(f.rmse_percent), "mean_abs_percent": _r(f.mean_abs_percent),
            "max_percent": _r(f.max_percent), "spectral_rmse_percent": _r(f.spectral_rmse_percent),
            "noise_percent_estimate": _r(noise.estimate_percent if noise.estimate_percent is not None
                                         else noise.percent),
            "verdict": str(res.verdict),
            "n_points": len(meas.illuminance) if meas.illuminance is not None else 0,
            "outliers": len(outliers), "outliers_excluded": res.outliers_excluded,
        }
        res.history_entry = append_history(meas.history_path, entry)
    t["total"] = time.perf_counter() - t0
    res.timing_s = t
    return res
