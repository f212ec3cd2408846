"""
Run one bake job in this process (needs ``bpy``) and write its products.

The executor (:mod:`lbscene.bakers.executor`) calls this through
``python -m lbscene.bakers.run_job`` in a subprocess, which also makes the
output atomic; call :func:`bake_job` directly only into a folder you own.

Per band group (6 passes for 16 bands) every product is rendered twice with
half the samples and two seeds; the product is the mean and the halves'
difference estimates its noise (:func:`lbscene.bakers.products.noise_summary`).
The seeds are the same for every band group, so the noise of neighbouring
bands is correlated (less colour noise) while the two halves are independent.

Irradiance-points products with a noise target (the ``final`` preset: 1 %
RMS illuminance noise) then sample on in rounds — more samples for both
halves, new seeds, sample-weighted means — until the two-half estimate
meets the target or the preset's sample cap; the manifest gives the samples
used and the rounds.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .job import BakeJob, save_job
from .products import (UNITS, band_photopic_weights, environment_irradiance, illuminance_lx,
                       noise_summary, write_exr, write_points_tables)

__all__ = ["bake_job", "MANIFEST_NAME", "PRODUCTS_KIND", "SEED_OFFSET", "product_files"]

MANIFEST_NAME = "manifest.json"
PRODUCTS_KIND = "lbscene.bake_products"
#: second half-render seed = seed + SEED_OFFSET
SEED_OFFSET = 7919
#: adaptive sampling of points products stops after this many extra rounds
MAX_NOISE_ROUNDS = 3
#: extra rounds aim this much below the target (the two-half estimate is itself noisy)
NOISE_MARGIN = 1.2
#: test hook: hard-exit after writing this many product files (simulates a crash)
_CRASH_ENV = "LBSCENE_BAKE_CRASH_AFTER_PRODUCTS"

Progress = Callable[[int, int, str], None]


def product_files(product) -> list[str]:
    """Files a product writes into the job's output folder."""
    files = [f"{product.id}.exr"]
    if product.type == "irradiance_points":
        files += [f"{product.id}.points.json", f"{product.id}.points.csv"]
    return files


def _shape(job: BakeJob, p) -> tuple[int, ...]:
    if p.type == "irradiance_points":
        return (len(p.points),)
    if p.type == "irradiance_map":
        return (p.resolution[1], p.resolution[0])
    if p.projection == "equirect":
        return (p.width_px // 2, p.width_px)
    return (p.width_px, 6 * p.width_px)


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _illuminance_noise_rms(parts: list[np.ndarray], w_v: np.ndarray) -> float:
    """RMS over points of the relative two-half noise of their illuminance."""
    ea, eb = parts[0] @ w_v, parts[1] @ w_v
    y = 0.5 * (ea + eb)
    ok = y > 0
    if not ok.any():
        return 0.0
    return float(np.sqrt(np.mean((0.5 * np.abs(ea - eb)[ok] / y[ok]) ** 2)))


def _render_runs(scene, p, g, runs) -> list[np.ndarray]:
    """Product ``p`` in the current band group ``g``, once per ``(samples, seed)`` run, with the
    product's group transforms applied (and always reset)."""
    scene.apply_group_transforms(p.group_transforms)
    try:
        out = []
        for ns, seed in runs:
            if p.type == "environment_map":
                rgb = scene.render_environment(p, ns, seed)
            else:
                rgb = scene.bake_irradiance(p, ns, seed)
            out.append(rgb[..., : len(g)])
        return out
    finally:
        scene.reset_group_transforms()


class _Steps:
    """Progress of a bake: ``done`` of ``total`` steps, reported through ``progress``."""

    def __init__(self, total: int, progress: Progress | None):
        self.done, self.total = 0, total
        self._report = progress or (lambda d, t, what: None)

    def __call__(self, what: str) -> None:
        self._report(self.done, self.total, what)


@dataclass
class _Bake:
    """A bake in progress: the job, its Blender scene and what has been rendered so far.

    ``halves``: per product, its parts (two halves with independent seeds when the job
    estimates noise, else one), each ``shape + (bands,)``; ``counts`` their samples;
    ``timings`` the seconds spent per product; ``rounds`` the adaptive-sampling record.
    """

    job: BakeJob
    out_dir: Path
    scene: Any
    steps: _Steps
    groups: list
    labels: list[str]
    w_v: np.ndarray
    halves: dict[str, list[np.ndarray]] = field(default_factory=dict)
    counts: dict[str, list[int]] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    rounds: dict[str, dict] = field(default_factory=dict)
    #: an environment map's irradiance on the sample from the map alone (its up normal)
    from_map: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def seeds(self) -> tuple[int, int]:
        a = self.job.quality.seed
        return a, a + SEED_OFFSET

    def render_all(self) -> None:
        """Every product in every band group, at the job's sample counts."""
        job, n = self.job, self.job.bands.count
        seed_a, seed_b = self.seeds
        self.timings = {p.id: 0.0 for p in job.products}
        for g in self.groups:
            self.scene.set_band_group(g)
            for p in job.products:
                self.steps(f"{p.id}: bands {self.labels[g[0]]}…{self.labels[g[-1]]}")
                t0 = time.perf_counter()
                s = job.samples_for(p)
                runs = [(s // 2, seed_a), (s - s // 2, seed_b)] if job.quality.noise_estimate else [(s, seed_a)]
                if p.id not in self.halves:
                    self.halves[p.id] = [np.zeros(_shape(job, p) + (n,)) for _ in runs]
                    self.counts[p.id] = [ns for ns, _ in runs]
                for k, part in enumerate(_render_runs(self.scene, p, g, runs)):
                    self.halves[p.id][k][..., g] = part
                self.timings[p.id] += time.perf_counter() - t0
                self.steps.done += 1

    def refine(self, p) -> None:
        """Adaptive sampling of product ``p``: more samples, in rounds, until the noise of its
        illuminance (from the two halves) meets its target or its sample cap."""
        job = self.job
        target = job.noise_target_for(p)
        if target is None or len(self.halves[p.id]) != 2:
            return
        seed_a, seed_b = self.seeds
        cap = job.max_samples_for(p)
        r = 0
        round_seeds = []
        while r < MAX_NOISE_ROUNDS:
            rel = _illuminance_noise_rms(self.halves[p.id], self.w_v)
            n_now = sum(self.counts[p.id])
            need = min(cap, int(math.ceil(n_now * (rel / target) ** 2 * NOISE_MARGIN)))
            if rel <= target or need - n_now < 2:
                break
            r += 1
            extra = [(need - n_now) // 2, need - n_now - (need - n_now) // 2]
            seeds = [seed_a + 2 * r * SEED_OFFSET, seed_b + 2 * r * SEED_OFFSET]
            round_seeds.append(seeds)
            new = [np.zeros_like(h) for h in self.halves[p.id]]
            self.steps.total += len(self.groups)
            t0 = time.perf_counter()
            for g in self.groups:
                self.steps(f"{p.id}: {need} samples for {100 * target:g} % noise "
                           f"(now {100 * rel:.2f} %), bands {self.labels[g[0]]}…{self.labels[g[-1]]}")
                self.scene.set_band_group(g)
                for k, part in enumerate(_render_runs(self.scene, p, g, list(zip(extra, seeds)))):
                    new[k][..., g] = part
                self.steps.done += 1
            for k in range(2):
                c = self.counts[p.id][k]
                self.halves[p.id][k] = (c * self.halves[p.id][k] + extra[k] * new[k]) / (c + extra[k])
                self.counts[p.id][k] = c + extra[k]
            self.timings[p.id] += time.perf_counter() - t0
        self.rounds[p.id] = {"noise_target": target, "rounds": r, "max_samples": cap,
                             "round_seeds": round_seeds}

    def _combined(self, p) -> tuple[np.ndarray, dict | None]:
        """Product ``p``'s data (its parts weighted by their samples) and its noise summary."""
        parts = self.halves[p.id]
        if len(parts) != 2:
            return parts[0], None
        ca, cb = self.counts[p.id]
        wa, wb = ca / (ca + cb), cb / (ca + cb)
        data = wa * parts[0] + wb * parts[1]
        w_v = self.w_v
        noise = noise_summary(parts[0], parts[1], w_v if p.type != "environment_map" else None)
        if p.type == "environment_map":
            # what the map is used for: irradiance on the sample (normal = the map's up)
            ea, eb = (environment_irradiance(x, p.projection, p.forward, p.up, p.up) for x in parts)
            noise["sample_irradiance"] = noise_summary(ea[None, :], eb[None, :], w_v)
        return data, noise

    def write_product(self, p, data: np.ndarray, noise: dict | None) -> dict:
        """Write product ``p``'s files (EXR; points also as JSON and CSV); its manifest entry."""
        job, labels, parts = self.job, self.labels, self.halves[p.id]
        image = data[None, ...] if p.type == "irradiance_points" else data
        attrs = {"lbscene:product": p.id, "lbscene:type": p.type, "lbscene:units": UNITS[p.type],
                 "lbscene:job_hash": job.content_hash,
                 "lbscene:band_edges_nm": ",".join(f"{e:g}" for e in job.bands.edges_nm())}
        if p.type == "environment_map":
            attrs.update({"lbscene:projection": p.projection,
                          "lbscene:forward": ",".join(f"{x:.9g}" for x in p.forward),
                          "lbscene:up": ",".join(f"{x:.9g}" for x in p.up),
                          "lbscene:position_mm": ",".join(f"{x:.9g}" for x in p.position_mm)})
        write_exr(self.out_dir / f"{p.id}.exr", image, labels, attrs)
        seed_a, seed_b = self.seeds
        entry = {"type": p.type, "files": product_files(p), "units": UNITS[p.type],
                 "shape": list(image.shape), "channels": labels,
                 "samples": int(sum(self.counts[p.id])),
                 "seeds": [seed_a, seed_b] if job.quality.noise_estimate else [seed_a],
                 "time_s": round(self.timings[p.id], 3), "noise": noise}
        if p.id in self.rounds:
            entry["adaptive_sampling"] = self.rounds[p.id]
        if p.type != "environment_map":
            entry["light_paths"] = p.light_paths
        if p.type == "irradiance_points":
            lux = illuminance_lx(data, job.bands)
            rel = err = None
            if len(parts) == 2:
                err = 0.5 * np.abs(parts[0] - parts[1])
                ea, eb = parts[0] @ self.w_v, parts[1] @ self.w_v
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.where(lux > 0, 0.5 * np.abs(ea - eb) / lux, 0.0)
            write_points_tables(self.out_dir, p, data, labels, lux, rel, err)
            entry["illuminance_lx"] = {"min": float(lux.min()), "max": float(lux.max()),
                                       "mean": float(lux.mean())}
        if p.type == "environment_map":
            e_up = self.from_map[p.id] = environment_irradiance(data, p.projection, p.forward, p.up, p.up)
            entry["direct_product"] = p.direct_product
            entry["sample_irradiance"] = {"normal": list(p.up), "from_map_W_m2_nm": [float(x) for x in e_up]}
            entry.update({"projection": p.projection, "forward": list(p.forward), "up": list(p.up),
                          "position_mm": list(p.position_mm), "geometry": p.geometry})
        if p.type == "irradiance_map":
            entry.update({"origin_mm": list(p.origin_mm), "u_axis": list(p.u_axis),
                          "v_axis": list(p.v_axis), "size_mm": list(p.size_mm),
                          "resolution": list(p.resolution)})
        return entry

    def write_products(self) -> dict[str, dict]:
        """Write every product; their manifest entries (an environment map's with the sample's
        irradiance: the map's integral plus the direct light of its points product, if baked)."""
        crash_after = int(os.environ.get(_CRASH_ENV, "-1"))
        products, finals = {}, {}
        for written, p in enumerate(self.job.products, start=1):
            data, noise = self._combined(p)
            finals[p.id] = data
            products[p.id] = self.write_product(p, data, noise)
            if written == crash_after:
                os._exit(70)   # simulated hard crash: no cleanup, no manifest
        # sample irradiance for the map's up normal = map integral + direct light (when baked)
        by_id = {p.id: p for p in self.job.products}
        for p in self.job.products:
            if p.type != "environment_map":
                continue
            si = products[p.id]["sample_irradiance"]
            e_all = e_up = self.from_map[p.id]
            dp = by_id.get(p.direct_product) if p.direct_product else None
            if dp is not None:
                ups = [i for i, q in enumerate(dp.points)
                       if np.allclose(q.position_mm, p.position_mm) and np.allclose(q.normal, p.up)]
                if ups:
                    si["direct_W_m2_nm"] = [float(x) for x in finals[dp.id][ups[0]]]
                    e_all = e_up + finals[dp.id][ups[0]]
            si["irradiance_W_m2_nm"] = [float(x) for x in e_all]
            si["illuminance_lx"] = float(e_all @ self.w_v)
            rel = self._sample_noise_relative(p, dp, ups[0] if dp is not None and ups else None)
            if rel is not None:
                si["illuminance_noise_relative"] = rel
        return products

    def _sample_noise_relative(self, p, dp, up: int | None) -> float | None:
        """Two-half noise of an environment map's sample illuminance (map + direct light):
        ``|E_a − E_b| / (E_a + E_b)`` with each half the map's integral plus the direct product's
        point; None without two halves."""
        parts = self.halves[p.id]
        if len(parts) != 2:
            return None
        e = [environment_irradiance(x, p.projection, p.forward, p.up, p.up) @ self.w_v for x in parts]
        if up is not None:
            d = self.halves[dp.id]
            if len(d) != 2:
                return None
            e = [e[k] + float(d[k][up] @ self.w_v) for k in range(2)]
        total = e[0] + e[1]
        return float(abs(e[0] - e[1]) / total) if total > 0 else 0.0

    def manifest(self, products: dict, renderer: dict, build_s: float, t_start: float) -> dict:
        """The bake folder's manifest: the job, bands, photometry, quality, renderer, products,
        timings and the sha256 of every file."""
        job, out_dir = self.job, self.out_dir
        files = sorted(f.name for f in out_dir.iterdir() if f.is_file() and f.name != MANIFEST_NAME)
        return {
            "kind": PRODUCTS_KIND,
            "job": job.name,
            "job_hash": job.content_hash,
            "job_version": job.job_version,
            "source": dict(job.source),
            "bands": {"labels": self.labels, "edges_nm": job.bands.edges_nm(),
                      "centres_nm": job.bands.centres_nm(), "grid": job.bands.model_dump()},
            "band_groups": self.groups,
            "photometry": {"illuminance": "683 lm/W · Σ E_b · ∫_band V(λ)dλ, CIE 1924 photopic V(λ)",
                           "band_weights_lm_W": [round(float(x), 6) for x in self.w_v]},
            "quality": {**job.quality.model_dump(), "max_bounces": job.max_bounces},
            "renderer": renderer,
            "products": products,
            "time_s": {"build_scene": round(build_s, 3),
                       "total": round(time.perf_counter() - t_start, 3)},
            "files": {f: _sha256(out_dir / f) for f in files},
        }


def bake_job(job: BakeJob, out_dir: Path, progress: Progress | None = None,
             save_blend: bool = True) -> dict:
    """Bake every product of ``job`` into ``out_dir`` (created); returns the manifest."""
    import bpy

    from .blender_scene import BlenderScene, band_groups

    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    groups = band_groups(job.bands.count)
    steps = _Steps(len(groups) * len(job.products) + 2, progress)
    steps("build scene")
    t0 = time.perf_counter()
    scene = BlenderScene.build(job)
    build_s = time.perf_counter() - t0
    steps.done += 1

    bake = _Bake(job, out_dir, scene, steps, groups, job.bands.labels(), band_photopic_weights(job.bands))
    bake.render_all()
    for p in job.products:
        bake.refine(p)
    steps("write products")
    products = bake.write_products()
    if save_blend:
        scene.save_blend(out_dir / "scene.blend")
    save_job(job, out_dir / "job.json")
    steps.done += 1
    steps("done")
    renderer = {"engine": "Cycles", "blender": bpy.app.version_string, "device": scene.device,
                "threads": bpy.context.scene.render.threads, "host": platform.node(),
                "settings": "no clamping, light threshold 0, no adaptive sampling, no denoiser, "
                            "box filter 1 px, float32 EXR, Raw view transform"}
    manifest = bake.manifest(products, renderer, build_s, t_start)
    # the manifest is written last: its presence means the folder is complete
    (out_dir / MANIFEST_NAME).write_text(json.dumps(manifest, indent=1, ensure_ascii=False) + "\n")
    return manifest
