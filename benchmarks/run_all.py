"""Run every benchmark script in this folder (bench_*.py), one after the other."""

import subprocess
import sys
from pathlib import Path

here = Path(__file__).resolve().parent
rc = 0
for script in sorted(here.glob("bench_*.py")):
    print(f"\n### {script.name}", flush=True)
    rc |= subprocess.call([sys.executable, str(script)])
sys.exit(rc)
