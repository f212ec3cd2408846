"""
The built-in effects, one per module (ids are part of the file format: never rename).

The registry imports every module here on its first lookup
(:mod:`lbscene.engine.light.effects.registry`); a module registers its effect with
:func:`~lbscene.engine.light.effects.registry.register_effect`.  Each effect declares the
parameters a booth file may give it (``Params``), its physics as forward-model hooks
(:mod:`lbscene.engine.light.effects.physics`) and what the diagnosis may fit when it tries
the effect (``fit_parameters``).  A new built-in effect is a new module here.

=====================  ==========  ============================================================
id (module)            kind        physics
=====================  ==========  ============================================================
angular_profile        geometric   lamps emit I0·f(θ) (declared profile, or Gaussian σ)
interreflection        global      radiosity between floor, walls, ceiling, meshes (spectral ρ)
diffuser               geometric   plate: spectral transmittance, Fresnel angular loss,
                                   Lambertian re-emission of a diffuse fraction; a
                                   ``roughness`` plate: the rough GGX slab's T(θ) on
                                   straight paths, or its BTDF on re-emitting cells when
                                   the lobe is wide (:mod:`lbscene.engine.light.rough_slab`)
aperture_occlusion     geometric   occluders (aperture plates, panels) block lamp→point paths
tube_end_falloff       geometric   tube emission falls linearly toward the ends
spectral_filter        spectral    a filter's transmittance multiplies a lamp's spectrum
lamp_spectrum_shift    spectral    the lamps' spectrum shifted, tilted and curved (ageing)
detector_cosine_error  instrument  the meter reads cos^k or f2-type response instead of cos
reflector              geometric   a mirror behind the lamp adds a mirror image; blocks behind
=====================  ==========  ============================================================

Shared pieces live below the plugins: the diffuser plate and occluders in
:mod:`lbscene.engine.light.plates`, a lamp's spectrum after the spectral effects in
:mod:`lbscene.engine.light.lamp_spectrum`.
"""
