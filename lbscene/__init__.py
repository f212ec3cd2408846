"""
lbscene: a declarative, spectral scene engine for colour-viewing light booths.

Subpackages map onto the repository's top-level folders:
``lbscene.schemas`` (schemas/), ``lbscene.engine`` (engine/),
``lbscene.bakers`` (bakers/), ``lbscene.runtimes`` (runtimes/).

The stable Python API (:mod:`lbscene.api`) is exported here: ``load_booth``,
``compile_booth``, ``ForwardModel``, ``validate``, ``build``, ``compare``, ``plan``,
``render_from_config``, ``write_report``, ``export_web``, ``bake``, ``conformance``,
``export_mitsuba``, and the error type ``LbsceneUserError``.
"""

from lbscene._version import __version__
from lbscene.api import __all__ as _API   # names only: the API module imports nothing heavy

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    # the API is imported on first use: `import lbscene` and `lbscene --help` stay light
    if name in _API:
        from lbscene import api

        return getattr(api, name)
    raise AttributeError(f"module 'lbscene' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
