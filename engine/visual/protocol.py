"""
The visual-test protocol: a session's cases, its randomised balanced trial order, and
the observers' results files (CSV or JSON, as the web viewer's test mode writes them).

Order (``order.method: balanced``): one *block* per observer and repeat; each block shows
every case exactly once.  Block orders are cyclic shifts of one seeded permutation of
the cases, with the shifts spread evenly over the blocks and dealt to the blocks in a
seeded random order: across blocks, every case is seen at evenly spread serial positions
(a Latin square when the number of blocks equals the number of cases; with more blocks
than cases each position holds each case ⌊blocks/cases⌋ or ⌈blocks/cases⌉ times).
Neighbours stay the same in every block (no carry-over balancing).

Examples
--------
>>> plan = balanced_blocks(3, 3, seed=1)
>>> [sorted(b) for b in plan] == [[0, 1, 2]] * 3          # each case once per block
True
>>> sorted(b[0] for b in plan)                             # and once in each position
[0, 1, 2]
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError

__all__ = [
    "RESULTS_FORMAT",
    "RESULT_COLUMNS",
    "LoadedSession",
    "load_session",
    "balanced_blocks",
    "plan_trials",
    "read_results",
    "MAX_RESULTS_BYTES",
    "case_key",
    "case_attribute",
]

RESULTS_FORMAT = "lbscene.visual_results"
#: Columns of a results CSV (the viewer writes them in this order).
RESULT_COLUMNS = ("session", "observer", "repeat", "order", "lighting", "geometry", "sample", "display",
                  "score", "response_time_ms", "attribute")


@dataclass
class LoadedSession:
    """A session file, its samples (:class:`~lbscene.engine.scene.sample.SampleSpec`, in the
    file's order) and its trials."""

    doc: object
    samples: list
    trials: list[dict]
    hash: str

    @property
    def model(self):
        return self.doc.model

    @property
    def cases(self) -> list[tuple]:
        """(lighting, geometry, sample name), in the file's order; a case that judges a texture
        attribute has it as a fourth element (:func:`case_key`)."""
        return [case_key(lt, g, s.name, a) for lt in self.model.lightings for g in self.model.geometries
                for s in self.samples for a in self.model.attributes]

    def to_viewer(self) -> dict:
        """What the viewer's test mode needs (embedded in the web export)."""
        m = self.model
        return {"name": m.name, "hash": self.hash, "observers": [{"id": o.id} for o in m.observers],
                "repeats": m.repeats, "response": m.response.model_dump(), "trials": self.trials}


def case_key(lighting: str, geometry: str, sample: str, attribute: str = "colour") -> tuple:
    """A case: ``(lighting, geometry, sample)`` for colour (as sessions without attributes have
    always named them), ``(lighting, geometry, sample, attribute)`` for sparkle and graininess."""
    return (lighting, geometry, sample) if attribute == "colour" else (lighting, geometry, sample, attribute)


def case_attribute(case: tuple) -> str:
    """The attribute a case judges."""
    return case[3] if len(case) > 3 else "colour"


def balanced_blocks(n_cases: int, n_blocks: int, seed: int = 0) -> list[list[int]]:
    """Orders of ``n_cases`` cases for ``n_blocks`` blocks (see the module's docstring)."""
    rng = np.random.default_rng(seed)
    base = rng.permutation(n_cases)
    shifts = [(b * n_cases) // n_blocks % n_cases for b in range(n_blocks)]
    deal = rng.permutation(n_blocks)
    out = []
    for b in range(n_blocks):
        s = shifts[deal[b]]
        order = np.roll(base, -s)
        out.append([int(i) for i in order])
    return out


def plan_trials(session_model, sample_names: list[str]) -> list[dict]:
    """Every trial of a session: observer, repeat (1…), order (1… within the observer's
    session), lighting, geometry, sample, attribute."""
    m = session_model
    cases = [(lt, g, s, a) for lt in m.lightings for g in m.geometries for s in sample_names
             for a in m.attributes]
    blocks = [(o.id, r) for o in m.observers for r in range(1, m.repeats + 1)]
    orders = balanced_blocks(len(cases), len(blocks), m.order.seed)
    trials = []
    counter: dict[str, int] = {}
    for (obs, rep), order in zip(blocks, orders):
        for i in order:
            counter[obs] = counter.get(obs, 0) + 1
            lt, g, s, a = cases[i]
            trials.append({"observer": obs, "repeat": rep, "order": counter[obs], "lighting": lt,
                           "geometry": g, "sample": s, "attribute": a})
    return trials


def load_session(path: Path, allowed_dirs=()) -> LoadedSession:
    """Read and check a session file (located diagnostics for every mistake)."""
    from lbscene.engine.files.load import load_document
    from lbscene.engine.scene.sample import SampleSpec
    from lbscene.schemas.sample import Sample
    from lbscene.schemas.visual_session import VisualSession

    from lbscene.engine.files.limits import check_work

    doc = load_document(Path(path), VisualSession, allowed_dirs=allowed_dirs)
    m = doc.model
    # every trial is planned, embedded in the viewer and answered: bounded before any is made
    check_work("trials", len(m.observers) * m.repeats * len(m.lightings) * len(m.geometries) * len(m.samples),
               doc.locate("observers"), what=f"trials of session {m.name!r} ({len(m.observers)} observers × "
               f"{m.repeats} repeats × {len(m.lightings) * len(m.geometries) * len(m.samples)} cases)")
    samples = []
    for i, ref in enumerate(doc.model.samples):
        sdoc = load_document(doc.resolve(ref), Sample, allowed_dirs=allowed_dirs)
        samples.append(SampleSpec.from_document(sdoc))
    names = [s.name for s in samples]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise LbsceneUserError(Diagnostic("LB702", f"two samples of the session have the name {dup[0]!r}",
                                          doc.locate("samples"), value=", ".join(dup),
                                          expected="samples with distinct names (cases are named by them)"))
    trials = plan_trials(doc.model, names)
    digest = hashlib.sha256(json.dumps({"session": doc.model.model_dump(mode="json"), "samples": [
        s.digest() for s in samples]}, sort_keys=True).encode()).hexdigest()[:16]
    return LoadedSession(doc=doc, samples=samples, trials=trials, hash=digest)


def _err(code, message, file, line=0, **kw):
    # a CSV row (or JSON line) is located at its first column
    return LbsceneUserError.single(code, message, file, line, 1 if line else 0, **kw)


#: Largest results file read (a panel of 16 observers writes a few hundred kB).
MAX_RESULTS_BYTES = 32 * 1024 * 1024


def _number(value, what: str, where, *, whole: bool = False, minimum: float | None = None):
    """A results field as a finite number (an integer when ``whole``), else the located ``LB710``.

    ``where`` is ``(file, line, item)``: a CSV row by its line, a JSON response by its index.
    """
    import math

    shown, line, item = where
    ok = not isinstance(value, bool) and (isinstance(value, (int, float)) or isinstance(value, str))
    x = math.nan
    if ok:
        try:
            x = float(value)
        except (TypeError, ValueError, OverflowError):
            x = math.nan
    if not math.isfinite(x) or (whole and x != int(x)) or (minimum is not None and x < minimum):
        need = ("a whole number" if whole else "a finite number") + \
            (f" ≥ {minimum:g}" if minimum is not None else "")
        raise _err("LB710", f"{item}{what} must be {need}", shown, line,
                   value=repr(value)[:60], expected=need)
    return int(x) if whole else x


def _text(value, what: str, where) -> str:
    shown, line, item = where
    if not isinstance(value, str):
        raise _err("LB710", f"{item}{what} must be text", shown, line, value=repr(value)[:60],
                   expected="a string")
    return value


def read_results(paths, session: LoadedSession) -> list[dict]:
    """Rows of results files (CSV with :data:`RESULT_COLUMNS` or the viewer's JSON),
    checked against the session: each row gets ``case`` = (lighting, geometry, sample[, attribute])
    (:func:`case_key`; files without an ``attribute`` column judge colour).

    Every file is read bounded (:data:`MAX_RESULTS_BYTES`), as UTF-8 text; every field is
    checked for its type (a JSON score of ``true``, ``"NaN"``, a list …) with the row's line (CSV)
    or the response's index (JSON): ``LB710``; what does not match the session: ``LB711``.
    """
    from lbscene.engine.files.load import display_path
    from lbscene.engine.files.yamlio import csv_rows, parse_json_text, read_text_bounded

    m = session.model
    cases = set(session.cases)
    observers = {o.id for o in m.observers}
    r = m.response
    rows: list[dict] = []
    seen: dict[tuple, str] = {}
    for path in paths:
        path = Path(path)
        shown = display_path(path)
        text = read_text_bounded(path, shown, MAX_RESULTS_BYTES)
        if path.suffix.lower() == ".json":
            d = parse_json_text(text, shown)
            if not isinstance(d, dict) or d.get("format") != RESULTS_FORMAT:
                raise _err("LB710", f"not an {RESULTS_FORMAT} file", shown, 1,
                           expected="the JSON the viewer's test mode writes")
            if d.get("session") != m.name:
                raise _err("LB711", f"results of session {d.get('session')!r}, not {m.name!r}", shown, 1,
                           expected=f"results of session {m.name!r}")
            responses = d.get("responses", [])
            if not isinstance(responses, list) or not all(isinstance(it, dict) for it in responses):
                raise _err("LB710", "'responses' must be a list of objects", shown, 1,
                           value=type(responses).__name__, expected="[{observer, repeat, lighting, …}, …]")
            items = [(None, f"responses[{i}]: ", it) for i, it in enumerate(responses)]
        else:
            table = csv_rows(text, shown)
            header = [h.strip() for h in table[0][1]] if table else []
            missing = [c for c in ("observer", "repeat", "lighting", "geometry", "sample", "score")
                       if c not in header]
            if missing:
                raise _err("LB710", f"missing column(s): {', '.join(missing)}", shown, 1,
                           expected=f"a CSV with columns {', '.join(RESULT_COLUMNS)}")
            items = []
            for line, row in table[1:]:
                if not any(c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise _err("LB710", f"row has {len(row)} fields, header has {len(header)}", shown, line)
                items.append((line, "", dict(zip(header, row))))
        for line, item, it in items:
            where = (shown, line or 0, item)
            if it.get("session") not in (None, "", m.name):
                raise _err("LB711", f"{item}row of session {it.get('session')!r}, not {m.name!r}", shown,
                           line or 0, expected=f"results of session {m.name!r}")
            for k in ("observer", "repeat", "lighting", "geometry", "sample", "score"):
                if k not in it:
                    raise _err("LB710", f"{item}missing field {k!r}", shown, line or 0,
                               expected="observer, repeat, lighting, geometry, sample, score")
            score = _number(it["score"], "score", where)
            repeat = _number(it["repeat"], "repeat", where, whole=True, minimum=1)
            attribute = it.get("attribute")
            case = case_key(*(_text(it[k], k, where) for k in ("lighting", "geometry", "sample")),
                            _text(attribute, "attribute", where) if attribute not in (None, "") else "colour")
            obs = _text(it["observer"], "observer", where)
            if case not in cases:
                raise _err("LB711", f"{item}case {' / '.join(case)} is not in session {m.name!r}", shown,
                           line or 0, expected="a lighting, geometry and sample of the session"
                           if m.attributes == ["colour"] else
                           "a lighting, geometry, sample and attribute of the session")
            if obs not in observers:
                raise _err("LB711", f"{item}observer {obs!r} is not in session {m.name!r}", shown, line or 0,
                           expected=f"one of {', '.join(sorted(observers))}")
            if repeat > m.repeats:
                raise _err("LB711", f"{item}repeat {repeat} is beyond the session's {m.repeats}", shown,
                           line or 0, expected=f"a repeat from 1 to {m.repeats}")
            if r.type == "grey_scale" and not (r.min - 1e-9 <= score <= r.max + 1e-9):
                raise _err("LB710", f"{item}score {score:g} is outside the grey scale {r.min:g}–{r.max:g}",
                           shown, line or 0)
            if r.type == "delta_e_estimate" and score < 0:
                raise _err("LB710", f"{item}ΔE estimate {score:g} is negative", shown, line or 0)
            key = (obs, repeat, case)
            if key in seen:
                raise _err("LB711", f"{item}second answer of observer {key[0]} to case {' / '.join(case)} in "
                                    f"repeat {repeat} (first in {seen[key]})", shown, line or 0,
                           expected="one answer per observer, repeat and case (each results file once)")
            seen[key] = shown + (f":{line}" if line else f" {item.rstrip(': ')}")
            rt = it.get("response_time_ms")
            rows.append({"observer": obs, "repeat": repeat, "case": case, "score": score,
                         "response_time_ms": float("nan") if rt in (None, "")
                         else _number(rt, "response_time_ms", where, minimum=0),
                         "source": shown})
    if not rows:
        raise _err("LB710", "no responses in the results", ", ".join(display_path(Path(p)) for p in paths))
    return rows
