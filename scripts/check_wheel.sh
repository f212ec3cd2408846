#!/usr/bin/env bash
# Build the sdist, build the wheel from that sdist, install the wheel (not editable) into a fresh
# virtual environment with the pinned constraints (no bpy: the `bake` extra is not needed), then, from
# a folder outside the repository, validate, build and render a shipped booth with the installed CLI.
# Any file the code opens at run time but the sdist or the wheel lacks makes one of these steps fail.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
PY=${PYTHON:-.venv/bin/python}
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/lbscene-check-wheel.XXXXXX")
trap 'rm -rf "$WORK"' EXIT

echo "== sdist and wheel (setuptools.build_meta, the build backend pip would call)"
mkdir -p "$WORK/dist"
"$PY" - "$WORK/dist" <<'PY'
import os, sys, tarfile
from pathlib import Path
from setuptools import build_meta
dist = Path(sys.argv[1])
sdist = dist / build_meta.build_sdist(str(dist))
with tarfile.open(sdist) as tar:
    tar.extractall(dist / "src", filter="data")
(src,) = (dist / "src").iterdir()
os.chdir(src)          # the wheel is built from the unpacked sdist: a file missing there is missing here
print(sdist.name, build_meta.build_wheel(str(dist)))
PY
WHEEL=$(ls "$WORK"/dist/lbscene-*.whl)

echo "== fresh virtual environment, wheel installed (pip cache reused)"
"${PYTHON_BASE:-python3.11}" -m venv "$WORK/venv"
"$WORK/venv/bin/python" -m pip install -q --upgrade "pip>=24"
"$WORK/venv/bin/python" -m pip install -q -c constraints.txt "$WHEEL"
LB="$WORK/venv/bin/lbscene"

mkdir -p "$WORK/user" && cd "$WORK/user"
"$WORK/venv/bin/python" - <<'PY'
import lbscene, sys
from pathlib import Path
site = Path(lbscene.__file__).resolve().parents[1]
assert "site-packages" in site.parts, f"lbscene imported from {site}, not the installed wheel"
print("lbscene", lbscene.__version__, "from", site)
PY
BOOTH=$("$WORK/venv/bin/python" -c "from lbscene.engine.files.shipped import shipped_booth; print(shipped_booth('xrite-spectralight-qc').parent)")
DISPLAY_YAML=$("$WORK/venv/bin/python" -c "from lbscene.engine.files.shipped import shipped_displays; print(shipped_displays()['srgb-reference'])")

echo "== validate-config, build and render the shipped SpectraLight QC from $PWD"
"$LB" validate-config "$BOOTH" "$DISPLAY_YAML"
"$LB" build xrite-spectralight-qc --out build-splqc
test -s build-splqc/scene.usda && test -s build-splqc/scene.ir.json
cat > grey.yaml <<'YAML'
version: 1
kind: sample
name: flat grey
provenance: {status: synthetic, source: "check-wheel"}
size_mm: [100, 85]
reflectance: {type: constant, value: 0.2}
YAML
cat > render.yaml <<YAML
version: 1
kind: render_config
booth: $BOOTH
lighting: D65
sample: grey.yaml
display: $DISPLAY_YAML
output: {png: grey-d65.png, width_px: 160, height_px: 120}
YAML
"$LB" render render.yaml
test -s grey-d65.png

echo "== the installed wheel reads its shipped tables (the light of every view, no forward model run)"
LBSCENE_CACHE_DIR=off "$WORK/venv/bin/python" - "$REPO/examples/render/sample-colorchecker-moderate-red-glossy.yaml" <<'PY'
import sys
from lbscene.engine.files.load import load_document
from lbscene.engine.files.shipped import shipped_booth
from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.scene.sample import SampleSpec
from lbscene.runtimes import scene
from lbscene.runtimes.colour_bridge import srgb_display
from lbscene.runtimes.graph import build_render_graph
from lbscene.schemas.sample import Sample

def no_model(*a, **k):
    raise SystemExit("the installed wheel computed the light of a shipped booth: its tables are missing or "
                     "its code digest differs from the checkout's")

scene._forward_model = no_model
sample = SampleSpec.from_document(load_document(sys.argv[1], Sample))
for name in ("xrite-spectralight-qc", "byk-byko-spectra-effect", "iso3664-p1-d50"):
    ir = compile_booth(shipped_booth(name).parent)
    for lighting in ir.lighting:
        sb = scene.SceneBuilder(ir, build_render_graph(ir, lighting), sample, srgb_display())
        for view in sb.view_names:
            sb.view(view)
print("shipped tables read for every view")
PY
echo "check-wheel: OK ($(basename "$WHEEL"))"
