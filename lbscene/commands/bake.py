"""``lbscene bake BUILD_DIR_OR_BOOTH [--lighting NAME] [--quality preview|final] [--samples N]``

Runs the Cycles bake jobs of a booth (one per lighting configuration), each in
its own process, with a content-hash cache: an unchanged job is not baked
again, an interrupted run resumes with the jobs that are left.

Products go to ``<build dir>/bake/<lighting>/`` (for a booth argument, the
build dir is ``build/<booth folder>``, as ``lbscene build`` uses), where the
realtime renderer finds them.

``--cross-check`` bakes nothing for the renderer: it compares Cycles with the
analytic forward model at the 55 grid points (:mod:`lbscene.bakers.crosscheck`),
direct light and with inter-reflection, and prints the deviations, the
bake's noise and whether the two engines agree within it and the model's
precision floor; exit code 1 when a check disagrees.
"""

from __future__ import annotations

import time
from enum import Enum
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo, out_console
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text


#: Bound on --samples: 65 536 samples per texel already takes hours for an environment map on a CPU.
MAX_SAMPLES = 65536


class QualityName(str, Enum):
    preview = "preview"
    final = "final"


class CrossMode(str, Enum):
    both = "both"
    direct = "direct"
    interreflection = "interreflection"


def _load_ir(target: Path, allowed_dirs) -> tuple[object, Path, bool]:
    """(IR, build dir, from a build folder?) for a build folder or a booth."""
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.scene.ir import SceneIR

    from lbscene.engine.files.yamlio import path_kind

    if path_kind(target) == "dir" and path_kind(target / "scene.ir.json") == "file":
        try:
            from lbscene.engine.files.yamlio import read_text_bounded

            ir = SceneIR.model_validate_json(read_text_bounded(target / "scene.ir.json",
                                                               str(target / "scene.ir.json"), 256 * 1024 * 1024))
        except ValueError as exc:
            raise LbsceneUserError.single("LB601", f"unreadable scene IR: {str(exc)[:200]}",
                                          str(target / "scene.ir.json"),
                                          expected="a build folder written by `lbscene build`") from None
        return ir, target, True
    from lbscene.engine.scene.compile import compile_booth, find_booth_file

    booth_file = find_booth_file(target)
    ir = compile_booth(booth_file, allowed_dirs=allowed_dirs)
    return ir, Path("build") / booth_file.resolve().parent.name, False


def _lighting_names(ir, target: Path, lighting: Optional[str]) -> list[str]:
    from lbscene.engine.files.diagnostics import LbsceneUserError

    names = list(ir.lighting)
    if lighting is None:
        return names
    if lighting not in ir.lighting:
        raise LbsceneUserError.single(
            "LB500", f"booth has no lighting configuration {lighting!r}", str(target),
            value=repr(lighting), expected=f"one of {', '.join(names)}")
    return [lighting]


def _load_targets(target: Path, lighting: Optional[str], quality: str, samples: Optional[int],
                  allowed_dirs) -> tuple[object, Path, list]:
    """(IR, build dir, [(lighting, job)]) for a build folder or a booth."""
    from lbscene.bakers.from_ir import job_path_in_build, lighting_job
    from lbscene.bakers.job import load_job

    ir, build_dir, from_build = _load_ir(target, allowed_dirs)
    names = _lighting_names(ir, target, lighting)
    jobs = []
    for name in names:
        job = None
        jp = job_path_in_build(build_dir, name)
        if from_build and jp.is_file():
            j = load_job(jp)
            if j.quality.preset == quality:   # resolutions follow the preset: else regenerate
                job = j
        if job is None:
            job = lighting_job(ir, name, quality=quality)
        if samples is not None:
            job = job.with_quality(samples=samples)
        jobs.append((name, job))
    return ir, build_dir, jobs


def register(app: typer.Typer) -> None:
    @app.command("bake")
    def bake(
        target: Path = typer.Argument(..., help="Build folder (from `lbscene build`) or booth folder/file."),
        lighting: Optional[str] = typer.Option(None, "--lighting", "-l", help="Only this lighting."),
        quality: QualityName = typer.Option(QualityName.preview, "--quality", "-q",
                                            help="preview (fast) or final (grid points sampled "
                                                 "until ≤ 1 % noise)."),
        samples: Optional[int] = typer.Option(None, "--samples", "-s", min=2, max=MAX_SAMPLES,
                                              help="Samples per pixel/texel for every product "
                                                   "(fixed: no sampling to a noise target)."),
        out: Optional[Path] = typer.Option(None, "--out", "-o",
                                           help="Folder of the bakes (default: <build dir>/bake)."),
        force: bool = typer.Option(False, "--force", help="Bake again even when cached."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
        cross_check: bool = typer.Option(
            False, "--cross-check",
            help="Compare Cycles with the analytic model at the 55 grid points (no products)."),
        cross_mode: CrossMode = typer.Option(CrossMode.both, "--cross-check-mode",
                                             help="Which comparison --cross-check runs."),
    ) -> None:
        """Bake spectral light products of a booth with Blender Cycles (env maps, irradiance)."""
        from lbscene.commands.console import table

        from lbscene.bakers.executor import BakeTask, run_tasks

        if cross_check:
            _run_cross_check(target, lighting, quality.value, samples, format, cross_mode,
                             tuple(allow_path or ()))
            return
        t0 = time.perf_counter()
        ir, build_dir, jobs = _load_targets(target, lighting, quality.value, samples,
                                            tuple(allow_path or ()))
        root = out or (build_dir / "bake")
        from lbscene.engine.files.outputs import check_outputs

        check_outputs([], inputs=[target], dirs=[(root / name, "--out" if out else "bake folder")
                                                 for name, _ in jobs])
        tasks = [BakeTask(job, root / name, label=f"{ir.booth_name} · {name}") for name, job in jobs]
        results = run_tasks(tasks, force=force, progress=format is Format.text)
        elapsed = time.perf_counter() - t0
        rows = []
        for (name, job), r in zip(jobs, results):
            row = {"lighting": name, "status": r.status, "out_dir": str(r.task.out_dir),
                   "job_hash": job.content_hash, "time_s": round(r.time_s, 2), "error": r.error}
            m = r.manifest or {}
            prods = m.get("products", {})
            if "grid" in prods:
                g = prods["grid"]
                row["grid_mean_lx"] = round(g["illuminance_lx"]["mean"], 2)
                row["grid_samples"] = g["samples"]
                if g.get("noise"):
                    row["grid_noise_percent"] = round(100 * g["noise"]["illuminance_relative_rms"], 3)
            envs = [p for p in prods.values() if p["type"] == "environment_map"]
            if envs:
                si = envs[0]["sample_irradiance"]
                row["sample_lx_from_env"] = round(si["illuminance_lx"], 2)
                if si.get("illuminance_noise_relative") is not None:
                    row["sample_noise_percent"] = round(100 * si["illuminance_noise_relative"], 3)
            rows.append(row)
        failed = [r for r in results if r.status == "failed"]
        if format is Format.json:
            echo(json_text({"booth": ir.booth_name, "ir_hash": ir.content_hash,
                                   "quality": quality.value, "elapsed_s": round(elapsed, 2),
                                   "bakes": rows}, indent=2))
        else:
            tab = table(title=f"{ir.booth_name}: Cycles bakes ({quality.value}) → {root}")
            for col in ("lighting", "status", "time s", "grid mean lx", "grid noise %", "sample lx (env)"):
                tab.add_column(col)
            for row in rows:
                tab.add_row(row["lighting"], row["status"], f"{row['time_s']:.1f}",
                              f"{row.get('grid_mean_lx', float('nan')):.1f}",
                              f"{row.get('grid_noise_percent', float('nan')):.2f}",
                              f"{row.get('sample_lx_from_env', float('nan')):.1f}")
            from lbscene.commands.console import out_console

            out_console().print(tab)
            echo(f"{len(results) - len(failed)}/{len(results)} bakes ready ({elapsed:.1f} s)")
            for r in failed:
                echo(f"error LB600: bake {r.task.label} failed: {r.error}", err=True)
                for line in r.log_tail[-8:]:
                    echo(f"    {line}", err=True)
        if failed:
            raise typer.Exit(1)


def _run_cross_check(target: Path, lighting: Optional[str], quality: str, samples: Optional[int],
                     format: Format, mode: CrossMode, allowed_dirs) -> None:
    """``--cross-check``: Cycles vs the analytic model at the grid points, per lighting and mode.

    One verdict per row (:attr:`lbscene.bakers.crosscheck.CrossCheck.agrees`): the differences
    are what the bake's noise and the model's precision floor give (mean within 3 standard
    errors, χ² test); the table, the summary line, the JSON and the exit status all say it.
    """
    from lbscene.commands.console import table

    from lbscene.bakers.crosscheck import (CHI2_P_MIN, MEAN_SIGMAS, MODEL_PRECISION_PERCENT, MODES,
                                           CrossCheckBakeFailed, cross_check_all)

    t0 = time.perf_counter()
    ir, _, _ = _load_ir(target, allowed_dirs)
    names = _lighting_names(ir, target, lighting)
    modes = MODES if mode is CrossMode.both else (mode.value,)
    checks = []
    try:
        for name in names:
            checks += cross_check_all(ir, name, modes=modes, quality=quality, samples=samples,
                                      progress=format is Format.text)
    except CrossCheckBakeFailed as exc:
        # Cycles itself failed (not the booth file): said as the bakes say it, exit status 1
        if format is Format.json:
            echo(json_text({"booth": ir.booth_name, "ir_hash": ir.content_hash, "quality": quality,
                            "ok": False, "error": {"code": "LB600", "message": str(exc),
                                                   "log_tail": exc.log_tail}}, indent=2))
        else:
            echo(f"error LB600: {exc}", err=True)
            for line in exc.log_tail[-8:]:
                echo(f"    {line}", err=True)
        raise typer.Exit(1) from None
    rows = [c.summary() for c in checks]
    failed = [r for r in rows if not r["agrees"]]
    elapsed = time.perf_counter() - t0
    if format is Format.json:
        echo(json_text({"booth": ir.booth_name, "ir_hash": ir.content_hash, "quality": quality,
                               "elapsed_s": round(elapsed, 2), "cross_check": rows},
                              indent=2))
    else:
        tab = table(title=f"{ir.booth_name}: Cycles / analytic model − 1 at "
                            f"{rows[0]['points'] if rows else 0} grid points ({quality})")
        for col in ("lighting", "mode", "spp", "time s", "mean %", "max|·| %", "noise %", "mean/σ",
                    "χ² p", "result"):
            tab.add_column(col, justify="left" if col in ("lighting", "mode", "result") else "right")
        for r in rows:
            tab.add_row(r["lighting"], "inter-refl." if r["mode"] == "interreflection" else r["mode"],
                          str(r["samples"]), f"{r['time_s']:.1f}", f"{r['mean_diff_percent']:+.2f}",
                          f"{r['max_abs_diff_percent']:.2f}", f"{r['noise_rms_percent']:.2f}",
                          f"{r['mean_diff_sigmas']:+.1f}", f"{r['chi2_p']:.2g}",
                          "agree" if r["agrees"] else "DISAGREE")
        out_console().print(tab)
        echo(f"{len(rows) - len(failed)}/{len(rows)} checks agree (mean within {MEAN_SIGMAS:g} σ, "
             f"χ² p ≥ {CHI2_P_MIN:g}; σ: bake noise and the model's {MODEL_PRECISION_PERCENT:g} %) "
             f"({elapsed:.1f} s)")
    if failed:
        raise typer.Exit(1)
