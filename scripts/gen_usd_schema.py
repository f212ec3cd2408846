"""Regenerate engine/scene/usd_schema/{plugInfo.json,generatedSchema.usda} from schema.usda.

Developer tool: runs usdGenSchema.py from the usd-core wheel (needs jinja2) and fills the
@PLUG_INFO_*@ placeholders for a codeless, resource-only plugin.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pxr

here = Path(__file__).resolve().parents[1] / "engine" / "scene" / "usd_schema"
gen = Path(pxr.__file__).parent / "Usd" / "usdGenSchema.py"
subprocess.run([sys.executable, str(gen), str(here / "schema.usda"), str(here)], check=True)
text = (here / "plugInfo.json").read_text()
text = (text.replace("@PLUG_INFO_LIBRARY_PATH@", "").replace("@PLUG_INFO_RESOURCE_PATH@", ".")
        .replace("@PLUG_INFO_ROOT@", "."))
# drop the comment header usdGenSchema writes, keep valid JSON for other readers
body = "\n".join(ln for ln in text.splitlines() if not ln.lstrip().startswith("#"))
json.loads(body)
(here / "plugInfo.json").write_text(body.strip() + "\n")
gs = (here / "generatedSchema.usda").read_text()
(here / "generatedSchema.usda").write_text(gs)
print("regenerated", here)
