"""The documentation: generated reference pages cover every schema field and CLI option, the
committed files carry no machine paths, hints name options that exist."""

from __future__ import annotations

import importlib.util
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def gen_docs():
    spec = importlib.util.spec_from_file_location("gen_docs", REPO / "scripts" / "gen_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _sections(page: str) -> dict[str, str]:
    parts = re.split(r"^### (\w+) \{#\w+\}$", page, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def test_file_reference_has_every_model_and_field(gen_docs):
    import importlib

    page = gen_docs.files_page()
    sections = _sections(page)
    for _, module, cls, _ in gen_docs.DOCUMENTS:
        for model in gen_docs.collect(getattr(importlib.import_module(module), cls)):
            assert model.__name__ in sections, f"no section for {model.__name__}"
            for name, f in model.model_fields.items():
                assert f"| `{f.alias or name}` |" in sections[model.__name__], f"{model.__name__}.{name}"


def test_file_reference_units_defaults_and_validated_examples(gen_docs):
    sections = _sections(gen_docs.files_page())
    lamp = sections["Lamp"]
    assert "| `position_mm` | [number, number, number] | mm | **required** |" in lamp
    assert "| `width_px` | integer | px | `1024` | ≥ `16`, ≤ `8192` |" in sections["RenderOutput"]
    assert "Example (from `booths/" in lamp
    # the render configuration documents the adaptation choice, with its default
    assert "| `adaptation` | one of `cat16`, `none` |  | `cat16` |" in sections["RenderConfig"]
    assert "`F32T8/TL841 (Triphosphor)`" in gen_docs.named_spectra()[-2]


def test_cli_reference_has_every_command_and_option(gen_docs):
    import typer

    from lbscene.cli import app

    page = gen_docs.cli_page()
    root = typer.main.get_command(app)
    for name, cmd in root.commands.items():
        assert f"## lbscene {name} " in page
        for p in cmd.params:
            for opt in getattr(p, "opts", []):
                if opt.startswith("-"):
                    assert f"`{opt}`" in page, f"{name} {opt}"
    assert "| `--adaptation` | one of `cat16`, `none` |" in page


def test_no_machine_paths_in_committed_files():
    files = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                           check=True).stdout.split()
    pattern = re.compile("/" + "work/|/" + "root/|/" + "tmp/briefs")
    bad = []
    for f in files:
        p = REPO / f
        if p.suffix in (".png", ".exr", ".npy", ".obj") or not p.is_file():
            continue
        try:
            text = p.read_text()
        except UnicodeDecodeError:
            continue
        bad += [f"{f}:{i}" for i, line in enumerate(text.splitlines(), 1) if pattern.search(line)]
    assert not bad, bad


def test_unknown_light_source_hint_names_real_choices():
    from pydantic import TypeAdapter

    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.spectra.evaluate import evaluate_spectrum
    from lbscene.schemas.spectrum import SpectrumSpec

    spec = TypeAdapter(SpectrumSpec).validate_python({"type": "light_source", "name": "F32T8/TL84 (Triphosphor)"})
    with pytest.raises(LbsceneUserError) as exc:
        evaluate_spectrum(spec, display="booth.yaml:3:4")
    assert exc.value.diagnostics[0].format() == (
        "booth.yaml:3:4: error LB204: unknown light source 'F32T8/TL84 (Triphosphor)' "
        "(expected a name in colour.SDS_LIGHT_SOURCES)\n"
        "    hint: did you mean 'F32T8/TL841 (Triphosphor)', 'F32T8/TL850 (Triphosphor)', "
        "'F32T8/TL835 (Triphosphor)'? Every name is listed in the documentation's file reference "
        "(Named spectra).")


def test_readme_points_at_the_docs_and_contributing():
    readme = (REPO / "README.md").read_text()
    assert "make docs" in readme and "CONTRIBUTING.md" in readme
    assert not (REPO / "docs" / "HELPERS.md").exists()
