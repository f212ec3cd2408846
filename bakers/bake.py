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
from pathlib import Path
from typing import Callable

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


def bake_job(job: BakeJob, out_dir: Path, progress: Progress | None = None,
             save_blend: bool = True) -> dict:
    """Bake every product of ``job`` into ``out_dir`` (created); returns the manifest."""
    import bpy

    from .blender_scene import BlenderScene, band_groups

    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n = job.bands.count
    labels = job.bands.labels()
    groups = band_groups(n)
    total = len(groups) * len(job.products) + 2
    done = 0
    step = progress or (lambda d, t, what: None)
    step(done, total, "build scene")
    t0 = time.perf_counter()
    scene = BlenderScene.build(job)
    build_s = time.perf_counter() - t0
    done += 1

    noise_on = job.quality.noise_estimate
    seed_a = job.quality.seed
    seed_b = seed_a + SEED_OFFSET
    w_v = band_photopic_weights(job.bands)
    halves: dict[str, list[np.ndarray]] = {}
    counts: dict[str, list[int]] = {}
    timings = {p.id: 0.0 for p in job.products}
    for g in groups:
        scene.set_band_group(g)
        for p in job.products:
            step(done, total, f"{p.id}: bands {labels[g[0]]}…{labels[g[-1]]}")
            t0 = time.perf_counter()
            s = job.samples_for(p)
            runs = [(s // 2, seed_a), (s - s // 2, seed_b)] if noise_on else [(s, seed_a)]
            if p.id not in halves:
                halves[p.id] = [np.zeros(_shape(job, p) + (n,)) for _ in runs]
                counts[p.id] = [ns for ns, _ in runs]
            for k, part in enumerate(_render_runs(scene, p, g, runs)):
                halves[p.id][k][..., g] = part
            timings[p.id] += time.perf_counter() - t0
            done += 1

    rounds = {}
    for p in job.products:
        target = job.noise_target_for(p)
        if target is None or len(halves[p.id]) != 2:
            continue
        cap = job.max_samples_for(p)
        r = 0
        round_seeds = []
        while r < MAX_NOISE_ROUNDS:
            rel = _illuminance_noise_rms(halves[p.id], w_v)
            n_now = sum(counts[p.id])
            need = min(cap, int(math.ceil(n_now * (rel / target) ** 2 * NOISE_MARGIN)))
            if rel <= target or need - n_now < 2:
                break
            r += 1
            extra = [(need - n_now) // 2, need - n_now - (need - n_now) // 2]
            seeds = [seed_a + 2 * r * SEED_OFFSET, seed_b + 2 * r * SEED_OFFSET]
            round_seeds.append(seeds)
            new = [np.zeros_like(h) for h in halves[p.id]]
            total += len(groups)
            t0 = time.perf_counter()
            for g in groups:
                step(done, total, f"{p.id}: {need} samples for {100 * target:g} % noise "
                                  f"(now {100 * rel:.2f} %), bands {labels[g[0]]}…{labels[g[-1]]}")
                scene.set_band_group(g)
                for k, part in enumerate(_render_runs(scene, p, g, list(zip(extra, seeds)))):
                    new[k][..., g] = part
                done += 1
            for k in range(2):
                c = counts[p.id][k]
                halves[p.id][k] = (c * halves[p.id][k] + extra[k] * new[k]) / (c + extra[k])
                counts[p.id][k] = c + extra[k]
            timings[p.id] += time.perf_counter() - t0
        rounds[p.id] = {"noise_target": target, "rounds": r, "max_samples": cap,
                        "round_seeds": round_seeds}

    step(done, total, "write products")
    crash_after = int(os.environ.get(_CRASH_ENV, "-1"))
    written = 0
    products = {}
    source_hash = job.content_hash
    finals = {}
    pending_direct = []
    for p in job.products:
        parts = halves[p.id]
        if len(parts) == 2:
            ca, cb = counts[p.id]
            wa, wb = ca / (ca + cb), cb / (ca + cb)
            data = wa * parts[0] + wb * parts[1]
            noise = noise_summary(parts[0], parts[1], w_v if p.type != "environment_map" else None)
            if p.type == "environment_map":
                # what the map is used for: irradiance on the sample (normal = the map's up)
                ea, eb = (environment_irradiance(x, p.projection, p.forward, p.up, p.up) for x in parts)
                noise["sample_irradiance"] = noise_summary(ea[None, :], eb[None, :], w_v)
        else:
            data, noise = parts[0], None
        finals[p.id] = data
        image = data[None, ...] if p.type == "irradiance_points" else data
        attrs = {"lbscene:product": p.id, "lbscene:type": p.type, "lbscene:units": UNITS[p.type],
                 "lbscene:job_hash": source_hash,
                 "lbscene:band_edges_nm": ",".join(f"{e:g}" for e in job.bands.edges_nm())}
        if p.type == "environment_map":
            attrs.update({"lbscene:projection": p.projection,
                          "lbscene:forward": ",".join(f"{x:.9g}" for x in p.forward),
                          "lbscene:up": ",".join(f"{x:.9g}" for x in p.up),
                          "lbscene:position_mm": ",".join(f"{x:.9g}" for x in p.position_mm)})
        write_exr(out_dir / f"{p.id}.exr", image, labels, attrs)
        entry = {"type": p.type, "files": product_files(p), "units": UNITS[p.type],
                 "shape": list(image.shape), "channels": labels,
                 "samples": int(sum(counts[p.id])),
                 "seeds": [seed_a, seed_b] if noise_on else [seed_a],
                 "time_s": round(timings[p.id], 3), "noise": noise}
        if p.id in rounds:
            entry["adaptive_sampling"] = rounds[p.id]
        if p.type != "environment_map":
            entry["light_paths"] = p.light_paths
        if p.type == "irradiance_points":
            lux = illuminance_lx(data, job.bands)
            rel = err = None
            if len(parts) == 2:
                err = 0.5 * np.abs(parts[0] - parts[1])
                ea, eb = parts[0] @ w_v, parts[1] @ w_v
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.where(lux > 0, 0.5 * np.abs(ea - eb) / lux, 0.0)
            write_points_tables(out_dir, p, data, labels, lux, rel, err)
            entry["illuminance_lx"] = {"min": float(lux.min()), "max": float(lux.max()),
                                       "mean": float(lux.mean())}
        if p.type == "environment_map":
            e_up = environment_irradiance(data, p.projection, p.forward, p.up, p.up)
            si = {"normal": list(p.up), "from_map_W_m2_nm": [float(x) for x in e_up]}
            entry["direct_product"] = p.direct_product
            entry["sample_irradiance"] = si
            pending_direct.append((p, si, e_up))
            entry.update({"projection": p.projection, "forward": list(p.forward), "up": list(p.up),
                          "position_mm": list(p.position_mm), "geometry": p.geometry})
        if p.type == "irradiance_map":
            entry.update({"origin_mm": list(p.origin_mm), "u_axis": list(p.u_axis),
                          "v_axis": list(p.v_axis), "size_mm": list(p.size_mm),
                          "resolution": list(p.resolution)})
        products[p.id] = entry
        written += 1
        if written == crash_after:
            os._exit(70)   # simulated hard crash: no cleanup, no manifest
    # sample irradiance for the map's up normal = map integral + direct light (when baked)
    by_id = {p.id: p for p in job.products}
    for p, si, e_up in pending_direct:
        e_all = e_up
        dp = by_id.get(p.direct_product) if p.direct_product else None
        if dp is not None:
            ups = [i for i, q in enumerate(dp.points)
                   if np.allclose(q.position_mm, p.position_mm) and np.allclose(q.normal, p.up)]
            if ups:
                si["direct_W_m2_nm"] = [float(x) for x in finals[dp.id][ups[0]]]
                e_all = e_up + finals[dp.id][ups[0]]
        si["irradiance_W_m2_nm"] = [float(x) for x in e_all]
        si["illuminance_lx"] = float(e_all @ w_v)
    if save_blend:
        scene.save_blend(out_dir / "scene.blend")
    save_job(job, out_dir / "job.json")
    done += 1
    step(done, total, "done")
    files = sorted(f.name for f in out_dir.iterdir() if f.is_file() and f.name != MANIFEST_NAME)
    manifest = {
        "kind": PRODUCTS_KIND,
        "job": job.name,
        "job_hash": source_hash,
        "job_version": job.job_version,
        "source": dict(job.source),
        "bands": {"labels": labels, "edges_nm": job.bands.edges_nm(),
                  "centres_nm": job.bands.centres_nm(), "grid": job.bands.model_dump()},
        "band_groups": groups,
        "photometry": {"illuminance": "683 lm/W · Σ E_b · ∫_band V(λ)dλ, CIE 1924 photopic V(λ)",
                       "band_weights_lm_W": [round(float(x), 6) for x in w_v]},
        "quality": {**job.quality.model_dump(), "max_bounces": job.max_bounces},
        "renderer": {"engine": "Cycles", "blender": bpy.app.version_string, "device": scene.device,
                     "threads": bpy.context.scene.render.threads, "host": platform.node(),
                     "settings": "no clamping, light threshold 0, no adaptive sampling, no denoiser, "
                                 "box filter 1 px, float32 EXR, Raw view transform"},
        "products": products,
        "time_s": {"build_scene": round(build_s, 3),
                   "total": round(time.perf_counter() - t_start, 3)},
        "files": {f: _sha256(out_dir / f) for f in files},
    }
    # the manifest is written last: its presence means the folder is complete
    (out_dir / MANIFEST_NAME).write_text(json.dumps(manifest, indent=1, ensure_ascii=False) + "\n")
    return manifest
