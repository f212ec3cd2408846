"""
Rendering frames: a render graph + scene inputs + the moderngl executor.

:class:`Renderer` is what the CLI, the benchmark and the tests use::

    r = Renderer(ir, build_render_graph(ir, "A"), SampleSpec.flat(refl_1nm), srgb_display())
    frame = r.render("45as45", (1024, 768), want_xyz=True)
    frame.rgba8          # (H, W, 4) uint8, top row first (display-encoded, dithered)
    frame.xyz            # (H, W, 3) float32, absolute XYZ (Y in cd/m²)

:func:`prepare_from_config` resolves a render configuration (booth, lighting,
geometry, sample, display, bake) into a :class:`RenderJob` with located
errors for user mistakes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lbscene.engine.scene.sample import SampleSpec

from .executor import GraphExecutor, PassTiming, create_context
from .scene import CameraSpec, SceneBuilder

__all__ = [
    "RenderResult",
    "render_job",
    "render_from_config",
    "xyz_view_path",
    "Frame",
    "Renderer",
    "RenderJob",
    "prepare_from_config",
    "parse_size",
    "MIN_SIZE_PX",
    "MAX_SIZE_PX",
    "contact_sheet",
    "write_png",
    "write_xyz",
    "geometry_list",
]

MIN_SIZE_PX = 16
MAX_SIZE_PX = 8192


@dataclass
class Frame:
    view: str
    size: tuple[int, int]
    rgba8: np.ndarray
    xyz: np.ndarray | None = None
    out_of_gamut: dict | None = None
    info: dict = field(default_factory=dict)
    timings: list[PassTiming] = field(default_factory=list)


class Renderer:
    """A booth's render graph on one GL context, for one sample and display."""

    def __init__(self, ir, graph: dict, sample: SampleSpec, display, *, bake=None,
                 diffuse: str = "analytic", exposure: str = "relative_white", white_fraction: float = 1.0,
                 dither: bool = True, camera: CameraSpec | None = None, ctx=None,
                 device_index: int | None = None, adaptation: str = "cat16"):
        self.scene = SceneBuilder(ir, graph, sample, display, bake=bake, diffuse=diffuse, exposure=exposure,
                                  white_fraction=white_fraction, dither=dither, camera=camera,
                                  adaptation=adaptation)
        self.graph = graph
        self.ctx = ctx if ctx is not None else create_context(device_index)
        self._own_ctx = ctx is None
        self.executor: GraphExecutor | None = None
        self._current_view: str | None = None

    @property
    def gl_renderer(self) -> str:
        return str(self.ctx.info.get("GL_RENDERER", "?"))

    def prepare(self, view: str, size: tuple[int, int]) -> None:
        """Upload everything for a view and viewport (cheap when nothing changed)."""
        if self.executor is None:
            self.executor = GraphExecutor(self.ctx, self.graph, size)
            for name, arr in self.scene.static_textures().items():
                self.executor.set_texture(name, arr)
        ex = self.executor
        ex.resize(size)
        vi = self.scene.view(view)
        if self._current_view != view:
            for name, (v, idx) in vi.meshes.items():
                ex.set_mesh(name, v, idx)
            for name, arr in vi.textures.items():
                ex.set_texture(name, arr)
            self._current_view = view
        ex.values.update({k: v for k, v in vi.values.items() if v is not None})
        cam = self.scene.camera_values(view, size)
        ex.values.update({k: v for k, v in cam.items() if not k.startswith("_")})

    def render(self, view: str | None = None, size: tuple[int, int] = (1024, 768), *,
               want_xyz: bool = False, want_gamut: bool = False, timings: bool = False,
               schedule: str | None = None) -> Frame:
        """Render one frame.  The ``realtime`` schedule (one raster pass straight to 8-bit
        colour) unless XYZ or gamut data are wanted (then ``analysis``, which keeps those
        images), or as ``schedule`` says; every schedule gives the same 8-bit image (up to
        rare one-level differences where float rounding meets a dither threshold)."""
        view = view or self.scene.view_names[0]
        self.prepare(view, size)
        if schedule is None:
            schedule = "analysis" if (want_xyz or want_gamut) else "realtime"
        t: list[PassTiming] | None = [] if timings else None
        self.executor.run(t, schedule)
        frame = Frame(view=view, size=tuple(size), rgba8=self.executor.read("display_rgba8"),
                      info=dict(self.scene.view(view).info), timings=t or [])
        if want_xyz:
            frame.xyz = self.executor.read("xyz")[..., :3]
        if want_gamut:
            ex = self.executor.read("display_drive")[..., 3]
            n = int((ex > 1e-6).sum())
            frame.out_of_gamut = {"pixels": n, "fraction": n / ex.size, "max_excess": float(ex.max()),
                                  "mapping": self.scene.display.gamut_mapping_name}
        return frame

    def sample_pixel(self, view: str, size: tuple[int, int]) -> tuple[float, float]:
        """Pixel coordinates (x right, y down) of the sample centre in a frame."""
        vi = self.scene.view(view)
        vp = self.scene.camera_values(view, size)["_view_proj"]
        c = vp @ np.r_[vi.sample_centre_mm, 1.0]
        ndc = c[:2] / c[3]
        w, h = size
        return (ndc[0] + 1) / 2 * w, (1 - ndc[1]) / 2 * h

    def close(self) -> None:
        if self.executor is not None:
            self.executor.release()
            self.executor = None
        if self._own_ctx:
            self.ctx.release()


# --------------------------------------------------------------------------- output files

def write_png(path: Path, rgba8: np.ndarray, text: dict[str, str] | None = None) -> None:
    """Write an RGB PNG atomically (temporary sibling, then ``os.replace``)."""
    import io

    from PIL import Image, PngImagePlugin

    from lbscene.engine.files.outputs import write_output

    info = PngImagePlugin.PngInfo()
    for k, v in (text or {}).items():
        info.add_text(k, str(v))
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba8[..., :3])).save(buf, format="PNG", pnginfo=info)
    write_output(Path(path), buf.getvalue(), option="output.png")


def write_xyz(path: Path, xyz: np.ndarray) -> None:
    """Write float XYZ (H, W, 3) as ``.npy`` or ``.exr`` (channels X, Y, Z), atomically."""
    from lbscene.engine.files.outputs import output_path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npy", ".exr"):
        raise ValueError(f"unsupported XYZ file type {suffix!r} (use .npy or .exr)")
    with output_path(path, suffix=suffix, option="--xyz") as tmp:
        if suffix == ".npy":
            np.save(tmp, np.asarray(xyz, np.float32))
        else:
            from lbscene.bakers.products import write_exr

            write_exr(Path(tmp), np.asarray(xyz, np.float32), ["X", "Y", "Z"],
                      {"lbscene:units": "XYZ, Y in cd/m2 (absolute)"})


def contact_sheet(frames: list[Frame], columns: int = 3, label: bool = True) -> np.ndarray:
    """Tile frames (same size) into one RGBA8 image with their view names."""
    from PIL import Image, ImageDraw

    w, h = frames[0].size
    rows = (len(frames) + columns - 1) // columns
    sheet = Image.new("RGBA", (columns * w, rows * h), (0, 0, 0, 255))
    for i, f in enumerate(frames):
        tile = Image.fromarray(f.rgba8)
        if label:
            d = ImageDraw.Draw(tile)
            d.rectangle([0, 0, 8 + 7 * len(f.view), 16], fill=(0, 0, 0, 255))
            d.text((4, 3), f.view, fill=(255, 255, 255, 255))
        sheet.paste(tile, ((i % columns) * w, (i // columns) * h))
    return np.asarray(sheet)


# --------------------------------------------------------------------------- configuration

def parse_size(text: str) -> tuple[int, int]:
    """``'1024x768'`` → (1024, 768); raises ValueError with a readable message."""
    parts = text.lower().replace("×", "x").split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"{text!r} is not a size like 1024x768")
    w, h = int(parts[0]), int(parts[1])
    for v in (w, h):
        if not MIN_SIZE_PX <= v <= MAX_SIZE_PX:
            raise ValueError(f"{w}x{h}: each side must be {MIN_SIZE_PX}..{MAX_SIZE_PX} px")
    return w, h


def _checked_size(size) -> tuple[int, int] | None:
    """A size given to the API or the command: ``None`` or two whole numbers of pixels, each
    :data:`MIN_SIZE_PX` … :data:`MAX_SIZE_PX`.

    Raises
    ------
    TypeError
        Not a pair of integers (a wrong Python type).
    LbsceneUserError
        ``LB500`` for a side out of range (0, negative, above 8192).
    """
    if size is None:
        return None
    if isinstance(size, str) or not hasattr(size, "__len__") or len(size) != 2 or not all(
            isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in size):
        raise TypeError(f"size must be (width_px, height_px), two integers; got {size!r}")
    w, h = int(size[0]), int(size[1])
    if not (MIN_SIZE_PX <= w <= MAX_SIZE_PX and MIN_SIZE_PX <= h <= MAX_SIZE_PX):
        from lbscene.engine.files.diagnostics import LbsceneUserError

        raise LbsceneUserError.single("LB500", f"size {w}x{h} is out of range", value=f"{w}x{h}",
                                      expected=f"each side {MIN_SIZE_PX}..{MAX_SIZE_PX} px")
    return w, h


@dataclass
class RenderJob:
    """A render configuration resolved into inputs of :class:`Renderer`."""

    config_path: Path
    ir: Any
    graph: dict
    sample: SampleSpec
    display: Any
    views: list[str]
    size: tuple[int, int]
    png: Path
    xyz: Path | None
    diffuse: str
    bake: Any = None
    bake_note: str = ""
    exposure: str = "relative_white"
    white_fraction: float = 1.0
    dither: bool = True
    camera: CameraSpec = field(default_factory=CameraSpec)
    notes: list[str] = field(default_factory=list)
    adaptation: str = "cat16"
    #: several views asked for (``--all-geometries`` or a list of ``--geometry``): one contact sheet
    contact: bool = False

    def renderer(self, ctx=None, device_index: int | None = None) -> Renderer:
        return Renderer(self.ir, self.graph, self.sample, self.display, bake=self.bake,
                        diffuse=self.diffuse, exposure=self.exposure, white_fraction=self.white_fraction,
                        dither=self.dither, camera=self.camera, ctx=ctx, device_index=device_index,
                        adaptation=self.adaptation)


def _err(code, message, loc=None, **kw):
    from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError

    return LbsceneUserError(Diagnostic(code, message, loc, **kw))


def xyz_view_path(xyz: Path, view: str) -> Path:
    """The XYZ file of one view of a contact sheet: ``<stem>.<view><suffix>``."""
    return xyz.with_name(f"{xyz.stem}.{view}{xyz.suffix}")


def _check_render_outputs(doc, base: Path, png: Path, png_from_cli: bool, xyz: Path | None,
                          xyz_from_cli: bool, views: list[str] | None, allowed_dirs) -> None:
    """The output policy for a render (:mod:`lbscene.engine.files.outputs`): outputs named in the config
    stay in its folder (unless ``--allow-path``); none replaces an input or a file lbscene did not
    write; every target is writable.  Checked before any rendering."""
    from lbscene.engine.files.outputs import check_output_file

    seen: dict[str, str] = {}
    items = [(Path(png), "--out" if png_from_cli else "output.png", None if png_from_cli else ("output", "png"))]
    if xyz is not None:
        opt, loc = ("--xyz", None) if xyz_from_cli else ("output.xyz", ("output", "xyz"))
        for p in ([xyz_view_path(Path(xyz), v) for v in views] if views else [Path(xyz)]):
            items.append((p, opt, loc))
    for p, opt, loc in items:
        key = str(p.resolve())
        if key in seen:
            raise _err("LB500", f"{opt} and {seen[key]} name the same output", None, value=str(p),
                       expected="different paths")
        seen[key] = opt
        check_output_file(p, option=opt, location=doc.locate(*loc) if loc else None,
                          confine_to=None if loc is None else base,
                          allowed_dirs=tuple(Path(d) for d in allowed_dirs))


def geometry_list(geometry) -> list[str]:
    """Viewing geometry names from ``--geometry``: one name, a comma-separated list, or a list of
    either (the option repeated); order kept, duplicates dropped.  ``TypeError`` for anything else."""
    if geometry is None:
        return []
    items = [geometry] if isinstance(geometry, str) else geometry
    if not isinstance(items, (list, tuple)) or not all(isinstance(g, str) for g in items):
        raise TypeError(f"geometry must be a name, a comma-separated string or a list of names, got {geometry!r}")
    return list(dict.fromkeys(n.strip() for g in items for n in g.split(",") if n.strip()))


def prepare_from_config(config_path: Path, *, geometry: str | list[str] | None = None,
                        all_geometries: bool = False,
                        size: tuple[int, int] | None = None, png: Path | None = None,
                        xyz: Path | None = None, diffuse: str | None = None,
                        bake_dirs: list[Path] | None = None, allowed_dirs=(),
                        adaptation: str | None = None, lighting: str | None = None) -> RenderJob:
    """Load and check a render configuration; everything a user can get wrong raises
    :class:`~lbscene.engine.files.diagnostics.LbsceneUserError` with a location.  Keyword arguments
    other than ``bake_dirs`` and ``allowed_dirs`` override the configuration's fields:
    ``lighting`` its lighting, ``geometry`` its geometry (a name, a comma-separated list or a
    list: several views make a contact sheet, as ``all_geometries`` does)."""
    from lbscene.engine.scene.compile import compile_booth, find_booth_file
    from lbscene.engine.files.load import display_path, load_document
    from lbscene.schemas.render_config import RenderConfig
    from lbscene.schemas.sample import Sample

    from .bake import find_bakes, load_bake
    from .colour_bridge import display_uniforms, srgb_display
    from .graph import build_render_graph, view_names

    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.limits import check_work

    size = _checked_size(size)
    for name, value, allowed in (("diffuse", diffuse, ("auto", "baked", "analytic")),
                                 ("adaptation", adaptation, ("cat16", "none"))):
        if value is not None and value not in allowed:
            raise LbsceneUserError.single("LB500", f"{name} must be one of {', '.join(allowed)}",
                                          value=repr(value), expected=" or ".join(allowed))
    config_path = Path(config_path)
    wanted = geometry_list(geometry)
    if lighting is not None and not isinstance(lighting, str):
        raise TypeError(f"lighting must be a lighting name, got {lighting!r}")
    doc = load_document(config_path, RenderConfig, allowed_dirs=allowed_dirs)
    cfg = doc.model
    # the pixels of one view, before anything is compiled or allocated (8192 × 8192 takes 9 GB)
    w_px, h_px = size or (cfg.output.width_px, cfg.output.height_px)
    check_work("pixels", w_px * h_px, None if size else doc.locate("output", "width_px"),
               what=f"pixels of one view ({w_px}x{h_px})")
    base = config_path.resolve().parent
    booth_path = (base / cfg.booth) if not Path(cfg.booth).is_absolute() else Path(cfg.booth)
    if not booth_path.exists():
        raise _err("LB200", f"booth {cfg.booth!r} does not exist", doc.locate("booth"),
                   value=str(booth_path), expected="a booth folder or booth.yaml")
    ir = compile_booth(find_booth_file(booth_path))
    lighting_name = lighting or cfg.lighting
    if lighting_name not in ir.lighting:
        raise _err("LB202", f"{'--lighting: ' if lighting else ''}booth {ir.booth_name!r} has no lighting "
                            f"configuration {lighting_name!r}", None if lighting else doc.locate("lighting"),
                   value=repr(lighting_name), expected=f"one of {', '.join(ir.lighting)}")
    graph = build_render_graph(ir, lighting_name)
    names = view_names(ir)
    booth_geoms = [g.name for g in ir.geometries]
    notes: list[str] = []
    if all_geometries:
        views = names
        if len(booth_geoms) < 2:
            notes.append(f"booth {ir.booth_name!r} declares "
                         + (f"one viewing geometry ({booth_geoms[0]})" if booth_geoms else "no viewing geometry")
                         + ": the contact sheet has one view")
    else:
        wants = wanted or ([cfg.geometry] if cfg.geometry is not None else [])
        if not wants:
            views = [names[0]]
        else:
            for want in wants:
                if want not in booth_geoms:
                    loc = None if wanted else doc.locate("geometry")
                    expected = f"one of {', '.join(booth_geoms)}" if booth_geoms else "no geometry (this booth has none)"
                    raise _err("LB303", f"{'--geometry: ' if wanted else ''}unknown viewing geometry {want!r} for "
                                        f"booth {ir.booth_name!r}", loc, value=repr(want), expected=expected)
            views = wants

    sdoc = load_document(doc.resolve(cfg.sample), Sample, allowed_dirs=allowed_dirs)
    sample = SampleSpec.from_document(sdoc)

    if cfg.display.strip().lower() in ("builtin:srgb", "srgb"):
        display = srgb_display()
    else:
        dpath = (base / cfg.display) if not Path(cfg.display).is_absolute() else Path(cfg.display)
        if not dpath.is_file():
            raise _err("LB200", f"display file {cfg.display!r} does not exist", doc.locate("display"),
                       value=str(dpath), expected="a display document (displays/*.yaml) or 'builtin:srgb'")
        display = display_uniforms(dpath)
        if display.source.startswith("builtin"):
            notes.append("display model not available in this build: rendering for the sRGB reference display")

    mode = diffuse or cfg.diffuse
    searched = list(bake_dirs or [])
    if cfg.bake:
        searched.insert(0, base / cfg.bake)
    booth_dir = find_booth_file(booth_path).resolve().parent
    searched += [Path.cwd() / "build" / booth_dir.name, booth_dir / "build"]
    bake = None
    bake_note = ""
    if mode in ("auto", "baked"):
        folder, reason = find_bakes(searched, ir, lighting_name)
        if folder is not None:
            fixed = graph["scene"]["platform"]["luminaire_turns_with_platform"]
            bake = load_bake(folder, lamps_turn_with_platform=fixed, views=len(names))
            missing = [v for v in views if not bake.has_view(v)]
            if missing:
                reason = f"the bake in {folder} has no environment map for {', '.join(missing)}"
                bake = None
        if bake is None:
            where = ", ".join(display_path(p) for p in searched)
            bake_note = f"{reason} (looked in {where})"
            if mode == "baked":
                from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError

                raise LbsceneUserError(Diagnostic(
                    "LB601", f"the configuration asks for baked lighting but {bake_note}",
                    doc.locate("diffuse"), value=f"diffuse: {mode}",
                    expected=f"bake products of lighting {lighting_name!r}",
                    hint=f"run `lbscene build {display_path(booth_dir)}` and `lbscene bake "
                         f"build/{booth_dir.name} --lighting {lighting_name}`, or pass --bake to "
                         f"run the bake now, or set `diffuse: analytic`"))
            mode = "analytic"
        else:
            mode = "baked"

    out_png = png or (base / cfg.output.png)
    out_xyz = xyz or ((base / cfg.output.xyz) if cfg.output.xyz else None)
    if png is not None and xyz is None and cfg.output.xyz:
        # -o redirects every output of the config: the float XYZ goes beside the PNG, never
        # into the config's own folder
        p_png = Path(png)
        out_xyz = p_png.with_name(p_png.stem + ".xyz" + Path(cfg.output.xyz).suffix.lower())
    if out_xyz is not None and Path(out_xyz).suffix.lower() not in (".npy", ".exr"):
        raise _err("LB104", f"XYZ output {str(out_xyz)!r} must end in .npy or .exr",
                   None if xyz else doc.locate("output", "xyz"), value=str(out_xyz),
                   expected="a .npy or .exr file name")
    xyz_from_cli = xyz is not None or (png is not None and bool(cfg.output.xyz))
    contact = all_geometries or len(views) > 1
    _check_render_outputs(doc, base, out_png, png is not None, out_xyz, xyz_from_cli,
                          views if contact else None, allowed_dirs)
    cam = cfg.camera
    camera = CameraSpec(position_mm=cam.position_mm if cam.type == "free" else None,
                        look_at_mm=cam.look_at_mm, vertical_fov_deg=cam.vertical_fov_deg)
    if cam.type == "free" and cam.position_mm is None:
        raise _err("LB102", "a free camera needs position_mm", doc.locate("camera"),
                   expected="camera.position_mm")
    return RenderJob(config_path=config_path, ir=ir, graph=graph, sample=sample, display=display,
                     views=views, size=size or (cfg.output.width_px, cfg.output.height_px),
                     png=Path(out_png), xyz=Path(out_xyz) if out_xyz else None, diffuse=mode,
                     bake=bake, bake_note=bake_note, exposure=cfg.exposure.mode,
                     white_fraction=cfg.exposure.white_fraction, dither=cfg.dither, camera=camera,
                     notes=notes, adaptation=adaptation or cfg.adaptation, contact=contact)


# --------------------------------------------------------------------------- one call: config → files


@dataclass
class RenderResult:
    """What :func:`render_job` made: the frames, the files written, and how long each part took."""

    job: RenderJob
    frames: list[Frame]
    png: Path
    xyz_files: list[Path]
    contact_sheet: bool
    gl_renderer: str
    timing_s: dict
    elapsed_s: float

    def to_json(self) -> dict:
        """The summary ``lbscene render --format json`` prints."""
        from lbscene.engine.colour.adaptation import ADAPTATION_DESCRIPTIONS

        from .colour_bridge import colour_module_features

        job, frames = self.job, self.frames
        ad = frames[0].info.get("adaptation", {}) if frames else {}
        return {
            "config": str(job.config_path), "png": str(self.png), "xyz": [str(p) for p in self.xyz_files],
            "size": list(job.size), "booth": job.ir.booth_name, "lighting": job.graph["lighting"],
            "sample": job.sample.name, "display": job.display.name, "diffuse": job.diffuse,
            "bake": job.bake_note or None,
            "adaptation": {"method": job.adaptation, "description": ADAPTATION_DESCRIPTIONS[job.adaptation],
                           "lighting_white_xy": ad.get("white_xy"), "display_white_xy": ad.get("display_white_xy")},
            "gl_renderer": self.gl_renderer, "elapsed_s": round(self.elapsed_s, 3), "notes": job.notes,
            # where the time goes: loading/compiling the booth, the forward model at the vertices
            # (per view), and the frame (uploads, first-use shader compilation, passes, read-back)
            "timing_s": self.timing_s,
            "contact_sheet": ({"views": len(frames), "columns": min(3, len(frames)), "tile_px": list(job.size)}
                              if self.contact_sheet else None),
            "colour_module": colour_module_features(),
            "views": [{"view": f.view, "realised": f.info.get("realised"),
                       "platform_rotation_deg": f.info.get("platform_rotation_deg"),
                       "sample_illuminance_lx": round(f.info.get("sample_illuminance_lx", 0.0), 3),
                       "out_of_gamut": f.out_of_gamut} for f in frames],
        }


def render_job(job: RenderJob, *, contact: bool = False, egl_device: int | None = None,
               progress=None, prepared_s: float = 0.0) -> RenderResult:
    """Render every view of ``job`` and write its PNG (and XYZ files).

    ``contact``: one labelled contact sheet of all views (else the first view's frame).
    ``progress(description, advance)`` is called before each step (``advance`` after a view).

    Raises
    ------
    LbsceneUserError
        ``LB600`` without an OpenGL context, ``LB500`` for a size over the GL limit.
    """
    import time

    from lbscene.engine.colour.adaptation import ADAPTATION_DESCRIPTIONS
    from lbscene.engine.files.diagnostics import LbsceneUserError

    from .executor import GLUnavailableError

    say = progress or (lambda description, advance=False: None)
    t_start = time.perf_counter()
    scene_s: dict[str, float] = {}
    frame_s: dict[str, float] = {}
    frames: list[Frame] = []
    say("render: GL context")
    try:
        renderer = job.renderer(device_index=egl_device)
    except GLUnavailableError as exc:
        raise LbsceneUserError.single(
            "LB600", str(exc), expected="an OpenGL 3.3 context through EGL",
            hint="install Mesa's EGL (libegl1, libgl1-mesa-dri) or pick a device with --egl-device")
    try:
        for v in job.views:
            say(f"render: {v}: light at the vertices (forward model)")
            t0 = time.perf_counter()
            renderer.scene.view(v)
            scene_s[v] = time.perf_counter() - t0
            say(f"render: {v}: {job.size[0]}x{job.size[1]}")
            t0 = time.perf_counter()
            try:
                frames.append(renderer.render(v, job.size, want_xyz=job.xyz is not None, want_gamut=True))
            except ValueError as exc:   # a viewport over the GL limit
                raise LbsceneUserError.single(
                    "LB500", f"--size: {exc}", value=f"{job.size[0]}x{job.size[1]}",
                    expected="a size this OpenGL implementation can render") from None
            frame_s[v] = time.perf_counter() - t0
            say(f"render: {v}: done", True)
        gl_name = renderer.gl_renderer
    finally:
        renderer.close()
    meta = {"lbscene:booth": job.ir.booth_name, "lbscene:ir_hash": job.ir.content_hash[:16],
            "lbscene:lighting": job.graph["lighting"], "lbscene:sample": job.sample.name,
            "lbscene:display": job.display.name, "lbscene:views": ",".join(f.view for f in frames),
            "lbscene:adaptation": f"{job.adaptation}: {ADAPTATION_DESCRIPTIONS[job.adaptation]}"}
    # a contact sheet has one labelled tile per view, even for a booth with one geometry
    write_png(job.png, contact_sheet(frames, columns=min(3, len(frames))) if contact else frames[0].rgba8, meta)
    xyz_files = []
    if job.xyz is not None:
        for f in frames:
            p = job.xyz if not contact else xyz_view_path(job.xyz, f.view)
            write_xyz(p, f.xyz)
            xyz_files.append(Path(p))
    timing = {"config_and_booth": round(prepared_s, 3),
              "scene_per_view": {v: round(x, 3) for v, x in scene_s.items()},
              "frame_per_view": {v: round(x, 3) for v, x in frame_s.items()}}
    return RenderResult(job, frames, Path(job.png), xyz_files, contact, gl_name, timing,
                        prepared_s + time.perf_counter() - t_start)


def render_from_config(config: Path | str, *, out: Path | str | None = None, xyz: Path | str | None = None,
                       geometry: str | list[str] | None = None, all_geometries: bool = False,
                       size: tuple[int, int] | None = None, diffuse: str | None = None,
                       adaptation: str | None = None, allowed_dirs=(), egl_device: int | None = None,
                       progress=None, lighting: str | None = None) -> RenderResult:
    """Render a configuration (``kind: render_config``) to its PNG: the whole ``lbscene render``.

    Parameters override the configuration as the command's options do (``out`` is ``-o``,
    ``lighting`` is ``--lighting``; ``geometry`` a name, a comma-separated list or a list: several
    views make a contact sheet).

    Examples
    --------
    >>> from lbscene import render_from_config                                   # doctest: +SKIP
    >>> r = render_from_config("examples/render/splqc-d65-moderate-red.yaml",    # doctest: +SKIP
    ...                        out="red.png", size=(320, 240))
    >>> r.png, r.frames[0].info["sample_illuminance_lx"]                        # doctest: +SKIP
    """
    import time

    t0 = time.perf_counter()
    job = prepare_from_config(Path(config), geometry=geometry, all_geometries=all_geometries, size=size,
                              png=Path(out) if out is not None else None,
                              xyz=Path(xyz) if xyz is not None else None, diffuse=diffuse,
                              allowed_dirs=tuple(allowed_dirs), adaptation=adaptation, lighting=lighting)
    return render_job(job, contact=job.contact, egl_device=egl_device, progress=progress,
                      prepared_s=time.perf_counter() - t0)
