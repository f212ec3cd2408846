"""
A hostile sweep of every command: odd output paths, odd input files, huge inputs, and kills.

Each case runs ``lbscene`` in a fresh process (timeout 120 s) inside a scratch workspace
that holds files "of the user" (a folder of notes, a regular file, the booth's own
sources).  A case passes when the process

* ends (no hang) with exit 0, or with exit 2 and a located ``LB…`` diagnostic,
* prints no Python traceback,
* leaves every file of the user byte-for-byte as it was,
* stays under the memory bound (peak RSS of the process and its children).

Run:  ``.venv/bin/python benchmarks/hostile_sweep.py [--quick]``.  Prints one line per
case and a summary table; exit 1 if any case fails.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MEMORY_BOUND_MB = 4096

_WRAPPER = (
    "import resource, sys\n"
    "from lbscene.cli import main\n"
    "rc = main(sys.argv[1:])\n"
    "ru = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,\n"
    "         resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    "print(f'@@maxrss_kb={ru}', file=sys.stderr)\n"
    "sys.exit(rc)\n"
)


def _digest(paths) -> dict:
    out = {}
    for root in paths:
        root = Path(root)
        if root.is_file():
            out[str(root)] = hashlib.sha256(root.read_bytes()).hexdigest()
        elif root.is_dir():
            for p in sorted(root.rglob("*")):
                if p.is_file() and not p.name.startswith(".lbscene-outputs"):
                    out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[str(root)] = "missing"
    return out


def workspace(tmp: Path) -> dict:
    """The scratch workspace: a booth, a measurement set, a render config and the user's files."""
    import numpy as np

    ws = {}
    booth = tmp / "booth"
    shutil.copytree(REPO / "tests" / "data" / "minimal-booth", booth)
    ws["booth"] = booth
    m = tmp / "m"
    m.mkdir()
    pts = [(x, y) for x in np.linspace(-400, 400, 7) for y in np.linspace(-250, 250, 5)]
    lux = [1000 * 0.7 / (0.49 + (x * x + y * y) / 1e6) ** 1.5 for x, y in pts]
    (m / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{x:g},{y:g},{e:.3f}\n" for (x, y), e in zip(pts, lux)))
    (m / "meas.yaml").write_text(
        "version: 1\nkind: measurement_set\nname: sweep\nbooth: ../booth\nlighting: A\n"
        "instrument: {illuminance_meter: m, repeatability_percent: 1}\nilluminance:\n  - path: grid.csv\n")
    ws["meas"] = m / "meas.yaml"
    ws["grid"] = m / "grid.csv"
    big = tmp / "big"
    big.mkdir()
    (big / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{x:.1f},{y:.1f},1000\n" for x in np.linspace(-490, 490, 100) for y in np.linspace(-290, 290, 100)))
    (big / "meas.yaml").write_text((m / "meas.yaml").read_text())
    ws["big_meas"] = big / "meas.yaml"
    cfg = tmp / "cfg"
    shutil.copytree(REPO / "tests" / "runtimes" / "data", cfg)
    ws["cfg"] = cfg / "tube-gonio.yaml"
    ws["sample"] = cfg / "sample-gonio.yaml"
    escaped = cfg / "escape.yaml"
    escaped.write_text(ws["cfg"].read_text().replace("png: out/tube-gonio.png", "png: ../../escaped.png"))
    ws["cfg_escape"] = escaped
    selfref = cfg / "self.yaml"
    selfref.write_text(ws["cfg"].read_text().replace("png: out/tube-gonio.png", "png: self.yaml"))
    ws["cfg_self"] = selfref
    user = tmp / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("the user's notes")
    ws["user_dir"] = user
    ws["user_file"] = tmp / "thesis.txt"
    ws["user_file"].write_text("precious")
    fifo = tmp / "pipe.yaml"
    os.mkfifo(fifo)
    ws["fifo"] = fifo
    ws["binary"] = tmp / "binary.yaml"
    ws["binary"].write_bytes(bytes(range(256)) * 64)
    ws["empty"] = tmp / "empty.yaml"
    ws["empty"].write_text("")
    many = tmp / "many-lamps"
    shutil.copytree(booth, many)
    text = (many / "booth.yaml").read_text()
    lamp = ("  - {{id: l{i}, type: point, position_mm: [{x}, 0, 700], point_sources: 100, "
            "spd: {{type: cie_illuminant, name: A}}, output: {{type: peak_intensity_cd, value_cd: 1}}}}\n")
    (many / "booth.yaml").write_text(text.replace("lighting:\n", "".join(
        lamp.format(i=i, x=-400 + (i % 800)) for i in range(3000)) + "lighting:\n"))
    ws["many_lamps"] = many
    atsample = tmp / "lamp-at-sample"
    shutil.copytree(booth, atsample)
    (atsample / "booth.yaml").write_text(text.replace("position_mm: [0, 0, 700]", "position_mm: [0, 0, 0]"))
    ws["lamp_at_sample"] = atsample
    # files of the user's named like old temporaries, beside an output lbscene writes
    for name in (".r.json.old-1", ".r.json.12345678.tmp"):
        (tmp / name).write_text("the user's backup")
        os.utime(tmp / name, (1_000_000_000, 1_000_000_000))
    (tmp / ".r.json.tmp-mywork").mkdir()
    (tmp / ".r.json.tmp-mywork" / "x.txt").write_text("mine")
    os.utime(tmp / ".r.json.tmp-mywork", (1_000_000_000, 1_000_000_000))
    # a cache folder holding the user's own .npy files and a FIFO where the index goes
    cache = tmp / "cache"
    (cache / "mine").mkdir(parents=True)
    np.save(cache / "mine" / "results.npy", np.arange(1000.0))
    os.mkfifo(cache / "lbscene-cache-index.json")
    ws["cache"] = cache
    # an earlier web export in which the user saved notes
    viewer = tmp / "viewer"
    subprocess.run([sys.executable, "-m", "lbscene", "export-web", str(booth), "--out", str(viewer)],
                   capture_output=True, check=True, cwd=tmp)
    (viewer / "notes.txt").write_text("what I saw")
    ws["viewer"] = viewer
    ws["protected"] = [booth, m, cfg, user, ws["user_file"], many, atsample, big, cache, viewer,
                       tmp / ".r.json.old-1", tmp / ".r.json.12345678.tmp", tmp / ".r.json.tmp-mywork"]
    return ws


def cases(ws: dict, quick: bool) -> list[tuple[str, list, dict]]:
    b, meas, cfg = ws["booth"], ws["meas"], ws["cfg"]
    odd_dirs = {"user folder": ws["user_dir"], "booth folder": b, "regular file": ws["user_file"],
                "cwd": Path("."), "under a file": ws["user_file"] / "x", "/proc": Path("/proc/lbs"),
                "measurement folder": meas.parent}
    odd_files = {"user file": ws["user_file"], "folder": ws["user_dir"], "input yaml": meas,
                 "input csv": ws["grid"], "under a file": ws["user_file"] / "x.out", "/proc": Path("/proc/x.out"),
                 "booth file": b / "booth.yaml"}
    odd_inputs = {"fifo": ws["fifo"], "/dev/zero": Path("/dev/zero"), "binary": ws["binary"],
                  "empty": ws["empty"], "missing": Path("nope.yaml"), "folder": ws["user_dir"]}
    out = []
    for name, p in odd_dirs.items():
        out.append((f"build --out {name}", ["build", b, "--out", p], {}))
    for name, p in odd_files.items():
        out.append((f"compare --json-out {name}", ["compare", meas, "--no-diagnose", "--no-history",
                                                   "--json-out", p], {}))
        out.append((f"compare --report {name}", ["compare", meas, "--no-diagnose", "--no-history",
                                                 "--report", p], {}))
        if not quick:
            out.append((f"plan --out {name}", ["plan", meas, "--out", p], {}))
            out.append((f"history --plot {name}", ["history", meas, "--plot", p], {}))
            out.append((f"accuracy --plot {name}", ["accuracy", "--booth", b, "--no-cie", "--plot", p], {}))
        out.append((f"render -o {name}", ["render", cfg, "--no-input", "-o", p], {}))
    for name, p in odd_dirs.items():
        out.append((f"export-web --out {name}", ["export-web", cfg, "--out", p], {}))
    out.append(("visual-report --report user file", ["visual-report", ws["grid"], "--session", ws["cfg"],
                                                     "--report", ws["user_file"]], {}))
    out.append(("render -o the sample", ["render", cfg, "--no-input", "-o", ws["sample"]], {}))
    out.append(("render output.png escapes", ["render", ws["cfg_escape"], "--no-input"], {}))
    out.append(("render output.png is its config", ["render", ws["cfg_self"], "--no-input"], {}))
    out.append(("render --xyz into a folder", ["render", cfg, "--no-input", "--xyz", ws["user_dir"]], {}))
    for name, p in odd_inputs.items():
        out.append((f"validate-config {name}", ["validate-config", p], {}))
        out.append((f"build {name}", ["build", p, "--out", "bx"], {}))
        out.append((f"compare {name}", ["compare", p], {}))
        if not quick:
            out.append((f"render {name}", ["render", p, "--no-input"], {}))
            out.append((f"history {name}", ["history", p], {}))
            out.append((f"bake {name}", ["bake", p], {}))
    out += [
        ("compare 10 000 readings", ["compare", ws["big_meas"], "--no-history"], {}),
        ("validate 3000 lamps x 100 points", ["validate-config", ws["many_lamps"]], {}),
        ("compare 3000 lamps", ["compare", meas, "--booth", ws["many_lamps"], "--no-history"], {}),
        ("build lamp at the sample", ["build", ws["lamp_at_sample"], "--out", "bl"], {}),
        ("bake --samples 1e9", ["bake", b, "--samples", "1000000000"], {}),
        ("LBSCENE_CACHE_MAX_MB=inf", ["compare", meas, "--no-history"], {"LBSCENE_CACHE_MAX_MB": "inf"}),
        ("LBSCENE_MAX_READINGS=-1", ["compare", meas, "--no-history"], {"LBSCENE_MAX_READINGS": "-1"}),
        ("render --size 0x0", ["render", cfg, "--no-input", "--size", "0x0"], {}),
        ("plan --points 0", ["plan", meas, "--points", "0"], {}),
        ("history of a fifo", ["history", ws["fifo"]], {}),
        ("compare --json-out beside old-named files", ["compare", meas, "--no-diagnose", "--no-history",
                                                      "--json-out", "r.json"], {}),
        ("cache of the user's .npy, tiny bound", ["compare", meas, "--no-history"],
         {"LBSCENE_CACHE_DIR": str(ws["cache"]), "LBSCENE_CACHE_MAX_MB": "0.001"}),
        ("export-web over an export with notes", ["export-web", b, "--out", ws["viewer"]], {}),
    ]
    return out


def run_case(args, env, cwd: Path) -> dict:
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-c", _WRAPPER, *map(str, args)], cwd=cwd, capture_output=True,
                           text=True, timeout=120, env={**os.environ, **env})
    except subprocess.TimeoutExpired:
        return {"rc": None, "err": "", "rss_mb": 0.0, "s": time.perf_counter() - t0}
    rss = 0.0
    for line in p.stderr.splitlines():
        if line.startswith("@@maxrss_kb="):
            rss = int(line.split("=")[1]) / 1024
    return {"rc": p.returncode, "err": p.stdout + p.stderr, "rss_mb": rss, "s": time.perf_counter() - t0}


def kill_builds(ws: dict, tmp: Path, n: int) -> tuple[int, int]:
    """Kill ``lbscene build`` at random moments; (trials, failures)."""
    import json
    import random

    out = tmp / "killed-build"
    rnd = random.Random(7)
    subprocess.run([sys.executable, "-m", "lbscene", "build", str(ws["booth"]), "--out", str(out)],
                   capture_output=True, check=True, cwd=tmp)
    fails = 0
    for _ in range(n):
        p = subprocess.Popen([sys.executable, "-m", "lbscene", "build", str(ws["booth"]), "--out", str(out)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp)
        time.sleep(rnd.uniform(0.05, 3.0))
        p.send_signal(signal.SIGKILL)
        p.wait()
        m = json.loads((out / "manifest.json").read_text())
        ok = all(hashlib.sha256((out / f).read_bytes()).hexdigest() == h for f, h in m["files"].items())
        r = subprocess.run([sys.executable, "-m", "lbscene", "build", str(ws["booth"]), "--out", str(out)],
                           capture_output=True, cwd=tmp)
        left = [q for q in tmp.iterdir() if q.name.startswith(".killed-build.")]
        fails += (not ok) or r.returncode != 0 or bool(left)
    return n, fails


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer cases (no plan/history/accuracy/bake rows)")
    ap.add_argument("--kills", type=int, default=8)
    ap.add_argument("--only", default="", help="run only the cases whose label holds this text")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="lbscene-sweep-"))
    try:
        ws = workspace(tmp)
        before = _digest(ws["protected"])
        rows = []
        for label, args, env in cases(ws, a.quick):
            if a.only not in label:
                continue
            r = run_case(args, env, tmp)
            now = _digest(ws["protected"])
            lost = sorted(k for k in before if before[k] != now.get(k))
            before = now if not lost else before
            tb = "Traceback" in r["err"]
            hang = r["rc"] is None
            located = " LB" in r["err"] or r["err"].startswith("LB") or "error LB" in r["err"]
            bad_exit = r["rc"] not in (0, 2) and not (r["rc"] == 1 and "--strict" in args)
            usage = r["rc"] == 2 and ("Usage:" in r["err"] or "Invalid value" in r["err"])
            ok = not tb and not hang and not lost and not bad_exit and (r["rc"] == 0 or located or usage) \
                and r["rss_mb"] <= MEMORY_BOUND_MB
            rows.append((label, r, ok, tb, hang, lost))
            first = next((x for x in r["err"].splitlines() if "error" in x.lower()), "")[:110]
            print(f"{'ok ' if ok else 'BAD'} {label:42s} rc={r['rc']} {r['rss_mb']:7.0f} MB {r['s']:5.1f} s  {first}")
        trials, kill_fails = kill_builds(ws, tmp, a.kills)
        n = len(rows)
        print()
        print("| cases | passed | exit 0 | exit 2 (located) | tracebacks | hangs | files lost | peak RSS MB | "
              "killed builds | broken after kill |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        print(f"| {n} | {sum(r[2] for r in rows)} | {sum(r[1]['rc'] == 0 for r in rows)} | "
              f"{sum(r[1]['rc'] == 2 for r in rows)} | {sum(r[3] for r in rows)} | {sum(r[4] for r in rows)} | "
              f"{sum(bool(r[5]) for r in rows)} | {max(r[1]['rss_mb'] for r in rows):.0f} | {trials} | {kill_fails} |")
        return 0 if all(r[2] for r in rows) and not kill_fails else 1
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
