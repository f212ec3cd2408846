"""Small test booths written as a user writes them: a booth file from its sections.

Each section is YAML text (a flow mapping, or a list of lamp mappings), so a test states only
what it is about (the lamps, the materials, the effects) and the rest is a plain box.

>>> text = booth_yaml(lamps=["{id: b, type: bulb, position_mm: [0, 0, 600], radius_mm: 2, "
...                          "spd: {type: constant, value: 1}, "
...                          "output: {type: luminous_flux_lm, value_lm: 1000}}"],
...                   lighting="{L: {lamps: [b]}}")
>>> text.splitlines()[:2]
['version: 1', 'kind: booth']
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["booth_yaml", "write_booth"]

#: a grey box: the sections a test does not give
DEFAULTS = {
    "name": "test booth",
    "interior": "{type: box, width_mm: 900, depth_mm: 600, height_mm: 700}",
    "materials": "{wall: {type: diffuse, reflectance: {type: constant, value: 0.5}}}",
    "surfaces": "{floor: wall, left_wall: wall, right_wall: wall, rear_wall: wall, ceiling: wall}",
    "effects": "{interreflection: {}}",
    "observer": "{type: eye_point, position_mm: [0, -900, 500]}",
}


def booth_yaml(*, lamps: list[str], lighting: str, **sections: str) -> str:
    """The booth file's text: ``lamps`` (one flow mapping each), ``lighting`` and any other
    top-level section as YAML text (``reflectors=…``, ``filters=…``); the sections not given are
    :data:`DEFAULTS`."""
    parts = {**DEFAULTS, **sections}
    lines = ["version: 1", "kind: booth", f"name: {parts.pop('name')}",
             'provenance: {status: synthetic, source: "lbscene test suite"}']
    for key in ("interior", "materials", "surfaces"):
        lines.append(f"{key}: {parts.pop(key)}")
    lines.append("lamps:")
    lines += [f"  - {lamp}" for lamp in lamps]
    lines.append(f"lighting: {lighting}")
    lines += [f"{key}: {value}" for key, value in parts.items()]
    return "\n".join(lines) + "\n"


def write_booth(folder: Path, **parts) -> Path:
    """:func:`booth_yaml` written to ``folder/booth.yaml`` (the folder made); returns the file."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "booth.yaml"
    path.write_text(booth_yaml(**parts), encoding="utf-8")
    return path
