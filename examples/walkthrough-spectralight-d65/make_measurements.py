"""Regenerate this walkthrough's measurements (synthetic, so the answer is known).

The "booth" measured here is the shipped X-Rite SpectraLight QC model with every
effect its booth file enables, plus one it does not: the illuminance meter's
cosine response is cos^1.2 instead of an ideal cosine (a common fault of cheap
meters, which under-read light arriving obliquely).  The readings come from
lbscene's brute-force Monte Carlo reference engine, not from the forward model
that ``lbscene compare`` fits, with 1 % meter noise; the white tile is measured
with 1 % spectral noise.

Run from the repository root::

    .venv/bin/python examples/walkthrough-spectralight-d65/make_measurements.py
"""

from __future__ import annotations

from pathlib import Path

from lbscene.engine.scene.compile import compile_booth, find_booth_file
from lbscene.engine.truth.synthetic import synthesize

HERE = Path(__file__).resolve().parent
BOOTH = HERE.parents[1] / "booths" / "xrite-spectralight-qc"
HIDDEN = {"detector_cosine_error": {"exponent": 1.2}}


def main() -> None:
    ir = compile_booth(find_booth_file(BOOTH))
    truth = {**{k: dict(v) for k, v in ir.effects.items()}, **HIDDEN}
    synthesize(BOOTH, HERE, lighting="D65", truth_effects=truth, noise_percent=1.0, seed=2026,
               name="SpectraLight QC, D65, A3 grid (synthetic: the meter has a cosine error)")
    print(f"wrote {HERE / 'measurements.yaml'}")


if __name__ == "__main__":
    main()
