"""The committed JSON Schema files are what the models export (regenerate: `make schemas`)."""

import json

import pytest

from lbscene.schemas.export import JSON_DIR, render_all


def test_committed_json_schemas_are_current():
    rendered = render_all()
    assert rendered, "no document kinds exported"
    stale = [name for name, text in rendered.items()
             if not (JSON_DIR / name).exists() or (JSON_DIR / name).read_text() != text]
    assert not stale, f"stale JSON Schema files (run `make schemas`): {stale}"


def test_booth_schema_lists_every_registered_effect():
    from lbscene.engine.light.effects.registry import available_effects

    schema = json.loads((JSON_DIR / "booth.schema.json").read_text())
    assert set(schema["properties"]["effects"]["properties"]) == set(available_effects())


def test_every_shipped_yaml_points_editors_at_its_schema():
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    files = [p for d in ("booths", "displays", "examples") for p in (repo / d).rglob("*.yaml")]
    files += list((repo / "tests" / "data").rglob("*.yaml"))
    missing = [str(p) for p in files if not p.read_text().startswith("# yaml-language-server: $schema=")]
    assert not missing
    for p in files:
        ref = p.read_text().splitlines()[0].split("$schema=", 1)[1].strip()
        assert (p.parent / ref).resolve().is_file(), f"{p}: {ref} does not exist"


@pytest.mark.parametrize("kind", ["booth", "sample", "render_config"])
def test_unknown_keys_forbidden_in_schema(kind):
    schema = json.loads((JSON_DIR / f"{kind}.schema.json").read_text())
    assert schema.get("additionalProperties") is False
