"""
``interreflection``: radiosity between floor, walls, ceiling and meshes (spectral ρ).

Kind ``global``.  Its one hook, ``global_transport``, hands the forward model a
:class:`~lbscene.engine.light.radiosity.RadiosityTransport`: the light the booth's
surfaces (and meshes such as a luminaire cavity) exchange, solved per band.
"""

from __future__ import annotations

from pydantic import Field

from lbscene.engine.light.effects.physics import PhysicalEffect
from lbscene.engine.light.effects.registry import EffectParams, register_effect

__all__ = ["InterreflectionEffect"]


@register_effect
class InterreflectionEffect(PhysicalEffect):
    id = "interreflection"
    summary = ("Light reflected between floor, walls, ceiling and meshes such as a luminaire cavity "
               "(radiosity with spectral reflectances).")
    kind = "global"
    order = 900
    fit_parameters = {"reflectance_scale": (0.05, 2.5)}
    fit_initial = {"reflectance_scale": 1.0}

    class Params(EffectParams):
        patch_size_mm: float = Field(100.0, gt=1, le=1000,
                                     description="Radiosity patch size (smaller: finer, slower).")
        max_bounces: int = Field(0, ge=0, le=100, description="0: solve to convergence.")
        reflectance_scale: float = Field(1.0, gt=0, le=3,
                                         description="Multiplier on all surface reflectances "
                                                     "(clipped at 0.99).")
        mesh_patch_size_mm: float | None = Field(None, gt=1, le=1000,
                                                 description="Patch size on the booth's meshes "
                                                             "(default: a third of the smallest "
                                                             "mesh's smallest extent, at most "
                                                             "patch_size_mm).")
        meshes: bool = Field(True, description="Include the booth's meshes (luminaire cavity, "
                                               "props): both faces reflect, and they block light "
                                               "between surfaces (visibility tested).")
        lamp_bodies: bool = Field(True, description="Lamp bodies (a tube's cylinder, a panel, a "
                                                    "bulb's sphere) block light between surfaces "
                                                    "and other lamps' light on them (absorbing).")

    @classmethod
    def applicable(cls, ir, lighting):
        return None if ir.surfaces else "the booth has no interior surfaces"

    #: the diagnosis refits every candidate: it solves radiosity on patches at least this coarse
    diagnosis_patch_mm: float = 100.0

    @classmethod
    def diagnosis_params(cls, params: dict) -> dict:
        """Parameters used for the diagnosis' many refits (coarser patches: ~0.2 % of the
        illuminance on the test booths, far below meter noise; 16× fewer unknowns than 50 mm)."""
        out = dict(params or {})
        out["patch_size_mm"] = max(float(out.get("patch_size_mm", 100.0)), cls.diagnosis_patch_mm)
        return out

    @classmethod
    def refit_cost_s(cls, ir, params: dict, lighting: str | None = None) -> float:
        """Rough seconds per forward evaluation when ``reflectance_scale`` changes (LU per band;
        the same in every lighting)."""
        ps = float((params or {}).get("patch_size_mm", 100.0))
        meshes = bool((params or {}).get("meshes", True))
        n = sum(s.area_mm2() for s in ir.surfaces if s.role != "mesh") / ps ** 2
        if meshes:
            from lbscene.engine.light.radiosity import mesh_patch_size_mm

            # both faces of a mesh are patches, at the (finer) mesh patch size
            n += sum(2.0 * s.area_mm2() for s in ir.surfaces if s.role == "mesh") / \
                mesh_patch_size_mm(ir, ps, (params or {}).get("mesh_patch_size_mm")) ** 2
        return 16 * 0.8 * (n / 1000.0) ** 3

    @staticmethod
    def global_transport(ctx, p, model):
        from lbscene.engine.light.radiosity import radiosity_transport

        return radiosity_transport(ctx, p, model)
