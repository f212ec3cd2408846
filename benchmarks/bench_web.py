"""Benchmark: the exported web viewer in headless Chromium against the moderngl runtime.

Run:  .venv/bin/python benchmarks/bench_web.py [--config examples/render/byko-gonio-blue-45as15.yaml]
      [--size 1024x768] [--frames 20] [--views 45as15,45as45] [--export DIR] [--json]

Setup (reported separately): ``export-web`` of the configuration (the forward model at every
vertex of every view: the bulk of the time), its data size.  Then per view:

* ``browser frame``: median of ``--frames`` frames of the viewer's realtime schedule in Chromium
  (SwiftShader WebGL2 on the CPU), each timed with ``performance.now()`` around the draw, the
  copy to the canvas and a one-pixel ``readPixels`` (waits for the GPU);
* ``moderngl frame``: the same schedule through the Python executor on this machine's EGL
  (Mesa llvmpipe without a GPU), median of as many frames, ending with ``ctx.finish()``; the
  ratio browser / moderngl is in the same run;
* ``ΔE00``: the Chromium screenshot (``--screenshot``) against the moderngl image, per pixel
  after the configuration's display model (mean, 99th percentile, max).

Without Chromium the script says so and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import median_of  # noqa: E402

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(REPO / "examples/render/byko-gonio-blue-45as15.yaml"))
    ap.add_argument("--size", default="1024x768")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--views", default="", help="comma-separated views (default: the config's)")
    ap.add_argument("--export", default="", help="reuse (or write) the export in this folder")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()

    from PIL import Image

    from lbscene.runtimes.render import parse_size, prepare_from_config
    from lbscene.runtimes.web.browser import find_chromium, image_delta_e00, run_viewer, screenshot
    from lbscene.runtimes.web.export import build_export, is_web_export, write_export
    from lbscene.commands.web import gather_inputs

    if find_chromium() is None:
        print("chromium not found: nothing to measure (scripts/install-test-deps.sh installs it)")
        return 0
    size = parse_size(a.size)
    cfg = Path(a.config)
    folder = Path(a.export) if a.export else Path(tempfile.mkdtemp(prefix="lbscene-web-")) / "viewer"
    setup = {}
    if not is_web_export(folder):
        t0 = time.perf_counter()
        inp, _ = gather_inputs(cfg, size=size)
        manifest = build_export(inp)
        write_export(manifest, folder)
        setup["export_s"] = round(time.perf_counter() - t0, 1)
    setup["data_file_MB"] = round((folder / "lbscene-data.js").stat().st_size / 1e6, 2)

    job = prepare_from_config(cfg)
    views = [v for v in a.views.split(",") if v] or job.views
    r = job.renderer()
    display_path = None
    if not job.display.source.startswith("builtin"):
        display_path = Path(job.display.source.split(": ", 1)[1])
    rows = []
    try:
        for v in views:
            ref = r.render(v, size).rgba8
            ml = median_of(lambda: r.render(v, size), a.frames)
            rep = run_viewer(folder, size_px=size, bench=a.frames, extra={"view": v}, timeout_s=600)
            with tempfile.TemporaryDirectory() as td:
                shot = np.asarray(Image.open(screenshot(folder, Path(td) / "s.png", size_px=size,
                                                        extra={"view": v}, timeout_s=600)).convert("RGB"))
            de = image_delta_e00(shot, ref[..., :3], display_path)
            br = float(np.median(rep.frame_ms))
            rows.append({"view": v, "browser_frame_ms": round(br, 1), "moderngl_frame_ms": round(1e3 * ml, 1),
                         "ratio_browser_to_moderngl": round(br / (1e3 * ml), 2),
                         "first_browser_frame_ms": round(rep.first_frame_ms or 0.0, 0),
                         "delta_e00_mean": round(float(de.mean()), 4),
                         "delta_e00_p99": round(float(np.percentile(de, 99)), 3),
                         "delta_e00_max": round(float(de.max()), 2),
                         "browser_gl": rep.gl_renderer, "moderngl_gl": r.gl_renderer})
    finally:
        r.close()
    result = {"config": str(cfg), "size": list(size), "frames": a.frames, "setup": setup, "views": rows}
    if a.json:
        print(json.dumps(result, indent=1))
        return 0
    print(f"{cfg.name}  {size[0]}x{size[1]}  export {setup.get('export_s', '(reused)')} s, "
          f"data {setup['data_file_MB']} MB")
    print(f"{'view':10} {'browser ms':>10} {'moderngl ms':>11} {'ratio':>6} {'first ms':>9} "
          f"{'ΔE00 mean':>9} {'p99':>6} {'max':>6}")
    for x in rows:
        print(f"{x['view']:10} {x['browser_frame_ms']:10.1f} {x['moderngl_frame_ms']:11.1f} "
              f"{x['ratio_browser_to_moderngl']:6.2f} {x['first_browser_frame_ms']:9.0f} "
              f"{x['delta_e00_mean']:9.4f} {x['delta_e00_p99']:6.3f} {x['delta_e00_max']:6.2f}")
    if rows:
        print(f"browser: {rows[0]['browser_gl']}\nmoderngl: {rows[0]['moderngl_gl']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
