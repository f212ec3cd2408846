"""
Safe, bounded YAML reading that remembers where every value came from.

Untrusted booth files are read with ruamel.yaml's *composer* only: we walk the
node graph ourselves, so that

* no Python object is ever constructed from a tag (only plain scalars, lists
  and mappings; any explicit non-standard tag is an error),
* anchors/aliases are allowed but their *expanded* size is computed on the
  node graph before anything is built (a "billion laughs" file is an error,
  not a hang),
* duplicate keys are errors, and
* every value's ``(line, column)`` is recorded in a :class:`PositionMap`
  keyed by its path, so pydantic errors can be mapped back onto the file.

Examples
--------
>>> doc = load_yaml_text("a:\\n  b: [1, 2]\\n", "x.yaml")
>>> doc.data
{'a': {'b': [1, 2]}}
>>> doc.positions.locate(("a", "b", 1))
SourceLocation(file='x.yaml', line=2, column=10)
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from .diagnostics import LbsceneUserError, SourceLocation

__all__ = [
    "MAX_YAML_BYTES",
    "MAX_EXPANDED_NODES",
    "PositionMap",
    "YamlDocument",
    "load_yaml_file",
    "load_yaml_text",
    "read_text_bounded",
    "read_bytes_bounded",
    "csv_rows",
    "MAX_CSV_CELL_CHARS",
    "parse_json_text",
    "load_json_bounded",
    "path_kind",
]

#: Largest YAML document accepted (booth files are a few kB).
MAX_YAML_BYTES = 4 * 1024 * 1024
#: Largest number of nodes after alias expansion.
MAX_EXPANDED_NODES = 200_000
#: Deepest nesting accepted.
MAX_DEPTH = 64

_STD = "tag:yaml.org,2002:"
_ALLOWED_TAGS = {_STD + t for t in ("str", "int", "float", "bool", "null", "map", "seq")}

Path_ = tuple  # a path into the document: keys and list indices


@dataclass
class PositionMap:
    """Maps a document path (tuple of keys/indices) to its position.

    ``key_positions`` holds where a mapping *key* starts (used for
    "unknown key" errors); ``positions`` where the *value* starts.
    """

    file: str
    positions: dict[Path_, tuple[int, int]]
    key_positions: dict[Path_, tuple[int, int]]

    def locate(self, path: Path_, *, key: bool = False) -> SourceLocation:
        """Best location for ``path``: the path itself or its nearest parent."""
        path = tuple(path)
        table = self.key_positions if key else self.positions
        while True:
            if path in table:
                line, col = table[path]
                return SourceLocation(self.file, line, col)
            if key and path in self.positions:
                line, col = self.positions[path]
                return SourceLocation(self.file, line, col)
            if not path:
                return SourceLocation(self.file, 1, 1)
            path = path[:-1]


@dataclass
class YamlDocument:
    """Plain data (dict/list/str/int/float/bool/None) plus positions."""

    data: Any
    positions: PositionMap
    path: Path | None = None

    @property
    def file(self) -> str:
        return self.positions.file


def path_kind(path, display: str | None = None) -> str:
    """``'file'``, ``'dir'``, ``'missing'`` or ``'other'`` (FIFO, device, socket) for a path given by
    the user, following symbolic links.

    Where the path cannot even be looked at — a name longer than the file system allows
    (``ENAMETOOLONG``), a loop of symbolic links (``ELOOP``), a folder without permission — the
    answer is the located ``LB013``, never ``OSError`` (``Path.is_dir`` raises on a long name and
    calls a loop "missing").
    """
    import errno
    import os
    import stat as _stat

    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return "missing"
    except OSError as exc:
        shown = display or str(path)
        if len(shown) > 120:
            shown = shown[:60] + "…" + shown[-40:]
        what = {errno.ENAMETOOLONG: "the name is longer than the file system allows",
                errno.ELOOP: "the path is a loop of symbolic links"}.get(exc.errno, exc.strerror or str(exc))
        raise LbsceneUserError.single("LB013", f"cannot use the path: {what}", shown,
                                      expected="an existing file or folder") from None
    except ValueError:    # a NUL byte in the name
        raise LbsceneUserError.single("LB013", "cannot use the path: it contains a NUL byte",
                                      (display or repr(path))[:120]) from None
    return "dir" if _stat.S_ISDIR(st.st_mode) else "file" if _stat.S_ISREG(st.st_mode) else "other"


def read_bytes_bounded(path: Path, display: str, max_bytes: int, *, is_input: bool = True) -> bytes:
    """Read at most ``max_bytes`` of a regular file, or fail with a located diagnostic.

    Only regular files are opened (a FIFO would block, ``/dev/zero`` never ends), and the read
    itself is bounded: the size ``stat`` reports is not trusted (``/proc`` files report 0).
    The file is recorded as an input of this run, so no output may replace it (``is_input=False``
    for a file the run itself rewrites, such as a history).
    """
    import stat as _stat

    from .outputs import register_input

    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise LbsceneUserError.single("LB010", "file not found", display) from None
    except PermissionError:
        raise LbsceneUserError.single("LB013", "cannot read the file: permission denied", display) from None
    except OSError as exc:
        raise LbsceneUserError.single("LB013", f"cannot read the file: {exc.strerror}", display) from None
    if _stat.S_ISDIR(st.st_mode):
        raise LbsceneUserError.single("LB011", "expected a file, got a directory", display)
    if not _stat.S_ISREG(st.st_mode):
        kind = ("a FIFO" if _stat.S_ISFIFO(st.st_mode) else "a device" if _stat.S_ISCHR(st.st_mode)
                or _stat.S_ISBLK(st.st_mode) else "a socket" if _stat.S_ISSOCK(st.st_mode) else "not a file")
        raise LbsceneUserError.single("LB012", "not a regular file", display, value=kind,
                                      expected="a regular file")
    if st.st_size > max_bytes:
        raise LbsceneUserError.single(
            "LB004", "file is too large", display,
            value=f"{st.st_size} bytes", expected=f"at most {max_bytes} bytes")
    try:
        with open(path, "rb") as f:
            raw = f.read(max_bytes + 1)
    except PermissionError:
        raise LbsceneUserError.single("LB013", "cannot read the file: permission denied", display) from None
    except OSError as exc:
        raise LbsceneUserError.single("LB013", f"cannot read the file: {exc.strerror}", display) from None
    if len(raw) > max_bytes:
        raise LbsceneUserError.single(
            "LB004", "file is too large", display,
            value=f"more than {max_bytes} bytes", expected=f"at most {max_bytes} bytes")
    if is_input:
        register_input(path)
    return raw


def read_text_bounded(path: Path, display: str, max_bytes: int) -> str:
    """Read a text file with a size bound and a clear error for binary data."""
    return _decode_utf8(read_bytes_bounded(path, display, max_bytes), display)


#: Largest CSV cell (characters): the csv module's own field limit (128 kB); a longer cell is
#: refused with its line (``LB014``) instead of the module's exception.
MAX_CSV_CELL_CHARS = 131072


def csv_rows(text: str, display: str) -> list[tuple[int, list[str]]]:
    """Rows of a CSV text, each with the line it starts on, or a located ``LB014``.

    Cells are bounded (:data:`MAX_CSV_CELL_CHARS`); broken quoting is reported at its line.

    Examples
    --------
    >>> csv_rows('a,b\\n1,"x\\ny"\\n2,3\\n', "t.csv")
    [(1, ['a', 'b']), (2, ['1', 'x\\ny']), (4, ['2', '3'])]
    """
    import csv

    reader = csv.reader(io.StringIO(text))
    out = []
    start = 1
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return out
        except csv.Error as exc:
            msg = str(exc)
            too_big = "field larger than field limit" in msg
            raise LbsceneUserError.single(
                "LB014", f"a CSV cell is larger than {MAX_CSV_CELL_CHARS // 1024} kB" if too_big
                else f"cannot parse the CSV: {msg}", display, max(reader.line_num, 1), 1,
                expected=f"cells of at most {MAX_CSV_CELL_CHARS} characters" if too_big
                else "comma-separated values with balanced quotes") from None
        out.append((start, row))
        start = reader.line_num + 1


def _json_too_deep_at(text: str, max_depth: int) -> tuple[int, int] | None:
    """(line, column) of the first bracket nested deeper than ``max_depth`` (strings skipped)."""
    import re

    blank = re.sub(r'"(?:[^"\\]|\\.)*"', lambda m: " " * len(m.group(0)), text)
    depth = 0
    for m in re.finditer(r"[\[\]{}]", blank):
        depth += 1 if m.group(0) in "[{" else -1
        if depth > max_depth:
            i = m.start()
            return text.count("\n", 0, i) + 1, i - (text.rfind("\n", 0, i) + 1) + 1
    return None


def _json_depth(value) -> int:
    """Nesting depth of parsed JSON (a scalar is 0), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (dict, list)):
            deepest = max(deepest, d + 1)
            stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


def parse_json_text(text: str, display: str, *, line: int = 0, max_depth: int = MAX_DEPTH):
    """JSON text → value, or a located ``LB015`` (syntax, or nesting deeper than ``max_depth``).

    ``line``: the line of ``text`` in its file when ``text`` is one line of it (a JSON-lines
    history), so errors point at that line.

    Examples
    --------
    >>> parse_json_text('{"a": [1, 2]}', "x.json")
    {'a': [1, 2]}
    >>> parse_json_text("[" * 100 + "]" * 100, "x.json")
    Traceback (most recent call last):
    ...
    lbscene.engine.files.diagnostics.LbsceneUserError: x.json:1:65: error LB015: JSON nested too deeply (expected at most 64 levels)
    """
    import json

    def deep() -> LbsceneUserError:
        ln, col = _json_too_deep_at(text, max_depth) or (1, 1)
        return LbsceneUserError.single("LB015", "JSON nested too deeply", display,
                                       (line or 1) + ln - 1 if line else ln, col,
                                       expected=f"at most {max_depth} levels")

    try:
        value = json.loads(text)
    except RecursionError:
        raise deep() from None
    except json.JSONDecodeError as exc:
        raise LbsceneUserError.single("LB015", f"not valid JSON: {exc.msg}", display,
                                      line or exc.lineno, exc.colno, expected="a JSON document") from None
    except ValueError as exc:      # e.g. a number too long to convert
        raise LbsceneUserError.single("LB015", f"not valid JSON: {exc}", display, line or 1, 1,
                                      expected="a JSON document") from None
    if _json_depth(value) > max_depth:
        raise deep()
    return value


def load_json_bounded(path: Path, display: str, max_bytes: int, *, is_input: bool = True):
    """Read a JSON file (regular file, bounded size, UTF-8, bounded nesting) with located errors."""
    raw = read_bytes_bounded(path, display, max_bytes, is_input=is_input)
    return parse_json_text(_decode_utf8(raw, display), display)


def _decode_utf8(raw: bytes, display: str) -> str:
    if b"\x00" in raw:
        raise LbsceneUserError.single(
            "LB003", "file contains NUL bytes: binary data, not text", display,
            expected="a UTF-8 text file")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise LbsceneUserError.single(
            "LB003", "file is not valid UTF-8 text", display, line, col,
            value=f"byte 0x{raw[exc.start]:02x}", expected="UTF-8 text") from None


def load_yaml_file(path: Path | str, display: str | None = None,
                   max_bytes: int = MAX_YAML_BYTES) -> YamlDocument:
    """Read and parse a YAML file safely.  Raises :class:`LbsceneUserError`."""
    path = Path(path)
    display = display or str(path)
    text = read_text_bounded(path, display, max_bytes)
    doc = load_yaml_text(text, display)
    doc.path = path
    return doc


def _mark(node_or_mark) -> tuple[int, int]:
    m = getattr(node_or_mark, "start_mark", node_or_mark)
    return (m.line + 1, m.column + 1)


def load_yaml_text(text: str, display: str) -> YamlDocument:
    """Parse YAML text; see module docstring for the safety rules."""
    yaml = YAML(typ="rt", pure=True)
    try:
        nodes = list(yaml.compose_all(io.StringIO(text)))
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = _mark(mark) if mark else (0, 0)
        msg = (exc.problem or "syntax error").strip()
        if exc.context:
            msg = f"{exc.context.strip()}: {msg}"
        raise LbsceneUserError.single("LB001", f"YAML syntax error: {msg}", display, line, col)
    except YAMLError as exc:  # pragma: no cover - ruamel raises Marked* in practice
        raise LbsceneUserError.single("LB001", f"YAML error: {exc}", display)
    except RecursionError:
        raise LbsceneUserError.single("LB005", "YAML nesting is too deep", display,
                                      expected=f"at most {MAX_DEPTH} levels")
    nodes = [n for n in nodes if n is not None]
    if not nodes:
        raise LbsceneUserError.single("LB002", "document is empty", display, 1, 1,
                                      expected="a YAML mapping with a 'version:' key")
    if len(nodes) > 1:
        line, col = _mark(nodes[1])
        raise LbsceneUserError.single("LB006", "more than one YAML document in the file",
                                      display, line, col, expected="a single document")
    root = nodes[0]
    _check_expansion(root, display)
    walker = _Walker(display)
    data = walker.build(root, ())
    return YamlDocument(data, PositionMap(display, walker.positions, walker.key_positions))


def _check_expansion(root: Node, display: str) -> None:
    """Count nodes after alias expansion without expanding (memoised on identity)."""
    memo: dict[int, int] = {}
    on_stack: set[int] = set()
    aliased = [False]   # a node reached twice: the document uses aliases

    def size(node: Node, depth: int) -> int:
        if depth > MAX_DEPTH:
            line, col = _mark(node)
            raise LbsceneUserError.single("LB005", "YAML nesting is too deep", display, line, col,
                                          expected=f"at most {MAX_DEPTH} levels")
        key = id(node)
        if key in memo:
            aliased[0] = True
            return memo[key]
        if key in on_stack:
            line, col = _mark(node)
            raise LbsceneUserError.single("LB005", "recursive YAML alias", display, line, col)
        on_stack.add(key)
        total = 1
        if isinstance(node, SequenceNode):
            for child in node.value:
                total += size(child, depth + 1)
        elif isinstance(node, MappingNode):
            for k, v in node.value:
                total += size(k, depth + 1) + size(v, depth + 1)
        on_stack.discard(key)
        memo[key] = total
        if total > MAX_EXPANDED_NODES:
            line, col = _mark(node)
            if not aliased[0]:   # a big plain document, not an alias bomb
                raise LbsceneUserError.single(
                    "LB004", "document has too many values", display, line, col,
                    value=f"more than {MAX_EXPANDED_NODES} values",
                    expected=f"at most {MAX_EXPANDED_NODES}")
            raise LbsceneUserError.single(
                "LB005", "aliases expand to too many values (alias bomb?)", display, line, col,
                value=f"more than {MAX_EXPANDED_NODES} values",
                expected=f"at most {MAX_EXPANDED_NODES}")
        return total

    size(root, 0)


class _Walker:
    """Turns a composed node graph into plain data, recording positions."""

    def __init__(self, display: str):
        self.display = display
        self.positions: dict[Path_, tuple[int, int]] = {}
        self.key_positions: dict[Path_, tuple[int, int]] = {}
        # ruamel's safe constructor resolves plain scalars (ints, floats, bools, nulls)
        self._constructor = YAML(typ="safe", pure=True).constructor

    def _error(self, node: Node, code: str, message: str, **kw) -> LbsceneUserError:
        line, col = _mark(node)
        return LbsceneUserError.single(code, message, self.display, line, col, **kw)

    def build(self, node: Node, path: Path_) -> Any:
        self.positions.setdefault(path, _mark(node))
        tag = node.tag.value if hasattr(node.tag, "value") else node.tag
        if tag not in _ALLOWED_TAGS:
            raise self._error(node, "LB006", "YAML tag not allowed", value=str(tag),
                              expected="plain scalars, lists and mappings (no tags)")
        if isinstance(node, ScalarNode):
            if tag == _STD + "str":
                return str(node.value)
            try:
                return self._constructor.construct_object(node, deep=True)
            except Exception as exc:  # malformed scalar for its resolved tag
                raise self._error(node, "LB001", f"cannot read scalar: {exc}", value=repr(node.value))
        if isinstance(node, SequenceNode):
            return [self.build(child, path + (i,)) for i, child in enumerate(node.value)]
        if isinstance(node, MappingNode):
            out: dict[Any, Any] = {}
            for knode, vnode in node.value:
                if not isinstance(knode, ScalarNode):
                    raise self._error(knode, "LB006", "mapping keys must be plain scalars")
                if knode.value == "<<":
                    raise self._error(knode, "LB006", "YAML merge keys ('<<') are not supported",
                                      expected="explicit keys (anchors/aliases on whole values are fine)")
                key = self.build(knode, path + ("<key>",))
                if not isinstance(key, (str, int)) or isinstance(key, bool):
                    raise self._error(knode, "LB101", "mapping key must be a string",
                                      value=repr(key))
                if key in out:
                    raise self._error(knode, "LB007", f"duplicate key {key!r}")
                self.key_positions[path + (key,)] = _mark(knode)
                out[key] = self.build(vnode, path + (key,))
            self.positions.pop(path + ("<key>",), None)
            return out
        raise self._error(node, "LB006", "unsupported YAML node")  # pragma: no cover
