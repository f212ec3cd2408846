"""
Conformance: does a file meet lbscene's schemas and rules, and does a booth meet the viewing
standard each of its lightings names?

:mod:`~lbscene.engine.conformance.validate` is ``validate-config``: every kind of document
(booths, samples, displays, measurement sets, render configs, visual sessions) checked against
its schema and its semantic rules, which live in the layers below (this layer sits above them
all, so it may run each kind's rules).

:func:`run_conformance` judges every lighting from the forward model with the booth's
effects (and from measurements when given): colorimetry at the sample
(:mod:`~lbscene.engine.conformance.colorimetry`), illuminance and its uniformity over the
viewing area (:mod:`~lbscene.engine.conformance.evaluate`), and the checks of the
standard (:mod:`~lbscene.engine.conformance.standards`); :mod:`~lbscene.engine.conformance.report`
writes the HTML report.  :mod:`~lbscene.engine.conformance.mitsuba_export` writes the Mitsuba 3
scene the truth provider renders, for independent checks.

Layer: above :mod:`lbscene.engine.visual`.

May import: every engine layer below it (:mod:`~lbscene.engine.files` …
:mod:`~lbscene.engine.visual`) and :mod:`lbscene.schemas`.
"""

from __future__ import annotations

from .evaluate import ConformanceResult, LightingConformance, run_conformance

__all__ = ["run_conformance", "ConformanceResult", "LightingConformance"]
