"""
Located diagnostics: every user-facing problem carries a stable code, a
``file:line:col`` location, the offending value and what was expected.

The CLI turns :class:`LbsceneUserError` into a printed list of diagnostics and
exit code 2; a user mistake never reaches the user as a traceback.

Codes are stable: tests pin them and users may grep for them.  The registry
:data:`CODES` documents every code in one place.

Examples
--------
>>> d = Diagnostic("LB101", "wrong type", SourceLocation("booth.yaml", 3, 7),
...                value="'abc'", expected="a number")
>>> d.format()
"booth.yaml:3:7: error LB101: wrong type (got 'abc'; expected a number)"
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import Enum
from typing import Iterable

__all__ = [
    "CODES",
    "Severity",
    "SourceLocation",
    "Diagnostic",
    "LbsceneUserError",
    "DiagnosticBag",
]

#: Every diagnostic code with a one-line meaning.  LB0xx: reading files,
#: LB1xx: schema, LB2xx: references, LB3xx: semantic rules (linter),
#: LB4xx: measurement data, LB5xx: command-line usage, LB6xx: build/bake/render.
CODES: dict[str, str] = {
    "LB001": "YAML syntax error",
    "LB002": "empty document",
    "LB003": "file is not UTF-8 text (binary data?)",
    "LB004": "file larger than the allowed size",
    "LB005": "alias/anchor expansion exceeds the allowed size",
    "LB006": "YAML tag or construct not allowed in lbscene files",
    "LB007": "duplicate key",
    "LB008": "top-level document must be a mapping",
    "LB009": "unsupported document version",
    "LB010": "file not found",
    "LB011": "path is a directory without a recognised document",
    "LB012": "not a regular file (a FIFO, device or socket is never read)",
    "LB013": "file cannot be read (permission or I/O error)",
    "LB014": "CSV file cannot be parsed (a cell over the size bound, broken quoting)",
    "LB015": "JSON syntax error, or nesting deeper than the bound",
    "LB100": "unknown key",
    "LB101": "wrong type",
    "LB102": "missing required key",
    "LB103": "value out of range",
    "LB104": "invalid value",
    "LB105": "unknown 'type' for a polymorphic node",
    "LB106": "unknown effect id",
    "LB200": "referenced file does not exist",
    "LB201": "referenced path escapes the document's folder",
    "LB202": "reference to an undefined name",
    "LB203": "referenced file has the wrong content",
    "LB204": "unknown named spectrum",
    "LB300": "lamp outside the booth",
    "LB301": "spectrum does not cover the band range",
    "LB302": "reflectance or transmittance outside [0, 1]",
    "LB303": "unknown or invalid viewing geometry name",
    "LB304": "duplicate id",
    "LB305": "lighting configuration switches on no lamp",
    "LB306": "sample or observer outside the booth",
    "LB307": "effect refers to something the booth does not define",
    "LB308": "a viewing geometry turns the platform out of the booth",
    "LB309": "a lamp reaches a receiver point or crosses a booth surface",
    "LB310": "illuminance outside ASTM D1729 / ISO 3668 / ISO 3664 recommendations",
    "LB311": "provenance marks values as estimates",
    "LB312": "mesh face is degenerate (zero area) or its normal overflows",
    "LB313": "mesh reaches outside the booth",
    "LB314": "a reflector the model draws only in part",
    "LB400": "measurement file: missing or unexpected column",
    "LB401": "measurement file: value is not a finite number",
    "LB402": "measurement file: negative value",
    "LB403": "measurement file: duplicate point",
    "LB404": "measurement file: point outside the booth floor",
    "LB405": "measurement file: wavelengths not strictly increasing",
    "LB406": "measurement file: implausible magnitude (unit mistake?)",
    "LB407": "measurement file: too few rows",
    "LB500": "command-line usage error",
    "LB501": "invalid environment variable value",
    "LB510": "the work exceeds a limit",
    "LB600": "build/bake/render failed",
    "LB601": "bake products missing",
    "LB602": "invalid bake job file",
    "LB603": "a truth provider cannot represent the booth",
    "LB604": "an optional dependency the command needs is not installed",
    "LB610": "output cannot be written there",
    "LB611": "output exists and was not written by lbscene",
    "LB612": "output would replace one of the run's inputs",
    "LB700": "web export: output folder is not a web export",
    "LB701": "web export: data over the size limit",
    "LB702": "visual session: inconsistent session",
    "LB710": "visual results: unreadable results file",
    "LB711": "visual results: results do not match the session",
}


class Severity(str, Enum):
    """How bad a diagnostic is."""

    ERROR = "error"
    WARNING = "warning"
    INFO = "info"


@dataclass(frozen=True, order=True)
class SourceLocation:
    """A 1-based position in a file (``line``/``column`` 0 when unknown)."""

    file: str
    line: int = 0
    column: int = 0

    def __str__(self) -> str:
        if self.line:
            return f"{self.file}:{self.line}:{self.column}"
        return self.file


@dataclass(frozen=True)
class Diagnostic:
    """One located problem."""

    code: str
    message: str
    location: SourceLocation | None = None
    value: str | None = None
    expected: str | None = None
    severity: Severity = Severity.ERROR
    hint: str | None = None

    def __post_init__(self) -> None:
        if self.code not in CODES:  # a programming error, not a user error
            raise ValueError(f"unregistered diagnostic code {self.code!r}")

    def format(self) -> str:
        """``file:line:col: severity CODE: message (got …; expected …)``.

        Control characters of every part (a file or sample name may hold ``\\x1b[2J`` or a
        newline) are shown as escapes: one diagnostic is one line, plus its hint line.
        """
        from .textsafe import printable

        def p(x) -> str:
            return printable(x, newlines=False)

        where = f"{p(self.location)}: " if self.location else ""
        extra = []
        if self.value is not None:
            extra.append(f"got {p(self.value)}")
        if self.expected is not None:
            extra.append(f"expected {p(self.expected)}")
        tail = f" ({'; '.join(extra)})" if extra else ""
        hint = f"\n    hint: {p(self.hint)}" if self.hint else ""
        return f"{where}{self.severity.value} {self.code}: {p(self.message)}{tail}{hint}"

    def to_json(self) -> dict:
        d = asdict(self)
        d["severity"] = self.severity.value
        if self.location is not None:
            d["location"] = {
                "file": self.location.file,
                "line": self.location.line,
                "column": self.location.column,
            }
        return d


class LbsceneUserError(Exception):
    """A user mistake: carries diagnostics; the CLI prints them and exits 2."""

    def __init__(self, diagnostics: Diagnostic | Iterable[Diagnostic]):
        if isinstance(diagnostics, Diagnostic):
            diagnostics = [diagnostics]
        self.diagnostics: list[Diagnostic] = list(diagnostics)
        super().__init__("\n".join(d.format() for d in self.diagnostics))

    def __reduce__(self):
        # pickled with its diagnostics (an error raised in a forked worker reaches the caller whole)
        return type(self), (self.diagnostics,)

    @classmethod
    def single(cls, code: str, message: str, file: str | None = None, line: int = 0,
               column: int = 0, **kw) -> "LbsceneUserError":
        loc = SourceLocation(file, line, column) if file else None
        return cls(Diagnostic(code, message, loc, **kw))


@dataclass
class DiagnosticBag:
    """Collects diagnostics so that all problems are reported at once."""

    items: list[Diagnostic] = field(default_factory=list)

    def add(self, diag: Diagnostic) -> None:
        self.items.append(diag)

    def extend(self, diags: Iterable[Diagnostic]) -> None:
        self.items.extend(diags)

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity is Severity.ERROR]

    @property
    def warnings(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity is Severity.WARNING]

    def raise_if_errors(self) -> None:
        if self.errors:
            raise LbsceneUserError(self.errors)

    def sorted(self) -> list[Diagnostic]:
        def key(d: Diagnostic):
            loc = d.location or SourceLocation("")
            return (loc.file, loc.line, loc.column, d.code)

        return sorted(self.items, key=key)
