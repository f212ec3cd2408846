"""Bake the lamp-shapes test booth with ``lbscene bake`` and write the illuminance at its sample.

    .venv/bin/python tests/data/lamp-shapes-booth/bake_reference.py [BAKE_DIR]   # a few minutes

Writes ``bake-reference.json`` beside this script: per lighting (tube, panel, bulb) the bake's
``sample_lx_from_env`` at ``SAMPLES`` samples (the sample's light from the bake's environment
map: a thin tube covers a fraction of a map pixel, and the preview's 8 samples leave a few % of
noise there; 128 leave under 1 %), with the booth file's sha256.
``tests/bakers/test_blender_export.py`` compares Blender's render of the exported ``.blend`` with
it; its slow test bakes again and checks that this file is current.  ``BAKE_DIR`` keeps the bakes
(``lbscene bake`` reuses them while the booth is unchanged).
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
BOOTH = HERE / "booth.yaml"
OUT = HERE / "bake-reference.json"
LIGHTINGS = ("tube", "panel", "bulb")
SAMPLES = 128


def bake_sample_lx(lighting: str, bake_dir: Path) -> float:
    """``lbscene bake``'s illuminance at the sample (lx) for one lighting."""
    r = subprocess.run([sys.executable, "-m", "lbscene", "bake", str(BOOTH), "--lighting", lighting,
                        "--samples", str(SAMPLES), "--out", str(bake_dir), "--format", "json"],
                       capture_output=True, text=True, timeout=1800)
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return float(json.loads(r.stdout)["bakes"][0]["sample_lx_from_env"])


def reference(bake_dir: Path) -> dict:
    return {"booth_sha256": hashlib.sha256(BOOTH.read_bytes()).hexdigest(), "samples": SAMPLES,
            "command": "lbscene bake booth.yaml --lighting L --samples 128 --format json",
            "sample_lx_from_env": {name: bake_sample_lx(name, bake_dir) for name in LIGHTINGS}}


def main(argv: list[str]) -> int:
    with tempfile.TemporaryDirectory(prefix="lbscene-ref-") as tmp:
        ref = reference(Path(argv[0]) if argv else Path(tmp))
    OUT.write_text(json.dumps(ref, indent=1, sort_keys=True) + "\n")
    print(f"wrote {OUT.name}: {ref['sample_lx_from_env']}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
