"""
Scene: from booth files to the typed scene IR and its products.

It owns the IR (:mod:`~lbscene.engine.scene.ir`), a booth document's effect parameters
(:mod:`~lbscene.engine.scene.effect_params`), the semantic rules
(:mod:`~lbscene.engine.scene.lint`), the meshes a booth names (:mod:`~lbscene.engine.scene.meshes`),
the compiler (:mod:`~lbscene.engine.scene.compile`), samples as the renderers
need them (:mod:`~lbscene.engine.scene.sample`), the USD stage with its codeless schema
(:mod:`~lbscene.engine.scene.usd_stage`, ``usd_schema/``) and the build folder
(:mod:`~lbscene.engine.scene.build`; bake jobs and render graphs are written by the
layers above through :data:`~lbscene.engine.scene.build.PRODUCT_WRITERS`, named, not
imported).

May import: :mod:`lbscene.engine.files`, :mod:`~lbscene.engine.spectra`,
:mod:`~lbscene.engine.colour`, :mod:`~lbscene.engine.light` and :mod:`lbscene.schemas`.
"""
