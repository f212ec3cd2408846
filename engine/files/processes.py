"""
Stopping cleanly: signals end a command through its clean-up code, and its children end with it.

* :func:`stop_on_signals` turns SIGTERM, SIGINT and SIGHUP into a :class:`Stopped`
  exception in the main thread, so every ``try``/``except BaseException`` on the way
  out runs: temporaries are removed (:mod:`lbscene.engine.files.outputs`), child processes
  are stopped (:mod:`lbscene.bakers.executor`).  A second signal during that clean-up
  is ignored, so the clean-up itself is not cut short.  The CLI exits with
  ``128 + signal number``.
* :func:`dies_with_parent` wraps a child's command line so that the child gets SIGKILL
  when this process ends in any way, SIGKILL included (Linux ``prctl(PR_SET_PDEATHSIG)``,
  set in the child before it ``exec``\\ s the real command, so no Python code runs
  between ``fork`` and ``exec`` in a process that has threads).  Without ``prctl``
  the command is returned unchanged.

What a process killed with SIGKILL leaves (its temporaries) is removed by the next
run (:func:`lbscene.engine.files.outputs.clean_leftovers`).

Examples
--------
>>> import sys
>>> cmd = dies_with_parent([sys.executable, "-c", "print('child')"])
>>> cmd[-3:] == [sys.executable, "-c", "print('child')"]
True
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Iterator

__all__ = ["Stopped", "stop_on_signals", "deferred_signals", "dies_with_parent", "SIGNALS"]

#: The signals that stop a command through its clean-up code.
SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)

#: Run by ``python -S -c`` in the child: parent-death signal, check the parent still is the one
#: that started it (it may have died before ``prctl``), then become the real command.
_LAUNCHER = (
    "import ctypes, os, sys\n"
    "if ctypes.CDLL(None, use_errno=True).prctl(1, 9, 0, 0, 0) != 0:\n"   # PR_SET_PDEATHSIG, SIGKILL
    "    sys.exit('lbscene: prctl(PR_SET_PDEATHSIG) failed')\n"
    "if os.getppid() != int(sys.argv[1]):\n"
    "    os._exit(1)\n"
    "os.execv(sys.argv[2], sys.argv[2:])\n"
)


class Stopped(BaseException):
    """The command was stopped by a signal (raised in the main thread by :func:`stop_on_signals`).

    A ``BaseException``, like ``KeyboardInterrupt``: ``except Exception`` does not swallow it,
    ``finally`` and ``except BaseException`` clean-ups run.

    Parameters
    ----------
    signum : int
        The signal's number.
    """

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(signal.Signals(signum).name)

    @property
    def exit_code(self) -> int:
        """``128 + signum``, as a shell reports a process ended by that signal."""
        return 128 + self.signum


class _Deferral:
    depth = 0
    pending: int | None = None


class deferred_signals:
    """A section that a signal must not cut in half (exchanging a folder and checking the old one,
    for instance): a stopping signal that arrives inside it raises :class:`Stopped` when the
    outermost such section ends (unless it ends with an exception of its own, which then goes on).

    Examples
    --------
    >>> with deferred_signals():
    ...     pass
    """

    def __enter__(self) -> "deferred_signals":
        _Deferral.depth += 1
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        _Deferral.depth -= 1
        if _Deferral.depth == 0 and _Deferral.pending is not None:
            signum, _Deferral.pending = _Deferral.pending, None
            if exc_type is None:
                raise Stopped(signum)


@contextmanager
def stop_on_signals() -> Iterator[None]:
    """While in this context, SIGTERM, SIGINT and SIGHUP raise :class:`Stopped` in the main thread
    (the first one; later ones are ignored so that clean-up runs to its end).  Signals that were
    ignored when the context was entered (``nohup``, a background job's SIGINT) stay ignored.
    Outside the main thread this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    stopping: list[int] = []

    def handler(signum, frame):
        if stopping:
            return
        stopping.append(signum)
        if _Deferral.depth:
            _Deferral.pending = signum
            return
        raise Stopped(signum)

    old = {}
    for sig in SIGNALS:
        prev = signal.getsignal(sig)
        if prev is signal.SIG_IGN:
            continue
        old[sig] = prev
        signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, prev in old.items():
            signal.signal(sig, prev if prev is not None else signal.SIG_DFL)


def dies_with_parent(cmd: list[str]) -> list[str]:
    """``cmd`` wrapped so that the child is killed (SIGKILL) when this process ends, however it
    ends (Linux); ``cmd`` itself elsewhere.

    Parameters
    ----------
    cmd : list of str
        The child's command line; ``cmd[0]`` must be a path (it is ``exec``\\ ed directly).

    Returns
    -------
    list of str
        The command line to start.
    """
    if not sys.platform.startswith("linux"):
        return list(cmd)
    return [sys.executable, "-S", "-c", _LAUNCHER, str(os.getpid()), *cmd]
