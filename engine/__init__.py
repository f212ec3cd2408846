"""
The engine: from booth files to predictions, products and verdicts, in layers.

Each sub-package owns one concern and imports only the layers below it (lowest
first); ``tests/test_layers.py`` checks it, function-local imports included, and
refuses any import cycle between modules.

==========  ===============================================================  ==========================
layer       owns                                                             may import
==========  ===============================================================  ==========================
``files``   reading and writing safely, located diagnostics, bounds, caches  ``lbscene.schemas``
``spectra`` spectra on the 1 nm grid and the bands, angular profiles, IES    files
``colour``  band weighting, adaptation, display model, dithering, accuracy   files, spectra
``light``   emitters, geometry, forward model, radiosity, effect plugins     files … colour
``scene``   the typed scene IR, its compiler, linter, USD stage and build    files … light
``truth``   what the model is checked against: reference engine, Mitsuba    files … scene
``loop``    the measurement loop: fit, outliers, diagnosis, plan, history    files … truth
``visual``  the visual test: protocol, model ΔE00, statistics, report        files … loop
==========  ===============================================================  ==========================

Above the engine: ``lbscene.bakers``, then ``lbscene.runtimes``, then the API and the
command line (``lbscene.api``, ``lbscene.cli``, ``lbscene.commands``).
"""
