#!/usr/bin/env bash
# The main job on a shipped booth: validate every shipped file, then build the SpectraLight QC.
# Grows with the project (compare, render) as those commands land.
set -euo pipefail
cd "$(dirname "$0")/.."
LB=.venv/bin/lbscene
BOOTH=booths/xrite-spectralight-qc
echo "== validate-config booths/ displays/ examples/"
targets=(booths)
for d in displays examples; do [ -d "$d" ] && ls "$d"/*.yaml "$d"/*/*.yaml >/dev/null 2>&1 && targets+=("$d"); done
$LB validate-config "${targets[@]}"
echo "== build $BOOTH"
$LB build "$BOOTH" --out build/xrite-spectralight-qc
if [ -f examples/walkthrough-spectralight-d65/measurements.yaml ] && $LB --help | grep -q compare; then
  echo "== compare the shipped example measurements"
  $LB compare examples/walkthrough-spectralight-d65/measurements.yaml --report build/compare-report.html
fi
echo "demo finished: see build/"
