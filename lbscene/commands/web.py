"""``lbscene export-web CONFIG_OR_BOOTH --out DIR``: the booth as a static WebGL2 viewer."""

from __future__ import annotations

import time
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text

#: Above this the export is refused unless --max-mb says otherwise (a browser tab holds
#: the whole data file in memory, decoded).
DEFAULT_MAX_MB = 256


def _err(code, message, value=None, expected=None, hint=None, loc=None):
    from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError

    return LbsceneUserError(Diagnostic(code, message, loc, value=value, expected=expected, hint=hint))


def _grey_sample():
    import numpy as np

    from lbscene.engine.scene.sample import SampleSpec

    # a neutral matte sample when only a booth is given: reflectance 0.5 on the 1 nm grid
    return SampleSpec.flat(np.full(471, 0.5), name="neutral grey 50 %")


def _load_sample(path: Path, allowed_dirs):
    from lbscene.engine.files.load import load_document
    from lbscene.engine.scene.sample import SampleSpec
    from lbscene.schemas.sample import Sample

    return SampleSpec.from_document(load_document(path, Sample, allowed_dirs=allowed_dirs))


def _load_display(text: str):
    from lbscene.runtimes.colour_bridge import display_uniforms, srgb_display

    if text.strip().lower() in ("builtin:srgb", "srgb"):
        return srgb_display()
    p = Path(text)
    if not p.is_file():
        raise _err("LB200", f"--display: display file {text!r} does not exist", value=text,
                   expected="a display document (displays/*.yaml) or 'builtin:srgb'")
    return display_uniforms(p)


def gather_inputs(source: Path, *, lightings=(), samples=(), displays=(), size=None, session=None,
                  allowed_dirs=()):
    """Resolve the command's arguments into :class:`~lbscene.runtimes.web.export.WebExportInputs`."""
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.runtimes.render import prepare_from_config
    from lbscene.runtimes.web.export import WebExportInputs

    ses = None
    if session is not None:
        from lbscene.engine.visual.protocol import load_session

        ses = load_session(session, allowed_dirs)
    if source is None:
        if ses is None or ses.model.render_config is None:
            raise _err("LB500", "nothing to export", expected="a render configuration or a booth, or "
                       "--session with a session that names its render_config")
        source = ses.doc.resolve(ses.model.render_config)
    from lbscene.engine.files.yamlio import path_kind

    source = Path(source)
    job = None
    is_config = False
    if path_kind(source) == "file" and source.suffix.lower() in (".yaml", ".yml"):
        with open(source, "rb") as fh:       # the head only: a multi-GB file is not read whole here
            is_config = b"render_config" in fh.read(4000)
    if is_config:
        job = prepare_from_config(source, allowed_dirs=allowed_dirs)
        ir = job.ir
    else:
        ir = compile_booth(find_booth_file(source))
    names = list(lightings) or ([job.graph["lighting"]] + [n for n in ir.lighting if n != job.graph["lighting"]]
                                if job else list(ir.lighting))
    if ses is not None:
        names += [n for n in ses.model.lightings if n not in names]
    unknown = [n for n in names if n not in ir.lighting]
    if unknown:
        raise _err("LB202", f"booth {ir.booth_name!r} has no lighting configuration {unknown[0]!r}",
                   value=unknown[0], expected=f"one of {', '.join(ir.lighting)}")
    if ses is not None:
        geoms = [g.name for g in ir.geometries] or ["default"]
        bad = [g for g in ses.model.geometries if g not in geoms]
        if bad:
            raise _err("LB303", f"session geometry {bad[0]!r} is not a viewing geometry of booth "
                                f"{ir.booth_name!r}", value=bad[0], expected=f"one of {', '.join(geoms)}",
                       loc=ses.doc.locate("geometries"))
    lmap = {}
    for n in names:
        if job is not None and n == job.graph["lighting"]:
            lmap[n] = (job.diffuse, job.bake)
        else:
            lmap[n] = ("analytic", None)
    sample_specs = ([job.sample] if job else []) + [_load_sample(Path(p), allowed_dirs) for p in samples]
    if ses is not None:
        have = {s.name for s in sample_specs}
        sample_specs += [s for s in ses.samples if s.name not in have]
    if not sample_specs:
        sample_specs = [_grey_sample()]
    display_specs = ([job.display] if job else []) + [_load_display(d) for d in displays]
    if not any(d.source.startswith("builtin") for d in display_specs):
        from lbscene.runtimes.colour_bridge import srgb_display

        display_specs.append(srgb_display())
    initial = {"lighting": names[0], "view": job.views[0] if job else None}
    kw = {}
    if job is not None:
        kw = dict(exposure=job.exposure, white_fraction=job.white_fraction, dither=job.dither,
                  camera=job.camera)
    wh = size or (job.size if job else (1024, 768))
    return WebExportInputs(ir=ir, lightings=lmap, samples=sample_specs, displays=display_specs,
                           size_px=tuple(wh), initial=initial,
                           session=ses.to_viewer() if ses is not None else None,
                           source=source.name, **kw), job


def run_export_web(source, out: Path, *, lightings=(), samples=(), displays=(), size=None, session=None,
                   max_mb: float = DEFAULT_MAX_MB, allowed_dirs=(), progress=None) -> dict:
    """Export the WebGL2 viewer into ``out`` (what ``lbscene export-web`` does); returns the
    command's JSON summary (``out``, ``files``, ``booth``, ``lightings``, ``views``, ``samples``,
    ``displays``, ``data_MB``, ``data_file_MB``, ``session``, ``elapsed_s``)."""
    from lbscene.engine.files.load import display_path
    from lbscene.engine.files.outputs import check_output_dir, check_outputs
    from lbscene.runtimes.web.export import build_export, is_web_export, write_export

    out = Path(out)
    if out.is_dir() and not out.is_symlink() and any(out.iterdir()) and not is_web_export(out):
        raise _err("LB700", f"--out {display_path(out)} exists and is not a web export", value=str(out),
                   expected="a new folder, or one an earlier export-web wrote (it is replaced whole)")
    check_outputs([], inputs=[source, session])
    check_output_dir(out, option="--out")     # every file export-web's, unchanged (checked again at the swap)
    t0 = time.perf_counter()
    inp, _ = gather_inputs(Path(source) if source is not None else None, lightings=lightings, samples=samples,
                           displays=displays, size=size, session=session, allowed_dirs=tuple(allowed_dirs))
    # the session's trials go into the data file as they are: counted before the export's work
    session_bytes = len(json_text(inp.session).encode()) if inp.session is not None else 0
    if session_bytes / 1e6 > max_mb:
        raise _err("LB701", f"the session alone would hold {session_bytes / 1e6:.0f} MB of trials",
                   value=f"{session_bytes / 1e6:.1f} MB", expected=f"at most --max-mb {max_mb:g}",
                   hint="fewer observers, repeats or cases per session (split the panel), or raise --max-mb")
    manifest = build_export(inp, progress=progress)
    mb = (manifest["blob_bytes"] + session_bytes) / 1e6
    if mb > max_mb:
        raise _err("LB701", f"the export would hold {mb:.0f} MB of data", value=f"{mb:.1f} MB",
                   expected=f"at most --max-mb {max_mb:g}",
                   hint="export fewer lightings (--lighting), samples or displays, or raise --max-mb")
    files = write_export(manifest, out)
    views = sum(len(lt["views"]) for lt in manifest["lightings"])
    return {"out": str(out), "files": [str(f) for f in files], "booth": manifest["booth"],
            "lightings": [lt["name"] for lt in manifest["lightings"]], "views": views,
            "samples": [s["name"] for s in manifest["samples"]],
            "displays": [d["name"] for d in manifest["displays"]],
            "data_MB": round(mb, 2), "data_file_MB": round((out / "lbscene-data.js").stat().st_size / 1e6, 2),
            "session": manifest["session"]["name"] if manifest["session"] else None,
            "elapsed_s": round(time.perf_counter() - t0, 2)}


def register(app: typer.Typer) -> None:
    @app.command("export-web")
    def export_web(
        source: Optional[Path] = typer.Argument(
            None, help="Render configuration (kind: render_config) or booth folder/booth.yaml; may be left "
                       "out with --session when the session names its render_config."),
        out: Path = typer.Option(..., "--out", "-o", help="Folder to write the viewer into (an earlier export "
                                 "is replaced whole while it holds only the files export-web wrote, unchanged)."),
        lighting: Optional[List[str]] = typer.Option(
            None, "--lighting", help="Lighting configurations to include (default: all of the booth)."),
        sample: Optional[List[Path]] = typer.Option(None, "--sample", help="Extra sample documents."),
        display: Optional[List[str]] = typer.Option(
            None, "--display", help="Extra display documents (or builtin:srgb); the sRGB reference is always in."),
        size: Optional[str] = typer.Option(None, "--size", help="WIDTHxHEIGHT in pixels (16..8192 each): the "
                                          "most pixels the viewer draws (it takes the screen's shape)."),
        session: Optional[Path] = typer.Option(None, "--session", help="Visual-test session (kind: "
                                               "visual_session): adds its cases and the viewer's test mode."),
        max_mb: float = typer.Option(DEFAULT_MAX_MB, "--max-mb", help="Refuse exports whose data exceed this."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Export a self-contained WebGL2 viewer of the booth (same render graph and shaders as render)."""
        from lbscene.engine.files.load import display_path
        from lbscene.runtimes.render import parse_size

        import math

        if not (math.isfinite(max_mb) and max_mb > 0):
            raise _err("LB500", "--max-mb must be a positive number of megabytes", value=f"{max_mb:g}",
                       expected="a number > 0")
        wh = None
        if size is not None:
            try:
                wh = parse_size(size)
            except ValueError as exc:
                raise _err("LB500", f"--size: {exc}", value=size, expected="WIDTHxHEIGHT with each side 16..8192")
        from lbscene.commands.console import err_console

        console = err_console()
        with console.status("export-web") as st:
            result = run_export_web(source, out, lightings=lighting or (), samples=sample or (),
                                    displays=display or (), size=wh, session=session, max_mb=max_mb,
                                    allowed_dirs=tuple(allow_path or ()),
                                    progress=lambda m: st.update(f"export-web: {m}"))
        views = result["views"]
        if format is Format.json:
            echo(json_text(result, indent=2))
            return
        echo(f"wrote {display_path(out)}/index.html  ({len(result['lightings'])} lighting(s), {views} views, "
                   f"{len(result['samples'])} sample(s), {len(result['displays'])} display(s); "
                   f"{result['data_file_MB']} MB; {result['elapsed_s']} s)")
        echo("open index.html in a browser with WebGL2 (works from file://; nothing is fetched)")
