"""
The effect registry: physical effects are plugins, looked up by id.

An effect is a class deriving from :class:`Effect` with a unique ``id``, a
pydantic ``Params`` model (the keys a booth file may write under
``effects: {<id>: {...}}``) and the physics hooks the forward model calls
(:mod:`lbscene.engine.light.effects.physics`).  Built-in effects are the modules of
:mod:`lbscene.engine.light.effects.builtin`, one effect per module; third-party
packages register theirs through the ``lbscene.effects`` entry-point group::

    [project.entry-points."lbscene.effects"]
    my_effect = "my_pkg.effects:MyEffect"

Nothing is hard-wired: the booth schema accepts any registered id, the
diagnosis tries every registered effect that a booth does not enable.

Discovery
---------
The registry is the lowest module of the effect machinery: the hook interface, the
forward model, radiosity and every effect import it, and it imports none of them (an
import of the built-ins from here would close a circle: an effect's physics needs the
forward model, which looks effects up here).  Instead, on the first lookup
(:func:`get_effect`, :func:`available_effects`) it *discovers* the effects, as Mitsuba
finds its plugins: it imports by name every module of the ``builtin`` package next to
it (:data:`BUILTIN_PACKAGE`), in name order, then loads every ``lbscene.effects`` entry
point.  Importing a module registers the classes it decorates with
:func:`register_effect`.  A new built-in effect is a new module in ``builtin/``; no list
names it.  A class checks itself when it is registered (:meth:`Effect.check_class`:
:class:`~lbscene.engine.light.effects.physics.PhysicalEffect` checks its hooks).
"""

from __future__ import annotations

import pkgutil
from importlib import import_module
from importlib.metadata import entry_points
from typing import ClassVar

from lbscene.schemas.base import StrictModel

__all__ = ["Effect", "EffectParams", "register_effect", "get_effect", "available_effects",
           "changes_lamp_light", "UnknownEffectError", "BUILTIN_PACKAGE"]

#: the package whose modules are the built-in effects (imported on the first lookup)
BUILTIN_PACKAGE = __name__.rpartition(".")[0] + ".builtin"


class EffectParams(StrictModel):
    """Base of every effect's parameter model (unknown keys are errors)."""


class Effect:
    """Base class of a physical effect plugin (the built-ins: :mod:`lbscene.engine.light.effects.builtin`)."""

    id: ClassVar[str]
    Params: ClassVar[type[EffectParams]] = EffectParams
    summary: ClassVar[str] = ""
    #: 'geometric', 'spectral', 'instrument' or 'global' (used by diagnosis and planning)
    kind: ClassVar[str] = "geometric"

    @classmethod
    def check_class(cls) -> None:
        """Raise ``TypeError`` if the class breaks its interface (called by
        :func:`register_effect`; a plain :class:`Effect` has nothing to check)."""


class UnknownEffectError(KeyError):
    pass


_REGISTRY: dict[str, type[Effect]] = {}
_LOADED = False


def register_effect(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect to the registry (ids are unique)."""
    eid = getattr(cls, "id", None)
    if not eid or not isinstance(eid, str):
        raise TypeError(f"{cls.__name__} needs a string class attribute 'id'")
    if issubclass(cls, Effect):
        cls.check_class()              # a PhysicalEffect: unknown hook names, wrong arities, backends
    if eid in _REGISTRY and _REGISTRY[eid] is not cls:
        raise ValueError(f"effect id {eid!r} is already registered by {_REGISTRY[eid].__module__}")
    _REGISTRY[eid] = cls
    return cls


def _load() -> None:
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    builtin = import_module(BUILTIN_PACKAGE)
    for info in sorted(pkgutil.iter_modules(builtin.__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            import_module(f"{BUILTIN_PACKAGE}.{info.name}")   # registers its effect

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


def changes_lamp_light(effect_id: str) -> bool:
    """Whether an effect changes the light lamps send to surfaces (any hook but a meter's):
    what keys the light stored on surfaces (the inter-reflection's patches, a rough plate's
    cells) for reuse by later models."""
    cls = get_effect(effect_id)
    return any(getattr(cls, h, None) is not None for h in
               ("modify_emitters", "extra_emitters", "path_factors", "secondary_sources"))
