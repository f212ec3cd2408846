"""Every Python package folder is listed in pyproject.toml (the package-dir mapping needs it)."""

import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_all_packages_listed():
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapping = cfg["package-dir"]
    listed = set(cfg["packages"])
    found = set()
    for pkg, folder in mapping.items():
        for init in (REPO / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(REPO / folder)
            found.add(".".join([pkg, *rel.parts]))
    assert found <= listed, f"add to [tool.setuptools].packages: {sorted(found - listed)}"


def test_cli_import_is_light():
    import subprocess
    import sys

    code = ("import sys, lbscene.cli; heavy = [m for m in ('colour', 'pxr', 'bpy', 'moderngl', "
            "'matplotlib', 'scipy', 'mitsuba') if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
