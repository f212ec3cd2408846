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


# --- the sdist and the wheel carry every run-time file ------------------------------------------------

import tarfile  # noqa: E402
import zipfile  # noqa: E402

import pytest  # noqa: E402

# folder in the repository → folder in the installed package, and the files the code opens there
RUNTIME_FILES = {
    "schemas/json": ("lbscene/schemas/json", ["*.schema.json"]),
    "engine/scene/usd_schema": ("lbscene/engine/scene/usd_schema", ["*.json", "*.usda"]),
    "engine/light/data/rough_slab": ("lbscene/engine/light/data/rough_slab", ["*.npz"]),
    "engine/spectra/data": ("lbscene/engine/spectra/data", ["*.npz"]),
    "engine/tables": ("lbscene/engine/tables", ["*.npy"]),
    "runtimes/shaders": ("lbscene/runtimes/shaders", ["*.glsl", "*.vert", "*.frag"]),
    "runtimes/data": ("lbscene/runtimes/data", ["*.json"]),
    "booths": ("lbscene/booths", ["*/booth.yaml", "*/spectra/*.csv", "*/geometry/*"]),
    "displays": ("lbscene/displays", ["*.yaml"]),
}


def _expected_runtime_files() -> set[str]:
    out = set()
    for src, (dst, patterns) in RUNTIME_FILES.items():
        for pat in patterns:
            for f in (REPO / src).glob(pat):
                out.add(f"{dst}/{f.relative_to(REPO / src).as_posix()}")
    return out


@pytest.fixture(scope="module")
def dists(tmp_path_factory):
    """sdist, then the wheel built from the unpacked sdist (as pip does), with setuptools' backend."""
    import subprocess
    import sys

    out = tmp_path_factory.mktemp("dist")
    code = ("import os, sys, tarfile; from pathlib import Path; from setuptools import build_meta as b\n"
            "d = Path(sys.argv[1]); s = d / b.build_sdist(str(d))\n"
            "tarfile.open(s).extractall(d / 'src', filter='data')\n"
            "os.chdir(next((d / 'src').iterdir())); w = b.build_wheel(str(d))\n"
            "print(s.name); print(w)\n")
    res = subprocess.run([sys.executable, "-c", code, str(out)], cwd=REPO, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-3000:]
    sdist_name, wheel_name = res.stdout.strip().splitlines()[-2:]
    return out / sdist_name, out / wheel_name


def test_wheel_carries_every_runtime_file(dists):
    expected = _expected_runtime_files()
    assert len(expected) > 30  # the globs above did find the repository's files
    names = set(zipfile.ZipFile(dists[1]).namelist())
    missing = sorted(expected - names)
    assert not missing, f"not in the wheel: {missing}"
    # development helpers stay out of the wheel
    assert not [n for n in names if n.startswith("lbscene/booths/tools/")]


def test_sdist_carries_license_and_runtime_files(dists):
    with tarfile.open(dists[0]) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    assert "LICENSE" in names
    repo_side = {f"{src}/{Path(p).relative_to(dst).as_posix()}"
                 for src, (dst, _) in RUNTIME_FILES.items()
                 for p in _expected_runtime_files() if p.startswith(dst + "/")}
    assert not sorted(repo_side - names)


def test_wheel_metadata_spdx_license_urls_classifiers(dists):
    from email.parser import Parser

    zf = zipfile.ZipFile(dists[1])
    meta_name = next(n for n in zf.namelist() if n.endswith(".dist-info/METADATA"))
    meta = Parser().parsestr(zf.read(meta_name).decode())
    assert meta["License-Expression"] == "BSD-3-Clause"
    assert "LICENSE" in meta.get_all("License-File")
    lic = next(n for n in zf.namelist() if n.endswith(".dist-info/licenses/LICENSE"))
    text = zf.read(lic).decode()
    assert "Redistribution and use in source and binary forms" in text and "the lbscene authors" in text
    urls = dict(u.split(", ", 1) for u in meta.get_all("Project-URL"))
    assert {"Documentation", "Source"} <= set(urls)
    classifiers = meta.get_all("Classifier")
    assert "Programming Language :: Python :: 3.11" in classifiers
    # PEP 639: no legacy license classifier next to an SPDX expression
    assert not [c for c in classifiers if c.startswith("License ::")]


def test_shipped_booth_by_name():
    from lbscene.engine.scene.compile import find_booth_file
    from lbscene.engine.files.diagnostics import LbsceneUserError

    assert find_booth_file("xrite-spectralight-qc") == REPO / "booths" / "xrite-spectralight-qc" / "booth.yaml"
    with pytest.raises(LbsceneUserError) as exc:
        find_booth_file("no-such-booth")
    d = exc.value.diagnostics[0]
    assert (d.code, d.message) == ("LB010", "file not found")
    assert d.expected == ("a booth folder, a booth.yaml, or a shipped booth: byk-byko-spectra-effect, "
                          "iso3664-p1-d50, xrite-spectralight-qc")
