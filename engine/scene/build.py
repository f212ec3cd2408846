"""
``lbscene build``: compile a booth and write its build folder, atomically and
deterministically.

Layout of a build folder::

    manifest.json               what was built: booth, IR hash, files and their sha256
    scene.ir.json               the scene IR (canonical JSON)
    ies/<LAMP>.ies              photometry of lamps with an IES profile (LM-63, from the IR)
    scene.usda                  USD stage, every lamp visible
    usd_plugin/                 the codeless lbscene schema (set PXR_PLUGINPATH_NAME to it)
    lighting/<NAME>/scene.usda  USD stage with only that configuration's lamps visible
    lighting/<NAME>/...         products of registered writers (bake jobs, render graphs)

Everything is written into a temporary sibling folder that replaces the old
build only when complete: an interrupted build leaves the previous one intact,
and the next build removes what it left.  ``--out`` follows the output policy of
:mod:`lbscene.engine.files.outputs`: an existing folder is replaced only if every file in
it, recursively, is one lbscene made and unchanged (checked before the work and
again when the new build is swapped in); never the booth's own folder, a folder of
the user's files, or a file.  Other lbscene products kept inside a build (bakes
under ``bake/``, outputs recorded in a ledger) are taken over by the new build.
A full disk is ``LB610``, the previous build intact.
Same inputs → byte-identical files (no timestamps; canonical JSON).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import dataclass, field
from importlib import import_module
from pathlib import Path
from typing import Callable

from lbscene.engine.files.atomic import atomic_replace_dir, write_atomic
from lbscene.engine.files.diagnostics import LbsceneUserError
from .ir import SceneIR, canonical_json
from lbscene.engine.files.outputs import (NO_SPACE_ERRNOS, _is_input, carry_over, check_output_dir, fault_point, no_space_error,
                      register_input, replace_dir, restore_interrupted, temporary_dir_for, write_new_file)

from .ir import SceneIR, canonical_json

__all__ = ["BuildResult", "build_booth", "PRODUCT_WRITERS"]

#: Writers of per-lighting products: (module, function).  The function is called as
#: ``fn(ir, lighting_name, folder) -> list[Path]``; a module that is not installed is skipped.
PRODUCT_WRITERS: list[tuple[str, str]] = [
    ("lbscene.bakers.from_ir", "write_build_products"),
    ("lbscene.runtimes.graph", "write_build_products"),
]


@dataclass
class BuildResult:
    out_dir: Path
    ir_hash: str
    booth_name: str
    lightings: list[str]
    files: dict[str, str] = field(default_factory=dict)   # relative path → sha256
    skipped_writers: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"out_dir": str(self.out_dir), "ir_hash": self.ir_hash, "booth": self.booth_name,
                "lightings": self.lightings, "files": self.files,
                "skipped_writers": self.skipped_writers}


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def build_booth(booth_path: Path, out_dir: Path, lighting: str | None = None,
                progress: Callable[[str], None] | None = None, allowed_dirs=()) -> BuildResult:
    """Compile ``booth_path`` and write the build folder ``out_dir``."""
    from .compile import compile_booth
    from .usd_stage import SCHEMA_DIR, write_stage

    step = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    register_input(booth_path)
    restore_interrupted(out_dir)
    check_output_dir(out_dir, option="--out")
    step("compile")
    ir: SceneIR = compile_booth(booth_path, allowed_dirs=allowed_dirs)
    held = _is_input(out_dir)        # every file the booth references is known now
    if held is not None:
        raise LbsceneUserError.single("LB612", "--out: output folder would replace or hold one of this "
                                      "run's inputs", str(out_dir), value=held,
                                      expected="a folder that holds no input")
    if lighting is not None and lighting not in ir.lighting:
        raise LbsceneUserError.single(
            "LB500", f"booth has no lighting configuration {lighting!r}", str(booth_path),
            value=repr(lighting), expected=f"one of {', '.join(ir.lighting)}")
    lightings = [lighting] if lighting else list(ir.lighting)
    tmp = temporary_dir_for(out_dir, option="--out")
    result = BuildResult(out_dir=out_dir, ir_hash=ir.content_hash, booth_name=ir.booth_name,
                         lightings=lightings)
    try:
        write_new_file(tmp / "scene.ir.json", ir.to_json())
        for lamp in ir.lamps:   # IES photometry travels with the build, written from the IR's table
            if lamp.profile.get("type") == "ies":
                from lbscene.engine.spectra.profiles import ies_text

                (tmp / "ies").mkdir(exist_ok=True)
                write_new_file(tmp / "ies" / f"{lamp.id}.ies", ies_text(lamp.profile["data"]))
        step("usd")
        write_stage(ir, tmp / "scene.usda")
        plug = tmp / "usd_plugin"
        plug.mkdir()
        for name in ("plugInfo.json", "generatedSchema.usda"):
            write_new_file(plug / name, (SCHEMA_DIR / name).read_bytes())
        writers = []
        for mod_name, fn_name in PRODUCT_WRITERS:
            try:
                writers.append(getattr(import_module(mod_name), fn_name))
            except (ModuleNotFoundError, AttributeError):
                result.skipped_writers.append(mod_name)
        for name in lightings:
            step(f"lighting {name}")
            folder = tmp / "lighting" / name
            folder.mkdir(parents=True)
            write_stage(ir, folder / "scene.usda", lighting=name)
            for fn in writers:
                fn(ir, name, folder)
            fault_point("build-lighting")
        files = sorted(p for p in tmp.rglob("*") if p.is_file())
        result.files = {p.relative_to(tmp).as_posix(): _sha256(p) for p in files}
        from lbscene._version import __version__

        manifest = {"lbscene_version": __version__, "booth": ir.booth_name,
                    "booth_source": ir.booth_source, "ir_hash": ir.content_hash,
                    "ir_version": ir.ir_version, "lightings": lightings, "files": result.files,
                    "units": {"length": "mm", "spectral_intensity": "W·sr⁻¹·nm⁻¹",
                              "bands": ir.bands}}
        # the manifest is written last: no file it lists is newer than it
        write_new_file(tmp / "manifest.json", json.dumps(json.loads(canonical_json(manifest)), indent=2,
                                                         sort_keys=True, ensure_ascii=False) + "\n")
        step("finish")
        fault_point("build-finish")
        carry_over(out_dir, tmp, option="--out")       # bakes and recorded outputs kept in the old build
        replace_dir(tmp, out_dir, option="--out")
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and exc.errno in NO_SPACE_ERRNOS:
            raise no_space_error(out_dir, "--out", exc) from None
        raise
    return result
