"""
Loop: the measurement loop.

It owns measurement sets (:mod:`~lbscene.engine.loop.measurements`), fitting the model's
free parameters (:mod:`~lbscene.engine.loop.fit`), outlying readings
(:mod:`~lbscene.engine.loop.outliers`), the diagnosis of missing effects
(:mod:`~lbscene.engine.loop.diagnose`) and of undeclared hardware
(:mod:`~lbscene.engine.loop.hypotheses`), the readings that would settle a tie
(:mod:`~lbscene.engine.loop.plan`), the history of runs (:mod:`~lbscene.engine.loop.history`),
``compare`` itself (:mod:`~lbscene.engine.loop.compare`) and its HTML report
(:mod:`~lbscene.engine.loop.report`).

May import: :mod:`lbscene.engine.files`, :mod:`~lbscene.engine.spectra`,
:mod:`~lbscene.engine.colour`, :mod:`~lbscene.engine.light`, :mod:`~lbscene.engine.scene`,
:mod:`~lbscene.engine.truth` and :mod:`lbscene.schemas`.
"""
