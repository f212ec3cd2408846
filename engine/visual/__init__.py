"""
Visual: the visual test.

It owns the session protocol and results files (:mod:`~lbscene.engine.visual.protocol`),
the model's ΔE00 of each case (:mod:`~lbscene.engine.visual.model`), the panel's
statistics (:mod:`~lbscene.engine.visual.stats`) and ``visual-report``
(:mod:`~lbscene.engine.visual.report`).

May import: every engine layer below it (:mod:`~lbscene.engine.files` …
:mod:`~lbscene.engine.loop`) and :mod:`lbscene.schemas`.
"""
