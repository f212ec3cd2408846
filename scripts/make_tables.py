"""Make the shipped tables: the light of every shipped booth, precomputed (``engine/tables/``).

Run:  .venv/bin/python scripts/make_tables.py [--check] [--booths A,B]

For every shipped booth, every lighting and every view of its render graph, the scene of the
view is built with the example sample (``examples/render/``), and the light on the A3 grid of the
seed's measurements is evaluated (what ``compare`` starts with), while the disk cache records
each computation it would keep (:func:`lbscene.engine.files.disk_cache.recording_tables`): the
patch radiosity of each lighting (read by every view, the web export and ``compare``), the light
at the booth's vertices and at the sample's centre, and which parts of each patch the A3 grid's
points see past the booth's meshes and bodies.  They are written as float32 ``.npy`` under
``engine/tables/<kind>-<key>.npy``; tables no longer produced (an edited booth or model) are
removed.  Their keys hold the booth's content and the light model's code, so a table is only
ever read for the booth and the code it was made from; a stale one is never used, and a missing
one costs time, not accuracy.

``--check``: write nothing; exit 1 when the tables on disk are not exactly the ones this code
would make (names), or their values differ by more than float32 rounding.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TABLES = REPO / "engine" / "tables"
BOOTHS = ["byk-byko-spectra-effect", "xrite-spectralight-qc", "iso3664-p1-d50"]
SAMPLES = [REPO / "examples" / "render" / "sample-colorchecker-moderate-red-glossy.yaml"]
#: what the views' recording keeps: their light and the solution it came from
VIEW_KINDS = ("patch_radiosity", "vertex_irradiance", "point_irradiance_1nm")
#: relative difference tolerated by --check (float32 storage, thread order of sums)
CHECK_RTOL = 1e-5


def record(booths) -> dict[str, np.ndarray]:
    """``{"kind-key.npy": array}`` of every table for ``booths``."""
    from lbscene.engine.files.disk_cache import recording_tables
    from lbscene.engine.files.load import load_document
    from lbscene.engine.light.forward import ForwardModel
    from lbscene.engine.truth.synthetic import a3_grid
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.scene.sample import SampleSpec
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.graph import build_render_graph
    from lbscene.runtimes.scene import SceneBuilder
    from lbscene.schemas.sample import Sample

    samples = [SampleSpec.from_document(load_document(p, Sample)) for p in SAMPLES]
    out: dict[str, np.ndarray] = {}
    for booth in booths:
        ir = compile_booth(REPO / "booths" / booth)
        for lighting in ir.lighting:
            graph = build_render_graph(ir, lighting)
            memo: dict = {}
            with recording_tables() as rec:
                for sample in samples:
                    scene = SceneBuilder(ir, graph, sample, srgb_display(), irradiance_memo=memo)
                    for name in scene.view_names:
                        scene.view(name)
            # the views' own light, not the visibility behind it (thousands of receivers, ~8 MB each)
            kept = {k: v for k, v in rec.items() if k.rsplit("-", 1)[0] in VIEW_KINDS}
            with recording_tables() as rec:
                ForwardModel(ir, lighting).illuminance_lx(a3_grid())
            kept.update(rec)
            print(f"{booth} {lighting}: {len(kept)} tables", flush=True)
            out.update(kept)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--booths", default=",".join(BOOTHS))
    a = ap.parse_args(argv)
    # tables are recorded, not read; the disk cache still speeds up the geometry
    os.environ.setdefault("LBSCENE_CACHE_DIR", tempfile.mkdtemp(prefix="lbscene-tables-"))
    tables = record(a.booths.split(","))
    old = {p.name for p in TABLES.glob("*.npy")}
    if a.check:
        bad = sorted(old ^ set(tables))
        for name, arr in tables.items():
            if name in old:
                have = np.load(TABLES / name)
                scale = max(float(np.max(np.abs(arr))), 1e-30)
                if have.shape != arr.shape or float(np.max(np.abs(have - arr))) > CHECK_RTOL * scale:
                    bad.append(name)
        print("shipped tables current" if not bad else "shipped tables stale: " + ", ".join(bad))
        return 1 if bad else 0
    for name, arr in tables.items():
        np.save(TABLES / name, np.asarray(arr, np.float32), allow_pickle=False)
    for name in old - set(tables):
        (TABLES / name).unlink()
    total = sum(p.stat().st_size for p in TABLES.glob("*.npy"))
    print(f"{len(tables)} tables, {total / 2 ** 20:.1f} MiB in {TABLES.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
