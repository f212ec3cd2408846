"""Every registered effect (built-ins and entry-point plugins) keeps to the declared hook
interface of engine/light/effects/physics.py; registering anything else is an error."""

from __future__ import annotations

import inspect

import pytest

from lbscene.engine.light.effects.physics import BACKENDS, HOOKS, EffectHooks, PhysicalEffect
from lbscene.engine.light.effects.registry import Effect, available_effects, register_effect


@pytest.mark.parametrize("eid", sorted(available_effects()))
def test_registered_effect_conforms(eid):
    cls = available_effects()[eid]
    assert issubclass(cls, Effect) and cls.id == eid
    defined = [h for h in HOOKS if getattr(cls, h, None) is not None]
    if issubclass(cls, PhysicalEffect):
        assert defined, f"{eid} defines no hook"
        assert "forward" in cls.backends and set(cls.backends) <= BACKENDS
    for h in defined:
        raw = inspect.getattr_static(cls, h)
        fn = raw.__func__ if isinstance(raw, (staticmethod, classmethod)) else raw
        n = len(inspect.signature(fn).parameters) - isinstance(raw, classmethod)
        assert n == len(inspect.signature(getattr(EffectHooks, h)).parameters), (eid, h)
    # parameters: defaults validate, unknown keys are refused
    if all(f.default is not None or not f.is_required() for f in cls.Params.model_fields.values()):
        cls.Params.model_validate({})
    with pytest.raises(Exception):
        cls.Params.model_validate({"no_such_parameter_xyz": 1})


def test_unknown_hook_name_is_refused():
    class Typo(PhysicalEffect):
        id = "test_typo_hook"

        @staticmethod
        def modify_emiters(ctx, p, lamp, es):      # misspelt: would silently never run
            return es

    with pytest.raises(TypeError, match="'modify_emiters' is not a hook"):
        register_effect(Typo)
    assert "test_typo_hook" not in available_effects()


def test_wrong_hook_arity_and_unknown_backend_are_refused():
    class Arity(PhysicalEffect):
        id = "test_bad_arity"

        @staticmethod
        def path_factors(ctx, p, es):
            return None

    with pytest.raises(TypeError, match="hook path_factors takes 3 arguments, the interface 4"):
        register_effect(Arity)

    class Backend(PhysicalEffect):
        id = "test_bad_backend"
        backends = frozenset({"forward", "povray"})

    with pytest.raises(TypeError, match="backends"):
        register_effect(Backend)
