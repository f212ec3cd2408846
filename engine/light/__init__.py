"""
Light: light transport in a booth.

It owns what each lamp type emits (:mod:`~lbscene.engine.light.emitters`), the booth's
geometry for light (shapes, visibility, patches, form factors:
:mod:`~lbscene.engine.light.geometry`), the analytic forward model
(:mod:`~lbscene.engine.light.forward`), radiosity between surfaces
(:mod:`~lbscene.engine.light.radiosity`), the rough glass slab
(:mod:`~lbscene.engine.light.rough_slab`, with its tables in ``data/rough_slab``), the
diffuser plate and occluders as the transport sees them
(:mod:`~lbscene.engine.light.plates`) and the effect plugins
(:mod:`~lbscene.engine.light.effects`: registry, hook interface, built-ins).

It works on a compiled scene IR handed to it and never imports the scene layer.

May import: :mod:`lbscene.engine.files`, :mod:`lbscene.engine.spectra`,
:mod:`lbscene.engine.colour` and :mod:`lbscene.schemas`.
"""
