"""
lbscene: a declarative, spectral scene engine for colour-viewing light booths.

Subpackages map onto the repository's top-level folders:
``lbscene.schemas`` (schemas/), ``lbscene.engine`` (engine/),
``lbscene.bakers`` (bakers/), ``lbscene.runtimes`` (runtimes/).
"""

__all__ = ["__version__"]
__version__ = "0.1.0"
