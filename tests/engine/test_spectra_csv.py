"""Spectrum CSV files: any sampling accepted, bad data located."""

import pytest

from lbscene.engine.files.diagnostics import LbsceneUserError
from lbscene.engine.spectra.evaluate import read_spectrum_csv
from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM


def _csv(tmp_path, text):
    p = tmp_path / "s.csv"
    p.write_text(text)
    return p


def test_irregular_sampling_interpolated_and_reflectance_held_at_ends(tmp_path):
    p = _csv(tmp_path, "# comment\nwavelength_nm,reflectance\n400,0.1\n455,0.65\n700,0.9\n")
    v = read_spectrum_csv(p, "s.csv", kind="reflectance")
    assert v[REFERENCE_WAVELENGTHS_NM == 430][0] == pytest.approx(0.1 + 0.55 * 30 / 55)
    assert v[0] == pytest.approx(0.1) and v[-1] == pytest.approx(0.9)
    e = read_spectrum_csv(p, "s.csv", kind="emission")
    assert e[0] == 0.0 and e[-1] == 0.0


@pytest.mark.parametrize("text,code,line,col", [
    ("wl,reflectance\n400,0.1\n", "LB400", 1, 1),
    ("wavelength_nm,reflectance\n400,0.1\n410,nan\n", "LB401", 3, 5),
    ("wavelength_nm,reflectance\n400,0.1\n410,-0.2\n", "LB402", 3, 5),
    ("wavelength_nm,reflectance\n400,0.1\n390,0.2\n", "LB405", 3, 1),
    ("wavelength_nm,reflectance\n400,0.1\n", "LB407", 1, 1),
    ("wavelength_nm,a,b\n400,0.1,0.2\n", "LB400", 1, 1),
])
def test_bad_csv_located(tmp_path, text, code, line, col):
    with pytest.raises(LbsceneUserError) as exc:
        read_spectrum_csv(_csv(tmp_path, text), "s.csv", kind="reflectance")
    d = exc.value.diagnostics[0]
    assert (d.code, d.location.line, d.location.column) == (code, line, col)
