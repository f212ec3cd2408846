"""``lbscene render CONFIG.yaml [-o out.png] [--lighting L] [--geometry 45as15[,45as45]] [--size 1024x768] [--all-geometries]``"""

from __future__ import annotations

import subprocess
import sys
import time
from enum import Enum
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text


class Diffuse(str, Enum):
    auto = "auto"
    baked = "baked"
    analytic = "analytic"


class Adaptation(str, Enum):
    cat16 = "cat16"
    none = "none"


def _usage_error(message: str, value: str, expected: str):
    from lbscene.engine.files.diagnostics import LbsceneUserError

    return LbsceneUserError.single("LB500", message, value=value, expected=expected)


def _run_bake(job, console) -> None:
    """Build the booth and bake the configuration's lighting (separate processes)."""
    from lbscene.engine.scene.compile import find_booth_file

    booth_file = find_booth_file(Path(job["booth"]))
    build_dir = Path("build") / booth_file.resolve().parent.name
    for cmd in ([sys.executable, "-m", "lbscene", "build", str(booth_file), "--out", str(build_dir)],
                [sys.executable, "-m", "lbscene", "bake", str(build_dir), "--lighting", job["lighting"]]):
        from lbscene.commands.console import styled

        console.print(styled(("running", "bold"), " " + " ".join(cmd[2:])))
        rc = subprocess.call(cmd)
        if rc != 0:
            from lbscene.engine.files.diagnostics import LbsceneUserError

            raise LbsceneUserError.single("LB600", f"`{' '.join(cmd[2:])}` failed (exit {rc})",
                                          expected="a successful bake")


def register(app: typer.Typer) -> None:
    @app.command("render")
    def render(
        config: Path = typer.Argument(..., help="Render configuration (kind: render_config)."),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="PNG to write (default: the config's output.png); the config's float XYZ then goes beside it as NAME.xyz.exr or .npy."),
        geometry: Optional[List[str]] = typer.Option(
            None, "--geometry", "-g",
            help="Viewing geometry, e.g. 45as15; several (comma-separated or the option repeated) make a "
                 "contact sheet of those views."),
        lighting: Optional[str] = typer.Option(
            None, "--lighting", "-l", help="Lighting configuration of the booth (overrides the config's)."),
        size: Optional[str] = typer.Option(None, "--size", help="WIDTHxHEIGHT in pixels (16..8192 each)."),
        all_geometries: bool = typer.Option(
            False, "--all-geometries",
            help="Render every viewing geometry of the booth (six for the byko-spectra effect) into one "
                 "contact sheet of labelled tiles, each --size; with --xyz, one XYZ file per view."),
        xyz: Optional[Path] = typer.Option(None, "--xyz", help="Also write the float XYZ image (.npy or .exr)."),
        diffuse: Optional[Diffuse] = typer.Option(None, "--diffuse",
                                                  help="Override the config: auto, baked or analytic."),
        adaptation: Optional[Adaptation] = typer.Option(
            None, "--adaptation",
            help="Override the config: cat16 (default: adapted to the lighting's white, what a person in "
                 "the booth sees) or none (what a camera sees: under A or TL84 the image looks warm)."),
        bake: bool = typer.Option(False, "--bake", help="Run a missing bake (build + bake) before rendering."),
        no_input: bool = typer.Option(False, "--no-input", help="Never ask questions (CI)."),
        egl_device: Optional[int] = typer.Option(None, "--egl-device", help="EGL device index (GPU choice)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Render a sample in a virtual booth (spectral, 16 bands) to a display-encoded PNG."""
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            SpinnerColumn,
            TextColumn,
            TimeElapsedColumn,
        )

        from lbscene.engine.colour.adaptation import ADAPTATION_DESCRIPTIONS
        from lbscene.engine.files.diagnostics import LbsceneUserError
        from lbscene.engine.files.load import display_path
        from lbscene.runtimes.render import parse_size, prepare_from_config, render_job

        from lbscene.commands.console import err_console, out_console, progress

        console = err_console()
        wh = None
        if size is not None:
            try:
                wh = parse_size(size)
            except ValueError as exc:
                raise _usage_error(f"--size: {exc}", size, "WIDTHxHEIGHT with each side 16..8192")
        if xyz is not None and xyz.suffix.lower() not in (".npy", ".exr"):
            raise _usage_error("--xyz must name a .npy or .exr file", str(xyz), "a .npy or .exr file name")
        if geometry and all_geometries:
            raise _usage_error("--geometry and --all-geometries exclude each other", ",".join(geometry),
                               "one of them")

        def prepare():
            return prepare_from_config(config, geometry=geometry or None, all_geometries=all_geometries, size=wh,
                                       lighting=lighting,
                                       png=out, xyz=xyz, diffuse=diffuse.value if diffuse else None,
                                       allowed_dirs=tuple(allow_path or ()),
                                       adaptation=adaptation.value if adaptation else None)

        t_start = time.perf_counter()
        try:
            job = prepare()
        except LbsceneUserError as exc:
            missing = [d for d in exc.diagnostics if d.code == "LB601"]
            if not missing:
                raise
            ask = not no_input and not bake and sys.stdin.isatty() and format is Format.text
            if ask:
                from lbscene.cli import print_diagnostics

                print_diagnostics(exc.diagnostics)
                if not typer.confirm("Run the bake now (build + bake; may take minutes)?", default=False):
                    raise
            elif not bake:
                raise
            import ruamel.yaml  # the config names booth and lighting; read them without validating twice

            from lbscene.engine.files.yamlio import read_text_bounded

            raw = ruamel.yaml.YAML(typ="safe").load(read_text_bounded(Path(config), str(config),
                                                                      4 * 1024 * 1024))
            booth = Path(config).resolve().parent / raw["booth"]
            _run_bake({"booth": str(booth), "lighting": lighting or raw["lighting"]}, console)
            job = prepare()

        columns = [SpinnerColumn(), TextColumn("{task.description}")]
        if len(job.views) > 1:
            columns.append(BarColumn())
            columns.append(MofNCompleteColumn())
        with progress(*columns, TimeElapsedColumn(), console=console, transient=True,
                      disable=format is Format.json) as prog:
            task = prog.add_task("render", total=len(job.views))

            def step(description: str, advance: bool = False) -> None:
                prog.update(task, description=description)
                if advance:
                    prog.advance(task)

            res = render_job(job, contact=job.contact, egl_device=egl_device, progress=step,
                             prepared_s=time.perf_counter() - t_start)
        result = res.to_json()
        frames, gl_name, elapsed = res.frames, res.gl_renderer, res.elapsed_s
        xyz_files = [str(p) for p in res.xyz_files]
        if format is Format.json:
            echo(json_text(result, indent=2))
            return
        from lbscene.commands.console import table

        tab = table(title=f"{job.ir.booth_name} / {job.graph['lighting']} / {job.sample.name}")
        for col in ("view", "illum °", "view °", "aspec °", "sample lx", "out of gamut"):
            tab.add_column(col, justify="right" if col != "view" else "left")
        for f in frames:
            r = f.info.get("realised") or {}
            og = f.out_of_gamut or {}
            tab.add_row(f.view, f"{r.get('illumination_deg', 0):.1f}", f"{r.get('viewing_deg', 0):.1f}",
                          f"{r.get('aspecular_deg', 0):.1f}", f"{f.info.get('sample_illuminance_lx', 0):.0f}",
                          f"{og.get('pixels', 0)} px ({100 * og.get('fraction', 0):.1f} %, max {og.get('max_excess', 0):.3f})")
        out_console().print(tab)
        if job.diffuse == "analytic" and job.bake_note:
            echo(f"note: diffuse light is analytic: {job.bake_note}; run `lbscene bake` for baked "
                       "lighting", err=True)
        for n in job.notes:
            echo(f"note: {n}", err=True)
        echo(f"wrote {display_path(job.png)}" + (f" and {', '.join(xyz_files)}" if xyz_files else "")
                   + f"  ({job.size[0]}x{job.size[1]}, {job.diffuse} diffuse light, display "
                     f"{job.display.name}, {gl_name}, {elapsed:.1f} s)")
        echo(f"adaptation: {job.adaptation}: {ADAPTATION_DESCRIPTIONS[job.adaptation]}")
