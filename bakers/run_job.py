"""
``python -m lbscene.bakers.run_job JOB.json OUTDIR``: bake one job, atomically.

Runs in its own process (a Blender crash cannot take the caller down).  The
products are written into a temporary sibling of ``OUTDIR`` that replaces
``OUTDIR`` only when complete; on any error the temporary folder is removed
and the previous ``OUTDIR`` (if any) is left as it was.

Progress goes to stdout as lines ``@@lbscene {"done": d, "total": t, "what": …}``
(Blender's own chatter is interleaved; the executor keeps only these lines).
Exit codes: 0 done, 1 bake failed, 2 bad job file.
"""

from __future__ import annotations

import json
import shutil
import sys
import traceback
from pathlib import Path

__all__ = ["main", "PROGRESS_PREFIX"]

PROGRESS_PREFIX = "@@lbscene "


def _emit(**kw) -> None:
    sys.stdout.write(PROGRESS_PREFIX + json.dumps(kw, ensure_ascii=False) + "\n")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m lbscene.bakers.run_job",
                                 description="Bake one lbscene bake job with Blender Cycles.")
    ap.add_argument("job", type=Path)
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--no-blend", action="store_true", help="do not save scene.blend")
    args = ap.parse_args(argv)

    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import replace_dir

    from .job import load_job

    try:
        job = load_job(args.job)
    except LbsceneUserError as exc:
        for d in exc.diagnostics:
            print(d.format(), file=sys.stderr)
        _emit(event="error", message=str(exc))
        return 2
    from lbscene.engine.files.outputs import restore_interrupted, temporary_dir_for

    out_dir = args.out_dir.resolve()
    restore_interrupted(out_dir)
    tmp = temporary_dir_for(out_dir)
    try:
        from .bake import bake_job

        manifest = bake_job(job, tmp, progress=lambda d, t, what: _emit(done=d, total=t, what=what),
                            save_blend=not args.no_blend)
        replace_dir(tmp, out_dir)      # only over a bake folder that is lbscene's and unchanged
    except LbsceneUserError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        for d in exc.diagnostics:
            print(d.format(), file=sys.stderr)
        _emit(event="error", message="; ".join(d.format() for d in exc.diagnostics))
        return 2
    except BaseException as exc:  # noqa: BLE001 - report anything, leave nothing half-written
        shutil.rmtree(tmp, ignore_errors=True)
        tb = traceback.format_exc()
        print(tb, file=sys.stderr)
        _emit(event="error", message=f"{type(exc).__name__}: {exc}")
        return 130 if isinstance(exc, KeyboardInterrupt) else 1
    _emit(event="done", out_dir=str(out_dir), job_hash=manifest["job_hash"],
          time_s=manifest["time_s"]["total"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
