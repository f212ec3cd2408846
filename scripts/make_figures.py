"""Make the figures of the documentation that show the product itself, from the current code.

    .venv/bin/python scripts/make_figures.py                 # writes docs/images/viewer-*.png (about a minute)
    .venv/bin/python scripts/make_figures.py --check         # exit 1 when a committed figure is stale

* ``viewer-tablet.png``: the web viewer of ``examples/booth-from-scratch`` at 1024 × 768 CSS px
  (an iPad in landscape), controls shown;
* ``viewer-tablet-test.png``: the same at the visual test's first case (score buttons only).

Each PNG carries a provenance stamp (text chunk ``lbscene-provenance``): the sha256 of every input
that decides what the figure shows (this script, the viewer's page in ``runtimes/web/assets/``, the
example booth's files). ``--check`` and ``tests/test_docs.py`` recompute the digest from the files
as they are and compare: a figure made before one of them changed is stale.

Needs Chromium (``scripts/install-test-deps.sh``) and an OpenGL context (the export computes the
light at every vertex with the forward model).
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "images"
EXAMPLE = REPO / "examples" / "booth-from-scratch"
STAMP_KEY = "lbscene-provenance"
FIGURES = ("viewer-tablet.png", "viewer-tablet-test.png")
SESSION_YAML = """version: 1
kind: visual_session
name: from-scratch
render_config: {config}
observers: [{{id: O1}}]
samples: [{sample}]
geometries: [default]
lightings: [D65]
response: {{type: grey_scale, min: 1, max: 5, step: 0.5}}
"""

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def input_files() -> list[Path]:
    """What decides the figures: this script, the viewer's page, the example booth."""
    files = [Path(__file__).resolve()]
    files += sorted((REPO / "runtimes" / "web" / "assets").iterdir())
    files += sorted(p for p in EXAMPLE.iterdir() if p.is_file() and p.suffix in (".yaml", ".csv"))
    return files


def inputs_digest() -> dict:
    """``{"inputs": {path: sha256}, "digest": sha256 of them all}`` (paths relative to the repository)."""
    inputs = {p.relative_to(REPO).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in input_files()}
    return {"inputs": inputs, "digest": digest_of(inputs)}


def digest_of(inputs: dict) -> str:
    """One sha256 over the inputs' names and hashes."""
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()


def read_stamp(png: Path) -> dict | None:
    """The provenance stamp of a figure (None when it has none)."""
    from PIL import Image

    with Image.open(png) as im:
        text = im.text.get(STAMP_KEY) if hasattr(im, "text") else None
    return json.loads(text) if text else None


def stale(out_dir: Path = OUT) -> list[str]:
    """The figures in ``out_dir`` that are missing, unstamped or made from other inputs."""
    want = inputs_digest()["digest"]
    bad = []
    for name in FIGURES:
        p = out_dir / name
        st = read_stamp(p) if p.is_file() else None
        if st is None or st.get("digest") != want:
            bad.append(name)
    return bad


def _save(png_bytes: bytes, path: Path, stamp: dict) -> None:
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text(STAMP_KEY, json.dumps(stamp, sort_keys=True))
    with Image.open(io.BytesIO(png_bytes)) as im:
        im.convert("RGB").save(path, pnginfo=info, optimize=True)


def make(out_dir: Path = OUT, size_px=(1024, 768), scale: float = 1.0) -> list[Path]:
    """Export the example booth's viewer (with a one-case session) and photograph it."""
    from lbscene.cli import main
    from lbscene.runtimes.web.browser import open_page

    stamp = inputs_digest()
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="lbscene-figures-") as tmp:
        tmp = Path(tmp)
        session = tmp / "session.yaml"
        session.write_text(SESSION_YAML.format(config=EXAMPLE / "render.yaml", sample=EXAMPLE / "sample-grey.yaml"))
        viewer = tmp / "viewer"
        code = main(["export-web", str(EXAMPLE / "render.yaml"), "--session", str(session), "--out", str(viewer),
                     "--allow-path", str(EXAMPLE), "--allow-path", str(tmp)])
        if code != 0:
            raise SystemExit(f"export-web failed (exit {code})")
        written = []
        with open_page(viewer, size_px=size_px, query={"scale": scale}) as page:
            path = out_dir / FIGURES[0]
            _save(page.screenshot_png(), path, stamp)
            written.append(path)
            page.evaluate("document.getElementById('starttest').click(), true")
            page.wait_for("document.body.classList.contains('testing')")
            page.evaluate("new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))")
            path = out_dir / FIGURES[1]
            _save(page.screenshot_png(), path, stamp)
            written.append(path)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT, help="folder for the PNGs (default docs/images)")
    ap.add_argument("--size", default="1024x768", help="viewport WIDTHxHEIGHT in CSS px")
    ap.add_argument("--scale", type=float, default=1.0, help="render size as a fraction of the viewport")
    ap.add_argument("--check", action="store_true", help="only check the stamps of the figures in --out")
    a = ap.parse_args(argv)
    if a.check:
        bad = stale(a.out)
        for name in bad:
            print(f"stale: {a.out / name} (run scripts/make_figures.py)")
        return 1 if bad else 0
    w, h = (int(v) for v in a.size.lower().split("x"))
    for p in make(a.out, (w, h), a.scale):
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
