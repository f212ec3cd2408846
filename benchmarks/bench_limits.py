"""
The memory bound of ``lbscene compare``: peak resident memory against the number of readings.

For each booth, a floor grid of N readings (the forward model's own prediction with 1 %
noise, so the fit converges as on real data) is compared in a fresh process (fit and
diagnosis, disk cache off); the table gives the peak RSS of that process and the time.
The per-reading slope is what ``engine/files/limits.py`` sizes ``LBSCENE_MAX_READINGS`` by.

Run: ``.venv/bin/python benchmarks/bench_limits.py [--booths xrite-spectralight-qc ...] [--n 55 250 1000]``
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

_WRAPPER = (
    "import resource, sys\n"
    "from lbscene.cli import main\n"
    "rc = main(sys.argv[1:])\n"
    "print(f'@@maxrss_kb={resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}', file=sys.stderr)\n"
    "sys.exit(rc)\n"
)


def make_set(booth: Path, n: int, out: Path) -> Path:
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.light.forward import ForwardModel

    ir = compile_booth(find_booth_file(booth))
    lighting = next(iter(ir.lighting))
    w, d = ir.interior.width_mm / 2 * 0.9, ir.interior.depth_mm / 2 * 0.9
    k = int(np.ceil(np.sqrt(n)))
    pts = np.array([[x, y, 0.0] for x in np.linspace(-w, w, k) for y in np.linspace(-d, d, k)])[:n]
    lux = ForwardModel(ir, lighting).illuminance_lx(pts)
    lux = lux * (1 + 0.01 * np.random.default_rng(0).standard_normal(len(lux)))
    out.mkdir(parents=True, exist_ok=True)
    (out / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{p[0]:.2f},{p[1]:.2f},{e:.4f}\n" for p, e in zip(pts, lux)))
    (out / "m.yaml").write_text(
        f"version: 1\nkind: measurement_set\nname: bench\nbooth: {booth.resolve()}\nlighting: {lighting}\n"
        "instrument: {illuminance_meter: m, repeatability_percent: 1}\nilluminance:\n  - path: grid.csv\n")
    return out / "m.yaml"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--booths", nargs="*", default=["xrite-spectralight-qc", "byk-byko-spectra-effect"])
    ap.add_argument("--n", nargs="*", type=int, default=[55, 250, 1000])
    ap.add_argument("--make", nargs=3, metavar=("BOOTH", "N", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.make:      # in its own process: a forked child would inherit this process's peak RSS
        make_set(Path(a.make[0]), int(a.make[1]), Path(a.make[2]))
        return 0
    print("| booth | readings | peak RSS MB | MB per reading (from the first row) | compare s |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for b in a.booths:
            first = None
            for n in a.n:
                out = Path(tmp) / f"{b}-{n}"
                subprocess.run([sys.executable, __file__, "--make", str(REPO / "booths" / b), str(n), str(out)],
                               check=True)
                m = out / "m.yaml"
                t0 = time.perf_counter()
                p = subprocess.run([sys.executable, "-c", _WRAPPER, "compare", str(m), "--no-history",
                                    "--format", "json"], capture_output=True, text=True,
                                   env={**os.environ, "LBSCENE_CACHE_DIR": "off",
                                        "LBSCENE_MAX_READINGS": str(max(a.n))})
                s = time.perf_counter() - t0
                rss = next((int(x.split("=")[1]) / 1024 for x in p.stderr.splitlines()
                            if x.startswith("@@maxrss_kb=")), float("nan"))
                if p.returncode != 0:
                    print(f"| {b} | {n} | failed (exit {p.returncode}) | | {s:.1f} |")
                    continue
                slope = "" if first is None else f"{(rss - first[1]) / (n - first[0]):.2f}"
                first = first or (n, rss)
                print(f"| {b} | {n} | {rss:.0f} | {slope} | {s:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
