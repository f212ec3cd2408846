"""Instrument exports read through colour-science (IES TM-27-14, X-Rite, Sekonic, UPRtek).

The sample files are colour-science's own test resources.  Expected values are read from
the files' text directly (not through colour-science or lbscene): the 1 nm spectrum must
pass through every sample the instrument reported that falls on the 1 nm grid, and between
samples stay within their range (linear interpolation).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.files.diagnostics import LbsceneUserError
from lbscene.engine.spectra.evaluate import evaluate_spectrum
from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL
from lbscene.schemas.spectrum import InstrumentFileSpectrum

colour = pytest.importorskip("colour")
RES = Path(colour.__file__).parent / "io" / "tests" / "resources"


def spdx_samples(path: Path) -> dict[float, float]:
    text = path.read_text()
    return {float(w): float(v) for w, v in
            re.findall(r'<SpectralData wavelength="([0-9.]+)">([0-9.eE+-]+)</SpectralData>', text)}


def read(tmp_path, fmt, filename, kind="emission", **kw):
    shutil.copy(RES / filename, tmp_path / filename)
    spec = InstrumentFileSpectrum(type="instrument_file", format=fmt, path=filename, **kw)
    return evaluate_spectrum(spec, lambda p: tmp_path / p, kind, display=filename)


def test_ies_tm27_14_passes_through_the_file_samples(tmp_path):
    got = read(tmp_path, "ies_tm27_14", "Fluorescent.spdx")
    samples = spdx_samples(RES / "Fluorescent.spdx")
    on_grid = {w: v for w, v in samples.items() if float(w).is_integer() and 360 <= w <= 830}
    assert len(on_grid) >= 5
    for w, v in on_grid.items():
        assert got[int(w) - 360] == pytest.approx(v, rel=1e-9, abs=1e-12)
    lo, hi = min(samples), max(samples)
    inside = (WL >= lo) & (WL <= hi)
    assert got[inside].max() <= max(samples.values()) + 1e-12


@pytest.mark.parametrize("fmt,name", [("sekonic", "RANDOM_001_02._3262K.csv"),
                                      ("uprtek", "uprtek.xls.txt")])
def test_spectroradiometer_exports_cover_the_visible(tmp_path, fmt, name):
    got = read(tmp_path, fmt, name)
    vis = (WL >= 400) & (WL <= 700)
    assert np.all(np.isfinite(got)) and np.all(got[vis] > 0)
    # both files are lamps of a few thousand kelvin: more red than blue
    assert got[(WL >= 600) & (WL <= 650)].mean() > got[(WL >= 420) & (WL <= 470)].mean()


def test_xrite_file_gives_a_named_reflectance(tmp_path):
    got = read(tmp_path, "xrite", "X-Rite_Digital_Colour_Checker.txt", kind="reflectance", name="X1")
    assert 0.0 <= got[(WL >= 400) & (WL <= 700)].min() and got.max() <= 1.0


def test_unknown_spectrum_name_is_a_user_error(tmp_path):
    with pytest.raises(LbsceneUserError) as e:
        read(tmp_path, "xrite", "X-Rite_Digital_Colour_Checker.txt", kind="reflectance", name="nope")
    d = e.value.diagnostics[0]
    assert d.code == "LB202" and d.message == "no spectrum named 'nope' in the file"


def test_broken_file_is_a_located_user_error(tmp_path):
    (tmp_path / "bad.spdx").write_text("this is not XML")
    spec = InstrumentFileSpectrum(type="instrument_file", format="ies_tm27_14", path="bad.spdx")
    with pytest.raises(LbsceneUserError) as e:
        evaluate_spectrum(spec, lambda p: tmp_path / p, "emission", display="bad.spdx")
    d = e.value.diagnostics[0]
    assert d.code == "LB203" and d.message.startswith("cannot read ies_tm27_14 file:")
