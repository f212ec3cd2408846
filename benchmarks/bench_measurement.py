"""Benchmark: the measurement loop's forward model and diagnosis.

Run: .venv/bin/python benchmarks/bench_measurement.py [--repeat 7]

Table 1, forward model: one evaluation of the seed's 55-point A3 grid × every lamp on × 16 bands
(plus 1 nm illuminance), with every effect the booth enables, inter-reflection included.

* cold: a new model and empty caches, in memory and on disk (form factors, LU factors, occlusion all
  computed);
* disk: the same once the geometry disk cache holds the booth (a later ``compare`` or ``render``);
* warm: a new model sharing the cache, same parameters (what a fit pays per evaluation when only
  the lamp intensities change);
* new σ: the same with a new Gaussian σ (the fit's most common non-linear parameter).

The baseline, measured in the same run, is the bare seed model on the same booth: N point sources
per lamp, E = Σ I·cos/d², no effect enabled (warm).  Goal (issue 3): ≤ 50 ms per evaluation.

Table 2, compare + diagnosis: a full ``run_compare`` (load, fit, refit with every candidate effect,
verdict) on synthetic measurements of the 55-point grid with a hidden effect, on the hidden-effect
test booth (no effect enabled: every catalog effect is a candidate) and on the shipped
SpectraLight QC (six effects enabled, each candidate refitted jointly with their parameters).
Goal (issue 3): diagnosis ≤ 5 s.  Median of ``--repeat`` runs (table 1) or best of 2 (table 2).
Table 2 runs with the geometry disk cache off, so "fit s" includes the first evaluation's geometry.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _timing import median_of  # noqa: E402  (benchmarks/ is the script's folder)

BOOTHS = [("xrite-spectralight-qc", "D65"), ("byk-byko-spectra-effect", "FL950"),
          ("iso3664-p1-d50", None)]


def _median_ms(fn, repeat: int) -> float:
    return 1e3 * median_of(fn, repeat)


def forward_table(repeat: int) -> None:
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.truth.synthetic import a3_grid

    pts = a3_grid()
    print(f"{'booth':26s} {'lighting':9s} {'effects':>7s} {'cold ms':>9s} {'disk ms':>9s} {'warm ms':>9s} "
          f"{'new σ ms':>9s} {'bare ms':>8s} {'warm/bare':>10s}")
    for name, lighting in BOOTHS:
        ir = compile_booth(find_booth_file(REPO / "booths" / name))
        lighting = lighting or next(iter(ir.lighting))
        eff = {k: dict(v) for k, v in ir.effects.items()}
        with tempfile.TemporaryDirectory() as td:
            # cold: empty memory and disk caches; disk: a new process's first evaluation once the
            # geometry disk cache holds this booth (engine.files.disk_cache)
            os.environ["LBSCENE_CACHE_DIR"] = td
            t0 = time.perf_counter()
            ForwardModel(ir, lighting, cache={}).illuminance_lx(pts)
            cold = 1e3 * (time.perf_counter() - t0)
            t0 = time.perf_counter()
            ForwardModel(ir, lighting, cache={}).illuminance_lx(pts)
            disk = 1e3 * (time.perf_counter() - t0)
        cache: dict = {}
        ForwardModel(ir, lighting, cache=cache).illuminance_lx(pts)
        warm = _median_ms(lambda: ForwardModel(ir, lighting, cache=cache).illuminance_lx(pts), repeat)
        sig = iter(range(20, 20 + 5 * repeat, 5))

        def new_sigma():
            e = {**eff, "angular_profile": {**eff.get("angular_profile", {}), "sigma_deg": float(next(sig))}}
            ForwardModel(ir, lighting, effects=e, cache=cache).illuminance_lx(pts)

        nsig = _median_ms(new_sigma, repeat) if "angular_profile" in eff else float("nan")
        bare_cache: dict = {}
        ForwardModel(ir, lighting, effects={}, cache=bare_cache).illuminance_lx(pts)
        bare = _median_ms(lambda: ForwardModel(ir, lighting, effects={}, cache=bare_cache).illuminance_lx(pts),
                          repeat)
        print(f"{name:26s} {lighting:9s} {len(eff):7d} {cold:9.0f} {disk:9.0f} {warm:9.1f} {nsig:9.1f} {bare:8.2f} "
              f"{warm / bare:10.1f}")


def diagnosis_table() -> None:
    from lbscene.engine.loop.compare import run_compare
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.truth.synthetic import synthesize

    cases = [("hidden-effect booth", REPO / "tests" / "data" / "hidden-effect-booth", "FL",
              {"diffuser": {}}),
             ("xrite-spectralight-qc", REPO / "booths" / "xrite-spectralight-qc", "D65",
              {"detector_cosine_error": {"exponent": 1.2}})]
    print(f"\n{'booth':24s} {'hidden effect':22s} {'candidates':>10s} {'load s':>7s} {'fit s':>6s} "
          f"{'diagnose s':>11s} {'total s':>8s}  verdict")
    for label, booth, lighting, hidden in cases:
        ir = compile_booth(find_booth_file(booth))
        truth = {**{k: dict(v) for k, v in ir.effects.items()}, **hidden}
        with tempfile.TemporaryDirectory() as td:
            m = synthesize(booth, Path(td), lighting=lighting, truth_effects=truth, noise_percent=1.0)
            runs = [run_compare(m, history=False) for _ in range(2)]
        best = min(runs, key=lambda r: r.timing_s["total"])
        t = best.timing_s
        n = len(best.diagnosis.suspects)
        print(f"{label:24s} {next(iter(hidden)):22s} {n:10d} {t['load']:7.2f} {t['fit']:6.2f} "
              f"{t['diagnose']:11.2f} {t['total']:8.2f}  {best.verdict}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    saved = os.environ.get("LBSCENE_CACHE_DIR")
    try:
        forward_table(args.repeat)
        # every compare as in a fresh process on a fresh machine: no geometry disk cache
        os.environ["LBSCENE_CACHE_DIR"] = "off"
        diagnosis_table()
    finally:
        if saved is None:
            os.environ.pop("LBSCENE_CACHE_DIR", None)
        else:
            os.environ["LBSCENE_CACHE_DIR"] = saved
    return 0


if __name__ == "__main__":
    sys.exit(main())
