"""The API's functions for the other commands: ``write_report``, ``export_web``, ``bake``,
``conformance``, ``export_mitsuba`` and ``export_blender``.  Bad arguments raise ``LbsceneUserError`` (located, with
its code) or ``TypeError``, never ``KeyError`` or ``AttributeError``."""

from __future__ import annotations

from pathlib import Path

import pytest

import lbscene


def test_the_new_functions_are_exported():
    names = ("write_report", "export_web", "bake", "conformance", "export_mitsuba", "export_blender")
    assert set(names) <= set(lbscene.__all__)
    for name in names:
        doc = getattr(lbscene, name).__doc__
        assert "Parameters\n    ----------" in doc and "Returns\n    -------" in doc and "Raises" in doc


@pytest.fixture
def compared(minimal_booth, tmp_path):
    m = tmp_path / "m"
    m.mkdir()
    pts = [(x, y) for x in (-300, -100, 100, 300) for y in (-200, 0, 200)]
    lux = [1000 * 0.7 / (0.49 + (x * x + y * y) / 1e6) ** 1.5 for x, y in pts]
    (m / "g.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{x},{y},{e:.4f}\n" for (x, y), e in zip(pts, lux)))
    (m / "s.yaml").write_text(f"version: 1\nkind: measurement_set\nname: api\nbooth: {minimal_booth}\n"
                              "lighting: A\ninstrument: {illuminance_meter: m, repeatability_percent: 0.5}\n"
                              "known_output_groups: [bulb]\nilluminance:\n  - path: g.csv\n")
    return lbscene.compare(m / "s.yaml", diagnose=False)


def test_write_report(compared, tmp_path):
    out = lbscene.write_report(compared, tmp_path / "r.html")
    html = out.read_text()
    assert html.startswith("<!DOCTYPE html>") and "<script" not in html.lower()
    assert "g.csv:" in html                                  # every reading is in it
    lbscene.write_report(compared, out)                      # lbscene wrote it: replaced
    mine = tmp_path / "mine.html"
    mine.write_text("mine")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.write_report(compared, mine)
    assert ei.value.diagnostics[0].code == "LB611" and mine.read_text() == "mine"
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.write_report(compared, compared.meas.path)   # an input
    assert ei.value.diagnostics[0].code == "LB612"
    with pytest.raises(TypeError):
        lbscene.write_report({"verdict": "none"}, tmp_path / "x.html")
    with pytest.raises(TypeError):
        lbscene.write_report(compared, 42)


def test_export_web_arguments(minimal_booth, tmp_path):
    with pytest.raises(TypeError):
        lbscene.export_web(minimal_booth, tmp_path / "v", lightings="A")
    with pytest.raises(TypeError):
        lbscene.export_web(minimal_booth, tmp_path / "v", size="64x48")
    with pytest.raises(TypeError):
        lbscene.export_web(minimal_booth, None)
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_web(minimal_booth, tmp_path / "v", size=(8, 8))
    assert ei.value.diagnostics[0].code == "LB500"


def test_export_blender_arguments(minimal_booth, tmp_path):
    with pytest.raises(TypeError):
        lbscene.export_blender(minimal_booth, tmp_path / "b.blend", lightings="A")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_blender(minimal_booth, tmp_path / "b.txt")
    assert ei.value.diagnostics[0].code == "LB500"
    assert ei.value.diagnostics[0].message == "--out must be a .blend file"
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_blender(minimal_booth, tmp_path / "b.blend", lightings=["D65"])
    assert ei.value.diagnostics[0].code == "LB202"
    assert not (tmp_path / "b.blend").exists()
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_web(minimal_booth, tmp_path / "v", lightings=["D65"])
    assert ei.value.diagnostics[0].code == "LB202"
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("x")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_web(minimal_booth, mine)
    assert ei.value.diagnostics[0].code == "LB700" and (mine / "notes.txt").read_text() == "x"


def test_export_web_writes_the_viewer(minimal_booth, tmp_path):
    res = lbscene.export_web(minimal_booth, tmp_path / "viewer", size=(64, 48))
    assert res["lightings"] == ["A"] and res["views"] >= 1
    assert (tmp_path / "viewer" / "index.html").is_file()
    assert Path(res["out"]) == tmp_path / "viewer"


def test_bake_arguments(minimal_booth):
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.bake(minimal_booth, quality="best")
    assert ei.value.diagnostics[0].format() == ("<arguments>: error LB500: unknown quality 'best' "
                                                "(got 'best'; expected 'preview' or 'final')")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.bake(minimal_booth, samples=1)
    assert ei.value.diagnostics[0].code == "LB500"
    with pytest.raises(TypeError):
        lbscene.bake(minimal_booth, samples="64")
    with pytest.raises(TypeError):
        lbscene.bake(minimal_booth, lighting=["A"])
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.bake(minimal_booth, lighting="D65")
    assert ei.value.diagnostics[0].code == "LB500" and "no lighting configuration 'D65'" in \
        ei.value.diagnostics[0].message
    with pytest.raises(TypeError):
        lbscene.bake(3.5)


@pytest.mark.slow
@pytest.mark.bake
def test_bake_runs_cycles(minimal_booth, tmp_path):
    pytest.importorskip("bpy")
    res = lbscene.bake(minimal_booth, samples=4, out=tmp_path / "bakes")
    assert [r.status for r in res] == ["baked"]
    assert (tmp_path / "bakes" / "A" / "manifest.json").is_file()
    assert [r.status for r in lbscene.bake(minimal_booth, samples=4, out=tmp_path / "bakes")] == ["cached"]


def test_conformance_and_export_mitsuba_arguments(minimal_booth, tmp_path):
    with pytest.raises(TypeError):
        lbscene.conformance(minimal_booth, lightings="A")
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.conformance(minimal_booth, lightings=["D65"])
    assert ei.value.diagnostics[0].code == "LB202"
    res = lbscene.conformance(minimal_booth, report=tmp_path / "c.html", grid=(3, 3))
    assert res.lightings[0].verdict == "not_applicable"      # the booth names no standard
    assert res.lightings[0].model.colorimetry.cct_K == pytest.approx(2856, abs=2)   # illuminant A
    assert (tmp_path / "c.html").read_text().startswith("<!DOCTYPE html>")
    with pytest.raises(TypeError):
        lbscene.export_mitsuba(minimal_booth, tmp_path / "s.xml", spp="many")
    with pytest.raises(TypeError):
        lbscene.export_mitsuba(minimal_booth, tmp_path / "s.xml", lighting=1)
    with pytest.raises(lbscene.LbsceneUserError) as ei:
        lbscene.export_mitsuba(minimal_booth, tmp_path / "s.txt")
    assert ei.value.diagnostics[0].code == "LB500"
