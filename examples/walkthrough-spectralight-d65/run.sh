#!/usr/bin/env bash
# The measurement loop end to end on the shipped SpectraLight QC (D65): compare, read the verdict,
# add the suggested effect to a copy of the booth file (a YAML edit, no code), compare again, plot
# the history.  Everything it writes goes to build/walkthrough/ (a fresh copy each run).
set -euo pipefail
cd "$(dirname "$0")/../.."
LB=.venv/bin/lbscene
PY=.venv/bin/python
HERE=examples/walkthrough-spectralight-d65
OUT=build/walkthrough
rm -rf "$OUT"
mkdir -p "$OUT/measurements"
cp "$HERE"/measurements.yaml "$HERE"/measurements-*.csv "$OUT/measurements/"
cp -r booths/xrite-spectralight-qc "$OUT/booth"
M="$OUT/measurements/measurements.yaml"

echo "== 1. compare the measurements with the booth model as shipped"
$LB compare "$M" --booth "$OUT/booth" --report "$OUT/report-1.html" --json-out "$OUT/compare-1.json"

echo "== 2. add what the diagnosis suggests to the booth file (YAML only)"
$PY - "$OUT/compare-1.json" "$OUT/booth/booth.yaml" <<'PYEOF'
import json, re, sys
res = json.load(open(sys.argv[1]))
if not res["verdict"].startswith("missing:"):
    sys.exit(f"expected a missing effect, got {res['verdict']}")
booth = open(sys.argv[2]).read()
# the snippet is the booth's whole effects: section with the new effect added
booth = re.sub(r"(?ms)^effects:\n(?:[ \t#].*\n?|\n)*", "", booth).rstrip("\n") + "\n"
open(sys.argv[2], "w").write(booth + res["snippet"].rstrip("\n") + "\n")
print(f"added {res['verdict'].split(':', 1)[1]}:\n{res['snippet']}")
PYEOF

echo "== 3. compare again"
$LB compare "$M" --booth "$OUT/booth" --report "$OUT/report-2.html"

echo "== 4. the history: error per step, labelled with what changed"
$LB history "$M" --plot "$OUT/history.png"
echo "walkthrough finished: see $OUT/ (report-1.html, report-2.html, history.png)"
