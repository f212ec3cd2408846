"""Measure diffuser plates in Mitsuba 3: directional-hemispherical T(θ) and R(θ).

Each plate is declared as a booth declares it (``diffuser:`` fields: ``ior``, ``thickness_mm``,
``scattering`` and, for an opal plate, its datasheet total transmittance); Mitsuba builds it as
the truth provider renders it in a booth (:func:`lbscene.engine.truth.mitsuba.plate_bsdf`; an opal
plate's scattering medium from :func:`lbscene.engine.truth.mitsuba.opal_medium`) and measures it by
reciprocity (:func:`lbscene.engine.truth.mitsuba.plate_optics`).  Writes ``<plate>.csv`` beside this
script: ``theta_deg, T, T_se, R, R_se`` with the plate's declaration in the header.

``tests/engine/test_plate_optics.py`` compares the forward model's plate laws with these values.

Run (a few minutes; opal plates are the slow ones)::

    nice -n 10 .venv/bin/python tests/data/validation/plate-optics/measure_plates.py [PLATE ...]
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: the plates: booth ``diffuser:`` declarations (thickness, ior, scattering, total transmittance)
PLATES = {
    "rough-a030": {"thickness_mm": 3.0, "ior": 1.49, "transmittance": None,
                   "scattering": {"type": "roughness", "roughness": 0.5477}},
    "rough-r030": {"thickness_mm": 3.0, "ior": 1.49, "transmittance": None,
                   "scattering": {"type": "roughness", "roughness": 0.3}},
    "opal-t055": {"thickness_mm": 3.0, "ior": 1.49, "transmittance": 0.55,
                  "scattering": {"type": "lambertian", "diffuse_fraction": 0.95}},
    "opal-t040": {"thickness_mm": 2.0, "ior": 1.5, "transmittance": 0.40,
                  "scattering": {"type": "lambertian", "diffuse_fraction": 0.97}},
    "opal-t070": {"thickness_mm": 4.0, "ior": 1.52, "transmittance": 0.70,
                  "scattering": {"type": "lambertian", "diffuse_fraction": 0.85}},
    # faces matched to the air (ior 1): the plates of the opal booth scenes (opal-black, opal-grey)
    "opal-n100-t055": {"thickness_mm": 3.0, "ior": 1.0, "transmittance": 0.55,
                       "scattering": {"type": "lambertian", "diffuse_fraction": 0.95}},
    "opal-n100-t065": {"thickness_mm": 2.0, "ior": 1.0, "transmittance": 0.65,
                       "scattering": {"type": "lambertian", "diffuse_fraction": 0.90}},
}
THETA_DEG = (0.0, 20.0, 40.0, 50.0, 60.0, 70.0, 80.0)
SPP = 16384
PASSES = 6

__all__ = ["PLATES", "THETA_DEG", "measure", "read", "main"]


def measure(name: str, *, spp: int = SPP, passes: int = PASSES) -> dict:
    from lbscene.engine.truth.mitsuba import _normalised_optics, opal_medium, plate_bsdf

    d = PLATES[name]
    medium = None
    if d["scattering"]["type"] == "lambertian":
        # Mitsuba's own bisection (the plates stay independent of the model's layer solution)
        medium = opal_medium(d["transmittance"], d["scattering"]["diffuse_fraction"], d["ior"], d["thickness_mm"],
                             asymmetry="bisection")
    mu = np.cos(np.deg2rad(THETA_DEG))
    res = _normalised_optics(plate_bsdf(d["scattering"], d["ior"]), d["thickness_mm"], mu, medium=medium,
                             spp=spp, passes=passes)
    return {"theta_deg": np.asarray(THETA_DEG), **res, "medium": medium}


def path(name: str) -> Path:
    return HERE / f"{name}.csv"


def write(name: str, res: dict) -> None:
    from lbscene.engine.truth.mitsuba import mitsuba_version

    lines = [f"# plate: {name}", f"# declaration: {json.dumps(PLATES[name], sort_keys=True)}",
             f"# mitsuba_medium: {json.dumps(res['medium'], sort_keys=True)}",
             f"# mitsuba_version: {mitsuba_version()}",
             f"# measurement: lbscene.engine.truth.mitsuba.plate_optics, {SPP} spp x {PASSES} passes",
             f"# date: {_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ')}",
             "theta_deg,T,T_se,R,R_se"]
    for k in range(len(res["theta_deg"])):
        lines.append(f"{res['theta_deg'][k]:g},{res['T'][k]:.6f},{res['T_se'][k]:.6f},"
                     f"{res['R'][k]:.6f},{res['R_se'][k]:.6f}")
    path(name).write_text("\n".join(lines) + "\n")


def read(name: str) -> dict:
    meta, rows = {}, []
    for line in path(name).read_text().splitlines():
        if line.startswith("#"):
            k, _, v = line[1:].partition(":")
            meta[k.strip()] = v.strip()
        elif line and not line.startswith("theta"):
            rows.append([float(x) for x in line.split(",")])
    a = np.asarray(rows)
    return {"theta_deg": a[:, 0], "T": a[:, 1], "T_se": a[:, 2], "R": a[:, 3], "R_se": a[:, 4], "meta": meta}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plates", nargs="*", metavar="PLATE", help=f"default all: {', '.join(PLATES)}")
    args = ap.parse_args(argv)
    for name in args.plates or list(PLATES):
        res = measure(name)
        write(name, res)
        print(name, " ".join(f"{t:g}°: T {a:.4f} R {b:.4f}" for t, a, b in zip(res["theta_deg"], res["T"], res["R"])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
