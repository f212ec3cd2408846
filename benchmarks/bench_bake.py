"""Benchmark: Cycles bake jobs of the shipped booths (one lighting each) and the cross-check.

Run:  .venv/bin/python benchmarks/bench_bake.py [--booths xrite,byk,iso] [--skip-final]
      [--final-grid-only] [--skip-cross-check] [--json]

Per booth (X-Rite SpectraLight QC · D65, BYK byko-spectra effect · FL950, ISO 3664 P1 · P1):

* **preview**: wall time of the whole preview job (environment map(s), floor/platform maps,
  the 55 grid points) through the executor, a fresh process per job as ``lbscene bake`` runs
  it; the issue's target is ≤ 60 s on a 2-core machine;
* **final**: the final job (or its grid product only, ``--final-grid-only``): samples used at
  the grid points (adaptive: up to a 1 % RMS noise target), wall time, grid noise;
* **cross-check** (final quality): Cycles / analytic model − 1 at the grid points, direct
  light and with inter-reflection, mean and max |·| in percent, the bake's noise, and whether
  the two engines agree (``agree``: mean within 3 standard errors, χ² test at p 0.001, the
  bake's noise and the model's 0.1 % floor; :attr:`lbscene.bakers.crosscheck.CrossCheck.agrees`).

Times are also given as ratios to a baseline measured in the same run: a one-sensor,
one-lamp bake (16 samples), i.e. the fixed cost of a bake process (Python + bpy start,
scene build, writing products).  Bakes run one after another with ``nice``-friendly
defaults; the whole run takes ~15 min on 2 cores (``--skip-final`` ~5 min).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

BOOTHS = {
    "xrite": ("booths/xrite-spectralight-qc", "D65"),
    "byk": ("booths/byk-byko-spectra-effect", "FL950"),
    "iso": ("booths/iso3664-p1-d50", "P1"),
}


def _baseline(tmp: Path) -> float:
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.job import BakeJob, IrradiancePointsProduct, MeasurementPoint, PointEmitters, Quality

    job = BakeJob(name="baseline",
                  emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1000)], intensity_W_sr_nm=[0.01] * 16)],
                  products=[IrradiancePointsProduct(id="pts", points=[MeasurementPoint(position_mm=(0, 0, 0))])],
                  quality=Quality(samples=16))
    t0 = time.perf_counter()
    [r] = run_tasks([BakeTask(job, tmp / "baseline")], force=True, progress=False)
    assert r.status == "baked", r.error
    return time.perf_counter() - t0


def _bake(ir, lighting: str, quality: str, out: Path, grid_only: bool = False) -> dict:
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.from_ir import lighting_job

    kw = dict(environment=False, maps=False) if grid_only else {}
    job = lighting_job(ir, lighting, quality=quality, **kw)
    t0 = time.perf_counter()
    [r] = run_tasks([BakeTask(job, out)], force=True, progress=False)
    wall = time.perf_counter() - t0
    if r.status != "baked":
        raise RuntimeError(f"{ir.booth_name} {lighting} {quality}: {r.error}\n" + "\n".join(r.log_tail))
    g = r.manifest["products"]["grid"]
    return {"time_s": round(wall, 2), "grid_samples": g["samples"],
            "grid_time_s": g["time_s"],
            "grid_noise_percent": round(100 * g["noise"]["illuminance_relative_rms"], 3),
            "grid_mean_lx": round(g["illuminance_lx"]["mean"], 2),
            "products": {k: {"samples": p["samples"], "time_s": p["time_s"]}
                         for k, p in r.manifest["products"].items()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--booths", default="xrite,byk,iso", help="Comma list of: " + ", ".join(BOOTHS))
    ap.add_argument("--skip-final", action="store_true", help="No final bake.")
    ap.add_argument("--final-grid-only", action="store_true",
                    help="Final bake of the grid points only (no environment maps or floor maps).")
    ap.add_argument("--skip-cross-check", action="store_true")
    ap.add_argument("--json", action="store_true", help="Print the results as JSON.")
    args = ap.parse_args(argv)

    from lbscene.bakers.crosscheck import cross_check_all
    from lbscene.engine.scene.compile import compile_booth, find_booth_file

    rows = []
    with tempfile.TemporaryDirectory(prefix="lbscene-bench-bake-") as tmp:
        tmp = Path(tmp)
        base = _baseline(tmp)
        for key in [k.strip() for k in args.booths.split(",") if k.strip()]:
            path, lighting = BOOTHS[key]
            ir = compile_booth(find_booth_file(REPO / path))
            row = {"booth": ir.booth_name, "lighting": lighting}
            row["preview"] = _bake(ir, lighting, "preview", tmp / key / "preview")
            if not args.skip_final:
                row["final"] = _bake(ir, lighting, "final", tmp / key / "final", args.final_grid_only)
                row["final"]["grid_only"] = args.final_grid_only
            if not args.skip_cross_check:
                row["cross_check"] = {c.mode: c.summary() for c in
                                      cross_check_all(ir, lighting, quality="final")}
            rows.append(row)
            print(f"  {ir.booth_name} · {lighting}: done", file=sys.stderr, flush=True)

    if args.json:
        print(json.dumps({"baseline_s": round(base, 2), "booths": rows}, indent=2, ensure_ascii=False))
        return 0
    print(f"baseline: one-sensor bake (process start, bpy, scene, products) {base:.2f} s\n")
    hdr = (f"{'booth':32s} {'lighting':8s} {'preview s':>10s} {'(×base)':>8s} {'final spp':>9s} "
           f"{'final s':>8s} {'grid noise %':>12s} {'direct mean/max %':>18s} {'inter mean/max %':>17s} "
           f"{'xc noise d/i %':>14s} {'agree d/i':>16s}")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        p, f, x = r["preview"], r.get("final"), r.get("cross_check", {})

        def mm(mode):
            c = x.get(mode)
            return "—" if c is None else f"{c['mean_diff_percent']:+.2f}/{c['max_abs_diff_percent']:.2f}"

        noise = "/".join("—" if x.get(m) is None else f"{x[m]['noise_rms_percent']:.2f}"
                         for m in ("direct", "interreflection"))
        within = "/".join("—" if x.get(m) is None else ("yes" if x[m]["agrees"] else "no")
                          for m in ("direct", "interreflection"))
        f_spp = str(f["grid_samples"]) if f else "—"
        f_time = f"{f['time_s']:.1f}" if f else "—"
        f_noise = f"{f['grid_noise_percent']:.2f}" if f else "—"
        print(f"{r['booth'][:32]:32s} {r['lighting']:8s} {p['time_s']:10.1f} {p['time_s'] / base:8.1f} "
              f"{f_spp:>9s} {f_time:>8s} {f_noise:>12s} {mm('direct'):>18s} {mm('interreflection'):>17s} "
              f"{noise:>14s} {within:>16s}")
    print("\npreview target: ≤ 60 s per booth and lighting; final target: grid noise ≤ 1 %;"
          " cross-check targets: direct ≤ 2 %, inter-reflection ≤ 3 %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
