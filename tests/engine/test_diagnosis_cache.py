"""A finished diagnosis is kept on disk: asked again of the same booth and readings it is read, not
recomputed, and is the same result; anything the result depends on changes the key; a damaged or
foreign entry is never trusted."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import lbscene.engine.loop.compare as C
from lbscene.engine.files import disk_cache as dc
from lbscene.engine.loop import diagnosis_cache as DC
from lbscene.engine.truth.synthetic import synthesize

BOOTH = Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth"


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    root = tmp_path / "cache"
    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(root))
    return root


@pytest.fixture
def meas(tmp_path) -> Path:
    booth = tmp_path / "booth"
    shutil.copytree(BOOTH, booth)
    return synthesize(booth, tmp_path / "m", lighting="FL", truth_effects={"interreflection": {}},
                      noise_percent=1.0)


class _Counting:
    """``diagnose`` counting its calls."""

    def __init__(self):
        self.calls = 0
        self._real = C.diagnose

    def __call__(self, *a, **k):
        self.calls += 1
        return self._real(*a, **k)


@pytest.fixture
def counted(monkeypatch) -> _Counting:
    c = _Counting()
    monkeypatch.setattr(C, "diagnose", c)
    return c


def _same(a, b) -> None:
    ja, jb = a.to_json(), b.to_json()
    for j in (ja, jb):
        j.pop("timing_s", None)
    assert json.dumps(ja, sort_keys=True) == json.dumps(jb, sort_keys=True)


def test_the_same_question_is_answered_from_the_disk(cache, meas, counted):
    first = C.run_compare(meas, history=False)
    assert counted.calls == 1 and first.verdict == "missing:interreflection"
    again = C.run_compare(meas, history=False)
    assert counted.calls == 1                                 # read, not diagnosed again
    _same(first, again)
    # the objects as computed: the plan predicts with each explanation's fit
    assert C.plan_for(first).to_json() == C.plan_for(again).to_json()
    assert [type(s.fit).__name__ for s in again.diagnosis.suspects] == \
        [type(s.fit).__name__ for s in first.diagnosis.suspects]
    np.testing.assert_array_equal(again.diagnosis.suspects[0].fit.lux_pred, first.diagnosis.suspects[0].fit.lux_pred)


def test_the_cli_in_another_format_reads_the_stored_diagnosis(cache, meas, counted, run_cli, tmp_path):
    code, out, err = run_cli("compare", meas, "--no-history", "--json-out", tmp_path / "a.json")
    assert code == 0, err
    code, out2, err = run_cli("compare", meas, "--no-history", "--format", "json")
    assert code == 0, err
    assert counted.calls == 1
    a, b = json.loads((tmp_path / "a.json").read_text()), json.loads(out2)
    assert a["diagnosis"] == b["diagnosis"] and a["verdict"] == b["verdict"] == "missing:interreflection"


def _edit_reading(m: Path) -> None:
    g = m.parent / "measurements-grid.csv"
    lines = g.read_text().splitlines()
    *head, e = lines[5].split(",")
    lines[5] = ",".join(head + [f"{float(e) * 1.02:.4f}"])
    g.write_text("\n".join(lines) + "\n")


def _edit_booth(m: Path) -> None:
    b = m.parents[1] / "booth" / "booth.yaml"
    text = b.read_text()
    assert "interreflection" not in text
    b.write_text(text.replace("effects:", "effects:\n  tube_end_falloff: {}", 1) if "effects:" in text
                 else text + "effects:\n  tube_end_falloff: {}\n")


def _edit_noise(m: Path) -> None:
    m.write_text(m.read_text() + "model_uncertainty_percent: 0.5\n")


@pytest.mark.parametrize("edit", [_edit_reading, _edit_booth, _edit_noise], ids=["reading", "booth", "noise"])
def test_a_changed_input_is_diagnosed_again(cache, meas, counted, edit):
    C.run_compare(meas, history=False)
    edit(meas)
    C.run_compare(meas, history=False)
    assert counted.calls == 2


def test_changed_code_is_diagnosed_again(cache, meas, counted, monkeypatch):
    C.run_compare(meas, history=False)
    monkeypatch.setattr(DC, "_code_digest", lambda ir: "another version of the code")
    C.run_compare(meas, history=False)
    assert counted.calls == 2


def test_with_the_cache_off_nothing_is_kept(tmp_path, meas, counted, monkeypatch):
    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")
    C.run_compare(meas, history=False)
    C.run_compare(meas, history=False)
    assert counted.calls == 2


def _entry(cache: Path) -> Path:
    (entry,) = (cache / DC.KIND).glob("*.npy")
    return entry


@pytest.mark.parametrize("damage", ["garbage", "foreign-type", "object-array", "short-array", "tampered-booth"])
def test_a_damaged_entry_is_diagnosed_again_and_never_trusted(cache, meas, counted, damage):
    first = C.run_compare(meas, history=False)
    path = _entry(cache)
    data = np.load(path).tobytes()
    doc = json.loads(data)
    if damage == "garbage":
        new = b"{not json"
    elif damage == "foreign-type":
        doc["attrs"]["verdict"] = {"__dc__": "PosixPath", "attrs": {}}
        new = json.dumps(doc).encode()
    elif damage == "object-array":
        doc["attrs"]["base"]["attrs"]["lux_pred"]["__nd__"] = "|O"
        new = json.dumps(doc).encode()
    elif damage == "short-array":
        doc["attrs"]["base"]["attrs"]["lux_pred"]["shape"] = [10 ** 6]
        new = json.dumps(doc).encode()
    else:
        # an explanation's booth whose content no longer hashes to what was stored
        doc = {"__ir__": {"anything": 1}, "hash": "0" * 64}
        new = json.dumps(doc).encode()
    with pytest.raises(ValueError, match="not a stored diagnosis"):
        DC.decode(new)
    # written in place (still the cache's own file): read, rejected, recomputed and replaced
    with open(path, "r+b") as f:
        np.lib.format.write_array(f, np.frombuffer(new, np.uint8), allow_pickle=False)
        f.truncate()
    again = C.run_compare(meas, history=False)
    assert counted.calls == 2
    _same(first, again)
    C.run_compare(meas, history=False)
    assert counted.calls == 2                                  # the replaced entry is sound


def test_a_result_holding_an_unknown_object_is_returned_and_not_kept(cache, meas, monkeypatch):
    real = C.diagnose

    def odd(*a, **k):
        d = real(*a, **k)
        d.base.extra = object()
        return d

    monkeypatch.setattr(C, "diagnose", odd)
    res = C.run_compare(meas, history=False)
    assert res.verdict == "missing:interreflection"
    assert not list((cache / DC.KIND).glob("*.npy"))
    with pytest.raises(ValueError, match="a diagnosis holding an object of type object cannot be stored"):
        DC.encode(res.diagnosis)


def test_encoding_keeps_every_value_bit_for_bit():
    from lbscene.engine.loop.diagnose import Verdict
    from lbscene.engine.loop.fit import FreeParameter

    v = Verdict("unstable", effects=("a",), rivals=(("missing:a", 0.26), ("ambiguous:a,b", 0.61)),
                point=Verdict("missing", ("a",)))
    obj = {"v": v, "x": [0.1 + 0.2, float("nan"), float("-inf"), 1e-308, np.float64(2.5)],
           "a": np.arange(6, dtype=np.float32).reshape(2, 3), "m": np.array([True, False]),
           "t": (1, "s", None), "k": {1.5: "float key", ("a", "b"): 2},
           "p": FreeParameter("effect.x.y", (0.0, 1.0), 0.5)}
    back = DC.decode(DC.encode(obj))
    assert back["v"] == v and back["v"].point == v.point and isinstance(back["v"].rivals, tuple)
    assert back["x"][0] == 0.1 + 0.2 and np.isnan(back["x"][1]) and back["x"][2] == float("-inf")
    assert back["x"][3] == 1e-308 and back["x"][4] == 2.5
    assert back["a"].dtype == np.float32 and back["a"].shape == (2, 3)
    np.testing.assert_array_equal(back["a"], obj["a"])
    assert back["m"].dtype == bool and back["t"] == (1, "s", None)
    assert back["k"] == {1.5: "float key", ("a", "b"): 2}
    assert back["p"] == obj["p"] and back["p"].linear is False


def test_the_entry_lives_in_the_cache_and_counts_toward_its_bound(cache, meas, monkeypatch):
    C.run_compare(meas, history=False)
    path = _entry(cache)
    index = json.loads((cache / dc.INDEX_NAME).read_text())["entries"]
    assert f"{DC.KIND}/{path.name}" in index
    # a bound smaller than the entry: nothing kept, nothing else touched
    shutil.rmtree(cache)
    monkeypatch.setenv("LBSCENE_CACHE_MAX_MB", "0.001")
    C.run_compare(meas, history=False)
    assert not (cache / DC.KIND).exists() or not list((cache / DC.KIND).glob("*.npy"))
