r"""
Cross-check: Cycles (the second engine) against the analytic forward model.

Two comparisons at measurement points (default: the seed's 55-point grid):

* **direct** — the booth's surfaces absorb everything (``surfaces='black'``), so
  Cycles delivers lamp light only: straight, through the diffuser (regular and
  diffuse parts), past occluders, via mirror images.  The model runs with the
  booth's effects minus ``interreflection``.
* **interreflection** — the surfaces have their reflectances and Cycles traces
  every bounce (up to the job's ``max_bounces``); the model runs with the
  booth's effects, ``interreflection`` included.

Both ignore the meter (``detector_cosine_error``): Cycles' sensors are ideal
cosine receivers.  A diffuser the bake draws as a sheet of no thickness (a clear or rough plate:
:func:`~lbscene.bakers.from_ir.diffuser_is_thin_sheet`) is compared with the model's plate with
``thickness_refraction`` off (its paths not refracted through the plate's thickness, which brings
the lamps behind a 4 mm glass plate 1.4 mm closer).  The report gives, per point, the spectral and
photometric ratio Cycles/model and the bake's own noise estimate.

For inter-reflection Cycles traces up to :data:`CONVERGED_BOUNCES` bounces
(the model solves its radiosity to convergence) unless the booth bounds the
model's ``max_bounces``.

One definition of agreement serves the table, the summary line, the JSON and
the exit code, at every quality (:attr:`CrossCheck.agrees`): the two engines
agree when their differences are what the bake's noise and the model's own
quadrature precision give.  With the per-point relative differences
:math:`d_i`, the bake's RMS relative noise :math:`σ_b` (pooled over the
points: each point's own two-half estimate has a single degree of freedom)
and the model's precision floor :math:`f` (:data:`MODEL_PRECISION_PERCENT`:
lamp quadrature and patches are converged to about 0.1 %, a systematic
error that does not average out over the points),

.. math::

   z = \frac{\bar d}{\sqrt{σ_b^2/n + f^2}}, \qquad
   χ^2 = \sum_i \frac{d_i^2}{σ_b^2 + f^2},

they agree when :math:`|z| ≤` :data:`MEAN_SIGMAS` and :math:`χ^2` is no larger
than :math:`n` points of pure noise exceed with probability
:data:`CHI2_P_MIN`.  A loose tolerance that grows with the noise would call a
preview bake 6 standard errors away, or a final one 25 away, agreement; this
test does not.

Examples
--------
>>> from lbscene.engine.scene.compile import compile_booth                       # doctest: +SKIP
>>> ir = compile_booth("booths/iso3664-p1-d50")                            # doctest: +SKIP
>>> [(c.mode, round(c.summary()["mean_diff_percent"], 1))                   # doctest: +SKIP
...  for c in cross_check_all(ir, "P1", quality="final")]
[('direct', 0.0), ('interreflection', -0.5)]

The same from the command line: ``lbscene bake booths/iso3664-p1-d50 -l P1 --cross-check
--quality final [--format json]``.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["CrossCheck", "CrossCheckBakeFailed", "cross_check", "cross_check_all", "bake_points", "MODES",
           "MODEL_PRECISION_PERCENT", "CONVERGED_BOUNCES", "MEAN_SIGMAS", "CHI2_P_MIN"]


class CrossCheckBakeFailed(RuntimeError):
    """The Cycles bake of a cross-check failed: ``error`` says why, ``log_tail`` the last lines of
    its log (the command reports both, exit status 1)."""

    def __init__(self, job_name: str, error: str | None, log_tail: list[str]):
        super().__init__(f"Cycles bake {job_name} failed: {error}")
        self.job_name, self.error, self.log_tail = job_name, error, list(log_tail)


#: effects the Cycles scene cannot represent at a receiver (instrument models)
INSTRUMENT_EFFECTS = ("detector_cosine_error",)
MODES = ("direct", "interreflection")
#: the model's own precision (percent of its illuminance): its lamp quadrature and radiosity
#: patches are converged to about this, a systematic floor added to the bake's noise
MODEL_PRECISION_PERCENT = 0.1
#: Cycles' path depth for the inter-reflection check (the model solves to convergence)
CONVERGED_BOUNCES = 64
#: agreement: the mean difference within this many of its standard errors …
MEAN_SIGMAS = 3.0
#: … and χ² of the differences over the per-point noise no less likely than this for noise alone
CHI2_P_MIN = 1e-3


@dataclass
class CrossCheck:
    booth: str
    lighting: str
    mode: str
    points_mm: np.ndarray
    cycles_lx: np.ndarray
    model_lx: np.ndarray
    cycles_bands: np.ndarray
    model_bands: np.ndarray
    noise_rel: np.ndarray             # per point, relative σ of Cycles' illuminance
    samples: int
    time_s: float
    effects: list[str] = field(default_factory=list)

    max_bounces: int | None = None

    @property
    def ratio(self) -> np.ndarray:
        return self.cycles_lx / self.model_lx

    @property
    def noise_rms(self) -> float:
        """RMS over the points of the bake's relative illuminance noise."""
        return float(np.sqrt(np.mean(np.asarray(self.noise_rel, float) ** 2)))

    @property
    def sigma_point(self) -> float:
        """Relative standard deviation of one point's difference: the bake's RMS noise and the
        model's precision floor in quadrature."""
        return float(np.hypot(self.noise_rms, MODEL_PRECISION_PERCENT / 100.0))

    @property
    def mean_diff_sigmas(self) -> float:
        """Mean of Cycles/model − 1 in standard errors of that mean: the bake's noise averaged
        over the points and the model's precision floor (systematic) in quadrature."""
        d = self.ratio - 1.0
        se = float(np.hypot(self.noise_rms / np.sqrt(len(d)), MODEL_PRECISION_PERCENT / 100.0))
        return float(d.mean() / se)

    @property
    def chi2_p(self) -> float:
        """Probability that noise alone gives a χ² of the per-point differences this large."""
        from scipy.stats import chi2

        d = self.ratio - 1.0
        return float(chi2.sf(np.sum(d ** 2) / self.sigma_point ** 2, len(d)))

    @property
    def agrees(self) -> bool:
        """Whether the two engines agree (see the module's docstring): the one verdict of the
        table, the summary line, the JSON and the exit code."""
        return bool(abs(self.mean_diff_sigmas) <= MEAN_SIGMAS and self.chi2_p >= CHI2_P_MIN)

    def summary(self) -> dict:
        d = 100.0 * (self.ratio - 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rb = 100.0 * (self.cycles_bands / self.model_bands - 1.0)
        band_mean = np.nanmean(np.where(self.model_bands > 1e-12 * self.model_bands.max(), rb, np.nan),
                               axis=0)
        return {"booth": self.booth, "lighting": self.lighting, "mode": self.mode,
                "points": int(len(self.points_mm)), "samples": self.samples,
                "max_bounces": self.max_bounces,
                "time_s": round(self.time_s, 2), "effects": self.effects,
                "mean_diff_percent": round(float(d.mean()), 3),
                "rms_diff_percent": round(float(np.sqrt(np.mean(d ** 2))), 3),
                "max_abs_diff_percent": round(float(np.abs(d).max()), 3),
                "noise_rms_percent": round(100 * self.noise_rms, 3),
                "model_precision_percent": MODEL_PRECISION_PERCENT,
                "mean_diff_sigmas": round(self.mean_diff_sigmas, 2),
                "chi2_p": float(f"{self.chi2_p:.3g}"),
                "agrees": self.agrees,
                "mean_model_lx": round(float(self.model_lx.mean()), 2),
                "mean_cycles_lx": round(float(self.cycles_lx.mean()), 2),
                "band_mean_diff_percent": [None if not np.isfinite(x) else round(float(x), 2)
                                           for x in band_mean]}


def bake_points(ir, lighting: str, points, normals=None, *, effects=None, surfaces="actual",
                light_paths="all", quality="preview", samples=None, out_dir: Path | None = None,
                progress: bool = False, max_bounces: int | None = None):
    """Bake irradiance at points only (no maps); returns (bands (M, B), lux (M,), rel noise (M,), manifest)."""
    import json

    from .executor import BakeTask, run_tasks
    from .from_ir import lighting_job

    job = lighting_job(ir, lighting, quality=quality, samples=samples, effects=effects,
                       surfaces=surfaces, points=points, normals=normals, light_paths=light_paths,
                       environment=False, maps=False, grid=False,
                       name=f"{lighting}.points.{surfaces}.{light_paths}")
    if max_bounces is not None:
        job = job.model_copy(update={"quality": job.quality.model_copy(update={"max_bounces": max_bounces})})
    tmp = None
    if out_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="lbscene-xcheck-")
        out_dir = Path(tmp.name) / job.name
    try:
        [res] = run_tasks([BakeTask(job, Path(out_dir))], progress=progress)
        if res.status == "failed":
            raise CrossCheckBakeFailed(job.name, res.error, res.log_tail[-15:])
        d = json.loads((Path(out_dir) / "points.points.json").read_text())
    finally:
        if tmp is not None:
            tmp.cleanup()
    bands = np.array([list(p["irradiance_W_m2_nm"].values()) for p in d["points"]])
    lux = np.array([p["illuminance_lx"] for p in d["points"]])
    noise = np.array([p.get("illuminance_noise_relative", 0.0) for p in d["points"]])
    return bands, lux, noise, res.manifest


def cross_check(ir, lighting: str, *, mode: str = "direct", points=None, normals=None,
                quality: str = "preview", samples: int | None = None, effects=None,
                out_dir: Path | None = None, progress: bool = False,
                max_bounces: int | None = None) -> CrossCheck:
    """Compare Cycles with :class:`lbscene.engine.light.forward.ForwardModel` at points.

    ``max_bounces`` (Cycles' path depth) defaults to the quality preset's for
    ``direct`` (irrelevant there) and, for ``interreflection``, to the model's
    own bound when the booth sets one, else :data:`CONVERGED_BOUNCES`.
    """
    import time

    from lbscene.engine.light.forward import ForwardModel

    from .from_ir import diffuser_is_thin_sheet, grid_points
    from .products import band_photopic_weights

    eff = dict(ir.effects if effects is None else effects)
    for e in INSTRUMENT_EFFECTS:
        eff.pop(e, None)
    if mode == "direct":
        eff.pop("interreflection", None)
        surfaces = "black"
    elif mode == "interreflection":
        surfaces = "actual"
        if max_bounces is None:
            bound = int((eff.get("interreflection") or {}).get("max_bounces", 0) or 0)
            # the model counts reflections at surfaces; Cycles' depth also counts the sensor's
            max_bounces = bound + 1 if bound > 0 else CONVERGED_BOUNCES
    else:
        raise ValueError(f"unknown cross-check mode {mode!r}")
    if diffuser_is_thin_sheet(ir, eff):
        # the bake draws the plate as a sheet of no thickness: the model's plate of no thickness is
        # what it is compared with (the bake's notes say so)
        eff["diffuser"] = {**dict(eff["diffuser"] or {}), "thickness_refraction": False}
    P = grid_points(ir) if points is None else np.atleast_2d(np.asarray(points, float))
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1)) if normals is None else \
        np.broadcast_to(np.asarray(normals, float), P.shape)
    t0 = time.perf_counter()
    bands, lux, noise, manifest = bake_points(
        ir, lighting, P, N, effects=eff, surfaces=surfaces, quality=quality, samples=samples,
        out_dir=out_dir, progress=progress, max_bounces=max_bounces)
    elapsed = time.perf_counter() - t0
    fm = ForwardModel(ir, lighting, effects=eff)
    model_bands = np.asarray(fm.spectral_irradiance_bands(P, N), float)
    # the same photometric weights on both sides: the comparison is of the transport
    w = band_photopic_weights(ir.grid)
    return CrossCheck(ir.booth_name, lighting, mode, P, lux, model_bands @ w, bands, model_bands, noise,
                      manifest["products"]["points"]["samples"], elapsed, sorted(eff),
                      manifest.get("quality", {}).get("max_bounces", max_bounces))


def cross_check_all(ir, lighting: str, *, modes=MODES, **kw) -> list[CrossCheck]:
    """:func:`cross_check` in each mode (``interreflection`` only when the booth enables it)."""
    out = []
    for mode in modes:
        if mode == "interreflection" and "interreflection" not in (kw.get("effects") or ir.effects):
            continue
        out.append(cross_check(ir, lighting, mode=mode, **kw))
    return out
