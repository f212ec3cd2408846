"""
Effect plugins: the registry, the hook interface and the built-in effects.

:mod:`~lbscene.engine.light.effects.registry` (lowest: imports no effect) finds the
effects; :mod:`~lbscene.engine.light.effects.physics` is the interface between the forward
model and an effect's hooks; :mod:`~lbscene.engine.light.effects.builtin` holds the
built-in effects, one per module.
"""
