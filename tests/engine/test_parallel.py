"""Forked workers (:func:`lbscene.engine.files.parallel.map_forked`): the loop's results, in order,
from processes that start as copies of this one."""

from __future__ import annotations

import os

import numpy as np
import pytest

from lbscene.engine.files import parallel


def test_forked_workers_give_the_loops_results_in_order(monkeypatch):
    monkeypatch.setenv("LBSCENE_PROCESSES", "2")
    state = {"scale": 3.0}              # a closure over this process' memory: never pickled

    def work(x):
        # the parent's thread pool did not survive the fork: chunks still run in the child
        out = np.empty(8)

        def chunk(a, b):
            out[a:b] = np.arange(a, b) * state["scale"] + x
        parallel.for_chunks(chunk, 8, 2)
        return os.getpid(), float(out.sum())

    parallel.for_chunks(lambda a, b: None, 4, 1)          # the parent's pool exists before the fork
    got = parallel.map_forked(work, [0.0, 1.0, 2.0, 3.0, 4.0])
    assert [v for _, v in got] == [84.0 + 8 * x for x in range(5)]
    assert all(pid != os.getpid() for pid, _ in got)


def test_one_worker_or_one_item_is_the_loop_itself(monkeypatch):
    monkeypatch.setenv("LBSCENE_PROCESSES", "1")
    assert parallel.map_forked(lambda x: (os.getpid(), x * 2), [1, 2]) == [(os.getpid(), 2), (os.getpid(), 4)]
    monkeypatch.setenv("LBSCENE_PROCESSES", "2")
    assert parallel.map_forked(lambda x: os.getpid(), [1]) == [os.getpid()]


def test_an_error_in_a_worker_reaches_the_caller(monkeypatch):
    monkeypatch.setenv("LBSCENE_PROCESSES", "2")

    def work(x):
        if x == 2:
            raise ValueError("point 2 failed")
        return x

    with pytest.raises(ValueError, match="point 2 failed"):
        parallel.map_forked(work, [1, 2, 3])


def test_a_user_error_in_a_worker_reaches_the_caller_with_its_diagnostics(monkeypatch):
    from lbscene.engine.files.diagnostics import LbsceneUserError

    monkeypatch.setenv("LBSCENE_PROCESSES", "2")

    def work(x):
        if x == 2:
            raise LbsceneUserError.single("LB407", "2 data values cannot fit 3 free parameters", "grid.csv",
                                          line=4, column=2, expected="at least 4 readings")
        return x

    with pytest.raises(LbsceneUserError) as e:
        parallel.map_forked(work, [1, 2, 3])
    assert str(e.value) == "grid.csv:4:2: error LB407: 2 data values cannot fit 3 free parameters " \
                           "(expected at least 4 readings)"
    assert [d.code for d in e.value.diagnostics] == ["LB407"]


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: every BLAS runs one thread anyway")
def test_every_blas_runs_one_thread_inside_the_limit():
    """numpy and scipy each bring their own OpenBLAS: inside :func:`blas_single_thread` both run
    one thread, however early the limit was first asked for (before scipy's linear algebra was
    loaded, scipy's kept its threads: two forked refits, each factorising on two threads, took
    three times as long as one after the other)."""
    import subprocess
    import sys

    code = ("import numpy\n"
            "from lbscene.engine.files.parallel import blas_single_thread\n"
            "ctx = blas_single_thread()\n"                       # scipy.linalg not imported yet
            "import scipy.linalg\n"
            "from threadpoolctl import threadpool_info\n"
            "with ctx:\n"
            "    print(sorted({(i['filepath'], i['num_threads']) for i in threadpool_info()"
            " if i['user_api'] == 'blas'}))\n")
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    libs = eval(out)
    assert len(libs) >= 2, f"numpy's and scipy's BLAS expected: {libs}"
    assert all(n == 1 for _, n in libs), libs
