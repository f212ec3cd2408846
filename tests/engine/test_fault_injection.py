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


def _default_signals() -> None:
    """In the child: the signals lbscene handles at their default disposition, as in a terminal.
    A run under ``nohup`` (or a CI runner that ignores SIGHUP) hands its children SIGHUP ignored,
    and lbscene keeps an ignored signal ignored, as ``nohup`` asks."""
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def _build(booth: Path, out: Path, env=None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "lbscene", "build", str(booth), "--out", str(out),
                             "--format", "json"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env={**os.environ, **(env or {})}, preexec_fn=_default_signals)


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


# --------------------------------------------------------------------------- stopped by a signal


def _digest(root: Path) -> dict:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _wait_for(p: subprocess.Popen, marker: str, timeout_s: float = 120.0) -> None:
    """Read the process's stderr until a line holds ``marker``."""
    t0 = time.monotonic()
    for line in p.stderr:
        if marker in line.decode(errors="replace"):
            return
        assert time.monotonic() - t0 < timeout_s, f"no {marker!r}"
    raise AssertionError(f"the process ended before {marker!r}")


def _gone(pid: int, timeout_s: float = 15.0) -> bool:
    """Whether process ``pid`` ends (or is a zombie) within ``timeout_s``."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state in ("Z", "X"):
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_build_stopped_by_a_signal_removes_its_temporaries(sig, minimal_booth, tmp_path):
    out = tmp_path / "b"
    assert _build(minimal_booth, out).wait() == 0
    before = _digest(out)
    _edit_level(minimal_booth, 1700)
    p = _build(minimal_booth, out, {"LBSCENE_FAULT": "build-lighting:wait"})
    _wait_for(p, "@@lbscene-fault build-lighting")
    assert _leftovers(tmp_path, "b")                         # the build is being assembled
    p.send_signal(sig)
    rc = p.wait(timeout=60)
    err = p.stderr.read().decode()
    assert rc == 128 + sig, err
    assert "Traceback" not in err
    assert f"lbscene: stopped by {sig.name}; its temporary files were removed" in err
    assert _leftovers(tmp_path, "b") == []
    assert _digest(out) == before


_BAKE_WRAPPER = '''
import sys

import lbscene.bakers.executor as ex

CHILD = "import os, sys, time\\nopen(sys.argv[1] + '.tmp', 'w').write(str(os.getpid()))\\n" \\
        "os.replace(sys.argv[1] + '.tmp', sys.argv[1])\\ntime.sleep(300)\\n"
ex._child_command = lambda job_path, out_dir: [sys.executable, "-c", CHILD, sys.argv[1]]
from lbscene.cli import main

sys.exit(main(sys.argv[2:]))
'''


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGKILL])
def test_a_stopped_bake_takes_its_child_with_it(sig, minimal_booth, tmp_path):
    """Killing ``bake`` (any signal, SIGKILL included) ends the process rendering for it, and what a
    killed run leaves never blocks the next ``build`` of the folder."""
    build = tmp_path / "b"
    assert _build(minimal_booth, build).wait() == 0
    wrapper = tmp_path / "bake_wrapper.py"
    wrapper.write_text(_BAKE_WRAPPER)
    marker = tmp_path / "child.pid"
    p = subprocess.Popen([sys.executable, str(wrapper), str(marker), "bake", str(build), "--lighting", "A"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tmp_path,
                         preexec_fn=_default_signals)
    t0 = time.monotonic()
    while not marker.exists():
        assert p.poll() is None, p.stderr.read().decode()
        assert time.monotonic() - t0 < 120
        time.sleep(0.05)
    child = int(marker.read_text())
    assert _leftovers(build / "bake", "A")                  # the job file of the running bake
    p.send_signal(sig)
    rc = p.wait(timeout=60)
    assert _gone(child), "the bake's child outlived it"
    if sig != signal.SIGKILL:
        assert rc == 128 + sig
        assert _leftovers(build / "bake", "A") == []
    assert _build(minimal_booth, build).wait() == 0          # not refused for what the killed run left
    assert list(build.rglob(".A.*")) == []


# --------------------------------------------------------------------------- a full disk


def _no_space(real_write):
    import errno

    def write(fd, data):
        if fd > 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_write(fd, data)

    return write


FULL = "cannot write: No space left on device (nothing was changed; temporary files were removed)"


def test_build_on_a_full_disk(minimal_booth, tmp_path, run_cli, monkeypatch):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    before = _digest(out)
    _edit_level(minimal_booth, 1700)
    monkeypatch.setattr(os, "write", _no_space(os.write))
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    monkeypatch.undo()
    assert code == 2
    assert "Traceback" not in err
    assert f"{out}: error LB610: --out: {FULL}" in err
    assert _digest(out) == before
    assert _leftovers(tmp_path, "b") == []


def test_export_web_on_a_full_disk(tmp_path, run_cli, monkeypatch):
    out = tmp_path / "v"
    monkeypatch.setattr(os, "write", _no_space(os.write))
    code, _, err = run_cli("export-web", REPO / "tests" / "runtimes" / "data" / "tube-booth", "--out", out)
    monkeypatch.undo()
    assert code == 2
    assert "Traceback" not in err
    assert f"{out}: error LB610: --out: {FULL}" in err
    assert sorted(os.listdir(tmp_path)) == []


def _can_mount_tmpfs() -> bool:
    try:
        return subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k none /mnt"],
                              capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


_FULL_DISK_SCRIPT = r'''
set -u
mount -t tmpfs -o size=256k lbscene-full "$MNT" || exit 99
lb() { "$PY" -m lbscene "$@"; }
lb build "$BOOTH" --out "$MNT/b" > /dev/null 2> "$OUT/first.err"; echo "first=$?" > "$OUT/rc"
find "$MNT/b" -type f -exec sha256sum {} + | sort > "$OUT/before"
sed -i 's/value_cd: 1000/value_cd: 1700/' "$BOOTH/booth.yaml"
lb build "$BOOTH" --out "$MNT/b" > /dev/null 2> "$OUT/build.err"; echo "build=$?" >> "$OUT/rc"
find "$MNT/b" -type f -exec sha256sum {} + | sort > "$OUT/after"
lb export-web "$WEB" --out "$MNT/v" > /dev/null 2> "$OUT/web.err"; echo "web=$?" >> "$OUT/rc"
ls -A "$MNT" > "$OUT/listing"
'''


@pytest.mark.skipif(not _can_mount_tmpfs(), reason="needs a user namespace to mount a small tmpfs")
def test_build_and_export_web_on_a_really_full_file_system(minimal_booth, tmp_path):
    """A 256 KiB tmpfs holds one build of the minimal booth but not a second one beside it, nor a web
    export: both commands fail with LB610, the earlier build is intact, no temporary is left."""
    res = tmp_path / "res"
    res.mkdir()
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    env = {**os.environ, "MNT": str(mnt), "OUT": str(res), "PY": sys.executable, "BOOTH": str(minimal_booth),
           "WEB": str(REPO / "tests" / "runtimes" / "data" / "tube-booth"), "LBSCENE_CACHE_DIR": "off"}
    p = subprocess.run(["unshare", "-rm", "bash", "-c", _FULL_DISK_SCRIPT], env=env, capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    rc = dict(line.split("=") for line in (res / "rc").read_text().split())
    assert rc == {"first": "0", "build": "2", "web": "2"}, (res / "build.err").read_text()
    build_err, web_err = (res / "build.err").read_text(), (res / "web.err").read_text()
    assert "Traceback" not in build_err + web_err
    assert f"{mnt}/b: error LB610: --out: {FULL}" in build_err
    assert f"{mnt}/v: error LB610: --out: {FULL}" in web_err
    assert (res / "after").read_text() == (res / "before").read_text() != ""
    assert (res / "listing").read_text().split() == ["b"]
