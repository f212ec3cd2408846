#!/usr/bin/env bash
# The main job on the shipped booths: validate every shipped file, build the SpectraLight QC, run the
# measurement loop on the shipped example measurements (compare, add the missing effect, compare again,
# history plot) and render a sample in the booth.  Everything goes to build/.
set -euo pipefail
cd "$(dirname "$0")/.."
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
LB=.venv/bin/lbscene
BOOTH=booths/xrite-spectralight-qc
echo "== validate-config booths/ displays/ examples/"
$LB validate-config booths displays examples
echo "== build $BOOTH"
$LB build "$BOOTH" --out build/xrite-spectralight-qc
echo "== measurement loop: examples/walkthrough-spectralight-d65"
bash examples/walkthrough-spectralight-d65/run.sh
echo "== render a ColorChecker patch in the SpectraLight QC under D65"
$LB render examples/render/splqc-d65-moderate-red.yaml -o build/demo-render.png
echo "== does the ISO 3664 booth meet its standard?"
$LB conformance booths/iso3664-p1-d50 --lighting P1 --report build/conformance-iso3664-p1.html
echo "demo finished: see build/ (walkthrough/report-*.html, walkthrough/history.png, demo-render.png, conformance-iso3664-p1.html)"
