"""
Files: reading and writing safely, located diagnostics, bounds and caches.

The lowest layer of the engine.  It owns safe YAML reading with positions
(:mod:`~lbscene.engine.files.yamlio`), the ``LB…`` diagnostics and the user-error type
(:mod:`~lbscene.engine.files.diagnostics`), parse → schema validation of a document
(:mod:`~lbscene.engine.files.load`), the output policy (:mod:`~lbscene.engine.files.outputs`)
and atomic writes (:mod:`~lbscene.engine.files.atomic`), the geometry disk cache
(:mod:`~lbscene.engine.files.disk_cache`), the bounds on the work
(:mod:`~lbscene.engine.files.limits`), the shipped booths and displays
(:mod:`~lbscene.engine.files.shipped`) and worker pools (:mod:`~lbscene.engine.files.parallel`).

May import: :mod:`lbscene.schemas` (and no other part of lbscene).
"""
