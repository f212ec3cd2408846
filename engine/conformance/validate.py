"""
``lbscene validate-config``: schema errors and semantic rules for any lbscene
document (booths, samples, displays, measurement sets, render configs), all
problems at once, located.

A folder is searched recursively for ``*.yaml``; a document's ``kind:``
selects its schema and its semantic rules (:data:`LINTERS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError, Severity, SourceLocation
from lbscene.engine.files.load import LoadedDocument, display_path, validate_data
from lbscene.engine.files.yamlio import load_yaml_file

__all__ = ["ValidationReport", "validate_paths", "collect_documents", "LINTERS", "SKIP_DIRS"]

SKIP_DIRS = {".git", ".venv", "build", "__pycache__", "node_modules", ".pytest_cache"}


def _lint_booth(doc: LoadedDocument) -> list[Diagnostic]:
    """The linter's rules, then, when they find no error, the viewing-standard warnings on the
    compiled booth (a booth that does not compile: the compiler's diagnostics)."""
    from lbscene.engine.scene.compile import compile_loaded
    from lbscene.engine.scene.lint import illuminance_rules, lint_booth, needs_illuminance_rules

    diags = lint_booth(doc)
    if any(d.severity is Severity.ERROR for d in diags) or not needs_illuminance_rules(doc):
        return diags
    try:
        ir = compile_loaded(doc)
    except LbsceneUserError as exc:
        return diags + exc.diagnostics
    return diags + illuminance_rules(doc, ir)


def _lint_measurement_set(doc: LoadedDocument) -> list[Diagnostic]:
    """A measurement set's data files, read as ``compare`` reads them (each problem located in
    its file): illuminance CSVs, the white tile's spectra, measured surface reflectances.  The
    booth's placement checks (points outside it) need the booth compiled and wait for compare."""
    from lbscene.engine.loop.measurements import _shown, _tile_column, read_illuminance_csv
    from lbscene.engine.spectra.evaluate import evaluate_spectrum

    m = doc.model
    out: list[Diagnostic] = []
    for f in m.illuminance:
        p = doc.resolve(f.path)
        try:
            _, diags = read_illuminance_csv(p, display_path(p), default_z_mm=f.z_mm,
                                            default_orientation=f.orientation)
        except LbsceneUserError as exc:
            diags = exc.diagnostics
        out += diags
    spectra = [(spec, "reflectance", f"surface_reflectances.{mid}") for mid, spec in m.surface_reflectances.items()]
    if m.white_tile is not None:
        spectra += [(m.white_tile.radiance, "emission", "white_tile.radiance"),
                    (m.white_tile.reflectance, "reflectance", "white_tile.reflectance")]
    for spec, kind, what in spectra:
        try:
            if what == "white_tile.radiance":
                spec = _tile_column(spec, doc.resolve)
            evaluate_spectrum(spec, doc.resolve, kind, display=_shown(doc, spec, what))
        except LbsceneUserError as exc:
            out += exc.diagnostics
    return out


def _lint_render_config(doc: LoadedDocument) -> list[Diagnostic]:
    """The work a render configuration asks for: the pixels of one view (``LB510``)."""
    from lbscene.engine.files.limits import check_work

    out = doc.model.output
    try:
        check_work("pixels", out.width_px * out.height_px, doc.locate("output", "width_px"),
                   what=f"pixels of one view ({out.width_px}x{out.height_px})")
    except LbsceneUserError as exc:
        return exc.diagnostics
    return []


def _lint_visual_session(doc: LoadedDocument) -> list[Diagnostic]:
    """A visual session as ``export-web`` and ``visual-report`` load it: the number of trials
    (``LB510``, before they are planned), its sample documents, distinct sample names."""
    from lbscene.engine.visual.protocol import load_session

    try:
        load_session(doc.path, doc.refs.allowed_dirs)
    except LbsceneUserError as exc:
        return exc.diagnostics
    return []


#: kind → semantic rules run after schema validation (other modules may add theirs).
LINTERS: dict[str, Callable[[LoadedDocument], list[Diagnostic]]] = {
    "booth": _lint_booth, "measurement_set": _lint_measurement_set, "render_config": _lint_render_config,
    "visual_session": _lint_visual_session}


@dataclass
class ValidationReport:
    files: list[str] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)

    @property
    def errors(self) -> int:
        return sum(d.severity is Severity.ERROR for d in self.diagnostics)

    @property
    def warnings(self) -> int:
        return sum(d.severity is Severity.WARNING for d in self.diagnostics)

    def exit_code(self, strict: bool) -> int:
        if self.errors:
            return 2
        if strict and self.warnings:
            return 1
        return 0

    def to_json(self) -> dict:
        return {"files": self.files, "errors": self.errors, "warnings": self.warnings,
                "diagnostics": [d.to_json() for d in self.diagnostics]}


def collect_documents(paths: Iterable[Path]) -> tuple[list[Path], list[Diagnostic]]:
    """Files to validate: files as given, folders searched for *.yaml."""
    from lbscene.engine.files.yamlio import path_kind

    out, diags = [], []
    for p in paths:
        p = Path(p)
        try:
            kind = path_kind(p)
        except LbsceneUserError as exc:
            diags += exc.diagnostics
            continue
        if kind == "dir":
            found = sorted(f for f in p.rglob("*.yaml")
                           if not any(part in SKIP_DIRS for part in f.relative_to(p).parts[:-1]))
            if not found:
                diags.append(Diagnostic("LB011", "no .yaml documents in this folder",
                                        SourceLocation(display_path(p))))
            out.extend(found)
        elif kind != "missing":
            out.append(p)
        else:
            diags.append(Diagnostic("LB010", "file not found", SourceLocation(str(p))))
    seen, unique = set(), []
    for f in out:
        try:
            key = f.resolve()
        except (OSError, RuntimeError):   # a loop under a folder: validate_file locates it
            key = f
        if key not in seen:
            seen.add(key)
            unique.append(f)
    return unique, diags


def validate_file(path: Path, allowed_dirs=()) -> list[Diagnostic]:
    from lbscene.schemas import DOCUMENT_KINDS, document_model
    from lbscene.schemas.refs import RefContext

    try:
        yaml = load_yaml_file(path, display_path(path))
        data = yaml.data
        if not isinstance(data, dict):
            raise LbsceneUserError.single("LB008", "the document must be a mapping", yaml.file, 1, 1,
                                          value=type(data).__name__, expected="a mapping with kind:")
        kind = data.get("kind")
        if kind not in DOCUMENT_KINDS:
            loc = yaml.positions.locate(("kind",)) if "kind" in data else SourceLocation(yaml.file, 1, 1)
            code = "LB104" if "kind" in data else "LB102"
            msg = f"unknown document kind {kind!r}" if "kind" in data else "missing required key 'kind'"
            raise LbsceneUserError([Diagnostic(code, msg, loc, value=None if kind is None else repr(kind),
                                               expected=f"one of {', '.join(DOCUMENT_KINDS)}")])
        try:
            model = document_model(kind)
        except ModuleNotFoundError:
            raise LbsceneUserError.single("LB104", f"document kind {kind!r} is not available in this "
                                          "build of lbscene", yaml.file, 1, 1)
        base = path.resolve().parent
        refs = RefContext(base_dir=base, root_dir=base, allowed_dirs=tuple(allowed_dirs))
        m = validate_data(model, data, yaml, refs)
        doc = LoadedDocument(model=m, yaml=yaml, path=path, refs=refs)
        linter = LINTERS.get(kind)
        return linter(doc) if linter else []
    except LbsceneUserError as exc:
        return exc.diagnostics


def validate_paths(paths: Iterable[Path], allowed_dirs=(), progress=None) -> ValidationReport:
    files, diags = collect_documents(paths)
    report = ValidationReport(files=[display_path(f) for f in files], diagnostics=list(diags))
    for f in files:
        report.diagnostics.extend(validate_file(f, allowed_dirs))
        if progress:
            progress(f)
    return report
