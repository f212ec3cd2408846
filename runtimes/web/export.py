"""
Export a booth's render graphs and their render-time inputs as a static WebGL2 viewer.

The viewer runs the **same render graph** (``runtimes/graph.py``, one per lighting)
with the **same GLSL ES 3.00 files** (``runtimes/shaders``, embedded verbatim and
composed in the browser by the same rule as :func:`~lbscene.runtimes.graph.compose_shader`)
as the moderngl executor.  What the moderngl runtime computes in Python per view
(:class:`~lbscene.runtimes.scene.SceneBuilder`: meshes with per-vertex band irradiance
from the forward model, the emitters and sample textures, the values the bindings name)
is computed here, at export time, for every lighting × view × sample × display, and
stored as little-endian binary blobs.  Only the camera (``view.view_proj``,
``view.eye_mm``) and the sample's tilt (``sample.model``) are computed per frame in the
browser.

Folder layout (everything self-contained; nothing is fetched, so ``index.html`` also
works from ``file://``)::

    index.html              the viewer page (controls, canvas, frame time, test mode)
    viewer.css
    lbscene-executor.js     the WebGL2 render-graph executor (generic: knows no booth)
    viewer.js               UI, camera, test mode, results export
    lbscene-data.js         ``window.LBSCENE_DATA = {...}``: manifest + base64 blobs
    model-delta-e00.csv     with a session: the model's ΔE00 per case
                            (:mod:`lbscene.engine.visual.model`), for ``visual-report --model-de``
    manifest.json           what export-web wrote: format, lbscene version, files and their sha256
                            (an earlier export is replaced only while every file in it is one of
                            these, unchanged: :mod:`lbscene.engine.files.outputs`)
    model-texture.csv       with a session and effect coatings with flakes: the model's texture
                            metrics per case (:mod:`lbscene.engine.coatings.visual`)

Blobs are content-addressed (sha256), so data shared by views, samples or displays
(booth meshes under fixed lamps, the LTC tables) are stored once.

Examples
--------
>>> from lbscene.runtimes.web.export import BlobStore
>>> import numpy as np
>>> s = BlobStore(); ref = s.add(np.ones((2, 3), np.float32))
>>> ref["dtype"], ref["shape"], len(s.blobs)
('float32', [2, 3], 1)
>>> s.add(np.ones((2, 3), np.float32)) == ref     # same content, same blob
True
"""

from __future__ import annotations

import base64
import hashlib
import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = [
    "EXPORT_FORMAT",
    "EXPORT_VERSION",
    "ASSET_DIR",
    "ASSET_FILES",
    "DATA_FILE",
    "BlobStore",
    "WebExportInputs",
    "build_export",
    "write_export",
    "is_web_export",
    "model_delta_e_csv",
    "MODEL_DE_FILE",
    "MODEL_TEXTURE_FILE",
    "model_texture_csv",
]

EXPORT_FORMAT = "lbscene.web_export"
EXPORT_VERSION = 1
ASSET_DIR = Path(__file__).resolve().parent / "assets"
ASSET_FILES = ("index.html", "viewer.css", "lbscene-executor.js", "viewer.js")
DATA_FILE = "lbscene-data.js"
#: Written with a session: the model's ΔE00 per case, for ``visual-report --model-de``.
MODEL_DE_FILE = "model-delta-e00.csv"
MODEL_TEXTURE_FILE = "model-texture.csv"
DATA_GLOBAL = "LBSCENE_DATA"


class BlobStore:
    """Content-addressed little-endian arrays: ``add`` returns a reference
    ``{"blob": id, "dtype": "float32"|"uint32", "shape": [...]}``."""

    def __init__(self) -> None:
        self.blobs: dict[str, bytes] = {}

    def add(self, array, dtype=np.float32) -> dict:
        a = np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
        raw = a.tobytes()
        key = hashlib.sha256(raw + str(a.dtype.name).encode()).hexdigest()[:20]
        self.blobs.setdefault(key, raw)
        return {"blob": key, "dtype": np.dtype(dtype).name, "shape": list(a.shape)}

    @property
    def nbytes(self) -> int:
        return sum(len(b) for b in self.blobs.values())

    def to_json(self) -> dict[str, str]:
        return {k: base64.b64encode(v).decode("ascii") for k, v in sorted(self.blobs.items())}


def _plain(v):
    """A binding value as JSON (arrays → flat lists, numpy scalars → Python)."""
    if isinstance(v, np.ndarray):
        return [float(x) for x in v.ravel()] if not np.issubdtype(v.dtype, np.integer) else \
            [int(x) for x in v.ravel()]
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    return v


@dataclass
class WebExportInputs:
    """What to export.

    ``lightings``: name → ``(diffuse, bake)`` (``'analytic'`` with ``None``, or ``'baked'``
    with :class:`~lbscene.runtimes.bake.BakeProducts`).  ``samples``: list of
    :class:`~lbscene.engine.scene.sample.SampleSpec`; ``displays``: list of
    :class:`~lbscene.runtimes.colour_bridge.DisplayUniforms`.
    """

    ir: Any
    lightings: dict[str, tuple[str, Any]]
    samples: list
    displays: list
    size_px: tuple[int, int] = (1024, 768)
    exposure: str = "relative_white"
    white_fraction: float = 1.0
    dither: bool = True
    camera: Any = None
    initial: dict = field(default_factory=dict)
    session: dict | None = None
    source: str = ""


def _display_path(display) -> Path | None:
    """The display document of a :class:`~lbscene.runtimes.colour_bridge.DisplayUniforms`
    (None for the built-in sRGB display)."""
    prefix = "colour module: "
    return Path(display.source[len(prefix):]) if display.source.startswith(prefix) else None


def _model_case(lighting, view_spec, sample, display, vi, white_fraction) -> dict:
    """The model's ΔE00 of a case (:mod:`lbscene.engine.visual.model`) on one display."""
    from lbscene.engine.visual.model import case_delta_e00, reflectance_at

    asp = float(view_spec["realised"]["aspecular_deg"])
    de = case_delta_e00(vi.sample_irradiance_1nm, reflectance_at(sample, asp), display,
                        display_path=_display_path(display), white_fraction=white_fraction)
    return {"lighting": lighting, "geometry": view_spec["name"], "sample": sample.name,
            "display": display.name, "aspecular_deg": asp, "delta_e00": round(de, 4)}


def _model_texture(lighting, view_spec, sample, builder, vi, camera) -> dict | None:
    """The model's texture metrics of a case (:mod:`lbscene.engine.coatings.visual`), for a sample
    with flakes (None otherwise)."""
    app = builder.coating_appearance()
    if app is None or app.flakes is None:
        return None
    from lbscene.engine.coatings.visual import case_texture_metrics

    v = vi.values
    eye = np.asarray(camera.position_mm or view_spec["camera"]["position_mm"], float)
    m = case_texture_metrics(app, vi.textures["emitters"], int(v["view.emitter_count"]), vi.sample_centre_mm,
                             vi.sample_normal, eye, v["sample.u_axis"],
                             np.asarray(v["view.xyz_weights"], float).reshape(16, 3),
                             float(v["sample.flake_cell_mm"]), float(v["sample.grain_sigma"]),
                             float(vi.info["coating"]["visible_share"]))
    return dict({"lighting": lighting, "geometry": view_spec["name"], "sample": sample.name}, **m)


def model_texture_csv(manifest: dict) -> str:
    """``lighting,geometry,sample`` and the texture metrics (``visual-report --model-texture``)."""
    import csv
    import io

    from lbscene.engine.coatings.visual import TEXTURE_COLUMNS

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["lighting", "geometry", "sample", *TEXTURE_COLUMNS])
    for r in manifest.get("model_texture", []):
        w.writerow([r["lighting"], r["geometry"], r["sample"], *(r[c] for c in TEXTURE_COLUMNS)])
    return buf.getvalue()


def model_delta_e_csv(manifest: dict) -> str:
    """``lighting,geometry,sample,delta_e00,display,aspecular_deg`` for ``visual-report
    --model-de``: the cases on the export's first display (the configuration's)."""
    import csv
    import io

    first = manifest["displays"][0]["name"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["lighting", "geometry", "sample", "delta_e00", "display", "aspecular_deg"])
    for r in manifest.get("model_delta_e00", []):
        if r["display"] == first:
            w.writerow([r["lighting"], r["geometry"], r["sample"], r["delta_e00"], r["display"], r["aspecular_deg"]])
    return buf.getvalue()


def _mesh_refs(store: BlobStore, meshes: dict) -> dict:
    out = {}
    for name, (v, idx) in meshes.items():
        out[name] = {"vertices": store.add(v, np.float32), "indices": store.add(idx, np.uint32),
                     "count": int(len(idx))}
    return out


def build_export(inp: WebExportInputs, progress: Callable[[str], None] | None = None) -> dict:
    """The viewer's data: a JSON-ready manifest with ``blobs`` (base64).

    For every lighting, view, sample and display the same
    :class:`~lbscene.runtimes.scene.SceneBuilder` calls as ``lbscene render`` make.
    """
    from lbscene.runtimes.graph import build_render_graph, shader_sources
    from lbscene.runtimes.scene import CameraSpec, SceneBuilder

    ir = inp.ir
    store = BlobStore()
    camera = inp.camera or CameraSpec()
    lightings = []
    model_de: list[dict] = []
    model_tex: list[dict] = []
    static_refs: dict[str, dict] = {}
    for lname, (diffuse, bake) in inp.lightings.items():
        graph = build_render_graph(ir, lname)
        memo: dict = {}
        builders = [[SceneBuilder(ir, graph, s, d, bake=bake, diffuse=diffuse, exposure=inp.exposure,
                                  white_fraction=inp.white_fraction, dither=inp.dither, camera=camera,
                                  irradiance_memo=memo)
                     for d in inp.displays] for s in inp.samples]
        b0 = builders[0][0]
        st = b0.static_textures()
        for name in ("ltc_minv", "ltc_mag", "blue_noise"):
            static_refs.setdefault(name, store.add(st[name]))
        views = []
        for vname in b0.view_names:
            if progress:
                progress(f"{lname} / {vname}")
            per_sample = []
            vs = next(v for v in graph["views"] if v["name"] == vname)
            cam = None
            for si, row in enumerate(builders):
                vi0 = row[0].view(vname)
                entry = {"meshes": _mesh_refs(store, vi0.meshes),
                         "textures": {k: store.add(a) for k, a in vi0.textures.items()},
                         "displays": []}
                for di, b in enumerate(row):
                    vi = b.view(vname)
                    vals = {k: _plain(v) for k, v in vi.values.items() if v is not None}
                    if inp.session is not None:
                        model_de.append(_model_case(lname, vs, inp.samples[si], inp.displays[di], vi,
                                                    inp.white_fraction))
                        if di == 0:
                            tex = _model_texture(lname, vs, inp.samples[si], b, vi, camera)
                            if tex is not None:
                                model_tex.append(tex)
                    entry["displays"].append({"values": vals,
                                              "exposure": float(vi.info["exposure"]),
                                              "sample_illuminance_lx": float(vi.info["sample_illuminance_lx"])})
                per_sample.append(entry)
                if cam is None:
                    # the camera rule of SceneBuilder.camera_values, as data for the browser
                    eye = np.asarray(camera.position_mm or vs["camera"]["position_mm"], float)
                    target = np.asarray(camera.look_at_mm if camera.look_at_mm is not None
                                        else vi0.sample_centre_mm, float)
                    dist = float(np.linalg.norm(target - eye))
                    cam = {"eye_mm": eye.tolist(), "target_mm": target.tolist(), "up": [0.0, 0.0, 1.0],
                           "vertical_fov_deg": float(camera.vertical_fov_deg),
                           "near_mm": max(1.0, min(10.0, 0.05 * dist)),
                           "far_mm": dist + 4.0 * row[0].extent_mm,
                           "sample_centre_mm": [float(x) for x in vi0.sample_centre_mm],
                           "sample_normal": [float(x) for x in vi0.sample_normal]}
            views.append({"name": vname, "geometry": vs["geometry"], "realised": vs["realised"],
                          "platform_rotation_deg": vs["platform_rotation_deg"], "camera": cam,
                          "samples": per_sample})
        lightings.append({"name": lname, "diffuse": diffuse, "graph": graph,
                          "textures": {"materials": store.add(st["materials"])}, "views": views})
    displays = [{"name": d.name, "source": d.source, "white_Y_cd_m2": float(d.white_Y_cd_m2),
                 "textures": {"tone_lut": store.add(d.lut_texture())}} for d in inp.displays]
    samples = [{"name": s.name, "gloss_GU": float(s.gloss_GU), "roughness": float(s.roughness),
                "size_mm": [float(x) for x in s.size_mm],
                "geometries": [label for _, label, _ in s.geometries]} for s in inp.samples]
    manifest = {
        "format": EXPORT_FORMAT, "version": EXPORT_VERSION,
        "booth": ir.booth_name, "ir_hash": ir.content_hash, "source": inp.source,
        "size_px": list(inp.size_px),
        "exposure": {"mode": inp.exposure, "white_fraction": inp.white_fraction},
        "initial": dict(inp.initial),
        "shaders": shader_sources(),
        "static_textures": static_refs,
        "lightings": lightings, "samples": samples, "displays": displays,
        "session": inp.session,
    }
    manifest["model_delta_e00"] = model_de
    manifest["model_texture"] = model_tex
    manifest["blob_bytes"] = store.nbytes
    manifest["blobs"] = store.to_json()
    return manifest


def is_web_export(folder: Path) -> bool:
    """Whether ``folder`` holds a web export: its ``manifest.json`` is one export-web wrote (a
    regular file of the current user, format ``lbscene.web_export``).  Whether it may be replaced
    is then :func:`lbscene.engine.files.outputs.verify_tree`'s question (every file listed, unchanged)."""
    from lbscene.engine.files.outputs import read_manifest

    got = read_manifest(Path(folder))
    return got is not None and got[0].get("format") == EXPORT_FORMAT


def write_export(manifest: dict, out_dir: Path, *, option: str | None = "--out") -> list[Path]:
    """Write the viewer folder atomically: assembled in a private sibling (files created
    exclusively and written through their descriptors), its ``manifest.json`` last, then swapped
    in by :func:`lbscene.engine.files.outputs.replace_dir` (which replaces an earlier export only while
    every file in it is one export-web wrote, unchanged).

    Raises
    ------
    LbsceneUserError
        ``LB611`` for an ``out_dir`` holding files export-web did not write (or changed since),
        ``LB610`` on a full disk (nothing changed, temporaries removed).
    """
    from lbscene._version import __version__
    from lbscene.engine.files.outputs import (NO_SPACE_ERRNOS, no_space_error, replace_dir, temporary_dir_for,
                                        write_new_file)

    out_dir = Path(out_dir)
    tmp = temporary_dir_for(out_dir, option=option)
    try:
        files = {}
        for name in ASSET_FILES:
            files[name] = write_new_file(tmp / name, (ASSET_DIR / name).read_bytes())
        text = json.dumps(manifest, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
        if manifest.get("model_delta_e00"):
            files[MODEL_DE_FILE] = write_new_file(tmp / MODEL_DE_FILE, model_delta_e_csv(manifest))
        if manifest.get("model_texture"):
            files[MODEL_TEXTURE_FILE] = write_new_file(tmp / MODEL_TEXTURE_FILE, model_texture_csv(manifest))
        files[DATA_FILE] = write_new_file(
            tmp / DATA_FILE, f"// lbscene web export: render graphs, shaders and data (generated; see index.html)\n"
                             f"window.{DATA_GLOBAL} = {text};\n")
        del text
        write_new_file(tmp / "manifest.json", json.dumps(
            {"format": EXPORT_FORMAT, "version": EXPORT_VERSION, "lbscene_version": __version__,
             "booth": manifest.get("booth"), "files": dict(sorted(files.items()))}, indent=1) + "\n")
        replace_dir(tmp, out_dir, option=option)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and exc.errno in NO_SPACE_ERRNOS:
            raise no_space_error(out_dir, option, exc) from None
        raise
    extra = ((MODEL_DE_FILE,) if manifest.get("model_delta_e00") else ()) + (
        (MODEL_TEXTURE_FILE,) if manifest.get("model_texture") else ())
    return [out_dir / n for n in ASSET_FILES + (DATA_FILE,) + extra]
