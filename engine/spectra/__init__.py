"""
Spectra: the 1 nm reference grid, the engine's bands, angular profiles and IES photometry.

It owns the band grid and band integration (:mod:`~lbscene.engine.spectra.bands`),
spectrum specifications evaluated into numbers with the standard data they name
(:mod:`~lbscene.engine.spectra.evaluate`) and the angular intensity profiles of lamps,
their photometric frame and IES files (:mod:`~lbscene.engine.spectra.profiles`).

May import: :mod:`lbscene.engine.files` and :mod:`lbscene.schemas`.
"""
