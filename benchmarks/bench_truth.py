"""Benchmark: the forward model against the Mitsuba truth of the validation scenes.

Run: .venv/bin/python benchmarks/bench_truth.py [--repeat 7] [--markdown OUT.md]

One row per validation scene (``tests/data/validation/<scene>``) and grid (``a3``: the
55-point A3 sheet, ``floor``: 9 × 7 over the floor), from the committed truth CSVs (rendered by
``tests/data/validation/render_truth.py`` with Mitsuba 3; no Mitsuba needed here):

* points: receivers of the grid;
* RMS %, max %: relative deviation model/truth − 1 (``engine.truth.validation``);
* noise %: the truth's own Monte Carlo noise, ν = RMS of σ/E;
* RMS−ν %: the model's RMS with that noise removed in quadrature, √max(0, RMS² − ν²), the
  figure held to the scene's threshold (the issue's: direct light 0.5 %, inter-reflection 1 %,
  cavity and aperture 1.5 %, rough diffuser 2 %);
* warm ms: one forward evaluation of the grid with a warm cache (a new ``ForwardModel`` sharing
  the cache, as a fit's evaluations do), median of ``--repeat``.

A row whose truth was rendered from another version of the booth (``booth_sha256``) says
``stale``: re-render it.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _timing import median_of  # noqa: E402  (benchmarks/ is the script's folder)

VALIDATION = REPO / "tests" / "data" / "validation"

COLUMNS = ("scene", "grid", "points", "RMS %", "max %", "noise %", "RMS−ν %", "limit %", "result", "warm ms")


def _scenes():
    spec = importlib.util.spec_from_file_location("render_truth", VALIDATION / "render_truth.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.SCENES, mod.THRESHOLDS_PERCENT, mod.grids_of


def rows(repeat: int) -> list[tuple]:
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.truth.validation import GRIDS, compare_with_truth

    scenes, limits, grids_of = _scenes()
    out = []
    for scene in scenes:
        ir = compile_booth(VALIDATION / scene)
        for grid in GRIDS:
            if grid not in grids_of(scene):
                out.append((scene, grid, 0, *(float("nan"),) * 4, limits[scene], "not rendered", float("nan")))
                continue
            if not (VALIDATION / scene / f"truth-{grid}.csv").is_file():
                out.append((scene, grid, 0, *(float("nan"),) * 4, limits[scene], "no truth", float("nan")))
                continue
            cache: dict = {}
            c = compare_with_truth(VALIDATION / scene, grid, ir=ir, cache=cache)
            P, N, lighting = c.truth.points_mm, c.truth.normals, c.truth.meta.get("lighting")
            warm = 1e3 * median_of(
                lambda: ForwardModel(ir, lighting, cache=cache).illuminance_lx(P, N, meter=False), repeat)
            ok = c.rms_noise_removed_percent <= limits[scene]
            result = "stale" if not c.booth_sha256_ok else ("pass" if ok else "FAIL")
            out.append((scene, grid, c.points, c.rms_percent, c.max_percent, c.truth_noise_percent,
                        c.rms_noise_removed_percent, limits[scene], result, warm))
    return out


def _cells(r) -> list[str]:
    scene, grid, n, rms, mx, nu, rms_c, lim, res, ms = r
    return [scene, grid, str(n), f"{rms:.2f}", f"{mx:.2f}", f"{nu:.3f}", f"{rms_c:.2f}", f"{lim:g}", res,
            f"{ms:.1f}"]


def text_table(rs) -> str:
    widths = [16, 5, 6, 7, 7, 8, 8, 8, 7, 8]
    head = " ".join(f"{c:<{w}s}" if i < 2 else f"{c:>{w}s}" for i, (c, w) in enumerate(zip(COLUMNS, widths)))
    lines = [head]
    for r in rs:
        cells = _cells(r)
        lines.append(" ".join(f"{c:<{w}s}" if i < 2 else f"{c:>{w}s}"
                              for i, (c, w) in enumerate(zip(cells, widths))))
    return "\n".join(lines)


def markdown_table(rs) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * (len(COLUMNS) - 2)) + "|"]
    lines += ["| " + " | ".join(_cells(r)) + " |" for r in rs]
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description="Forward model vs the Mitsuba truth of the validation scenes.")
    ap.add_argument("--repeat", type=int, default=7, help="forward evaluations timed per row (median)")
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table as Markdown here")
    args = ap.parse_args()
    rs = rows(args.repeat)
    print(text_table(rs))
    if args.markdown:
        from lbscene.engine.files.atomic import write_atomic

        write_atomic(args.markdown, markdown_table(rs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
