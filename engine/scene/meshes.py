"""
Meshes a booth file names (OBJ and USD geometry files): bounded reads, the face count before any
mesh library opens a file, and their located checks (finite vertices, faces that are not
degenerate, normals that do not overflow, every vertex inside the booth, also at each platform
rotation for platform-mounted meshes).  ``validate-config`` and the compiler read meshes here.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError
from lbscene.engine.files.load import LoadedDocument
from lbscene.schemas.booth import Booth

__all__ = ["MAX_MESH_BYTES", "ObjScan", "mesh_diagnostics", "obj_diagnostics", "usd_diagnostics",
           "geometry_file_diagnostics", "inside_booth", "TOLERANCE_MM"]

TOLERANCE_MM = 1.0


def inside_booth(p, booth: Booth, margin: float = 0.0) -> bool:
    if booth.interior.type == "box":
        w, d, h = booth.interior.width_mm, booth.interior.depth_mm, booth.interior.height_mm
    else:
        w, d, h = booth.interior.bounds_mm
    x, y, z = p
    t = TOLERANCE_MM
    return (abs(x) <= w / 2 - margin + t and abs(y) <= d / 2 - margin + t
            and -t + margin <= z <= h - margin + t)


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
    from lbscene.engine.files.yamlio import read_bytes_bounded

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
    (``LB510``, :data:`~lbscene.engine.files.limits.LIMITS` ``mesh_triangles``) before anything is
    parsed; then each polygon counts as the triangles it becomes (n corners: n − 2).
    """
    from lbscene.engine.files.diagnostics import SourceLocation
    from lbscene.engine.files.limits import LIMITS, check_work, limit_value

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
        from lbscene.engine.light.geometry import rotation_matrix

        o = np.asarray(pf.pivot_mm if pf.pivot_mm is not None else pf.centre_mm, float)
        poses += [(f"at geometry {g.name}", rotation_matrix(pf.rotation_axis, g.platform_rotation_deg), o)
                  for g in booth.geometries if g.platform_rotation_deg]
    for label, R, o in poses:
        q = (v - o) @ R.T + o
        outside = [i for i in range(len(q)) if not inside_booth(q[i], booth)]
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
    from lbscene.engine.files.diagnostics import SourceLocation

    try:
        scan = _obj_scan(_check_mesh_size(path, display), display)
    except LbsceneUserError as exc:
        return exc.diagnostics
    return mesh_diagnostics(
        _placed(scan.vertices, transform), scan.faces, booth, mount=mount, what=f"mesh {display}",
        where_vertex=lambda i: SourceLocation(display, scan.vertex_lines[i], 1),
        where_face=lambda j: SourceLocation(display, scan.face_lines[j], 1))


def _scan_triangles(scan: ObjScan) -> np.ndarray | None:
    """The triangles of an OBJ whose faces are all triangles or all quads, as trimesh makes them
    (a quad ``a b c d`` → ``a b c``, then, after every quad's first, ``c d a``); None for other
    files (trimesh triangulates them).  Saves importing trimesh (0.5–2 s of a first frame)."""
    counts = {len(f) for f in scan.faces}
    if counts == {3}:
        return np.asarray(scan.faces, np.int64).reshape(-1, 3)
    if counts == {4}:
        q = np.asarray(scan.faces, np.int64).reshape(-1, 4)
        return np.concatenate([q[:, [0, 1, 2]], q[:, [2, 3, 0]]])
    return None


def _mesh_from_obj(path: Path, display: str) -> tuple[np.ndarray, np.ndarray]:
    # bounded and located before trimesh parses it (trimesh takes minutes and gigabytes on 10⁶ faces)
    scan = _obj_scan(_check_mesh_size(path, display), display)
    tris = _scan_triangles(scan)
    if tris is not None:
        return scan.vertices, tris
    import trimesh

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

    from .usd_stage import register_schema

    # USD makes its schema registry once per process, at the first stage opened: the lbscene schema
    # must be registered before, or the stage ``build`` writes later cannot apply its API schemas
    register_schema()
    _check_mesh_size(path, display)
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:
        raise LbsceneUserError.single("LB203", f"cannot open USD file: {str(exc).strip()[:300]}", display,
                                      expected="a USD stage (.usda/.usdc/.usd)")
    if stage is None:
        raise LbsceneUserError.single("LB203", "cannot open USD file", display,
                                      expected="a USD stage (.usda/.usdc/.usd)")
    from lbscene.engine.files.diagnostics import SourceLocation
    from lbscene.engine.files.limits import check_work

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
    from lbscene.engine.files.diagnostics import SourceLocation

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
