"""The diagnosis' refits run side by side in forked processes (``LBSCENE_PROCESSES``): the same
diagnosis as one after the other, whatever process computed each candidate."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

BOOTH = Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth"


def test_refits_side_by_side_give_the_diagnosis_of_the_loop(tmp_path, monkeypatch):
    """Readings with an inter-reflection the booth does not enable: every candidate refitted, in
    this process (one worker) and then side by side (two).  The same candidates come back in the
    same order with the same scores and verdict, and some of them were computed elsewhere."""
    import lbscene.engine.loop.diagnose as D
    from lbscene.engine.loop.compare import run_compare
    from lbscene.engine.truth.synthetic import synthesize

    booth = tmp_path / "booth"
    shutil.copytree(BOOTH, booth)
    m = synthesize(booth, tmp_path / "m", lighting="FL", truth_effects={"interreflection": {}},
                   noise_percent=1.0)
    monkeypatch.setenv("LBSCENE_CACHE_DIR", "off")      # no diagnosis read back from the first run
    real = D._refit

    def tagged(b, items, rival=None):
        s = real(b, items, rival)
        if s is not None:
            s.computed_by = os.getpid()                 # travels back with the suspect
        return s

    monkeypatch.setattr(D, "_refit", tagged)
    runs = {}
    for workers in ("1", "2"):
        monkeypatch.setenv("LBSCENE_PROCESSES", workers)
        runs[workers] = run_compare(m, history=False)
    one, two = runs["1"].diagnosis, runs["2"].diagnosis
    assert len(one.suspects) >= 3, "too few candidates to run side by side: nothing tested"
    assert all(s.computed_by == os.getpid() for s in one.suspects)
    assert any(s.computed_by != os.getpid() for s in two.suspects)
    assert [s.items for s in two.suspects] == [s.items for s in one.suspects]
    for a, b in zip(one.suspects, two.suspects):
        assert b.score == pytest.approx(a.score, abs=0.05), a.items
    assert str(two.verdict) == str(one.verdict) == "missing:interreflection"
