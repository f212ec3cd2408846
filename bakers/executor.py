"""
Local executor: run bake jobs one after another, each in its own process.

* **Cache**: a job whose output folder holds a complete manifest with the
  same job content hash (and all its files) is not baked again.
* **Atomic**: each job's products appear only when complete (see
  :mod:`lbscene.bakers.run_job`); a crashed or interrupted job leaves no
  partial product, and its temporary folder is removed here when the child
  could not remove it itself.
* **Resume**: after an interruption, running the same list again skips the
  finished jobs (cache hits) and bakes the rest.
* **Children end with the command**: a child runs in its own process group,
  which is stopped (SIGTERM, then SIGKILL) when the command is stopped; it also
  gets SIGKILL from the kernel when the command dies any other way, SIGKILL
  included (:func:`lbscene.engine.files.processes.dies_with_parent`).  The job file
  given to the child is named in lbscene's temporary pattern, so what a killed
  run leaves is removed by the next one and never makes a build refuse the folder.
* A rich progress bar follows the children's progress lines.

Examples
--------
>>> from lbscene.bakers.executor import BakeTask, is_cached
>>> callable(is_cached) and BakeTask.__name__
'BakeTask'
"""

from __future__ import annotations

import collections
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Literal

from .job import BakeJob, save_job

__all__ = ["BakeTask", "TaskResult", "is_cached", "run_tasks", "clean_stale_temps"]


@dataclass
class BakeTask:
    job: BakeJob
    out_dir: Path
    #: the job file the child reads (written next to the output when absent or stale)
    job_path: Path | None = None
    label: str | None = None


@dataclass
class TaskResult:
    task: BakeTask
    status: Literal["cached", "baked", "failed"]
    time_s: float = 0.0
    manifest: dict | None = None
    error: str | None = None
    log_tail: list[str] = field(default_factory=list)


def _manifest(out_dir: Path) -> dict | None:
    from lbscene.engine.files.outputs import read_manifest

    got = read_manifest(Path(out_dir))          # a regular file of this user, read without blocking
    return got[0] if got is not None else None


def is_cached(job: BakeJob, out_dir: Path) -> dict | None:
    """The manifest of a complete, up-to-date bake of ``job`` in ``out_dir``, else None."""
    m = _manifest(out_dir)
    if not m or m.get("job_hash") != job.content_hash:
        return None
    if not all((Path(out_dir) / f).is_file() for f in m.get("files", {})):
        return None
    return m


def clean_stale_temps(out_dir: Path) -> list[Path]:
    """Remove temporary folders a killed bake of ``out_dir`` left behind (those of live
    processes, e.g. a concurrent bake, are kept)."""
    from lbscene.engine.files.outputs import clean_leftovers

    return clean_leftovers(Path(out_dir).parent, Path(out_dir).name)


def _child_env() -> dict:
    env = dict(os.environ)
    # the child must import the same lbscene as this process (located, not imported: the
    # package's __init__ loads the API, a layer above the bakers)
    from importlib.util import find_spec

    root = str(Path(find_spec("lbscene").origin).resolve().parents[1])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def _child_command(job_path: Path, out_dir: Path) -> list[str]:
    """The command line of the child process that bakes ``job_path`` into ``out_dir``."""
    return [sys.executable, "-m", "lbscene.bakers.run_job", str(job_path), str(out_dir)]


def _stop(proc: subprocess.Popen) -> None:
    """Stop a child and everything it started (its process group): SIGTERM, then SIGKILL."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


def _run_child(task: BakeTask, on_progress: Callable[[int, int, str], None]) -> TaskResult:
    from lbscene.engine.files.outputs import temporary_name
    from lbscene.engine.files.processes import dies_with_parent

    from .run_job import PROGRESS_PREFIX

    out_dir = Path(task.out_dir).resolve()
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temps(out_dir)
    job_path = task.job_path
    tmp_job = None
    if job_path is None or not Path(job_path).is_file():
        tmp_job = temporary_name(out_dir, suffix=".json")     # removed below, or by a later run
        save_job(task.job, tmp_job)
        job_path = tmp_job
    t0 = time.perf_counter()
    tail: collections.deque[str] = collections.deque(maxlen=40)
    error = None
    proc = None
    try:
        # (a child started in a process stopped before `proc` is set ends with it: dies_with_parent)
        proc = subprocess.Popen(dies_with_parent(_child_command(job_path, out_dir)), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, bufsize=1, env=_child_env(),
                                start_new_session=True)
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.startswith(PROGRESS_PREFIX):
                try:
                    msg = json.loads(line[len(PROGRESS_PREFIX):])
                except ValueError:
                    continue
                if "done" in msg:
                    on_progress(int(msg["done"]), int(msg["total"]), str(msg.get("what", "")))
                elif msg.get("event") == "error":
                    error = msg.get("message")
            else:
                tail.append(line.rstrip("\n"))
        rc = proc.wait()
    except BaseException:
        # interrupted: stop the child and everything it started, then leave nothing behind
        if proc is not None:
            _stop(proc)
        clean_stale_temps(out_dir)
        raise
    finally:
        if tmp_job is not None:
            tmp_job.unlink(missing_ok=True)
    elapsed = time.perf_counter() - t0
    clean_stale_temps(out_dir)   # after a hard crash the child could not clean up
    manifest = is_cached(task.job, out_dir) if rc == 0 else None
    if rc != 0 or manifest is None:
        return TaskResult(task, "failed", elapsed, None,
                          error or f"bake process exited with code {rc}", list(tail))
    return TaskResult(task, "baked", elapsed, manifest, None, list(tail))


def run_tasks(tasks: list[BakeTask], *, force: bool = False, progress: bool = True,
              console=None, stop_on_error: bool = False,
              on_result: Callable[[TaskResult], None] | None = None) -> list[TaskResult]:
    """Run ``tasks`` in order (cache hits are skipped unless ``force``)."""
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)

    from lbscene.engine.files.textsafe import printable

    console = console or Console(stderr=True)
    results: list[TaskResult] = []
    # labels name lightings and jobs as the booth file writes them: shown literally, never as markup
    with Progress(SpinnerColumn(), TextColumn("{task.description}", markup=False), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn(),
                  console=console, transient=True, disable=not progress) as prog:
        overall = prog.add_task("bake", total=len(tasks))
        for i, task in enumerate(tasks):
            label = printable(task.label or task.job.name, newlines=False)
            if not force:
                m = is_cached(task.job, task.out_dir)
                if m is not None:
                    res = TaskResult(task, "cached", 0.0, m)
                    results.append(res)
                    if on_result:
                        on_result(res)
                    prog.advance(overall)
                    continue
            sub = prog.add_task(f"  {label}", total=None)

            def on_progress(done, total, what, sub=sub, label=label):
                prog.update(sub, completed=done, total=total, description=f"  {label}: {what}")

            prog.update(overall, description=f"bake {i + 1}/{len(tasks)}")
            res = _run_child(task, on_progress)
            prog.remove_task(sub)
            prog.advance(overall)
            results.append(res)
            if on_result:
                on_result(res)
            if res.status == "failed" and stop_on_error:
                break
    return results
