"""Kill ``build`` and ``bake`` at chosen and at random moments: the previous output stays
intact (or the new one is complete), and the next run removes what the killed one left.

Chosen moments use the ``LBSCENE_FAULT`` injection points (the process ends with
``os._exit``, as under ``kill -9``); random ones send SIGKILL after a random delay.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def _complete(build: Path) -> bool:
    """A build folder whose manifest lists exactly its files, each with its sha256."""
    m = json.loads((build / "manifest.json").read_text())
    files = {p.relative_to(build).as_posix() for p in build.rglob("*") if p.is_file()} - {"manifest.json"}
    return files == set(m["files"]) and all(
        hashlib.sha256((build / f).read_bytes()).hexdigest() == h for f, h in m["files"].items())


def _ir_hash(build: Path) -> str:
    return json.loads((build / "manifest.json").read_text())["ir_hash"]


def _build(booth: Path, out: Path, env=None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "lbscene", "build", str(booth), "--out", str(out),
                             "--format", "json"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env={**os.environ, **(env or {})})


def _leftovers(folder: Path, name: str) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(f".{name}."))


def _edit_level(booth: Path, value: int) -> None:
    f = booth / "booth.yaml"
    f.write_text(f.read_text().replace("value_cd: 1000", f"value_cd: {value}"))


@pytest.mark.parametrize("point", ["build-lighting", "build-finish", "replace"])
def test_build_killed_at_each_step(point, minimal_booth, tmp_path):
    out = tmp_path / "b"
    assert _build(minimal_booth, out).wait() == 0
    old_hash = _ir_hash(out)
    _edit_level(minimal_booth, 1700)
    p = _build(minimal_booth, out, {"LBSCENE_FAULT": point})
    assert p.wait() == 70
    assert _complete(out)
    # killed before the swap: the old build; after it: the new one, complete
    assert _ir_hash(out) == old_hash if point != "replace" else _ir_hash(out) != old_hash
    assert _leftovers(tmp_path, "b")                                     # the killed run left its temporary
    assert _build(minimal_booth, out).wait() == 0
    assert _complete(out) and _ir_hash(out) != old_hash
    assert _leftovers(tmp_path, "b") == []                               # and the next run removed it


def test_build_killed_at_random_moments(minimal_booth, tmp_path):
    out = tmp_path / "b"
    t0 = time.perf_counter()
    assert _build(minimal_booth, out).wait() == 0
    full_s = time.perf_counter() - t0
    rng = np.random.default_rng(12)
    hashes = {_ir_hash(out)}
    level = 1000
    for new in (1200, 1300, 1400):
        f = minimal_booth / "booth.yaml"
        f.write_text(f.read_text().replace(f"value_cd: {level}", f"value_cd: {new}"))
        level = new
        p = _build(minimal_booth, out)
        time.sleep(float(rng.uniform(0.1, 1.0)) * full_s)
        p.send_signal(signal.SIGKILL)
        p.wait()
        assert _complete(out)                                # never half-written
        assert _build(minimal_booth, out).wait() == 0         # the next run finishes and cleans up
        assert _complete(out)
        assert _leftovers(tmp_path, "b") == []
        hashes.add(_ir_hash(out))
    assert len(hashes) == 4                                   # every edit reached the build


@pytest.mark.bake
def test_bake_killed_at_random_moments(tmp_path):
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.job import save_job

    sys.path.insert(0, str(REPO / "tests" / "bakers"))
    try:
        from test_executor import tiny_job
    finally:
        sys.path.pop(0)
    out = tmp_path / "bk"
    [r] = run_tasks([BakeTask(tiny_job(), out)], progress=False)
    assert r.status == "baked"
    before = (out / "manifest.json").read_text()
    changed = tiny_job(z_mm=1400.0)
    job = tmp_path / "job.json"
    save_job(changed, job)
    rng = np.random.default_rng(5)
    for _ in range(3):
        p = subprocess.Popen([sys.executable, "-m", "lbscene.bakers.run_job", str(job), str(out), "--no-blend"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(float(rng.uniform(0.3, 2.5)))
        p.send_signal(signal.SIGKILL)
        p.wait()
        m = (out / "manifest.json").read_text()
        assert m == before or json.loads(m)["job_hash"] == changed.content_hash   # old intact, or new complete
        if m != before:
            break
    [r] = run_tasks([BakeTask(changed, out)], progress=False)
    assert r.status in ("baked", "cached")
    assert json.loads((out / "manifest.json").read_text())["job_hash"] == changed.content_hash
    assert _leftovers(tmp_path, "bk") == []
