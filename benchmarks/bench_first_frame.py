"""Benchmark: the first frame of every shipped booth, the BYK web export and the first BYK compare.

Run:  .venv/bin/python benchmarks/bench_first_frame.py [--baseline main] [--revision REV] [--booths A,B]
      [--skip-web] [--skip-compare] [--skip-ratio] [--no-tables] [--json]

Every row runs in a fresh process (as ``lbscene render``, ``export-web`` or ``compare`` does), with
``LBSCENE_CACHE_DIR`` set to a folder of its own: ``empty`` (a first run on a new machine), then
``warm`` (the same folder again, a later run).  The shipped booths' precomputed light
(``engine/tables/``, ``scripts/make_tables.py``) is read as lbscene reads it; ``--no-tables``
turns it off (``LBSCENE_SHIPPED_TABLES=off``): what a booth of one's own costs the first time.  ``--baseline REV`` measures git revision ``REV``
(run from its own tree through ``PYTHONPATH``) alongside the working tree, interleaved row by row,
so that before and after see the same load.

First frame: compiling the booth and its render graph, the scene of its first view (the forward
model at every vertex) and one realtime frame at 1024×768 (GL context, uploads, shader
compilation) of the example glossy red sample (read as ``lbscene render`` reads it), seconds from
the first line of work after importing lbscene (lazy imports such as colour-science's count).
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
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BOOTHS = ["byk-byko-spectra-effect", "xrite-spectralight-qc", "iso3664-p1-d50"]
SAMPLE = REPO / "examples" / "render" / "sample-colorchecker-moderate-red-glossy.yaml"
WEB_CONFIG = REPO / "examples" / "render" / "byko-gonio-blue-45as15.yaml"


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


def _run(what: str, arg: str, cache: Path, pythonpath: Path | None) -> dict:
    env = {**os.environ, "LBSCENE_CACHE_DIR": str(cache), "PYOPENGL_PLATFORM": "egl"}
    if NO_TABLES:
        env["LBSCENE_SHIPPED_TABLES"] = "off"
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    p = subprocess.run([sys.executable, __file__, "--child", what, arg], env=env, capture_output=True,
                       text=True, cwd=REPO)
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(f"{what} {arg} failed:\n{p.stderr[-3000:]}")


NO_TABLES = False


def _package_of(rev: str, root: Path) -> Path:
    """A folder whose ``lbscene`` package is the tree of git revision ``rev`` (the layout of
    ``[tool.setuptools] package-dir``), for ``PYTHONPATH``: it comes before the editable install."""
    src = root / f"tree-{rev}"
    src.mkdir()
    tar = subprocess.run(["git", "archive", rev], cwd=REPO, capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(src)], input=tar, check=True)
    pkg = root / f"pkg-{rev}" / "lbscene"
    pkg.mkdir(parents=True)
    for item in (src / "lbscene").iterdir():
        (pkg / item.name).symlink_to(item)
    for sub in ("schemas", "engine", "bakers", "runtimes", "booths", "displays"):
        (pkg / sub).symlink_to(src / sub)
    return pkg.parent


def _states(what: str, arg: str, key: str, root: Path, trees: dict) -> dict:
    """``empty`` and ``warm`` of one measurement for every tree, interleaved (the baseline and
    the change see the same load)."""
    row: dict = {"key": key}
    for state in ("empty", "warm"):
        for name, path in trees.items():
            row[f"{name} {state}"] = _run(what, arg, root / f"cache-{name}-{what}-{arg}", path)
    return row


def _realtime_ratio(pythonpath: Path | None) -> dict:
    env = {**os.environ, "PYOPENGL_PLATFORM": "egl"}
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    p = subprocess.run([sys.executable, str(REPO / "benchmarks" / "bench_render.py"), "--sizes", "1024x768",
                        "--json"], capture_output=True, text=True, cwd=REPO, env=env)
    info = json.loads(p.stdout)
    rows = info["sizes"]["1024x768"]
    return {"bare_ms": rows["baseline: bare 16 bands → XYZ → RGB8"]["median_ms"],
            "realtime_ms": rows["frame realtime"]["median_ms"],
            "ratio": rows["frame realtime"]["ratio_to_baseline"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--booths", default=",".join(BOOTHS))
    ap.add_argument("--baseline", default="", help="git revision measured alongside, e.g. main")
    ap.add_argument("--revision", default="",
                    help="git revision measured as 'after' (default: the working tree)")
    ap.add_argument("--skip-web", action="store_true")
    ap.add_argument("--skip-compare", action="store_true")
    ap.add_argument("--skip-ratio", action="store_true")
    ap.add_argument("--no-tables", action="store_true", help="without the shipped tables (a new booth)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    global NO_TABLES
    NO_TABLES = a.no_tables
    if a.child:
        return _child(*a.child)
    info: dict = {"cpus": os.cpu_count(), "loadavg_start": os.getloadavg()[0], "rows": {},
                  "shipped_tables": not a.no_tables}
    with tempfile.TemporaryDirectory(prefix="lbscene-bench-") as td:
        root = Path(td)
        trees = {"before": _package_of(a.baseline, root)} if a.baseline else {}
        trees["after"] = _package_of(a.revision, root) if a.revision else None
        info["trees"] = {"before": a.baseline or None, "after": a.revision or "working tree"}
        for booth in a.booths.split(","):
            info["rows"][f"first frame {booth}"] = _states("first_frame", booth, "first_frame_s", root, trees)
        if not a.skip_web:
            info["rows"]["BYK export-web, 6 geometries"] = _states("web", "byk", "export_s", root, trees)
        if not a.skip_compare:
            info["rows"]["first BYK compare (A3 grid)"] = _states("compare", "byk", "compare_s", root, trees)
        if not a.skip_ratio:
            info["realtime"] = {name: _realtime_ratio(path) for name, path in trees.items()}
    info["loadavg_end"] = os.getloadavg()[0]
    if a.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"cpus {info['cpus']}, load average {info['loadavg_start']:.2f} → {info['loadavg_end']:.2f}; "
          f"seconds, each a fresh process; before: {a.baseline or '-'}, "
          f"after: {a.revision or 'the working tree'}; shipped tables "
          f"{'off (a new booth)' if a.no_tables else 'on'}")
    cols = [f"{t} {s}" for s in ("empty", "warm") for t in trees]
    print(f"\n{'':36s}" + "".join(f"{c + ' s':>15s}" for c in cols))
    for name, row in info["rows"].items():
        k = row["key"]
        print(f"{name:36s}" + "".join(f"{row[c][k]:15.2f}" for c in cols))
    for name, r in info.get("realtime", {}).items():
        print(f"\nrealtime frame 1024x768 ({name}): {r['realtime_ms']:.1f} ms, bare 16-band pass "
              f"{r['bare_ms']:.1f} ms: {r['ratio']:.2f}× (goal ≤ 1.0×)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
