r"""
The Mitsuba 3 scene of a booth, a lighting and a measurement grid, for independent checks.

``lbscene export-mitsuba`` writes the scene that the Mitsuba truth provider
(:class:`lbscene.engine.truth.mitsuba.MitsubaTruth`) renders — built by the provider's own
:meth:`~lbscene.engine.truth.mitsuba.MitsubaTruth.scene_dict`, never rebuilt here — so a
user can render their own booth in Mitsuba 3 and compare it with lbscene's forward model:

``scene.xml``
    Mitsuba 3 XML (written by Mitsuba's own ``mitsuba.parser.write_string``); the booth's
    surfaces are binary PLY meshes in ``<stem>_meshes/`` beside it, referenced relatively.
    Render it with ``mitsuba.load_file("scene.xml")`` (variant ``scalar_spectral``).
``scene.py``
    A Python module whose ``scene_dict()`` returns the same scene as a dict for
    ``mitsuba.load_dict`` (meshes inline); ``python scene.py`` renders every reading and
    prints it in lux.

What the scene represents
-------------------------
Everything the provider represents (the table in :mod:`lbscene.engine.truth.mitsuba`):
the interior as diffuse meshes (black when ``interreflection`` is off), each lamp of the
lighting as a Lambertian emitting shape (tube: cylinder, panel: rectangle, bulb: sphere,
point: point light) of the lamp's spectral radiance, lamps that are off as black bodies,
occluders and the rough diffuser plate when their effects are on.  Lengths are in
millimetres.  Each reading is a white Lambertian disc of radius
:data:`~lbscene.engine.truth.mitsuba.DISC_RADIUS_MM` at the point, seen by a
``radiancemeter`` (``meter_00000``, …) whose ``specfilm`` has one band, the photopic
:math:`V(λ)`; the illuminance is

.. math:: E_v = 683\,\mathrm{lm/W} \cdot π \cdot \text{(the film's value)}\quad\text{lx}.

The readings are the measurement set's (``--measurements``: its points and orientations,
its lighting), else the seed's 55-point A3 grid (11 × 5 points, 400 × 240 mm) centred
under the sample position at its height.  Readings are ideal cosine receivers: a meter's
``detector_cosine_error`` is not in the scene.

What it refuses
---------------
What the provider refuses (``LB603``, located at the booth file's line): effects with no
Mitsuba representation (``end falloff``, a reflector other than a plane or a prism,
non-isotropic angular profiles, a Lambertian diffuse-fraction plate, …), glossy materials,
occluders that block some lamps only.  Without the ``mitsuba`` package: ``LB604``.

Examples
--------
>>> export_mitsuba("iso3664-p1-d50", "scene.xml", lighting="P1")       # doctest: +SKIP
>>> import mitsuba as mi; mi.set_variant("scalar_spectral")              # doctest: +SKIP
>>> scene = mi.load_file("scene.xml")                                    # doctest: +SKIP
>>> E_lx = 683 * np.pi * np.asarray(mi.render(scene, sensor=0)).ravel()[0]   # doctest: +SKIP
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError, SourceLocation

__all__ = ["MitsubaExport", "export_mitsuba", "check_export_target", "LX_PER_READING", "ply_bytes"]

#: the illuminance (lx) of a film value of 1: 683 lm/W · π
LX_PER_READING = 683.0 * np.pi
FORMATS = {".xml": "xml", ".py": "python"}


@dataclass
class MitsubaExport:
    """What :func:`export_mitsuba` wrote."""

    booth: str
    lighting: str
    out: Path
    format: str
    files: list[Path]
    points_mm: np.ndarray
    normals: np.ndarray
    effects: list[str]
    spp: int
    receivers_from: str
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        from lbscene.engine.truth.mitsuba import mitsuba_version

        return {"booth": self.booth, "lighting": self.lighting, "out": str(self.out), "format": self.format,
                "files": [str(f) for f in self.files], "readings": int(len(self.points_mm)),
                "receivers_from": self.receivers_from, "effects": self.effects, "spp": self.spp,
                "lx_per_reading": LX_PER_READING, "mitsuba_version": mitsuba_version(),
                "variant": "scalar_spectral", "notes": list(self.notes)}


def ply_bytes(vertices, triangles) -> bytes:
    """A binary little-endian PLY of a triangle mesh (float32 x, y, z; uint8 count + uint32 indices)."""
    v = np.ascontiguousarray(vertices, "<f4")
    t = np.ascontiguousarray(triangles, "<u4")
    head = (f"ply\nformat binary_little_endian 1.0\ncomment lbscene export-mitsuba (millimetres)\n"
            f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
            f"element face {len(t)}\nproperty list uchar uint vertex_indices\nend_header\n").encode("ascii")
    faces = b"".join(struct.pack("<B3I", 3, *map(int, tri)) for tri in t)
    return head + v.tobytes() + faces


def _mitsuba_or_refuse():
    try:
        import mitsuba  # noqa: F401
    except ImportError:
        raise LbsceneUserError(Diagnostic(
            "LB604", "export-mitsuba needs the mitsuba package, which is not installed",
            SourceLocation("<environment>"), expected="mitsuba >= 3.9",
            hint="pip install -c constraints.txt 'lbscene[truth]'")) from None


_REFUSAL_PATHS = (
    (re.compile(r"^effect '([^']+)'"), lambda m, doc: ("effects", m.group(1))),
    (re.compile(r"^angular_profile parameters"), lambda m, doc: ("effects", "angular_profile")),
    (re.compile(r"^aperture_occlusion "), lambda m, doc: ("effects", "aperture_occlusion")),
    (re.compile(r"^lamp '([^']+)'"), lambda m, doc: ("lamps", _index(doc.model.lamps, m.group(1)))),
    (re.compile(r"^surface '[^']+': material '([^']+)'"), lambda m, doc: ("materials", m.group(1))),
    (re.compile(r"^occluder '([^']+)'"), lambda m, doc: ("occluders", _index(doc.model.occluders, m.group(1)))),
    (re.compile(r"^diffuser"), lambda m, doc: ("diffuser",)),
)


def _index(items, ident) -> int:
    return next((i for i, x in enumerate(items) if x.id == ident), 0)


def _located_refusals(exc: LbsceneUserError, doc) -> LbsceneUserError:
    """The provider's LB603 refusals, one located diagnostic each (at the booth file's line)."""
    prefix = "the Mitsuba truth cannot represent this booth: "
    out = []
    for d in exc.diagnostics:
        if d.code != "LB603" or not d.message.startswith(prefix):
            out.append(d)
            continue
        for part in d.message[len(prefix):].split("; "):
            # the provider's Python-level escape hatch is no option of the command
            part = part.replace(" (pass allow_lamp_specific_occluders=True to accept that)", "")
            path = None
            for rx, where in _REFUSAL_PATHS:
                m = rx.match(part)
                if m:
                    path = where(m, doc)
                    break
            loc = doc.locate(*path, key=path[0] == "effects") if path else SourceLocation(doc.file)
            out.append(Diagnostic("LB603", f"export-mitsuba: Mitsuba cannot represent this: {part}", loc,
                                  expected="a booth the Mitsuba truth provider represents",
                                  hint="switch the effect off (effects:) or export a booth without it"))
    return LbsceneUserError(out)


def check_export_target(out: Path | str) -> str:
    """The format of ``out`` by its suffix (``.xml`` or ``.py``), else ``LB500``."""
    fmt = FORMATS.get(Path(out).suffix.lower())
    if fmt is None:
        raise LbsceneUserError(Diagnostic("LB500", "--out must name a .xml or .py file", SourceLocation(str(out)),
                                          value=str(out), expected="scene.xml (Mitsuba XML) or scene.py "
                                                                  "(a Python dict module)"))
    return fmt


def _mesh_dir(out: Path) -> Path:
    return out.with_name(out.stem + "_meshes")


def _python_value(v, indent: int = 1) -> str:
    import mitsuba as mi

    pad = "    " * indent
    if isinstance(v, dict):
        if not v:
            return "{}"
        inner = ",\n".join(f"{pad}    {k!r}: {_python_value(x, indent + 1)}" for k, x in v.items())
        return "{\n" + inner + f",\n{pad}}}"
    if isinstance(v, (mi.ScalarTransform4f, getattr(mi, "AffineTransform4f", mi.ScalarTransform4f))):
        m = np.array(v.matrix, float).tolist()
        return f"mi.ScalarTransform4f({m!r})"
    if isinstance(v, np.ndarray):
        return repr(v.tolist())
    if isinstance(v, (np.floating, np.integer)):
        return repr(v.item())
    if isinstance(v, (list, tuple)):
        return repr([x.item() if isinstance(x, (np.floating, np.integer)) else x for x in v])
    return repr(v)


_PY_HEAD = '''"""Mitsuba 3 scene of {booth}, lighting {lighting!r} ({n} readings), written by `lbscene export-mitsuba`.

The scene lbscene's Mitsuba truth provider renders (engine/truth/mitsuba.py): lengths in mm,
spectra on 360-830 nm.  `scene_dict()` returns it for `mitsuba.load_dict` (variant
scalar_spectral); sensor `meter_NNNNN` measures reading NNNNN at RECEIVERS_MM[NNNNN] facing
NORMALS[NNNNN]: its film value times LX_PER_READING (683 lm/W * pi) is the illuminance in lux.
`python {name}` renders every reading and prints it.
"""

import numpy as np
import mitsuba as mi

VARIANT = "scalar_spectral"
LX_PER_READING = 683.0 * np.pi
SPP = {spp}
EFFECTS = {effects!r}
RECEIVERS_MM = {points!r}
NORMALS = {normals!r}


def _mesh(name, vertices_mm, triangles, bsdf):
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(name, len(vertices_mm), len(triangles), props=props)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(np.asarray(vertices_mm, np.float32).ravel())
    params["faces"] = type(params["faces"])(np.asarray(triangles, np.uint32).ravel())
    params.update()
    return mesh


def scene_dict():
    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    scene = {scene}
{meshes}
    return scene


def render(spp=SPP, seed=0):
    """Illuminance (lx) of every reading."""
    scene = mi.load_dict(scene_dict())
    return [LX_PER_READING * float(np.asarray(mi.render(scene, sensor=i, spp=spp, seed=seed + i)).ravel()[0])
            for i in range(len(scene.sensors()))]


if __name__ == "__main__":
    for p, e in zip(RECEIVERS_MM, render()):
        print(f"{{p[0]:g}},{{p[1]:g}},{{p[2]:g}},{{e:.6g}}")
'''


def export_mitsuba(booth: Path | str, out: Path | str, *, lighting: str | None = None,
                   measurements: Path | str | None = None, spp: int = 16384,
                   allowed_dirs: Iterable[Path] = ()) -> MitsubaExport:
    """Write the Mitsuba 3 scene of a booth, a lighting and its readings (see the module docstring).

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    out : path or str
        ``….xml`` (Mitsuba XML, meshes as PLY beside it) or ``….py`` (a Python dict module).
    lighting : str, optional
        Lighting configuration (default: the measurement set's, else the booth's first).
    measurements : path or str, optional
        A measurement set of the booth: its readings become the scene's sensors.
    spp : int
        Samples per reading written into the scene (the provider's default, 16384).
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    MitsubaExport

    Raises
    ------
    LbsceneUserError
        ``LB603`` (located) for what Mitsuba cannot represent, ``LB604`` without mitsuba,
        ``LB202`` an unknown lighting, ``LB500`` a bad ``out`` suffix or lighting clash,
        ``LB610``–``LB612`` an output the policy refuses.
    """
    from lbscene.schemas.booth import Booth

    from lbscene.engine.scene.compile import compile_loaded, find_booth_file
    from lbscene.engine.files.diagnostics import Severity
    from lbscene.engine.truth.synthetic import a3_grid
    from lbscene.engine.scene.lint import lint_booth
    from lbscene.engine.files.load import display_path, load_document
    from lbscene.engine.files.outputs import check_output_file, register_input, write_output
    from lbscene.engine.truth.mitsuba import MAX_SPP_PER_CALL, MitsubaTruth

    if not isinstance(spp, (int, np.integer)) or isinstance(spp, bool):
        raise TypeError(f"spp must be an int, got {spp!r}")
    if not 1 <= int(spp) <= MAX_SPP_PER_CALL:
        raise LbsceneUserError(Diagnostic("LB500", f"--spp must be 1..{MAX_SPP_PER_CALL}", SourceLocation("<arguments>"),
                                          value=str(spp), expected=f"1..{MAX_SPP_PER_CALL} (float32 film)"))
    out = Path(out)
    fmt = check_export_target(out)
    booth_file = find_booth_file(Path(booth))
    register_input(booth_file)
    if measurements is not None:
        register_input(measurements)
    check_output_file(out, option="--out")
    _mitsuba_or_refuse()
    doc = load_document(booth_file, Booth, allowed_dirs=allowed_dirs)
    errors = [d for d in lint_booth(doc) if d.severity is Severity.ERROR]
    if errors:
        raise LbsceneUserError(errors)
    ir = compile_loaded(doc)
    notes: list[str] = []
    if measurements is not None:
        from lbscene.engine.loop.measurements import load_measurements

        meas = load_measurements(Path(measurements), booth=booth_file, allowed_dirs=allowed_dirs)
        if lighting is not None and lighting != meas.lighting:
            raise LbsceneUserError(Diagnostic(
                "LB500", f"--lighting {lighting!r} differs from the measurement set's lighting {meas.lighting!r}",
                SourceLocation(display_path(meas.path)), value=repr(lighting), expected=repr(meas.lighting)))
        lighting = meas.lighting
        if meas.illuminance is None or not len(meas.illuminance):
            raise LbsceneUserError(Diagnostic("LB500", "the measurement set has no illuminance readings",
                                              SourceLocation(display_path(meas.path)),
                                              expected="illuminance: files whose points become the sensors"))
        P, N = meas.illuminance.points_mm.copy(), meas.illuminance.normals.copy()
        source = f"measurement set {display_path(meas.path)}"
    else:
        s = np.asarray(ir.sample_position_mm, float)
        P = a3_grid(centre_mm=(s[0], s[1]), z_mm=s[2])
        N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
        source = "the 55-point A3 grid at the sample"
    name = lighting or next(iter(ir.lighting))
    if name not in ir.lighting:
        raise LbsceneUserError(Diagnostic(
            "LB202", f"--lighting: booth {ir.booth_name!r} has no lighting configuration {name!r}",
            SourceLocation(display_path(booth_file)), value=repr(name), expected=f"one of {', '.join(ir.lighting)}"))
    try:
        truth = MitsubaTruth(ir, name, spp=int(spp), passes=2)
    except LbsceneUserError as exc:
        raise _located_refusals(exc, doc) from None
    meshes = truth.surface_meshes()
    ply_paths = {}
    if fmt == "xml":
        mdir = _mesh_dir(out)
        for k in meshes:
            ply_paths[k] = check_output_file(mdir / f"{k}.ply", option="--out (meshes)")
    scene = truth.scene_dict(P, N)
    if len({(tuple(np.round(n, 9)), round(float(p @ n), 6)) for p, n in zip(P, N)}) > 1:
        notes.append("the readings lie in several planes: their measuring discs (radius 0.05 mm) share one "
                     "scene here, where the provider renders each plane on its own")
    files: list[Path] = []
    if fmt == "xml":
        import mitsuba.parser as mp

        for k, (v, t, bsdf) in meshes.items():
            scene[k] = {"type": "ply", "filename": f"{_mesh_dir(out).name}/{k}.ply", "face_normals": True,
                        "bsdf": bsdf}
        state = mp.parse_dict(mp.ParserConfig("scalar_spectral"), scene)
        text = mp.write_string(state)
        head = (f"<!-- Mitsuba 3 scene of {_xml_comment(ir.booth_name)}, lighting {_xml_comment(name)}, "
                f"written by lbscene export-mitsuba. Lengths in mm. Sensor meter_NNNNN is reading NNNNN "
                f"({source}); its film value x 683 x pi is the illuminance in lx. Variant: scalar_spectral. -->\n")
        for k, (v, t, _) in meshes.items():
            write_output(ply_paths[k], ply_bytes(v, t), option="--out (meshes)")
            files.append(ply_paths[k])
        write_output(out, head + text, option="--out")
    else:
        mesh_lines = []
        for k, (v, t, bsdf) in meshes.items():
            scene.pop(k)
            mesh_lines.append(f"    scene[{k!r}] = _mesh({k!r}, {np.asarray(v, float).tolist()!r}, "
                              f"{np.asarray(t, int).tolist()!r}, {_python_value(bsdf, 1)})")
        body = _PY_HEAD.format(booth=ir.booth_name.replace('"""', "'''"), lighting=name, n=len(P),
                               name=out.name, spp=int(spp), effects=sorted(truth.effects),
                               points=P.tolist(), normals=N.tolist(), scene=_python_value(scene, 1),
                               meshes="\n".join(mesh_lines))
        write_output(out, body, option="--out")
    files.append(out)
    return MitsubaExport(ir.booth_name, name, out, fmt, files, P, N, sorted(truth.effects), int(spp), source, notes)


def _xml_comment(text: str) -> str:
    return str(text).replace("--", "- -").replace("<", "(").replace(">", ")")
