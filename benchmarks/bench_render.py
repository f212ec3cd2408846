"""Benchmark: frame time of the realtime render graph (moderngl, headless EGL).

Run:  .venv/bin/python benchmarks/bench_render.py [--sizes 1024x768,2048x1536] [--frames 20]
      [--warmup 3] [--booth booths/byk-byko-spectra-effect] [--lighting NAME] [--geometry 45as45]
      [--egl-device N] [--json]

Setup (once, reported separately, never in a frame time): compiling the booth and its render
graph, the scene of the view (the forward model at every vertex: the bulk of ``lbscene render``'s
wall time), the GL context, and per viewport size the first frame (target allocation, uploads,
shader compilation and LLVM JIT on llvmpipe).

Then, for each viewport size, interleaved so that a busy machine slows every row alike:

* ``baseline: bare 16 bands → XYZ → RGB8``: one full-screen pass reading the four RGBA32F
  spectral images, weighting them to XYZ, a 3×3 matrix to linear sRGB and a 1/2.2 power, written
  as RGBA8 — the least any spectral pipeline must do per pixel after shading; the ratios are
  against it;
* ``touch every pixel``: a trivial full-screen RGBA8 pass (fill-rate reference);
* ``frame realtime``: the full graph as rendered interactively (``realtime`` schedule: one raster
  pass shading the booth and the sample — diffuse light, LTC highlights, gonio interpolation —
  straight to display-encoded, dithered 8-bit colour);
* ``frame deferred`` (spectral images + one full-screen resolve) and ``frame analysis`` (four
  passes, keeps float XYZ and drive values): the same image through float render targets;
* every pass of the analysis schedule on its own (``ctx.finish()`` after each);
* reading the 8-bit image and the float XYZ image back.

Times are medians (and minima) over ``--frames`` frames after ``--warmup`` frames; each frame
ends with ``ctx.finish()``.  ``--egl-device N`` picks the EGL device (a GPU on a machine with
several); without it the default EGL display is used (Mesa llvmpipe on a machine without a GPU).
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
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

TRIVIAL_FRAG = """#version 300 es
precision highp float;
layout(location = 0) out vec4 o_rgba;
void main() { o_rgba = vec4(fract(gl_FragCoord.xy / 256.0), 0.5, 1.0); }
"""

BARE_FRAG = """#version 300 es
precision highp float;
precision highp sampler2D;
uniform sampler2D u_radiance0;
uniform sampler2D u_radiance1;
uniform sampler2D u_radiance2;
uniform sampler2D u_radiance3;
uniform mat3 u_xyz_to_rgb;
uniform float u_exposure;
layout(location = 0) out vec4 o_rgba;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 xyz = spectral_to_xyz(texelFetch(u_radiance0, p, 0), texelFetch(u_radiance1, p, 0),
                               texelFetch(u_radiance2, p, 0), texelFetch(u_radiance3, p, 0));
    vec3 rgb = clamp(u_xyz_to_rgb * (xyz * u_exposure), 0.0, 1.0);
    o_rgba = vec4(pow(rgb, vec3(1.0 / 2.2)), 1.0);
}
"""


def _default_booth() -> Path:
    byko = REPO / "booths" / "byk-byko-spectra-effect"
    return byko if (byko / "booth.yaml").is_file() else REPO / "tests" / "data" / "minimal-booth"


def _sample():
    """ColorChecker 'moderate red' (Ohta), glossy (LTC highlights on), as a flat sample."""
    import colour
    import numpy as np
    from lbscene.engine.scene.sample import SampleSpec

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
    ap.add_argument("--egl-device", type=int, default=None, help="EGL device index.")
    ap.add_argument("--json", action="store_true", help="Print the results as JSON.")
    a = ap.parse_args(argv)

    import numpy as np

    t0 = time.perf_counter()
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.executor import compile_program, create_context
    from lbscene.runtimes.graph import SHADER_DIR, build_render_graph, compose_shader
    from lbscene.runtimes.render import Renderer, parse_size

    booth = a.booth or _default_booth()
    ir = compile_booth(booth)
    lighting = a.lighting or next(iter(ir.lighting))
    graph = build_render_graph(ir, lighting)
    view = a.geometry or graph["views"][0]["name"]
    setup = {"import_compile_booth_and_graph_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    ctx = create_context(a.egl_device)
    setup["gl_context_s"] = time.perf_counter() - t0
    renderer = Renderer(ir, graph, _sample(), srgb_display(), ctx=ctx)
    t0 = time.perf_counter()
    renderer.scene.view(view)
    setup["scene_of_view_s"] = time.perf_counter() - t0

    vert = (SHADER_DIR / "fullscreen.vert").read_text()
    trivial = compile_program(ctx, vert, TRIVIAL_FRAG)
    bare = compile_program(ctx, vert, compose_shader(BARE_FRAG, include=["lib_spectral.glsl"]))
    trivial_vao, bare_vao = ctx.vertex_array(trivial, []), ctx.vertex_array(bare, [])
    info = {"booth": ir.booth_name, "lighting": lighting, "view": view,
            "gl_renderer": ctx.info.get("GL_RENDERER"), "gl_version": ctx.info.get("GL_VERSION"),
            "egl_device": a.egl_device, "cpus": os.cpu_count(), "frames": a.frames, "warmup": a.warmup,
            "loadavg_start": os.getloadavg()[0], "setup": setup, "sizes": {}}
    for text in a.sizes.split(","):
        size = parse_size(text.strip())
        t0 = time.perf_counter()
        for sched in ("realtime", "deferred", "analysis"):     # allocate, upload, compile, JIT
            renderer.render(view, size, schedule=sched)
        setup[f"first_frames_{size[0]}x{size[1]}_s"] = time.perf_counter() - t0
        ex = renderer.executor
        vi = renderer.scene.view(view)
        for k in range(4):
            ex.targets[f"spectral_radiance_{k}"].use(k)
            bare[f"u_radiance{k}"].value = k
        bare["u_xyz_weights"].write(np.asarray(vi.values["view.xyz_weights"], np.float32).tobytes())
        bare["u_xyz_to_rgb"].write(np.asarray(vi.values["display.xyz_to_rgb"], np.float32).tobytes())
        bare["u_exposure"].value = float(vi.values["display.exposure"])
        tex = ctx.texture(size, 4)
        fbo = ctx.framebuffer(color_attachments=[tex])

        def full_screen(vao, fbo=fbo, ex=ex):
            fbo.use()
            for k in range(4):
                ex.targets[f"spectral_radiance_{k}"].use(k)
            vao.render(vertices=3)

        rows: dict[str, list[float]] = {
            "baseline: bare 16 bands → XYZ → RGB8": [], "touch every pixel": [],
            "frame realtime": [], "frame deferred": [], "frame analysis": [],
            "readback rgba8": [], "readback xyz float": []}
        ex.run(None, "analysis")           # the spectral images the bare pass reads
        for i in range(a.warmup + a.frames):
            sample = {}
            for name, fn in (("baseline: bare 16 bands → XYZ → RGB8", lambda: full_screen(bare_vao)),
                             ("touch every pixel", lambda: full_screen(trivial_vao)),
                             ("frame realtime", lambda ex=ex: ex.run(None, "realtime")),
                             ("frame deferred", lambda ex=ex: ex.run(None, "deferred")),
                             ("frame analysis", lambda ex=ex: ex.run(None, "analysis"))):
                t = time.perf_counter()
                fn()
                ctx.finish()
                sample[name] = time.perf_counter() - t
            timings = []
            ex.run(timings, "analysis")
            t = time.perf_counter()
            ex.read("display_rgba8")
            sample["readback rgba8"] = time.perf_counter() - t
            t = time.perf_counter()
            ex.read("xyz")
            sample["readback xyz float"] = time.perf_counter() - t
            if i >= a.warmup:
                for name, v in sample.items():
                    rows[name].append(v)
                for p in timings:
                    rows.setdefault(f"  analysis pass {p.name}", []).append(p.seconds)
        fbo.release()
        tex.release()
        base_med = _stats(rows["baseline: bare 16 bands → XYZ → RGB8"])[0]
        info["sizes"][f"{size[0]}x{size[1]}"] = {
            name: {"median_ms": round(_stats(v)[0], 3), "min_ms": round(_stats(v)[1], 3),
                   "ratio_to_baseline": round(_stats(v)[0] / base_med, 2)} for name, v in rows.items()}
    info["loadavg_end"] = os.getloadavg()[0]
    renderer.close()
    for vao in (trivial_vao, bare_vao):
        vao.release()

    if a.json:
        print(json.dumps(info, indent=2, ensure_ascii=False))
        return 0
    print(f"{info['booth']} / {lighting} / {view}   GL: {info['gl_renderer']} ({info['gl_version']})")
    print(f"cpus {info['cpus']}, load average {info['loadavg_start']:.2f} → {info['loadavg_end']:.2f}; "
          f"median and minimum of {a.frames} frames after {a.warmup} warm-up frames")
    print("\nsetup (once; not in any frame time)")
    for name, s in setup.items():
        print(f"  {name:<40s} {s:8.2f} s")
    for size, rows in info["sizes"].items():
        print(f"\n{size:<40s} {'median ms':>10s} {'min ms':>8s} {'× baseline':>11s}")
        for name, r in rows.items():
            print(f"{name:<40s} {r['median_ms']:10.2f} {r['min_ms']:8.2f} {r['ratio_to_baseline']:11.2f}")
    goal = info["sizes"].get("1024x768", {}).get("frame realtime")
    if goal:
        print(f"\nfull graph (realtime) at 1024x768: median {goal['median_ms']:.1f} ms "
              f"(goal <= 50 ms: {'met' if goal['median_ms'] <= 50 else 'NOT met'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
