"""Benchmark: how long the diagnosis takes on 55 readings with every candidate and hypothesis.

Run: .venv/bin/python benchmarks/bench_diagnosis.py [--baseline CHECKOUT] [--repeat 2]

The measurement sets are made once, by this checkout: the Mitsuba 3 cases of
``tests/engine/test_diagnosis_on_truth.py`` (55-point A3 grid, white tile at 5 nm), the
narrow-dip filter of ``tests/engine/test_spectral_verdicts.py`` (σ = 15 nm, 25 %), and
synthetic readings of the shipped SpectraLight QC (six effects enabled, a detector's cosine
error hidden; the reference engine).  "refitted": the candidates refitted; "out of reach":
hardware hypotheses the white tile's spectrum ruled out before any refit
(:mod:`lbscene.engine.loop.spectral_reach`).  Each ``compare`` runs in a fresh process (nothing
cached in memory, the geometry disk cache off); the table gives the best of ``--repeat`` runs
of its ``diagnose`` step, wall and CPU time (all threads and the worker processes it forks; on a
shared machine the wall time measures the other jobs too).  With ``--baseline``, a checkout of the code before (with its own
``.venv``) runs the same files in the same run, and the table gives the ratio.
Goal: diagnosis ≤ 5 s on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent


def _load(relpath: str, name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, REPO / relpath)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def make_cases(root: Path) -> list[tuple[str, Path]]:
    """The measurement sets, written under ``root``."""
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.truth.synthetic import synthesize

    T = _load("tests/engine/test_diagnosis_on_truth.py", "diagnosis_on_truth")
    S = _load("tests/engine/test_spectral_verdicts.py", "spectral_verdicts")
    out = []
    for cid in ("filter-undeclared-fitted", "lamp-shift-fitted", "filter-declared-known",
                "interreflection-45-fitted", "aperture-declared-known"):
        c = next(x for x in T.CASES if x.id == cid)
        out.append((cid, T.make_case(c, root / cid)))
    d = root / "dip-15nm"
    d.mkdir()
    out.append(("filter dip σ 15 nm (undeclared)", S.filter_case(d, S.gaussian_dip(0.25, 560.0, 15.0))))
    booth = REPO / "booths" / "xrite-spectralight-qc"
    ir = compile_booth(find_booth_file(booth))
    truth = {**{k: dict(v) for k, v in ir.effects.items()}, "detector_cosine_error": {"exponent": 1.2}}
    out.append(("xrite-spectralight-qc (cosine error)",
                synthesize(booth, root / "xrite", lighting="D65", truth_effects=truth, noise_percent=1.0)))
    return out


def time_one(python: str, m: Path, repeat: int) -> dict:
    """Best of ``repeat`` fresh-process runs of ``compare`` on ``m`` under ``python``."""
    # the diagnose step's CPU time too (all threads, and the processes it forked): on a shared
    # machine its wall time measures the other jobs as much as the diagnosis
    code = ("import json, os, sys, time\n"
            "import lbscene.engine.loop.compare as C\n"
            "cpu = []\n"
            "def used():\n"
            "    t = os.times()\n"
            "    return time.process_time() + t.children_user + t.children_system\n"
            "def timed(*a, _d=C.diagnose, **k):\n"
            "    c0 = used()\n"
            "    try:\n"
            "        return _d(*a, **k)\n"
            "    finally:\n"
            "        cpu.append(used() - c0)\n"
            "C.diagnose = timed\n"
            "r = C.run_compare(sys.argv[1], history=False)\n"
            "print(json.dumps({'diagnose': r.timing_s.get('diagnose'), 'total': r.timing_s.get('total'),"
            " 'cpu': sum(cpu), 'verdict': str(r.verdict), 'candidates': len(r.diagnosis.suspects),"
            " 'screened': sum(1 for v in r.diagnosis.skipped.values() if v.startswith('not refitted'))}))\n")
    env = {**os.environ, "LBSCENE_CACHE_DIR": "off"}
    runs = []
    for _ in range(repeat):
        p = subprocess.run([python, "-c", code, str(m)], capture_output=True, text=True, env=env,
                           cwd=str(m.parent))
        if p.returncode != 0:
            return {"error": p.stderr.strip().splitlines()[-1] if p.stderr.strip() else f"exit {p.returncode}"}
        runs.append(json.loads(p.stdout.strip().splitlines()[-1]))
    return min(runs, key=lambda r: r["cpu"])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", type=Path, help="a checkout of the code before, with its own .venv")
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    base_py = str(a.baseline / ".venv" / "bin" / "python") if a.baseline else None
    with tempfile.TemporaryDirectory() as td:
        cases = make_cases(Path(td))
        head = "| case | refitted | out of reach | diagnose s | diagnose CPU s | total s | verdict |"
        if base_py:
            head += " before: diagnose s | before: diagnose CPU s | before: verdict | before / now (CPU) |"
        print(head)
        print("|" + "---|" * (head.count("|") - 1))
        for label, m in cases:
            now = time_one(sys.executable, m, a.repeat)
            if "error" in now:
                print(f"| {label} | error: {now['error']} |", flush=True)
                continue
            row = (f"| {label} | {now['candidates']} | {now.get('screened', 0)} | {now['diagnose']:.2f} | "
                   f"{now['cpu']:.2f} | {now['total']:.2f} | "
                   f"{now['verdict']} |")
            if base_py:
                old = time_one(base_py, m, a.repeat)
                if "error" in old:
                    row += f" error: {old['error']} | — | — | — |"
                else:
                    row += (f" {old['diagnose']:.2f} | {old['cpu']:.2f} | {old['verdict']} | "
                            f"{old['cpu'] / now['cpu']:.2f} |")
            print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
