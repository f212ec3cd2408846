"""
Truth: what the model is checked against.

It owns the brute-force Monte Carlo reference engine (:mod:`~lbscene.engine.truth.reference`),
synthetic measurements made with it (:mod:`~lbscene.engine.truth.synthetic`), the
Mitsuba 3 truth provider (:mod:`~lbscene.engine.truth.mitsuba`) and the comparison of the
model with committed truth data (:mod:`~lbscene.engine.truth.validation`).

May import: :mod:`lbscene.engine.files`, :mod:`~lbscene.engine.spectra`,
:mod:`~lbscene.engine.colour`, :mod:`~lbscene.engine.light`, :mod:`~lbscene.engine.scene`
and :mod:`lbscene.schemas`.
"""
