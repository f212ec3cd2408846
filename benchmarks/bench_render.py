"""Benchmark: frame time of the realtime render graph (moderngl, headless EGL).

Run:  .venv/bin/python benchmarks/bench_render.py [--sizes 1024x768,2048x1536] [--frames 20]
      [--booth booths/byk-byko-spectra-effect] [--lighting NAME] [--geometry 45as45]
      [--egl-device N] [--json]

For each viewport size it renders the booth with a glossy sample and times, interleaved so
that a busy machine slows every row alike:

* ``baseline``: a trivial full-screen pass writing RGBA8 (the cost of touching every pixel once);
* every pass of the ``analysis`` schedule on its own (``ctx.finish()`` after each);
* the whole frame of the ``realtime`` schedule (surfaces + fused resolve) and of the
  ``analysis`` schedule (four passes, keeps float XYZ), without per-pass synchronisation;
* reading the 8-bit image back.

Times are medians (and minima) over ``--frames`` frames after warm-up; ratios are medians
divided by the baseline's median from the same run.  Scene preparation (forward model at the
vertices, uploads) happens once before timing and is reported separately.

``--egl-device N`` picks the EGL device (e.g. a GPU on a machine with several); without it the
default EGL display is used (Mesa llvmpipe on a machine without a GPU).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

BASELINE_FRAG = """#version 300 es
precision highp float;
layout(location = 0) out vec4 o_rgba;
void main() { o_rgba = vec4(fract(gl_FragCoord.xy / 256.0), 0.5, 1.0); }
"""


def _default_booth() -> Path:
    byko = REPO / "booths" / "byk-byko-spectra-effect"
    return byko if (byko / "booth.yaml").is_file() else REPO / "tests" / "data" / "minimal-booth"


def _sample():
    """ColorChecker 'moderate red' (Ohta), glossy, as a flat sample."""
    import colour
    import numpy as np

    from lbscene.runtimes.scene import SampleSpec

    sd = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]["moderate red"]
    refl = np.interp(np.arange(360.0, 831.0), sd.wavelengths, sd.values)
    return SampleSpec.flat(refl, name="moderate red (glossy)", gloss_GU=90.0, roughness=0.15)


def _stats(xs):
    import numpy as np

    a = np.asarray(xs) * 1e3
    return float(np.median(a)), float(a.min())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--booth", type=Path, default=None, help="Booth folder (default: byko-spectra effect).")
    ap.add_argument("--lighting", default=None, help="Lighting configuration (default: the first).")
    ap.add_argument("--geometry", default=None, help="View / geometry (default: the first).")
    ap.add_argument("--sizes", default="1024x768,2048x1536")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--egl-device", type=int, default=None, help="EGL device index (GLCONTEXT_DEVICE_INDEX).")
    ap.add_argument("--json", action="store_true", help="Print the results as JSON.")
    a = ap.parse_args(argv)

    from lbscene.engine.compile import compile_booth
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.executor import compile_program, create_context
    from lbscene.runtimes.graph import SHADER_DIR, build_render_graph
    from lbscene.runtimes.render import Renderer, parse_size

    booth = a.booth or _default_booth()
    ir = compile_booth(booth)
    lighting = a.lighting or next(iter(ir.lighting))
    graph = build_render_graph(ir, lighting)
    view = a.geometry or graph["views"][0]["name"]
    ctx = create_context(a.egl_device)
    renderer = Renderer(ir, graph, _sample(), srgb_display(), ctx=ctx)
    t0 = time.perf_counter()
    renderer.scene.view(view)
    prep_s = time.perf_counter() - t0

    base_prog = compile_program(ctx, (SHADER_DIR / "fullscreen.vert").read_text(), BASELINE_FRAG)
    base_vao = ctx.vertex_array(base_prog, [])
    info = {"booth": ir.booth_name, "lighting": lighting, "view": view,
            "gl_renderer": ctx.info.get("GL_RENDERER"), "gl_version": ctx.info.get("GL_VERSION"),
            "egl_device": a.egl_device, "cpus": os.cpu_count(),
            "loadavg_start": os.getloadavg()[0], "prepare_view_s": round(prep_s, 3), "sizes": {}}
    for text in a.sizes.split(","):
        size = parse_size(text.strip())
        renderer.render(view, size, schedule="analysis")       # upload, compile, JIT
        ex = renderer.executor
        tex = ctx.texture(size, 4)
        fbo = ctx.framebuffer(color_attachments=[tex])
        rows: dict[str, list[float]] = {"baseline": [], "frame realtime": [], "frame analysis": [],
                                        "readback rgba8": []}
        for i in range(a.warmup + a.frames):
            keep = i >= a.warmup
            t = time.perf_counter()
            fbo.use()
            base_vao.render(vertices=3)
            ctx.finish()
            b = time.perf_counter() - t
            t = time.perf_counter()
            ex.run(None, "realtime")
            rt = time.perf_counter() - t
            t = time.perf_counter()
            ex.run(None, "analysis")
            an = time.perf_counter() - t
            timings = []
            ex.run(timings, "analysis")
            t = time.perf_counter()
            ex.read("display_rgba8")
            rb = time.perf_counter() - t
            if keep:
                rows["baseline"].append(b)
                rows["frame realtime"].append(rt)
                rows["frame analysis"].append(an)
                rows["readback rgba8"].append(rb)
                for p in timings:
                    rows.setdefault(f"pass {p.name}", []).append(p.seconds)
        fbo.release()
        tex.release()
        base_med = _stats(rows["baseline"])[0]
        info["sizes"][f"{size[0]}x{size[1]}"] = {
            name: {"median_ms": round(_stats(v)[0], 3), "min_ms": round(_stats(v)[1], 3),
                   "ratio_to_baseline": round(_stats(v)[0] / base_med, 2)} for name, v in rows.items()}
    info["loadavg_end"] = os.getloadavg()[0]
    renderer.close()

    if a.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{info['booth']} / {lighting} / {view}   GL: {info['gl_renderer']} ({info['gl_version']})")
    print(f"cpus {info['cpus']}, load average {info['loadavg_start']:.2f} → {info['loadavg_end']:.2f}, "
          f"scene preparation {prep_s:.2f} s (once per view, not per frame)")
    for size, rows in info["sizes"].items():
        print(f"\n{size:>10s} {'median ms':>10s} {'min ms':>8s} {'× baseline':>11s}")
        for name, r in rows.items():
            print(f"{name:>24s} {r['median_ms']:10.2f} {r['min_ms']:8.2f} {r['ratio_to_baseline']:11.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
