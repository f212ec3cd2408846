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
        if cls.applied_by is None:
            assert defined, f"{eid} defines no hook"
        else:
            # a parameter-only effect: the effect it names applies it in its global transport
            assert not defined, f"{eid} both defines hooks and names applied_by"
            host = available_effects()[cls.applied_by]
            assert getattr(host, "global_transport", None) is not None, (eid, cls.applied_by)
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


def test_every_builtin_module_registers_the_effect_it_is_named_after():
    import pkgutil
    from importlib import import_module

    from lbscene.engine.light.effects.registry import BUILTIN_PACKAGE

    effects = available_effects()
    names = [m.name for m in pkgutil.iter_modules(import_module(BUILTIN_PACKAGE).__path__)]
    assert len(names) >= 9
    for name in names:
        assert name in effects, f"{BUILTIN_PACKAGE}.{name} registers no effect '{name}'"
        assert effects[name].__module__ == f"{BUILTIN_PACKAGE}.{name}"


PLUGIN = '''
from pydantic import Field

from lbscene.engine.light.effects.physics import PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect


@register_effect
class LampAgeing(PhysicalEffect):
    id = "test_lamp_ageing"
    summary = "Lamp output falls with burning hours."
    kind = "geometric"
    fit_parameters = {"level": (0.5, 1.0)}

    class Params(EffectParams):
        level: float = Field(1.0, gt=0, le=1, description="Relative output.")

    @staticmethod
    def modify_emitters(ctx, p, lamp, es):
        return es.with_(weights=es.weights * p.level)
'''


def test_an_entry_point_plugin_is_registered_on_first_lookup(tmp_path, monkeypatch):
    """A package that declares ``[project.entry-points."lbscene.effects"]`` (the CONTRIBUTING
    example, installed as a distribution on the path) is registered beside the built-ins."""
    import sys

    from lbscene.engine.light.effects import registry

    (tmp_path / "lbscene_test_plugin.py").write_text(PLUGIN)
    dist = tmp_path / "lbscene_test_plugin-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: lbscene-test-plugin\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text(
        "[lbscene.effects]\ntest_lamp_ageing = lbscene_test_plugin:LampAgeing\n")
    builtins = set(available_effects())
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))   # restored afterwards
    monkeypatch.setattr(registry, "_LOADED", False)
    try:
        effects = registry.available_effects()
        assert set(effects) == builtins | {"test_lamp_ageing"}
        assert effects["test_lamp_ageing"].__module__ == "lbscene_test_plugin"
        assert registry.get_effect("test_lamp_ageing").Params().level == 1.0
    finally:
        sys.modules.pop("lbscene_test_plugin", None)
