"""
Colour: band weighting, chromatic adaptation, the display model, dithering, accuracy.

It owns the lighting-dependent band values of reflectances
(:mod:`~lbscene.engine.colour.band_weighting`), CAT16 adaptation
(:mod:`~lbscene.engine.colour.adaptation`), display characterisation and its inverse
(:mod:`~lbscene.engine.colour.display_model`), 8-bit dithering
(:mod:`~lbscene.engine.colour.dither`) and the colour-accuracy figures of a set of
lightings (:mod:`~lbscene.engine.colour.accuracy`, given their spectra: a booth is
compiled by the caller).

May import: :mod:`lbscene.engine.files`, :mod:`lbscene.engine.spectra` and
:mod:`lbscene.schemas`.
"""
