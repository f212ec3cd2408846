"""
Compile a booth document into the :class:`~lbscene.engine.ir.SceneIR`.

parse (yamlio) → validate (schemas, effect params via the registry) →
semantic rules (:mod:`lbscene.engine.lint`) → instantiate (this module): read
every referenced file, evaluate spectra to numbers, triangulate geometry, turn
lamp output specs into absolute spectral intensity.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Iterable

import numpy as np
from pydantic import ValidationError

from lbscene.schemas.booth import Booth, parse_geometry_name

from .diagnostics import Diagnostic, DiagnosticBag, LbsceneUserError
from .ir import (IR_VERSION, IRDiffuser, IRFilter, IRGeometry, IRInterior, IRLamp, IRLighting,
                 IRMaterial, IRObserver, IROccluder, IRPlatform, IRReflector, IRSpectrum,
                 IRSurface, SceneIR)
from .load import LoadedDocument, display_path, load_document, pydantic_to_diagnostics
from .spectral import DEFAULT_GRID, BandGrid

__all__ = ["BOOTH_FILENAME", "find_booth_file", "load_booth", "validate_effects",
           "compile_booth", "compile_loaded"]

BOOTH_FILENAME = "booth.yaml"


def find_booth_file(path: Path | str) -> Path:
    """A booth folder or file → its ``booth.yaml``."""
    from .yamlio import path_kind

    p = Path(path)
    kind = path_kind(p)
    if kind == "dir":
        f = p / BOOTH_FILENAME
        if path_kind(f, display_path(f)) != "file":
            raise LbsceneUserError.single("LB011", f"no {BOOTH_FILENAME} in this folder",
                                          display_path(p), expected=f"a folder with {BOOTH_FILENAME}")
        return f
    if kind == "missing":
        from .shipped import shipped_booth, shipped_booths

        # a bare name that is not a path here: one of the booths shipped with lbscene
        if len(p.parts) == 1 and (shipped := shipped_booth(p.name)) is not None:
            return shipped
        raise LbsceneUserError.single(
            "LB010", "file not found", str(p),
            expected=("a booth folder, a booth.yaml, or a shipped booth: "
                      + ", ".join(shipped_booths())) if len(p.parts) == 1 else None)
    return p


def validate_effects(doc: LoadedDocument) -> tuple[dict[str, dict], list[Diagnostic]]:
    """Validate ``effects:`` against the registry: unknown ids and bad params, located."""
    from .effects.registry import available_effects

    registry = available_effects()
    out: dict[str, dict] = {}
    diags: list[Diagnostic] = []
    for eid, params in doc.model.effects.items():
        if eid not in registry:
            diags.append(Diagnostic(
                "LB106", f"unknown effect id '{eid}'", doc.locate("effects", eid, key=True),
                value=repr(eid), expected=f"one of {', '.join(registry)} (or a plugin's id)"))
            continue
        model = registry[eid].Params
        try:
            out[eid] = model.model_validate(params if params is not None else {}).model_dump(mode="json")
        except ValidationError as exc:
            data = params if params is not None else {}
            diags.extend(pydantic_to_diagnostics(exc, data, doc.yaml.positions,
                                                 prefix=("effects", eid)))
    return out, diags


def load_booth(path: Path | str, allowed_dirs: Iterable[Path] = ()) -> LoadedDocument:
    """Load and validate a booth (schema + effect parameters); raise on errors."""
    f = find_booth_file(path)
    doc = load_document(f, Booth, allowed_dirs=allowed_dirs)
    _, diags = validate_effects(doc)
    if diags:
        raise LbsceneUserError(diags)
    return doc


def compile_booth(path: Path | str, grid: BandGrid = DEFAULT_GRID,
                  allowed_dirs: Iterable[Path] = ()) -> SceneIR:
    """Booth folder or file → SceneIR (raises :class:`LbsceneUserError` on any error)."""
    doc = load_booth(path, allowed_dirs)
    from .lint import lint_booth

    bag = DiagnosticBag()
    bag.extend(lint_booth(doc, illuminance=False))
    bag.raise_if_errors()
    return compile_loaded(doc, grid)


# --------------------------------------------------------------------------- geometry helpers

def _unit(v) -> tuple[float, float, float]:
    a = np.asarray(v, float)
    a = a / np.linalg.norm(a)
    return tuple(float(f"{x:.12g}") for x in a)


def _quad(p0, p1, p2, p3):
    """Two triangles of a quad given counter-clockwise as seen from its front side."""
    return [tuple(map(float, p)) for p in (p0, p1, p2, p3)], [(0, 1, 2), (0, 2, 3)]


def _box_surfaces(booth: Booth) -> list[IRSurface]:
    it = booth.interior
    w, d, h = it.width_mm / 2, it.depth_mm / 2, it.height_mm
    s = booth.surfaces
    # vertices ordered so that the triangle normal (right-hand rule) points into the box
    quads = {
        "floor": ((-w, -d, 0), (w, -d, 0), (w, d, 0), (-w, d, 0)),
        "ceiling": ((-w, -d, h), (-w, d, h), (w, d, h), (w, -d, h)),
        "left_wall": ((-w, -d, 0), (-w, d, 0), (-w, d, h), (-w, -d, h)),
        "right_wall": ((w, -d, 0), (w, -d, h), (w, d, h), (w, d, 0)),
        "rear_wall": ((-w, d, 0), (w, d, 0), (w, d, h), (-w, d, h)),
        "front_wall": ((-w, -d, 0), (-w, -d, h), (w, -d, h), (w, -d, 0)),
    }
    out = []
    for role, q in quads.items():
        if role == "front_wall" and (it.open_front or s.front_wall is None):
            continue
        mat = getattr(s, role)
        verts, tris = _quad(*q)
        out.append(IRSurface(id=role, role=role, material=mat, vertices_mm=tuple(verts),
                             triangles=tuple(tris)))
    return out


def _rotation_matrix_xyz(deg) -> np.ndarray:
    rx, ry, rz = np.radians(deg)
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return mz @ my @ mx


#: Largest mesh file accepted (booth geometry is small; this bounds untrusted input).
MAX_MESH_BYTES = 64 * 1024 * 1024


def _check_mesh_size(path: Path, display: str) -> bytes:
    """A mesh file must be a regular file within the size bound (a bounded read, not ``stat``),
    before a mesh library opens it; returns its bytes."""
    from .yamlio import read_bytes_bounded

    return read_bytes_bounded(path, display, MAX_MESH_BYTES)


class ObjScan:
    """The vertices and polygons of an OBJ file with the line of each, read before any mesh
    library opens the file, so that every problem is located and the work is bounded.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3)
        ``v`` lines, in file units.
    vertex_lines : list of int
        Line of each vertex.
    faces : list of ndarray
        ``f`` lines as 0-based vertex indices (texture and normal indices dropped).
    face_lines : list of int
        Line of each face.
    """

    def __init__(self, vertices, vertex_lines, faces, face_lines):
        self.vertices, self.vertex_lines, self.faces, self.face_lines = vertices, vertex_lines, faces, face_lines


_TOKEN = re.compile(r"\S+")


def _obj_scan(raw: bytes, display: str) -> ObjScan:
    """Read the ``v`` and ``f`` lines of an OBJ file (located errors: ``LB203``, ``LB510``).

    The number of faces is counted on the raw bytes first, so a file of 10⁶ faces is refused
    (``LB510``, :data:`~lbscene.engine.limits.LIMITS` ``mesh_triangles``) before anything is
    parsed; then each polygon counts as the triangles it becomes (n corners: n − 2).
    """
    from .diagnostics import SourceLocation
    from .limits import LIMITS, check_work, limit_value

    def err(message, line=0, col=0, **kw):
        return LbsceneUserError.single("LB203", message, display, line, col, **kw)

    bound = limit_value("mesh_triangles")
    fast_faces = raw.count(b"\nf ") + raw.count(b"\nf\t") + int(raw[:2] in (b"f ", b"f\t"))
    fast_vertices = raw.count(b"\nv ") + raw.count(b"\nv\t") + int(raw[:2] in (b"v ", b"v\t"))
    what = f"faces in {display}"
    check_work("mesh_triangles", fast_faces, SourceLocation(display), what=what)
    if fast_vertices > 3 * bound:
        lim = LIMITS["mesh_triangles"]
        check_work("mesh_triangles", -(-fast_vertices // 3), SourceLocation(display),
                   what=f"vertices in {display} / 3 ({fast_vertices} vertices; {lim.counts})")
    verts, vlines, faces, flines = [], [], [], []
    triangles = 0
    for no, line in enumerate(raw.decode("utf-8", errors="replace").splitlines(), 1):
        s = line.strip()
        if not s or s[0] not in "vf" or (len(s) > 1 and not s[1].isspace()):
            continue                       # comments, vt/vn/vp, o/g/s/usemtl/mtllib, lines …
        toks = [(m.group(0), m.start() + 1) for m in _TOKEN.finditer(line)]   # (token, column)
        parts = [t for t, _ in toks]
        col = toks[0][1]
        if parts[0] == "v":
            if len(parts) < 4:
                raise err("vertex needs three coordinates", no, col, value=repr(s[:80]), expected="v x y z")
            xyz = []
            for tok, c in toks[1:4]:
                try:
                    x = float(tok)
                except ValueError:
                    x = float("nan")
                if not np.isfinite(x):
                    raise err("vertex coordinate is not a finite number", no, c, value=repr(tok[:40]),
                              expected="a finite number")
                xyz.append(x)
            verts.append(xyz)
            vlines.append(no)
        else:
            if len(parts) < 4:
                raise err("face needs at least three corners", no, col, value=repr(s[:80]), expected="f i j k …")
            idx = []
            for tok, c in toks[1:]:
                head = tok.split("/", 1)[0]
                try:
                    i = int(head)
                except ValueError:
                    raise err("face corner is not a vertex index", no, c, value=repr(tok[:40]),
                              expected="a vertex number (1 …, or negative: relative)") from None
                if i < 0:
                    i = len(verts) + i + 1          # relative to the vertices read so far
                idx.append(i - 1)
            triangles += len(idx) - 2
            if triangles > bound:
                check_work("mesh_triangles", triangles, SourceLocation(display, no, col),
                           what=f"triangles in {display} (counted up to this line)")
            faces.append(np.asarray(idx, np.int64))
            flines.append(no)
    n = len(verts)
    for f, no in zip(faces, flines):
        bad = f[(f < 0) | (f >= n)]
        if bad.size:
            raise err(f"face names vertex {int(bad[0]) + 1}, the file has {n}", no, 1,
                      expected=f"vertex numbers 1 … {n}")
    if not faces:
        raise err("OBJ file has no faces", expected="a Wavefront OBJ mesh with faces")
    return ObjScan(np.asarray(verts, float).reshape(-1, 3), vlines, faces, flines)


def _placed(v, transform) -> np.ndarray:
    """File coordinates → booth millimetres (scale, rotate x-y-z, translate); overflow gives inf."""
    with np.errstate(over="ignore", invalid="ignore"):
        return (np.asarray(v, float) * transform.scale) @ _rotation_matrix_xyz(transform.rotate_xyz_deg).T \
            + np.asarray(transform.translate_mm)


def mesh_diagnostics(v_mm: np.ndarray, polys, booth: Booth, *, where_vertex, where_face,
                     mount: str = "booth", what: str = "mesh") -> list[Diagnostic]:
    """What a mesh in booth coordinates must satisfy before it enters the IR.

    * every vertex finite (``LB203``): the transform of a huge coordinate can overflow;
    * every vertex inside the booth's interior (``LB313``, 1 mm tolerance), at every viewing
      geometry for a mesh that turns with the platform;
    * every triangle of each polygon's fan has an area and a finite normal (``LB312``): a
      face whose corners are collinear or coincide has no normal, and one whose edges are
      ~1e154 mm long overflows it — either would turn every later product into NaN.

    Parameters
    ----------
    v_mm : ndarray, shape (n, 3)
        Vertices in booth millimetres.
    polys : list of ndarray
        Polygons as vertex indices (triangles are polygons of three).
    booth : Booth
        The booth (interior, platform, geometries).
    where_vertex, where_face : callable
        Index → :class:`SourceLocation` of a vertex / polygon in its file.
    mount : str
        ``'platform'`` for a mesh that turns with the platform.
    what : str
        How to name the mesh in messages.

    Returns
    -------
    list of Diagnostic
        At most one per kind of problem (the first found, with the count).
    """
    from .lint import _inside

    out: list[Diagnostic] = []
    v = np.asarray(v_mm, float)
    bad = np.nonzero(~np.isfinite(v).all(axis=1))[0]
    if bad.size:
        return [Diagnostic("LB203", f"{what}: vertex is not finite after the transform"
                           + (f" ({bad.size} vertices)" if bad.size > 1 else ""), where_vertex(int(bad[0])),
                           value=str(v[bad[0]].tolist()), expected="finite coordinates (check scale and units)")]
    poses = [("at rest", np.eye(3), np.zeros(3))]
    pf = booth.platform
    if mount == "platform" and pf is not None:
        from .forward_geometry import rotation_matrix

        o = np.asarray(pf.pivot_mm if pf.pivot_mm is not None else pf.centre_mm, float)
        poses += [(f"at geometry {g.name}", rotation_matrix(pf.rotation_axis, g.platform_rotation_deg), o)
                  for g in booth.geometries if g.platform_rotation_deg]
    for label, R, o in poses:
        q = (v - o) @ R.T + o
        outside = [i for i in range(len(q)) if not _inside(q[i], booth)]
        if outside:
            i = outside[0]
            out.append(Diagnostic(
                "LB313", f"{what} reaches outside the booth {label}"
                + (f" ({len(outside)} vertices)" if len(outside) > 1 else ""), where_vertex(i),
                value=f"vertex at {np.round(q[i], 1).tolist()} mm", expected="every vertex inside the interior "
                "(|x| ≤ width/2, |y| ≤ depth/2, 0 ≤ z ≤ height; check scale, rotation and translation)"))
            break
    degenerate, overflow = [], []
    with np.errstate(over="ignore", invalid="ignore"):
        for j, p in enumerate(polys):
            a, b, c = v[p[0]], v[p[1:-1]], v[p[2:]]
            e1, e2 = b - a, c - a
            n = np.cross(e1, e2)
            if not np.isfinite(n).all():
                overflow.append(j)
                continue
            longest = np.max([np.einsum("ij,ij->i", e, e) for e in (e1, e2, c - b)], axis=0)
            if np.any(np.einsum("ij,ij->i", n, n) <= (1e-12 * longest) ** 2) or np.any(longest == 0):
                degenerate.append(j)
    for idx, msg, exp in ((overflow, "normal overflows (coordinates too large)",
                           "edges shorter than about 1e150 mm"),
                          (degenerate, "is degenerate: its corners are collinear or coincide",
                           "a face with an area (corners not on one line)")):
        if idx:
            out.append(Diagnostic("LB312", f"{what}: face {idx[0] + 1} {msg}"
                                  + (f" ({len(idx)} faces)" if len(idx) > 1 else ""), where_face(idx[0]),
                                  value="corners " + str(np.round(v[polys[idx[0]]], 3).tolist())[:200],
                                  expected=exp))
    return out


def obj_diagnostics(path: Path, display: str, booth: Booth, transform, mount: str = "booth") -> list[Diagnostic]:
    """Every problem of an OBJ geometry file, located in it (``LB0xx`` reading, ``LB203``, ``LB312``,
    ``LB313``, ``LB510``); what :func:`mesh_diagnostics` checks, on the file's own polygons."""
    from .diagnostics import SourceLocation

    try:
        scan = _obj_scan(_check_mesh_size(path, display), display)
    except LbsceneUserError as exc:
        return exc.diagnostics
    return mesh_diagnostics(
        _placed(scan.vertices, transform), scan.faces, booth, mount=mount, what=f"mesh {display}",
        where_vertex=lambda i: SourceLocation(display, scan.vertex_lines[i], 1),
        where_face=lambda j: SourceLocation(display, scan.face_lines[j], 1))


def _mesh_from_obj(path: Path, display: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    # bounded and located before trimesh parses it (trimesh takes minutes and gigabytes on 10⁶ faces)
    _obj_scan(_check_mesh_size(path, display), display)
    try:
        scene_or_mesh = trimesh.load(str(path), file_type="obj", force="mesh", process=False)
    except Exception as exc:
        raise LbsceneUserError.single("LB203", f"cannot read OBJ file: {exc}", display,
                                      expected="a Wavefront OBJ mesh")
    v = np.asarray(scene_or_mesh.vertices, float)
    f = np.asarray(scene_or_mesh.faces, np.int64)
    if v.size == 0 or f.size == 0:
        raise LbsceneUserError.single("LB203", "OBJ file has no faces", display,
                                      expected="a Wavefront OBJ mesh with faces")
    return v, f


def _meshes_from_usd(path: Path, display: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    from pxr import Tf, Usd, UsdGeom

    _check_mesh_size(path, display)
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:
        raise LbsceneUserError.single("LB203", f"cannot open USD file: {str(exc).strip()[:300]}", display,
                                      expected="a USD stage (.usda/.usdc/.usd)")
    if stage is None:
        raise LbsceneUserError.single("LB203", "cannot open USD file", display,
                                      expected="a USD stage (.usda/.usdc/.usd)")
    from .diagnostics import SourceLocation
    from .limits import check_work

    to_mm = UsdGeom.GetStageMetersPerUnit(stage) * 1000.0
    out = []
    cache = UsdGeom.XformCache()
    triangles = 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        where = str(prim.GetPath())
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], np.int64)
        # bounded before the points are read or a single triangle is made
        triangles += int(np.maximum(counts - 2, 0).sum())
        check_work("mesh_triangles", triangles, SourceLocation(display),
                   what=f"triangles in {display} (up to mesh {where})")
        pts = np.asarray(mesh.GetPointsAttr().Get() or [], float).reshape(-1, 3)
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], np.int64)
        if not len(pts) or not counts.size:
            continue
        problem = ("a face with fewer than three corners" if np.any(counts < 3) else
                   f"{idx.size} face-vertex indices for faces of {int(counts.sum())} corners"
                   if idx.size != counts.sum() else
                   f"a face-vertex index outside the {len(pts)} points" if np.any((idx < 0) | (idx >= len(pts)))
                   else "a point that is not finite" if not np.isfinite(pts).all() else None)
        if problem:
            raise LbsceneUserError.single("LB203", f"USD mesh {where} has {problem}", display,
                                          expected="faceVertexCounts ≥ 3 that add up to the faceVertexIndices, "
                                                   "indices into points, finite points")
        gm = cache.GetLocalToWorldTransform(prim)  # Gf matrices use the row-vector convention
        m = np.array([[gm[i][j] for j in range(4)] for i in range(4)], float)
        pts_h = np.c_[pts, np.ones(len(pts))] @ m
        tris, k = [], 0
        for c in counts.tolist():
            for j in range(1, c - 1):  # fan triangulation
                tris.append((idx[k], idx[k + j], idx[k + j + 1]))
            k += c
        out.append((prim.GetName(), pts_h[:, :3] * to_mm, np.asarray(tris, np.int64).reshape(-1, 3)))
    return out


def usd_diagnostics(path: Path, display: str, booth: Booth, transform=None, mount: str = "booth",
                    ) -> list[Diagnostic]:
    """Every problem of a USD geometry file (or a USD interior, ``transform=None``), located in it:
    reading (``LB0xx``, ``LB203``), the bound (``LB510``), and :func:`mesh_diagnostics` per mesh."""
    from .diagnostics import SourceLocation

    try:
        meshes = _meshes_from_usd(path, display)
    except LbsceneUserError as exc:
        return exc.diagnostics
    out = []
    for name, v, f in meshes:
        placed = v if transform is None else _placed(v, transform)
        out += mesh_diagnostics(placed, list(f), booth, mount=mount, what=f"USD mesh {name}",
                                where_vertex=lambda i: SourceLocation(display),
                                where_face=lambda j: SourceLocation(display))
    return out


def geometry_file_diagnostics(doc: LoadedDocument) -> list[Diagnostic]:
    """Every geometry file of a booth (and a USD interior) opened and checked as the compiler
    will read it: each problem located in the file that has it."""
    booth: Booth = doc.model
    out: list[Diagnostic] = []
    if booth.interior.type == "usd":
        p = doc.resolve(booth.interior.path)
        out += usd_diagnostics(p, booth.interior.path, booth)
    for g in booth.geometry_files:
        p = doc.resolve(g.path)
        check = obj_diagnostics if g.type == "obj" else usd_diagnostics
        out += check(p, g.path, booth, g.transform, g.mount)
    return out


def _file_surfaces(doc: LoadedDocument) -> list[IRSurface]:
    booth: Booth = doc.model
    out = []
    for g in booth.geometry_files:
        path = doc.resolve(g.path)
        t = g.transform
        rot = _rotation_matrix_xyz(t.rotate_xyz_deg)
        if g.type == "obj":
            parts = [(g.id,) + _mesh_from_obj(path, g.path)]
        else:
            parts = [(f"{g.id}.{name}", v, f) for name, v, f in _meshes_from_usd(path, g.path)]
        for pid, v, f in parts:
            v = (v * t.scale) @ rot.T + np.asarray(t.translate_mm)
            out.append(IRSurface(
                id=pid, role="mesh", material=g.material,
                vertices_mm=tuple(tuple(float(f"{c:.9g}") for c in row) for row in v),
                triangles=tuple(tuple(int(i) for i in tri) for tri in f),
                source=f"{g.type}:{g.path}", mount=g.mount))
    return out


# --------------------------------------------------------------------------- lamps

def _lamp_ir(lamp, doc: LoadedDocument, grid: BandGrid) -> IRLamp:
    from .emitters import emitter_from_lamp, projected_area_m2, solid_angle_weight_sr, unit_irradiance
    from .profiles import profile_shape, read_ies
    from .spectra import evaluate_spectrum, luminous_efficacy_sum

    spd = evaluate_spectrum(lamp.spd, doc.resolve, "emission", display=f"lamp {lamp.id} spd")
    ref = np.interp(560.0, np.arange(360.0, 831.0), spd)
    spd = spd / (ref if ref > 0 else spd.max())
    profile = lamp.profile.model_dump(mode="json")
    if profile["type"] == "ies":
        data = read_ies(doc.resolve(lamp.profile.path), lamp.profile.path)
        profile["data"] = {"vertical_deg": data.vertical_deg.tolist(),
                           "horizontal_deg": data.horizontal_deg.tolist(),
                           "candela": data.candela.tolist(),
                           "lumens_per_lamp": data.lumens_per_lamp}
    shape = profile_shape(profile)
    lum_per_unit = luminous_efficacy_sum(spd)  # cd per (W·sr⁻¹·nm⁻¹ scale)
    aim = np.asarray(_unit(lamp.aim))
    axis = np.asarray(_unit(lamp.axis))
    # Φ / I_ref of the lamp's own Lambertian shape times its modulation (emitters module)
    omega = solid_angle_weight_sr(lamp.type, axis, aim, shape, radius_mm=lamp.radius_mm,
                                  length_mm=lamp.length_mm, end_caps=lamp.end_caps)
    area_m2 = projected_area_m2(lamp.type, lamp.length_mm, lamp.width_mm, lamp.radius_mm)
    out = lamp.output
    if out.type == "peak_intensity_cd":
        scale = out.value_cd / lum_per_unit
    elif out.type == "luminous_flux_lm":
        scale = out.value_lm / (lum_per_unit * omega)
    elif out.type == "luminance_cd_m2":                 # I_ref = L_v · A
        scale = out.value_cd_m2 * area_m2 / lum_per_unit
    elif out.type == "radiance_W_sr_m2":
        scale = out.value_W_sr_m2 * area_m2 / float(spd.sum())
    elif out.type == "peak_radiant_intensity_W_sr":
        scale = out.value_W_sr / float(spd.sum())      # Σ over the 1 nm grid = ∫ dλ
    elif out.type == "radiant_flux_W":
        scale = out.value_W / (float(spd.sum()) * omega)
    else:  # illuminance at a point from the bare emitter (its shape and profile), upward receiver
        tmp = IRLamp(id=lamp.id, group=lamp.group or lamp.id, kind=lamp.type,
                     position_mm=lamp.position_mm, axis=tuple(axis), aim=tuple(aim),
                     length_mm=lamp.length_mm, width_mm=lamp.width_mm, radius_mm=lamp.radius_mm,
                     spd=IRSpectrum(values_1nm=(0.0,), bands=(0.0,)), intensity_scale_W_sr_nm=1.0,
                     peak_luminous_intensity_cd=0.0, luminous_flux_lm=0.0, profile=profile,
                     point_sources=lamp.point_sources, end_caps=lamp.end_caps)
        geo = unit_irradiance(emitter_from_lamp(tmp, shape), out.point_mm, (0.0, 0.0, 1.0))
        if geo <= 0:
            raise LbsceneUserError.single(
                "LB104", f"lamp {lamp.id}: the output point receives no light from the lamp",
                doc.file, expected="a point below the lamp")
        scale = out.value_lx / (lum_per_unit * geo)
    return IRLamp(
        id=lamp.id, group=lamp.group or lamp.id, kind=lamp.type,
        position_mm=tuple(float(c) for c in lamp.position_mm), axis=_unit(lamp.axis),
        aim=tuple(float(c) for c in aim), length_mm=lamp.length_mm, width_mm=lamp.width_mm,
        radius_mm=lamp.radius_mm, spd=IRSpectrum.from_1nm(spd, grid),
        intensity_scale_W_sr_nm=float(f"{scale:.10g}"),
        peak_luminous_intensity_cd=float(f"{scale * lum_per_unit:.10g}"),
        luminous_flux_lm=float(f"{scale * lum_per_unit * omega:.10g}"),
        profile=profile, point_sources=lamp.point_sources, filter=lamp.filter,
        reflector=lamp.reflector, mount=lamp.mount, end_caps=lamp.end_caps)


# --------------------------------------------------------------------------- compile

def compile_loaded(doc: LoadedDocument, grid: BandGrid = DEFAULT_GRID) -> SceneIR:
    """Instantiate a validated, linted booth document."""
    from .spectra import evaluate_spectrum

    booth: Booth = doc.model
    effects, diags = validate_effects(doc)
    if diags:
        raise LbsceneUserError(diags)

    def spectrum(spec, kind, what):
        return IRSpectrum.from_1nm(evaluate_spectrum(spec, doc.resolve, kind, display=what), grid)

    materials = {mid: IRMaterial(id=mid, type=m.type,
                                 reflectance=spectrum(m.reflectance, "reflectance", f"material {mid}"),
                                 gloss_GU=m.gloss_GU, roughness=m.roughness)
                 for mid, m in booth.materials.items()}
    if booth.interior.type == "box":
        interior = IRInterior(width_mm=booth.interior.width_mm, depth_mm=booth.interior.depth_mm,
                              height_mm=booth.interior.height_mm, open_front=booth.interior.open_front)
        surfaces = _box_surfaces(booth)
    else:
        bw, bd, bh = booth.interior.bounds_mm
        interior = IRInterior(width_mm=bw, depth_mm=bd, height_mm=bh, open_front=True)
        surfaces = []
        roles = set(type(booth.surfaces).model_fields)
        for name, v, f in _meshes_from_usd(doc.resolve(booth.interior.path), booth.interior.path):
            role = next((r for r in roles if r in name.lower()), "mesh")
            mat = getattr(booth.surfaces, role, None) if role != "mesh" else None
            mat = mat or booth.surfaces.floor
            surfaces.append(IRSurface(
                id=name, role=role, material=mat,
                vertices_mm=tuple(tuple(float(f"{c:.9g}") for c in row) for row in v),
                triangles=tuple(tuple(int(i) for i in t) for t in f),
                source=f"usd:{booth.interior.path}"))
    if booth.platform is not None and booth.surfaces.platform:
        cx, cy, cz = booth.platform.centre_mm
        sx, sy = booth.platform.size_mm[0] / 2, booth.platform.size_mm[1] / 2
        verts, tris = _quad((cx - sx, cy - sy, cz), (cx + sx, cy - sy, cz),
                            (cx + sx, cy + sy, cz), (cx - sx, cy + sy, cz))
        surfaces.append(IRSurface(id="platform", role="platform", material=booth.surfaces.platform,
                                  vertices_mm=tuple(verts), triangles=tuple(tris)))
    surfaces.extend(_file_surfaces(doc))

    lamps = tuple(_lamp_ir(lp, doc, grid) for lp in booth.lamps)
    filters = {fid: IRFilter(id=fid, transmittance=spectrum(f.transmittance, "transmittance",
                                                            f"filter {fid}"))
               for fid, f in booth.filters.items()}
    reflectors = {rid: IRReflector(id=rid, type=r.type,
                                   reflectance=spectrum(r.reflectance, "reflectance", f"reflector {rid}"),
                                   distance_mm=r.distance_mm, normal=_unit(r.normal), width_mm=r.width_mm)
                  for rid, r in booth.reflectors.items()}
    diffuser = None
    if booth.diffuser is not None:
        df = booth.diffuser
        diffuser = IRDiffuser(z_mm=df.z_mm, size_mm=df.size_mm, centre_mm=df.centre_mm,
                              thickness_mm=df.thickness_mm,
                              transmittance=spectrum(df.transmittance, "transmittance", "diffuser"),
                              scattering=df.scattering.model_dump(mode="json"), ior=df.ior)
    occluders = tuple(IROccluder(id=o.id, type=o.type, centre_mm=o.centre_mm, normal=_unit(o.normal),
                                 u_axis=_unit(o.u_axis), size_mm=o.size_mm, opening_mm=o.opening_mm,
                                 lamps=tuple(o.lamps) if o.lamps is not None else None,
                                 material=o.material, mount=o.mount)
                      for o in booth.occluders)
    lighting = {name: IRLighting(name=name, lamps=tuple(c.lamps), dimming=dict(c.dimming),
                                 description=c.description,
                                 nominal_illuminance_lx=c.nominal_illuminance_lx, standard=c.standard)
                for name, c in booth.lighting.items()}
    geometries = []
    for g in booth.geometries:
        ill, asp = parse_geometry_name(g.name)
        geometries.append(IRGeometry(name=g.name, illumination_deg=ill, aspecular_deg=asp,
                                     viewing_deg=ill - asp,
                                     platform_rotation_deg=g.platform_rotation_deg))
    ob = booth.observer
    platform = None
    if booth.platform is not None:
        p = booth.platform
        platform = IRPlatform(centre_mm=p.centre_mm, size_mm=p.size_mm,
                              rotation_axis=_unit(p.rotation_axis),
                              pivot_mm=p.pivot_mm if p.pivot_mm is not None else p.centre_mm,
                              illumination_fixed_to_platform=p.illumination_fixed_to_platform,
                              illumination_angle_deg=p.illumination_angle_deg)
    ir = SceneIR(
        ir_version=IR_VERSION, booth_name=booth.name,
        # folder/file, not a cwd-relative path: the IR (and its hash) must not depend on where
        # the command was run from
        booth_source=f"{doc.path.resolve().parent.name}/{doc.path.name}",
        provenance_status=booth.provenance.status,
        bands=grid.to_json(), interior=interior, materials=materials, surfaces=tuple(surfaces),
        lamps=lamps, filters=filters, reflectors=reflectors, diffuser=diffuser,
        occluders=occluders, lighting=lighting, geometries=tuple(geometries), platform=platform,
        observer=IRObserver(type=ob.type, position_mm=ob.position_mm, look_at_mm=ob.look_at_mm,
                            slit_size_mm=ob.slit_size_mm),
        sample_position_mm=booth.sample_position_mm, effects=effects,
        fit=booth.fit.model_dump(mode="json"))
    ir = _with_projected_reflectances(ir)
    try:
        ir.to_json()          # finite floats only: a NaN here would reach every product
    except ValueError:
        raise LbsceneUserError.single(
            "LB600", "the booth's numbers give a non-finite value (NaN or infinity) in the scene IR",
            display_path(doc.path), expected="a booth whose lamp levels and geometry are finite",
            hint="check lamp positions against output points and surfaces (LB309), and zero sizes") from None
    return ir


def _with_projected_reflectances(ir: SceneIR) -> SceneIR:
    """Lighting-dependent band reflectances of the booth's materials (colour accuracy)."""
    try:
        from .colour.band_weighting import project_reflectance
    except ImportError:  # colour module not available in this build
        return ir
    new = {}
    for mid, m in ir.materials.items():
        by = {}
        for name in ir.lighting:
            light = ir.lighting_spd_1nm(name)
            if not np.any(light > 0):
                continue
            bands = project_reflectance(m.reflectance.array_1nm, light, ir.grid)
            by[name] = tuple(float(f"{x:.10g}") for x in np.asarray(bands).ravel())
        new[mid] = m.model_copy(update={"reflectance_bands_by_lighting": by})
    return ir.model_copy(update={"materials": new})
