"""
Render-time inputs of a render graph: meshes with per-vertex band irradiance,
data textures and the values its bindings name.

:class:`SceneBuilder` turns the graph (plain data), the scene IR, a sample, a
display and (optionally) bake products into :class:`ViewInputs`, per view,
cached.  Nothing here touches OpenGL: the executor uploads what it gets.

Coordinates: booth millimetres.  Geometry is placed per view on the CPU
(platform-mounted parts rotated about the platform axis), so the vertex
shader's model matrix is the identity.

Irradiance at vertices (``diffuse='analytic'``) comes from the analytic forward
model (:class:`lbscene.engine.light.forward.ForwardModel`: every enabled effect of
the booth).  When the luminaire turns with the platform, the light transport
is evaluated in the platform's frame (fixed parts transformed by the inverse
rotation): exact for the direct light of platform-mounted lamps, approximate
for inter-reflection between fixed walls.  With ``diffuse='baked'`` the sample's
irradiance comes from the bake's environment map of the view (cosine-weighted)
and floor vertices from the floor irradiance map; the rest stays analytic.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lbscene.engine.scene.sample import SampleSpec

from .graph import EMITTER_TEXELS, PROFILE_SAMPLES, rotation_matrix

__all__ = [
    "VERTEX_FLOATS",
    "CameraSpec",
    "ViewInputs",
    "SceneBuilder",
    "look_at",
    "perspective",
    "tessellate_surface",
    "noise_texture",
    "model_code_digest",
]

#: position 3, normal 3, uv 2, material 1, irradiance 16
VERTEX_FLOATS = 25
#: Fresnel reflectance at normal incidence of a clear coat with n = 1.567 (the gloss
#: standard's black glass): ((n − 1)/(n + 1))².
COAT_F0 = ((1.567 - 1.0) / (1.567 + 1.0)) ** 2
SAMPLE_GRID = 16


# --------------------------------------------------------------------------- inputs

@dataclass
class CameraSpec:
    """``position_mm``/``look_at_mm`` None: the view's observer and the sample centre."""

    position_mm: tuple[float, float, float] | None = None
    look_at_mm: tuple[float, float, float] | None = None
    vertical_fov_deg: float = 30.0


@dataclass
class ViewInputs:
    """Everything one view needs besides the static data."""

    name: str
    meshes: dict[str, tuple[np.ndarray, np.ndarray]]
    textures: dict[str, np.ndarray]
    values: dict[str, Any]
    sample_irradiance_1nm: np.ndarray
    sample_centre_mm: np.ndarray
    sample_normal: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------- camera

def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """View matrix (4×4, column vectors) of a camera at ``eye`` looking at ``target``."""
    eye = np.asarray(eye, float)
    f = np.asarray(target, float) - eye
    f /= np.linalg.norm(f)
    up = np.asarray(up, float)
    if abs(f @ up) > 0.999:
        up = np.array([0.0, 1.0, 0.0])
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """OpenGL perspective projection (4×4)."""
    f = 1.0 / np.tan(np.radians(fovy_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def display_linear_matrix(exposure: float, adaptation, xyz_offset, xyz_to_rgb, inv_y_span: float) -> np.ndarray:
    r"""The display model's affine part as one 4×4 matrix (``display.linear``, lib_display.glsl).

    With display XYZ :math:`D = e\,A\,X` (exposure :math:`e`, chromatic adaptation :math:`A`,
    absolute XYZ :math:`X`), offset :math:`o` (black + ambient), the matrix :math:`M` to linear
    channel values and :math:`s = 1/(Y_w - Y_k)`:

    .. math:: \begin{pmatrix} \ell \\ y \end{pmatrix} =
              \begin{pmatrix} e\,M A & -M o \\ e\,s\,A_{Y\cdot} & -s\,o_Y \end{pmatrix}
              \begin{pmatrix} X \\ 1 \end{pmatrix},
              \quad \ell = M (D - o),\ y = s\,(D_Y - o_Y)

    Parameters
    ----------
    exposure
        Absolute → display XYZ scale :math:`e` (``display.exposure``).
    adaptation
        (3, 3) chromatic adaptation :math:`A` (``display.adaptation``).
    xyz_offset
        XYZ :math:`o` of the display's black plus reflected ambient, cd/m².
    xyz_to_rgb
        (3, 3) display XYZ → linear channel values :math:`M`.
    inv_y_span
        :math:`s`, 1 / (white − black luminance) of the display, m²/cd.

    Returns
    -------
    numpy.ndarray
        (4, 4), row-major; the runtime uploads it column-major with :func:`_gl`.
    """
    a = float(exposure) * np.asarray(adaptation, float)
    m = np.asarray(xyz_to_rgb, float)
    o = np.asarray(xyz_offset, float)
    out = np.zeros((4, 4))
    out[:3, :3] = m @ a
    out[:3, 3] = -(m @ o)
    out[3, :3] = float(inv_y_span) * a[1]
    out[3, 3] = -float(inv_y_span) * o[1]
    return out


def _gl(m: np.ndarray) -> np.ndarray:
    """Column-major float32 for glUniformMatrix*."""
    return np.ascontiguousarray(np.asarray(m, float).T, dtype=np.float32).ravel()


# --------------------------------------------------------------------------- tessellation

def _grid_quad(q: np.ndarray, nu: int, nv: int):
    s = np.linspace(0.0, 1.0, nu + 1)
    t = np.linspace(0.0, 1.0, nv + 1)
    S, T = np.meshgrid(s, t, indexing="ij")
    S, T = S.ravel()[:, None], T.ravel()[:, None]
    p = (1 - S) * (1 - T) * q[0] + S * (1 - T) * q[1] + S * T * q[2] + (1 - S) * T * q[3]
    uv = np.c_[S, T]
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tris = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 3)
    return p, uv, tris


def _split_long(v: np.ndarray, max_edge: float, max_levels: int = 4) -> np.ndarray:
    """Triangles (k, 3, 3) split 1→4 until every edge is ≤ max_edge (or max_levels)."""
    out = [v]
    for _ in range(max_levels):
        cur = out[-1]
        e = np.max(np.linalg.norm(cur - np.roll(cur, 1, axis=1), axis=2), axis=1)
        big = e > max_edge
        if not big.any():
            break
        t = cur[big]
        m01, m12, m20 = (t[:, 0] + t[:, 1]) / 2, (t[:, 1] + t[:, 2]) / 2, (t[:, 2] + t[:, 0]) / 2
        new = np.concatenate([np.stack([t[:, 0], m01, m20], 1), np.stack([m01, t[:, 1], m12], 1),
                              np.stack([m20, m12, t[:, 2]], 1), np.stack([m01, m12, m20], 1)])
        out[-1] = np.concatenate([cur[~big], new])
    return out[-1]


def tessellate_surface(surface, cell_mm: float):
    """Positions (n, 3), normals (n, 3), uv (n, 2), triangles (m, 3) of an IR surface.

    A quad (4 vertices, two triangles) becomes a grid of cells ≤ ``cell_mm``; other
    meshes are flat-shaded (face normals) with long triangles split.
    """
    v = surface.vertex_array
    t = surface.triangle_array
    if len(v) == 4 and t.tolist() == [[0, 1, 2], [0, 2, 3]]:
        nu = max(1, int(np.ceil(np.linalg.norm(v[1] - v[0]) / cell_mm)))
        nv = max(1, int(np.ceil(np.linalg.norm(v[3] - v[0]) / cell_mm)))
        p, uv, tris = _grid_quad(v, nu, nv)
        n = np.cross(v[1] - v[0], v[2] - v[0])
        n = n / np.linalg.norm(n)
        return p, np.tile(n, (len(p), 1)), uv, tris
    tv = _split_long(v[t], 2.0 * cell_mm)
    n = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
    ln = np.linalg.norm(n, axis=1)
    keep = ln > 1e-12
    tv, n = tv[keep], n[keep] / ln[keep, None]
    p = tv.reshape(-1, 3)
    return p, np.repeat(n, 3, axis=0), np.zeros((len(p), 2)), np.arange(len(p)).reshape(-1, 3)


# --------------------------------------------------------------------------- irradiance

_FORWARD_CACHE: dict = {}


def _forward_model(ir, lighting):
    key = (ir.content_hash, lighting)
    fm = _FORWARD_CACHE.get(key)
    if fm is None:
        from lbscene.engine.light.forward import ForwardModel

        if len(_FORWARD_CACHE) > 8:
            _FORWARD_CACHE.clear()
        fm = _FORWARD_CACHE[key] = ForwardModel(ir, lighting)
    return fm


def _prediction_bands(fm, terms, n) -> np.ndarray:
    from lbscene.engine.light.forward import Prediction

    return Prediction(fm.groups, list(terms), n, fm.ir.grid).bands()


def _plane_groups(points: np.ndarray, normals: np.ndarray, min_size: int = 16):
    """Indices of vertices grouped by plane (same normal and offset), and the rest."""
    key_n = np.round(normals * 1000).astype(np.int64)
    key_d = np.round(np.einsum("ij,ij->i", points, normals) * 10).astype(np.int64)
    keys = np.c_[key_n, key_d]
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    groups, rest = [], []
    for g in range(inv.max() + 1 if len(inv) else 0):
        idx = np.nonzero(inv == g)[0]
        (groups if len(idx) >= min_size else rest).append(idx)
    return groups, (np.concatenate(rest) if rest else np.zeros(0, int))


def _indirect_nodes(points, normals, cell_mm):
    """Coarse receivers for the smooth (global) part of the irradiance and how to
    interpolate it back: planar groups get a bilinear grid, other vertices the value
    of their voxel's centroid."""
    groups, rest = _plane_groups(points, normals)
    nodes_p, nodes_n, plans = [], [], []
    base = 0
    for idx in groups:
        n = normals[idx[0]]
        u = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        p = points[idx]
        s, t = p @ u, p @ v
        ns = max(2, int(np.ceil((s.max() - s.min()) / cell_mm)) + 1)
        nt = max(2, int(np.ceil((t.max() - t.min()) / cell_mm)) + 1)
        gs = np.linspace(s.min(), s.max(), ns)
        gt = np.linspace(t.min(), t.max(), nt)
        S, T = np.meshgrid(gs, gt, indexing="ij")
        d = float(p[0] @ n)
        nodes_p.append(S.ravel()[:, None] * u + T.ravel()[:, None] * v + d * n)
        nodes_n.append(np.tile(n, (ns * nt, 1)))
        plans.append(("grid", idx, base, gs, gt, s, t))
        base += ns * nt
    if len(rest):
        vox = np.floor(points[rest] / cell_mm).astype(np.int64)
        nk = np.round(normals[rest] * 2).astype(np.int64)
        _, inv = np.unique(np.c_[vox, nk], axis=0, return_inverse=True)
        k = inv.max() + 1
        cp = np.zeros((k, 3))
        cn = np.zeros((k, 3))
        np.add.at(cp, inv, points[rest])
        np.add.at(cn, inv, normals[rest])
        cnt = np.bincount(inv, minlength=k)[:, None]
        cp /= cnt
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-12)
        nodes_p.append(cp)
        nodes_n.append(cn)
        plans.append(("voxel", rest, base, inv))
        base += k
    if not nodes_p:
        return np.zeros((0, 3)), np.zeros((0, 3)), []
    return np.concatenate(nodes_p), np.concatenate(nodes_n), plans


def _interpolate_nodes(values, plans, m, bands) -> np.ndarray:
    out = np.zeros((m, bands))
    for plan in plans:
        if plan[0] == "grid":
            _, idx, base, gs, gt, s, t = plan
            ns, nt = len(gs), len(gt)
            g = values[base:base + ns * nt].reshape(ns, nt, bands)
            x = np.clip((s - gs[0]) / max(gs[-1] - gs[0], 1e-12) * (ns - 1), 0, ns - 1)
            y = np.clip((t - gt[0]) / max(gt[-1] - gt[0], 1e-12) * (nt - 1), 0, nt - 1)
            i0 = np.minimum(np.floor(x).astype(int), ns - 2)
            j0 = np.minimum(np.floor(y).astype(int), nt - 2)
            fx, fy = (x - i0)[:, None], (y - j0)[:, None]
            out[idx] = ((1 - fx) * (1 - fy) * g[i0, j0] + fx * (1 - fy) * g[i0 + 1, j0]
                        + (1 - fx) * fy * g[i0, j0 + 1] + fx * fy * g[i0 + 1, j0 + 1])
        else:
            _, idx, base, inv = plan
            out[idx] = values[base + inv]
    return out


def _irradiance_bands(ir, lighting, points, normals, cell_mm: float, chunk: int = 2048) -> np.ndarray:
    """Band-mean spectral irradiance (M, B), W·m⁻²·nm⁻¹, at vertices, from the forward model.

    First-order light (lamps with every path/emitter effect, secondary sources) is
    evaluated at every vertex; global transport (inter-reflection), which varies
    slowly, on a coarse set of receivers (cells of ``cell_mm``) and interpolated.
    """
    fm = _forward_model(ir, lighting)
    m, nb = len(points), ir.grid.count
    out = np.zeros((m, nb))
    if m == 0:
        return out
    off = np.zeros(m, bool)
    for i in range(0, m, chunk):
        sl = slice(i, i + chunk)
        out[sl] = _prediction_bands(fm, fm.first_order_terms(points[sl], normals[sl], off[sl]),
                                    len(points[sl]))
    transports = fm.global_transports()
    if transports:
        np_, nn_, plans = _indirect_nodes(points, normals, cell_mm)
        vals = np.zeros((len(np_), nb))
        for i in range(0, len(np_), chunk):
            sl = slice(i, i + chunk)
            k = len(np_[sl])
            terms = [t for gt in transports for t in gt.terms(np_[sl], nn_[sl], np.zeros(k, bool))]
            vals[sl] = _prediction_bands(fm, terms, k)
        out += _interpolate_nodes(vals, plans, m, nb)
    return np.clip(out, 0.0, None)


def model_code_digest(ir) -> str:
    """Hash of everything besides the IR that the light at the vertices is computed from: the
    light model's code (:func:`lbscene.engine.light.code_digest.light_code_digest`) and this
    module.  A change to any of them gives the per-vertex results another disk cache key, so an
    edited model never reads a stale result.

    Parameters
    ----------
    ir
        The compiled booth (its enabled effects name the plugin modules).

    Returns
    -------
    str
        Hex digest.
    """
    from pathlib import Path

    from lbscene.engine.light.code_digest import light_code_digest

    return light_code_digest(ir, extra=(Path(__file__),))


def _vertex_irradiance_bands(ir, lighting, points, normals, cell_mm: float) -> np.ndarray:
    """:func:`_irradiance_bands`, kept in the disk cache (key: the receivers, the IR's
    :attr:`~lbscene.engine.scene.ir.SceneIR.light_hash`, the lighting, the interpolation cell and
    :func:`model_code_digest`): the same booth and view in a later process costs a file read
    instead of the forward model."""
    from lbscene.engine.files.disk_cache import cached_array

    return cached_array("vertex_irradiance", (np.asarray(points, float), np.asarray(normals, float)),
                        (ir.light_hash, lighting, float(cell_mm), model_code_digest(ir)),
                        lambda: _irradiance_bands(ir, lighting, points, normals, cell_mm),
                        shape=(len(points), ir.grid.count), shipped=True)


def _irradiance_1nm(ir, lighting, point, normal) -> np.ndarray:
    from lbscene.engine.files.disk_cache import cached_array

    def compute():
        fm = _forward_model(ir, lighting)
        return np.clip(fm.spectral_irradiance_1nm([point], [normal])[0], 0.0, None)

    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM

    return cached_array("point_irradiance_1nm", (np.asarray(point, float), np.asarray(normal, float)),
                        (ir.light_hash, lighting, model_code_digest(ir)), compute,
                        shape=(REFERENCE_WAVELENGTHS_NM.size,), shipped=True)


def noise_texture(mask: np.ndarray) -> np.ndarray:
    """(s, s, 4) float32 for the ``blue_noise`` texture: channel c at texel (x, y) holds the
    mask at ((x + dx_c) mod s, (y + dy_c) mod s) for the channel offsets, so the shader
    fetches one texel for three channels."""
    from lbscene.engine.colour.dither import channel_offsets_xy

    mask = np.asarray(mask, np.float32)
    out = np.zeros(mask.shape + (4,), np.float32)
    for c, (dx, dy) in enumerate(channel_offsets_xy(mask.shape[0])):
        out[..., c] = np.roll(mask, (-dy, -dx), axis=(0, 1))
    return out


# --------------------------------------------------------------------------- builder

class _ViewFrame:
    """A view's platform rotation: ``R`` about ``origin``; whether the luminaire turns with it."""

    def __init__(self, rotation: dict, lamps_rotate: bool):
        self.R = rotation_matrix(rotation["axis"], rotation["angle_deg"])
        self.origin = np.asarray(rotation["origin_mm"], float)
        self.lamps_rotate = bool(lamps_rotate)

    def to_world(self, p, n, mounted: bool):
        """Rest positions and normals placed for the view (parts on the platform turn)."""
        if not mounted:
            return p, n
        return (p - self.origin) @ self.R.T + self.origin, n @ self.R.T

    def to_light_frame(self, p_rest, n_rest, mounted: bool):
        """Receiver positions in the frame the forward model's lamps are in."""
        if self.lamps_rotate:
            if mounted:
                return p_rest, n_rest
            return (p_rest - self.origin) @ self.R + self.origin, n_rest @ self.R     # R⁻¹ = Rᵀ
        return self.to_world(p_rest, n_rest, mounted)


def _emitter_texture(ems: list, frame: _ViewFrame, xyz_weights: np.ndarray, grid):
    """The emitters placed for the view as the texture sample.frag reads, with the ``#define`` s
    of the kinds present and of whether any profile varies."""
    et = np.zeros((max(len(ems), 1), EMITTER_TEXELS, 4), np.float32)
    kinds = {"sphere": 0.0, "tube": 1.0, "panel": 2.0}
    R, o = frame.R, frame.origin
    for i, e in enumerate(ems):
        c = np.asarray(e["centre_mm"], float)
        ax, aim, wax = (np.asarray(e[k], float) for k in ("axis", "aim", "width_axis"))
        if e["rotates_with_platform"]:
            c, ax, aim, wax = (c - o) @ R.T + o, ax @ R.T, aim @ R.T, wax @ R.T
        et[i, 0] = (*c, kinds[e["kind"]])
        et[i, 1] = (*ax, e["half_length_mm"])
        et[i, 2] = (*aim, e["half_width_mm"])
        et[i, 3] = (*wax, 0.0)
        b = np.zeros(16)
        b[:grid.count] = e["intensity_bands_W_sr_nm"]
        et[i, 4:8] = b.reshape(4, 4)
        prof = np.asarray(e["profile"], float)
        et[i, 8:8 + PROFILE_SAMPLES // 4] = prof.reshape(-1, 4)
        # the band intensities in XYZ (the realtime schedule sums the highlights in XYZ)
        et[i, 8 + PROFILE_SAMPLES // 4, :3] = xyz_weights.T @ b
    kind_bits = {"sphere": 1, "tube": 2, "panel": 4}
    emitter_kinds = 0
    for e in ems:
        emitter_kinds |= kind_bits[e["kind"]]
    emitter_profiles = int(any(np.any(np.asarray(e["profile"], np.float32) != 1.0) for e in ems))
    return et, emitter_kinds, emitter_profiles


class SceneBuilder:
    """Render-time inputs of a graph for one IR, sample and display.

    Parameters
    ----------
    ir, graph
        The compiled booth and its render graph (dict, as from JSON).
    sample
        :class:`SampleSpec`.
    display
        :class:`~lbscene.runtimes.colour_bridge.DisplayUniforms`.
    bake
        :class:`~lbscene.runtimes.bake.BakeProducts` or None.
    irradiance_memo
        A dict shared with other builders of the same IR, lighting, diffuse mode and bake
        (per-vertex irradiance is keyed by mesh name and receiver positions).
    diffuse
        ``'analytic'`` or ``'baked'`` (needs ``bake``).
    exposure
        ``'relative_white'``: a perfect white diffuser at the sample is shown at
        ``white_fraction`` of the display's white luminance; ``'absolute'``: XYZ in
        cd/m² as they are.
    adaptation
        ``'cat16'`` (default): colours are taken from the white of the lighting at the sample
        to the display's white (what a person in the booth sees); ``'none'``: shown as they are
        (what a camera with a D65 white balance sees).  See
        :mod:`lbscene.engine.colour.adaptation`.
    """

    def __init__(self, ir, graph: dict, sample: SampleSpec, display, *, bake=None,
                 diffuse: str = "analytic", exposure: str = "relative_white",
                 white_fraction: float = 1.0, dither: bool = True, camera: CameraSpec | None = None,
                 adaptation: str = "cat16", irradiance_memo: dict | None = None):
        from lbscene.engine.colour.adaptation import ADAPTATION_METHODS

        if adaptation not in ADAPTATION_METHODS:
            raise ValueError(f"adaptation must be one of {ADAPTATION_METHODS}")
        self.adaptation = adaptation
        if diffuse == "baked" and bake is None:
            raise ValueError("diffuse='baked' needs bake products")
        self.ir = ir
        self.graph = graph
        self.lighting = graph["lighting"]
        self.sample = sample
        self.display = display
        self.bake = bake
        self.diffuse = diffuse
        self.exposure = exposure
        self.white_fraction = float(white_fraction)
        self.dither = bool(dither)
        self.camera = camera or CameraSpec()
        self._views: dict[str, ViewInputs] = {}
        # per-vertex irradiance by (mesh, receivers): builders of one booth and lighting that
        # differ in sample or display (the web export) can share it
        self._irradiance_memo: dict[tuple, np.ndarray] = {} if irradiance_memo is None else irradiance_memo
        self._static: dict[str, np.ndarray] | None = None
        self._geometry: dict | None = None
        dims = (ir.interior.width_mm, ir.interior.depth_mm, ir.interior.height_mm)
        self.extent_mm = float(max(dims))
        self.cell_mm = self.extent_mm / 48.0
        self.indirect_cell_mm = self.extent_mm / 8.0

    # ------------------------------------------------------------------ static data
    @property
    def view_names(self) -> list[str]:
        return [v["name"] for v in self.graph["views"]]

    def static_textures(self) -> dict[str, np.ndarray]:
        if self._static is None:
            from .colour_bridge import blue_noise_mask
            from .ltc import load_table

            mats = self.graph["scene"]["materials"]
            nb = self.graph["bands"]["blocks"]
            m = np.zeros((len(mats), nb, 4), np.float32)
            for row in mats:
                b = np.zeros(4 * nb)
                b[:len(row["reflectance_bands"])] = row["reflectance_bands"]
                m[row["index"]] = b.reshape(nb, 4)
            lt = load_table()
            mag = np.zeros(lt.mag.shape[:2] + (4,), np.float32)
            mag[..., :2] = lt.mag
            bn = noise_texture(blue_noise_mask(64))
            self._static = {"materials": m, "ltc_minv": lt.minv.astype(np.float32), "ltc_mag": mag,
                            "blue_noise": bn, "tone_lut": self.display.lut_texture()}
        return self._static

    def _rest_geometry(self) -> dict:
        """Meshes at platform rotation 0: name → (positions, normals, uv, material, triangles)."""
        if self._geometry is not None:
            return self._geometry
        by_id = {s.id: s for s in self.ir.surfaces}
        mat_index = {m["id"]: m["index"] for m in self.graph["scene"]["materials"]}
        out = {}
        for name, spec in self.graph["resources"]["meshes"].items():
            if name == "sample":
                continue
            parts = []
            base = 0
            for sid in spec["surfaces"]:
                s = by_id[sid]
                p, n, uv, tris = tessellate_surface(s, self.cell_mm)
                parts.append((p, n, uv, np.full(len(p), mat_index[s.material], float), tris + base))
                base += len(p)
                if spec.get("sides", 1) == 2:
                    # the back layer: same points, flipped normals, reversed winding (so that
                    # back-face culling shows exactly one layer), its own irradiance
                    parts.append((p, -n, uv, np.full(len(p), mat_index[s.material], float),
                                  tris[:, ::-1] + base))
                    base += len(p)
            if parts:
                out[name] = tuple(np.concatenate([pt[i] for pt in parts]) for i in range(5))
            else:
                out[name] = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0),
                             np.zeros((0, 3), int))
        # the sample: a grid over its size, lifted off the platform
        sp = self.graph["scene"]["sample_placement"]
        c = np.asarray(sp["centre_mm"], float) + np.asarray(sp["normal"], float) * sp["lift_mm"]
        u = np.asarray(sp["u_axis"], float)
        nrm = np.asarray(sp["normal"], float)
        v = np.cross(nrm, u)
        w, h = self.sample.size_mm
        q = np.array([c - u * w / 2 - v * h / 2, c + u * w / 2 - v * h / 2,
                      c + u * w / 2 + v * h / 2, c - u * w / 2 + v * h / 2])
        p, uv, tris = _grid_quad(q, SAMPLE_GRID, SAMPLE_GRID)
        out["sample"] = (p, np.tile(nrm, (len(p), 1)), uv, np.zeros(len(p)), tris)
        self._geometry = out
        return out

    # ------------------------------------------------------------------ views
    def view(self, name: str) -> ViewInputs:
        if name not in self._views:
            self._views[name] = self._build_view(name)
        return self._views[name]

    def _view_spec(self, name: str) -> dict:
        for v in self.graph["views"]:
            if v["name"] == name:
                return v
        raise KeyError(name)

    def _build_view(self, name: str) -> ViewInputs:
        ir, grid = self.ir, self.ir.grid
        vs = self._view_spec(name)
        frame = _ViewFrame(vs["rotation"], self.graph["scene"]["platform"]["luminaire_turns_with_platform"])
        meshes = self._view_meshes(frame)

        # the light at the sample centre (1 nm): weights, projection, exposure
        sp = self.graph["scene"]["sample_placement"]
        c_rest = np.asarray(sp["centre_mm"], float) + np.asarray(sp["normal"], float) * sp["lift_mm"]
        n_rest = np.asarray(sp["normal"], float)
        c_world, n_world = frame.to_world(c_rest[None], n_rest[None], True)
        c_light, n_light = frame.to_light_frame(c_rest[None], n_rest[None], True)
        e_1nm = _irradiance_1nm(ir, self.lighting, c_light[0], n_light[0])
        info: dict[str, Any] = {"diffuse": self.diffuse}
        if self.diffuse == "baked":
            e_1nm = self._apply_bake(name, meshes, e_1nm, n_world[0], info)

        packed = {}
        for mname, (pw, nw, uv, mat, irr, tris) in meshes.items():
            v = np.zeros((len(pw), VERTEX_FLOATS), np.float32)
            v[:, 0:3], v[:, 3:6], v[:, 6:8], v[:, 8] = pw, nw, uv, mat
            v[:, 9:9 + grid.count] = irr
            packed[mname] = (v, np.ascontiguousarray(tris, dtype=np.uint32).ravel())

        # spectral → XYZ weights for the light at the sample
        from .colour_bridge import radiance_xyz_weights

        w = np.zeros((16, 3))
        w[:grid.count] = radiance_xyz_weights(e_1nm, grid)
        xyz_weights = np.ascontiguousarray(w.reshape(4, 4, 3), dtype=np.float32).ravel()
        ems = self.graph["scene"]["emitters"]
        et, emitter_kinds, emitter_profiles = _emitter_texture(ems, frame, w, grid)

        # the illumination centre of the geometry (lamps' luminous centre), placed for the view
        illum = self._illumination_centre()
        if frame.lamps_rotate:
            illum = (illum - frame.origin) @ frame.R.T + frame.origin

        white_xyz, y_white, adapt, k = self._exposure(e_1nm)
        d, sm = self.display, self.sample
        values = {
            "view.identity": _gl(np.eye(4)),
            "sample.model": _gl(np.eye(4)),
            "view.eye_mm": None,   # set per frame (camera)
            "view.illumination_centre_mm": np.asarray(illum, np.float32),
            "view.emitter_count": len(ems),
            "view.emitter_kinds": emitter_kinds,
            "view.emitter_profiles": emitter_profiles,
            "view.xyz_weights": xyz_weights,
            "sample.geometry_count": len(sm.geometries),
            "sample.roughness": float(sm.roughness),
            "sample.specular_weight": float(min(sm.gloss_GU, 200.0) / 100.0),
            "sample.f0": float(COAT_F0),
            "ltc.size": int(self.static_textures()["ltc_minv"].shape[0]),
            "display.exposure": float(k),
            "display.adaptation": _gl(adapt),
            "display.xyz_offset": np.asarray(d.xyz_offset, np.float32),
            "display.xyz_to_rgb": _gl(d.xyz_to_rgb),
            "display.tone_kind": int(d.tone_kind),
            "display.tone_params": np.asarray(d.tone_params, np.float32).ravel(),
            "display.tone_lut_size": int(d.lut_texture().shape[1]),
            "display.gamut_mapping": int(d.gamut_mapping),
            "display.inv_y_span": float(d.inv_y_span),
            "display.linear": _gl(display_linear_matrix(k, adapt, d.xyz_offset, d.xyz_to_rgb, d.inv_y_span)),
            "dither.noise_size": int(self.static_textures()["blue_noise"].shape[0]),
            "dither.amplitude": 1.0 if self.dither else 0.0,
        }
        values.update(self._coating_values(vs, frame, e_1nm, c_world[0], n_world[0], illum, ems, info))
        from lbscene.engine.spectra.evaluate import cmfs_1nm

        info.update({"realised": vs["realised"], "geometry": vs["geometry"],
                     "platform_rotation_deg": vs["platform_rotation_deg"],
                     "sample_illuminance_lx": float(683.0 * e_1nm @ cmfs_1nm()[:, 1]),
                     "white_Y_cd_m2": y_white, "exposure": k,
                     "adaptation": {"method": self.adaptation,
                                    "white_xy": ([float(v) for v in white_xyz[:2] / white_xyz.sum()]
                                                 if y_white > 0 else None),
                                    "display_white_xy": [float(v) for v in d.adapted_white_xyz[:2]
                                                         / d.adapted_white_xyz.sum()]}})
        return ViewInputs(name=name, meshes=packed,
                          textures={"emitters": et, "sample_reflectance": self._sample_reflectance(e_1nm)},
                          values=values, sample_irradiance_1nm=e_1nm, sample_centre_mm=c_world[0],
                          sample_normal=n_world[0], info=info)

    def _view_meshes(self, frame: "_ViewFrame") -> dict[str, list]:
        """Every mesh placed for the view, ``[positions, normals, uv, material, band irradiance,
        triangles]``, its light computed in the frame of the lamps."""
        ir, grid = self.ir, self.ir.grid
        placement = {k: m["placement"] for k, m in self.graph["resources"]["meshes"].items()}
        meshes = {}
        for mname, (p, n, uv, mat, tris) in self._rest_geometry().items():
            mounted = placement[mname] == "platform"
            pw, nw = frame.to_world(p, n, mounted)
            if len(p):
                pl, nl = frame.to_light_frame(p, n, mounted)
                # the same receivers in the light's frame give the same light: parts that turn
                # with a platform-mounted luminaire, or fixed parts under fixed lamps, are
                # evaluated once for all views
                key = (mname, hashlib.sha256(np.ascontiguousarray(pl).tobytes()
                                             + np.ascontiguousarray(nl).tobytes()).hexdigest())
                if key not in self._irradiance_memo:
                    self._irradiance_memo[key] = _vertex_irradiance_bands(ir, self.lighting, pl, nl,
                                                                          self.indirect_cell_mm)
                irr = self._irradiance_memo[key].copy()
            else:
                irr = np.zeros((0, grid.count))
            meshes[mname] = [pw, nw, uv, mat, irr, tris]
        return meshes

    def _apply_bake(self, name: str, meshes: dict, e_1nm: np.ndarray, n_sample, info: dict) -> np.ndarray:
        """The baked levels in place of the analytic ones: the sample's bands scaled to the bake's,
        the floor's vertices given the baked floor; returns the sample's 1 nm irradiance with each
        band's level from the bake (its shape inside the band kept)."""
        from .colour_bridge import band_membership

        grid = self.ir.grid
        e_bake = self.bake.sample_irradiance_bands(name, n_sample)
        e_ana = grid.integrate(e_1nm)
        ratio = np.where(e_ana > 0, e_bake / np.where(e_ana > 0, e_ana, 1.0), 0.0)
        meshes["sample"][4] = meshes["sample"][4] * ratio[None, :]
        memb = band_membership(grid.first_centre_nm, grid.width_nm, grid.count)
        e_1nm = e_1nm * (ratio @ memb)
        floor = self.bake.floor_irradiance
        if floor is not None and "booth" in meshes:
            pw, nw = meshes["booth"][0], meshes["booth"][1]
            on_floor = (np.abs(pw[:, 2]) < 1e-6) & (nw[:, 2] > 0.99)
            vals, inside = floor.lookup(pw[on_floor])
            sel = np.nonzero(on_floor)[0][inside]
            meshes["booth"][4][sel] = vals[inside]
        info["bake"] = self.bake.describe(name)
        return e_1nm

    def _sample_reflectance(self, e_1nm: np.ndarray) -> np.ndarray:
        """The sample's reflectance per measured geometry, projected for this light: (5, G, 4)
        float32, four blocks of four bands and the aspecular angle."""
        from .colour_bridge import project_reflectance

        grid, sm = self.ir.grid, self.sample
        st = np.zeros((5, len(sm.geometries), 4), np.float32)
        for j, (asp, _, r1) in enumerate(sm.geometries):
            b = np.zeros(16)
            b[:grid.count] = project_reflectance(r1, e_1nm, grid)
            st[:4, j, :] = b.reshape(4, 4)
            st[4, j, 0] = asp
        return st

    def _exposure(self, e_1nm: np.ndarray):
        """``(white XYZ, its Y, adaptation matrix, exposure)``: a perfect white diffuser at the
        sample under this light (cd/m²), adapted to the display's white and exposed as declared."""
        from lbscene.engine.colour.adaptation import adaptation_matrix
        from lbscene.engine.spectra.evaluate import cmfs_1nm

        white_xyz = 683.0 / np.pi * (e_1nm @ cmfs_1nm())
        y_white = float(white_xyz[1])
        d = self.display
        adapt = (adaptation_matrix(white_xyz, d.adapted_white_xyz, self.adaptation)
                 if y_white > 0 else np.eye(3))
        if self.exposure == "absolute":
            k = 1.0
        else:
            k = self.white_fraction * d.white_Y_cd_m2 / y_white if y_white > 0 else 1.0
        return white_xyz, y_white, adapt, k

    def _coating_values(self, vs: dict, frame: "_ViewFrame", e_1nm, c_sample, n_sample, illum, ems,
                        info: dict) -> dict:
        """The effect coating's values (or the neutral ones every sample draw binds); its
        description goes to ``info["coating"]``."""
        from .coating import coating_inputs, flat_coating_values

        sm = self.sample
        appearance = self.coating_appearance()
        if appearance is None:
            return flat_coating_values(sm.size_mm)
        sp = self.graph["scene"]["sample_placement"]
        eye = np.asarray(self.camera.position_mm or vs["camera"]["position_mm"], float)
        # the geometry's light and the eye in the sample's frame (its normal n_sample; the
        # sample's u axis turns with the platform), for the flakes' visible share
        n_w = n_sample / np.linalg.norm(n_sample)
        u_w = np.asarray(sp.get("u_axis", [1.0, 0.0, 0.0]), float) @ frame.R.T
        u_w = u_w - n_w * (u_w @ n_w)
        u_w /= np.linalg.norm(u_w)
        basis = np.stack([u_w, np.cross(n_w, u_w), n_w])
        light_dir = basis @ ((illum - c_sample) / np.linalg.norm(illum - c_sample))
        view_dir = basis @ ((eye - c_sample) / np.linalg.norm(eye - c_sample))
        coat_values, info["coating"] = coating_inputs(
            appearance, sm, e_1nm, self.ir.grid, float(np.linalg.norm(eye - c_sample)),
            self.camera.vertical_fov_deg, light_dir, view_dir,
            [e["intensity_bands_W_sr_nm"] for e in ems], u_w)
        return coat_values

    def coating_appearance(self):
        """The sample's :class:`~lbscene.engine.coatings.model.CoatingAppearance` (None without
        ``effect_coating``), computed once per builder (fits cached on disk)."""
        if not hasattr(self, "_coating"):
            from lbscene.engine.coatings.model import coating_appearance

            self._coating = coating_appearance(self.sample, self.ir.grid)
        return self._coating

    def _illumination_centre(self) -> np.ndarray:
        from .graph import _illumination_centre

        return _illumination_centre(self.ir, self.lighting)

    # ------------------------------------------------------------------ per frame
    def camera_values(self, name: str, size: tuple[int, int]) -> dict[str, Any]:
        """view_proj and eye for a view at a viewport size."""
        vs = self._view_spec(name)
        vi = self.view(name)
        eye = np.asarray(self.camera.position_mm or vs["camera"]["position_mm"], float)
        target = np.asarray(self.camera.look_at_mm if self.camera.look_at_mm is not None
                            else vi.sample_centre_mm, float)
        dist = float(np.linalg.norm(target - eye))
        near = max(1.0, min(10.0, 0.05 * dist))
        far = dist + 4.0 * self.extent_mm
        w, h = size
        vp = perspective(self.camera.vertical_fov_deg, w / h, near, far) @ look_at(eye, target)
        return {"view.view_proj": _gl(vp), "view.eye_mm": eye.astype(np.float32),
                "_view_proj": vp}
