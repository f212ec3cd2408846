"""
Bake products for the realtime runtime: find them, check they belong to the
booth being rendered, and turn them into what the shaders use.

A bake folder holds ``manifest.json`` (written last by
:func:`lbscene.bakers.bake.bake_job`) and one multi-channel float32 EXR per
product (channels named by band, ``390-410nm`` …).  Used here:

* ``environment_map`` (per geometry): spectral radiance arriving at the sample
  → cosine-weighted irradiance on the sample for the view's sample normal,
  plus the light straight from the point lamps, which no camera ray of the
  map can see: the map's ``direct_product`` (irradiance points at the map's
  position for its up normal, the sample's, and 62 more normals);
* ``irradiance_map`` on the floor: band irradiance of floor vertices.

Units as the manifest states (W·sr⁻¹·m⁻²·nm⁻¹ and W·m⁻²·nm⁻¹, band means).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["FloorMap", "BakeProducts", "find_bakes", "load_bake", "environment_irradiance"]

MANIFEST = "manifest.json"


@dataclass
class FloorMap:
    """An irradiance map over a rectangle (see bakers.job.IrradianceMapProduct)."""

    data: np.ndarray          # (ny, nx, B), row 0 at the far (t = 1) edge
    origin_mm: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    size_mm: tuple[float, float]

    def lookup(self, points_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear values (k, B) at points, and which points lie on the rectangle."""
        p = np.asarray(points_mm, float) - self.origin_mm
        s = p @ self.u_axis / self.size_mm[0]
        t = p @ self.v_axis / self.size_mm[1]
        ny, nx = self.data.shape[:2]
        inside = (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
        x = np.clip(s * nx - 0.5, 0, nx - 1)
        y = np.clip((1 - t) * ny - 0.5, 0, ny - 1)
        x0 = np.clip(np.floor(x).astype(int), 0, max(nx - 2, 0))
        y0 = np.clip(np.floor(y).astype(int), 0, max(ny - 2, 0))
        x1, y1 = np.minimum(x0 + 1, nx - 1), np.minimum(y0 + 1, ny - 1)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        d = self.data
        v = ((1 - fx) * (1 - fy) * d[y0, x0] + fx * (1 - fy) * d[y0, x1]
             + (1 - fx) * fy * d[y1, x0] + fx * fy * d[y1, x1])
        return v, inside


def _vec(x) -> np.ndarray:
    if isinstance(x, str):
        x = [float(c) for c in x.split(",")]
    a = np.asarray(x, float)
    return a / np.linalg.norm(a)


def environment_irradiance(data: np.ndarray, projection: str, forward, up, normal) -> np.ndarray:
    """Σ L(ω)·max(n·ω, 0)·dΩ over an environment map (H, W, B) → irradiance (B,)."""
    from lbscene.bakers.products import cube_directions, equirect_directions

    n = np.asarray(normal, float) / np.linalg.norm(normal)
    h, w = data.shape[:2]
    if projection == "equirect":
        dirs = equirect_directions(w, forward, up)
        el = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
        domega = (2 * np.pi / w) * (np.pi / h) * np.cos(el)[:, None] * np.ones((1, w))
    elif projection == "cube":
        f = h
        dirs = cube_directions(f, forward, up)
        c = 2.0 * (np.arange(f) + 0.5) / f - 1.0
        x, y = np.meshgrid(c, c)
        face = (2.0 / f) ** 2 / (1.0 + x * x + y * y) ** 1.5
        domega = np.tile(face, (1, 6))
    else:
        raise ValueError(f"unknown projection {projection!r}")
    cos = np.clip(dirs @ n, 0.0, None)
    return np.einsum("hwb,hw->b", data.astype(float), cos * domega)


@dataclass
class BakeProducts:
    """The bake of one lighting configuration, loaded."""

    folder: Path
    manifest: dict
    env_maps: dict = field(default_factory=dict)       # geometry (or None) → (data, entry)
    direct: dict = field(default_factory=dict)         # irradiance-points id → (normals (N, 3), bands (N, B))
    floor_irradiance: FloorMap | None = None
    notes: list[str] = field(default_factory=list)

    def _env(self, view: str):
        if view in self.env_maps:
            return self.env_maps[view]
        if None in self.env_maps:
            return self.env_maps[None]
        if len(self.env_maps) == 1:
            return next(iter(self.env_maps.values()))
        raise KeyError(view)

    def has_view(self, view: str) -> bool:
        try:
            self._env(view)
            return True
        except KeyError:
            return False

    def sample_irradiance_bands(self, view: str, normal_world) -> np.ndarray:
        """Irradiance (B,) on the sample for ``normal_world``: the map's light plus the direct
        light of the point lamps (the map cannot hold it)."""
        data, e = self._env(view)
        env = environment_irradiance(data, e.get("projection", "equirect"), e.get("forward", (0, 1, 0)),
                                     e.get("up", (0, 0, 1)), normal_world)
        return env + self._direct(e, normal_world)

    def _direct(self, e: dict, normal) -> np.ndarray:
        pid = e.get("direct_product")
        if pid is None or pid not in self.direct:
            return 0.0
        normals, bands = self.direct[pid]
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        cos = normals @ n
        k = int(np.argmax(cos))
        if cos[k] > 1.0 - 1e-9:          # the map's up normal (the view's sample normal): as baked
            return bands[k]
        # another normal: the nearest baked ones, weighted by closeness (point lamps' direct light
        # varies smoothly with the normal away from their horizons)
        near = np.argsort(-cos)[:4]
        w = 1.0 / np.maximum(np.arccos(np.clip(cos[near], -1.0, 1.0)), 1e-9)
        return (w[:, None] * bands[near]).sum(axis=0) / w.sum()

    def describe(self, view: str) -> dict:
        _, e = self._env(view)
        return {"folder": str(self.folder), "environment_map": e.get("files"), "samples": e.get("samples"),
                "floor_irradiance_map": self.floor_irradiance is not None, "notes": self.notes}


#: Largest bake manifest or points file read (a final bake's manifest is a few kB).
MAX_MANIFEST_BYTES = 64 * 1024 * 1024


def load_bake(folder: Path, *, lamps_turn_with_platform: bool = False, views: int = 1) -> BakeProducts:
    """Read a bake folder (manifest + EXR products) for the runtime."""
    from lbscene.bakers.products import read_product

    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.yamlio import load_json_bounded

    folder = Path(folder)
    # bounded, with its nesting bounded too: a damaged manifest is a located error, not a traceback
    m = load_json_bounded(folder / MANIFEST, str(folder / MANIFEST), MAX_MANIFEST_BYTES)
    if not isinstance(m, dict) or not isinstance(m.get("products", {}), dict):
        raise LbsceneUserError.single("LB602", "bake manifest is not an object with products", str(folder / MANIFEST),
                                      expected="the manifest.json lbscene bake writes")
    out = BakeProducts(folder=folder, manifest=m)
    for pid, e in sorted(m.get("products", {}).items()):
        files = e.get("files") or [f"{pid}.exr"]
        exr = next((folder / f for f in files if str(f).endswith(".exr")), folder / f"{pid}.exr")
        if e.get("type") == "environment_map":
            data, _ = read_product(exr)
            out.env_maps[e.get("geometry")] = (data, e)
        elif e.get("type") == "irradiance_points" and any(
                x.get("direct_product") == pid for x in m.get("products", {}).values()):
            data, _ = read_product(exr)
            pj = folder / f"{pid}.points.json"
            meta = load_json_bounded(pj, str(pj), MAX_MANIFEST_BYTES)
            nrm = np.array([[p["nx"], p["ny"], p["nz"]] for p in meta["points"]], float)
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            out.direct[pid] = (nrm, data.reshape(len(nrm), -1).astype(float))
        elif e.get("type") == "irradiance_map":
            u, v = _vec(e["u_axis"]), _vec(e["v_axis"])
            floorish = "floor" in pid.lower() or (abs(float(e["origin_mm"][2])) < 1e-6 and np.cross(u, v)[2] > 0.99)
            if not floorish or out.floor_irradiance is not None:
                continue
            if lamps_turn_with_platform and views > 1:
                out.notes.append(f"{pid}: floor map not used (the luminaire turns with the platform)")
                continue
            data, _ = read_product(exr)
            out.floor_irradiance = FloorMap(data.astype(float), np.asarray(e["origin_mm"], float), u, v,
                                            tuple(float(x) for x in e["size_mm"]))
    return out


def find_bakes(search_dirs, ir, lighting: str) -> tuple[Path | None, str]:
    """The newest complete bake folder for ``(ir, lighting)`` under ``search_dirs``.

    Returns ``(folder, '')`` or ``(None, reason)``; a bake of another IR (stale) is
    reported as such.
    """
    stale = []
    seen = []
    for d in search_dirs:
        d = Path(d)
        if not d.is_dir():
            continue
        cands = [d / MANIFEST] if (d / MANIFEST).is_file() else []
        cands += sorted(d.glob(f"**/{MANIFEST}"))
        from lbscene.engine.files.diagnostics import LbsceneUserError
        from lbscene.engine.files.yamlio import load_json_bounded

        for mf in cands:
            try:
                m = load_json_bounded(mf, str(mf), MAX_MANIFEST_BYTES, is_input=False)
            except LbsceneUserError:       # unreadable, too large, not JSON, nested too deeply
                continue
            if not isinstance(m, dict) or "products" not in m or "job_hash" not in m:
                continue
            src = m.get("source", {})
            if src.get("lighting") not in (None, lighting):
                continue
            if not any(p.get("type") == "environment_map" for p in m["products"].values()):
                continue
            if src.get("ir_hash") not in (None, ir.content_hash):
                stale.append(mf.parent)
                continue
            seen.append(mf.parent)
    if seen:
        return max(seen, key=lambda p: (p / MANIFEST).stat().st_mtime), ""
    if stale:
        return None, f"bake products in {stale[0]} are stale (made for another version of the booth)"
    return None, "no bake products found"
