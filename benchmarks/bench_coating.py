"""Benchmark: frame time of effect coatings against the flat sample (moderngl, headless EGL).

Run:  .venv/bin/python benchmarks/bench_coating.py [--size 1024x768] [--frames 20] [--warmup 3]
      [--booth booths/byk-byko-spectra-effect] [--lighting FL950] [--geometries 45as15,45as45,45as110]
      [--sample examples/render/sample-coating-coarse-silver.yaml] [--json]

For each geometry, in one run, interleaved frame by frame so that a busy machine slows every row
alike, the ``realtime`` schedule (one raster pass to 8-bit display colour) of

* ``flat``: the sample as a reflectance per geometry (interpolated by aspecular angle) — the same
  measured reflectances without ``effect_coating`` (the baseline);
* ``flop``: the coating's fitted BRDF, lamps integrated over their extent, no texture;
* ``texture``: flop plus sparkle and graininess from the flakes.

Setup (the forward model at every vertex, the coating's fits, the GL context, the first frame
with its shader compilation) is excluded.  Times are medians over ``--frames`` frames after
``--warmup``; the table gives each ratio to ``flat`` in the same run.  The goal: texture ≤ 1.3×
flat at 1024×768.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1024x768")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--booth", default=str(REPO / "booths" / "byk-byko-spectra-effect"))
    ap.add_argument("--lighting", default=None)
    ap.add_argument("--geometries", default="45as15,45as45,45as110")
    ap.add_argument("--sample", default=str(REPO / "examples" / "render" / "sample-coating-coarse-silver.yaml"))
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)

    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.colour_bridge import display_uniforms
    from lbscene.runtimes.executor import create_context
    from lbscene.runtimes.graph import build_render_graph, view_names
    from lbscene.runtimes.render import Renderer, parse_size
    from lbscene.runtimes.scene import SampleSpec
    from lbscene.schemas.sample import Sample

    size = parse_size(a.size)
    ir = compile_booth(find_booth_file(Path(a.booth)))
    lighting = a.lighting or next(iter(ir.lighting))
    graph = build_render_graph(ir, lighting)
    views = [v for v in a.geometries.split(",") if v in view_names(ir)] or [view_names(ir)[0]]
    textured = SampleSpec.from_document(load_document(Path(a.sample), Sample))
    variants = {
        "flat": dataclasses.replace(textured, coating=None),
        "flop": dataclasses.replace(textured, coating=textured.coating.model_copy(update={"texture": None})),
        "texture": textured,
    }
    display = display_uniforms(REPO / "displays" / "tablet-wide-gamut.yaml")
    ctx = create_context()
    memo: dict = {}
    renderers = {}
    t0 = time.perf_counter()
    for k, s in variants.items():
        r = Renderer(ir, graph, s, display, ctx=ctx)
        r.scene._irradiance_memo = memo          # the forward model once for all three
        renderers[k] = r
    rows = []
    for view in views:
        for r in renderers.values():
            r.render(view, size)                 # setup: scene, uploads, compilation
        setup_s = time.perf_counter() - t0
        times = {k: [] for k in renderers}
        for i in range(a.warmup + a.frames):
            for k, r in renderers.items():
                r.prepare(view, size)
                t = time.perf_counter()
                r.executor.run(None, "realtime")
                dt = time.perf_counter() - t
                if i >= a.warmup:
                    times[k].append(dt)
        med = {k: statistics.median(v) for k, v in times.items()}
        rows.append({"view": view, "size": list(size), "median_s": med,
                     "ratio_to_flat": {k: med[k] / med["flat"] for k in med}, "setup_s": setup_s})
    gl = str(ctx.info.get("GL_RENDERER", "?"))
    if a.json:
        print(json.dumps({"gl_renderer": gl, "booth": ir.booth_name, "lighting": lighting,
                          "sample": textured.name, "rows": rows}, indent=1))
        return 0
    print(f"{ir.booth_name} · {lighting} · {textured.name} · {size[0]}×{size[1]} · {gl}")
    print(f"{'view':<10} {'flat ms':>9} {'flop ms':>9} {'texture ms':>11} {'flop/flat':>10} {'texture/flat':>13}")
    for r in rows:
        m, q = r["median_s"], r["ratio_to_flat"]
        print(f"{r['view']:<10} {1e3 * m['flat']:>9.1f} {1e3 * m['flop']:>9.1f} {1e3 * m['texture']:>11.1f} "
              f"{q['flop']:>10.2f} {q['texture']:>13.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
