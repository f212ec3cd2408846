"""Benchmark: the first frame of every shipped booth, the BYK web export and the first BYK compare.

Run:  .venv/bin/python benchmarks/bench_first_frame.py [--skip-web] [--skip-compare] [--skip-ratio]
      [--json]

Every row runs in a fresh process (as ``lbscene render``, ``export-web`` or ``compare`` does), with
``LBSCENE_CACHE_DIR`` set to a folder of its own:

* ``empty``: a fresh, empty disk cache (a first run on a new machine);
* ``warm``: the same folder again, as the previous row left it (a later run);
* ``warm, geometry only``: the warm folder less the per-vertex results (``vertex_irradiance``,
  ``point_irradiance_1nm``): the state a warm cache had before the vertices' light was cached,
  the baseline of the warm rows, measured in the same run.

First frame: compiling the booth and its render graph, the scene of its first view (the forward
model at every vertex) and one realtime frame at 1024×768 (GL context, uploads, shader
compilation) of the example glossy red sample (read as ``lbscene render`` reads it), seconds from the first line of work after the imports.
Web export: ``export-web`` inputs and manifest of ``examples/render/byko-gonio-blue-45as15.yaml``
with all six geometries.  Compare: the first forward-model evaluation of the seed's 55-point A3
grid in the BYK booth (what ``lbscene compare`` starts with).  Realtime ratio: the ``frame
realtime`` row of ``bench_render.py`` at 1024×768 against its bare 16-band pass (same run).

Goals (issue "A house you can live in"): first frame ≤ 5 s empty, ≤ 1 s warm; web export ≤ 30 s;
first compare ≤ 3 s; realtime frame ≤ 1.0× the bare pass.  Timings on a shared machine are noisy:
compare rows of one run only.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BOOTHS = ["byk-byko-spectra-effect", "xrite-spectralight-qc", "iso3664-p1-d50"]
SAMPLE = REPO / "examples" / "render" / "sample-colorchecker-moderate-red-glossy.yaml"
WEB_CONFIG = REPO / "examples" / "render" / "byko-gonio-blue-45as15.yaml"
#: cache folders holding results rather than geometry (removed for the "geometry only" rows)
RESULT_KINDS = ("vertex_irradiance", "point_irradiance_1nm")


def _first_frame(booth: str) -> dict:
    t0 = time.perf_counter()
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.graph import build_render_graph
    from lbscene.engine.files.load import load_document
    from lbscene.engine.scene.sample import SampleSpec
    from lbscene.runtimes.render import Renderer
    from lbscene.schemas.sample import Sample

    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    sample = SampleSpec.from_document(load_document(SAMPLE, Sample))
    ir = compile_booth(REPO / "booths" / booth)
    lighting = next(iter(ir.lighting))
    graph = build_render_graph(ir, lighting)
    view = graph["views"][0]["name"]
    t_compile = time.perf_counter() - t0
    r = Renderer(ir, graph, sample, srgb_display())
    t1 = time.perf_counter()
    r.scene.view(view)
    t_scene = time.perf_counter() - t1
    r.render(view, (1024, 768), schedule="realtime")
    total = time.perf_counter() - t0
    r.close()
    return {"lighting": lighting, "view": view, "import_s": t_import, "compile_s": t_compile,
            "scene_s": t_scene, "first_frame_s": total}


def _web_export() -> dict:
    from lbscene.commands.web import gather_inputs
    from lbscene.runtimes.web.export import build_export

    t0 = time.perf_counter()
    inp, _ = gather_inputs(WEB_CONFIG, size=(1024, 768))
    manifest = build_export(inp)
    return {"export_s": time.perf_counter() - t0, "views": len(manifest.get("views", []))
            if isinstance(manifest, dict) else None}


def _compare() -> dict:
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.synthetic import a3_grid

    ir = compile_booth(REPO / "booths" / "byk-byko-spectra-effect")
    t0 = time.perf_counter()
    ForwardModel(ir, "FL950").illuminance_lx(a3_grid())
    return {"compare_s": time.perf_counter() - t0}


def _child(what: str, arg: str) -> int:
    out = {"first_frame": lambda: _first_frame(arg), "web": _web_export, "compare": _compare}[what]()
    print("RESULT " + json.dumps(out))
    return 0


def _run(what: str, arg: str, cache: Path) -> dict:
    env = {**os.environ, "LBSCENE_CACHE_DIR": str(cache), "PYOPENGL_PLATFORM": "egl"}
    p = subprocess.run([sys.executable, __file__, "--child", what, arg], env=env, capture_output=True,
                       text=True, cwd=REPO)
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(f"{what} {arg} failed:\n{p.stderr[-3000:]}")


def _three_states(what: str, arg: str, key: str, root: Path) -> dict:
    """``empty``, ``warm`` and ``warm, geometry only`` (the warm baseline) of one measurement."""
    cache = root / f"{what}-{arg}"
    row = {"empty": _run(what, arg, cache)}
    geo = root / f"{what}-{arg}-geometry"
    shutil.copytree(cache, geo)
    for kind in RESULT_KINDS:
        shutil.rmtree(geo / kind, ignore_errors=True)
    # interleaved: the baseline and the change see the same load
    row["warm, geometry only"] = _run(what, arg, geo)
    row["warm"] = _run(what, arg, cache)
    row["key"] = key
    return row


def _realtime_ratio() -> dict:
    p = subprocess.run([sys.executable, str(REPO / "benchmarks" / "bench_render.py"), "--sizes", "1024x768",
                        "--json"], capture_output=True, text=True, cwd=REPO,
                       env={**os.environ, "PYOPENGL_PLATFORM": "egl"})
    info = json.loads(p.stdout)
    rows = info["sizes"]["1024x768"]
    return {"bare_ms": rows["baseline: bare 16 bands → XYZ → RGB8"]["median_ms"],
            "realtime_ms": rows["frame realtime"]["median_ms"],
            "ratio": rows["frame realtime"]["ratio_to_baseline"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--booths", default=",".join(BOOTHS))
    ap.add_argument("--skip-web", action="store_true")
    ap.add_argument("--skip-compare", action="store_true")
    ap.add_argument("--skip-ratio", action="store_true")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    if a.child:
        return _child(*a.child)
    info: dict = {"cpus": os.cpu_count(), "loadavg_start": os.getloadavg()[0], "rows": {}}
    with tempfile.TemporaryDirectory(prefix="lbscene-bench-") as td:
        root = Path(td)
        for booth in a.booths.split(","):
            info["rows"][f"first frame {booth}"] = _three_states("first_frame", booth, "first_frame_s", root)
        if not a.skip_web:
            info["rows"]["BYK export-web, 6 geometries"] = _three_states("web", "byk", "export_s", root)
        if not a.skip_compare:
            info["rows"]["first BYK compare (A3 grid)"] = _three_states("compare", "byk", "compare_s", root)
    if not a.skip_ratio:
        info["realtime"] = _realtime_ratio()
    info["loadavg_end"] = os.getloadavg()[0]
    if a.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"cpus {info['cpus']}, load average {info['loadavg_start']:.2f} → {info['loadavg_end']:.2f}; "
          "seconds, each a fresh process")
    print(f"\n{'':42s} {'empty s':>9s} {'warm (geometry only) s':>23s} {'warm s':>8s}")
    for name, row in info["rows"].items():
        k = row["key"]
        print(f"{name:42s} {row['empty'][k]:9.2f} {row['warm, geometry only'][k]:23.2f} {row['warm'][k]:8.2f}")
    if "realtime" in info:
        r = info["realtime"]
        print(f"\nrealtime frame 1024x768: {r['realtime_ms']:.1f} ms, bare 16-band pass {r['bare_ms']:.1f} ms: "
              f"{r['ratio']:.2f}× (goal ≤ 1.0×)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
