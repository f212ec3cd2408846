"""
The effect registry: physical effects are plugins, looked up by id.

An effect is a class deriving from :class:`Effect` with a unique ``id``, a
pydantic ``Params`` model (the keys a booth file may write under
``effects: {<id>: {...}}``) and the physics hooks the forward model calls.
Built-in effects live in :mod:`lbscene.engine.light.effects.catalog`; third-party
packages register theirs through the ``lbscene.effects`` entry-point group::

    [project.entry-points."lbscene.effects"]
    my_effect = "my_pkg.effects:MyEffect"

Nothing is hard-wired: the booth schema accepts any registered id, the
diagnosis tries every registered effect that a booth does not enable.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import ClassVar

from lbscene.schemas.base import StrictModel

__all__ = ["Effect", "EffectParams", "register_effect", "get_effect", "available_effects",
           "UnknownEffectError"]


class EffectParams(StrictModel):
    """Base of every effect's parameter model (unknown keys are errors)."""


class Effect:
    """Base class of a physical effect plugin (see :mod:`lbscene.engine.light.effects.catalog`)."""

    id: ClassVar[str]
    Params: ClassVar[type[EffectParams]] = EffectParams
    summary: ClassVar[str] = ""
    #: 'geometric', 'spectral', 'instrument' or 'global' (used by diagnosis and planning)
    kind: ClassVar[str] = "geometric"


class UnknownEffectError(KeyError):
    pass


_REGISTRY: dict[str, type[Effect]] = {}
_LOADED = False


def register_effect(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect to the registry (ids are unique)."""
    eid = getattr(cls, "id", None)
    if not eid or not isinstance(eid, str):
        raise TypeError(f"{cls.__name__} needs a string class attribute 'id'")
    from .physics import PhysicalEffect, check_effect_class

    if issubclass(cls, PhysicalEffect):
        check_effect_class(cls)        # unknown hook names, wrong arities, unknown backends
    if eid in _REGISTRY and _REGISTRY[eid] is not cls:
        raise ValueError(f"effect id {eid!r} is already registered by {_REGISTRY[eid].__module__}")
    _REGISTRY[eid] = cls
    return cls


def _load() -> None:
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    from . import catalog  # noqa: F401  (registers the built-in effects)

    for ep in entry_points(group="lbscene.effects"):
        cls = ep.load()
        register_effect(cls)


def available_effects() -> dict[str, type[Effect]]:
    """All registered effects, by id (built-ins and entry points)."""
    _load()
    return dict(sorted(_REGISTRY.items()))


def get_effect(effect_id: str) -> type[Effect]:
    _load()
    try:
        return _REGISTRY[effect_id]
    except KeyError:
        raise UnknownEffectError(effect_id) from None
