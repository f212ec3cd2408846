"""
Spatial dithering with a blue-noise threshold mask before 8-bit quantisation.

A smooth gradient quantised to 8 bits by rounding shows bands: inside each
band every pixel carries the same error, a sawtooth of ±½ code across the
gradient.  Adding a threshold ``n`` in [0, 1) before truncation,
``q = floor(255·d + n)``, makes each pixel round up with probability equal to
its fractional part, so the *local mean* of the codes equals the target; a
blue-noise mask puts that noise at high spatial frequencies where the eye
averages it away (Ulichney 1993).

The mask is generated here (void-and-cluster, Ulichney 1993, toroidal
Gaussian energy with σ = 1.5 px, fixed seed): nothing is downloaded, and the
same arguments always give the same mask.  Its values are ``(rank + ½)/N²``:
each threshold occurs exactly once per tile, so any constant level is
reproduced exactly on average over one tile.

The realtime runtime mirrors :func:`dither_quantise` in
``runtimes/shaders/lib_dither.glsl``: the mask is tiled from the pixel (x, y)
= (column, row), and channel c reads it at the offset
:func:`channel_offsets_xy` ``[c]`` (pixels, x then y), so the
three channels' errors are not correlated (the runtime stores the shifted
masks in the noise texture's G and B channels: one texel read per pixel).  The shader indexes by
``gl_FragCoord`` (origin at the bottom-left), so it reproduces
:func:`dither_quantise` bit for bit on an image whose row 0 is the bottom row
(the order ``glReadPixels`` returns); flip a top-row-first image before and
after to compare.

Examples
--------
>>> import numpy as np
>>> mask = blue_noise(16)
>>> sorted(np.round(mask.ravel() * 256 - 0.5).astype(int).tolist()) == list(range(256))
True
>>> ramp = np.tile(np.linspace(0.2, 0.25, 256), (16, 1))
>>> codes = dither_quantise(ramp, mask)
>>> codes.dtype.name, abs(codes.mean() - ramp.mean() * 255) < 0.02
('uint8', True)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = [
    "blue_noise",
    "blue_noise_mask",
    "white_noise_mask",
    "channel_offsets_xy",
    "dither_quantise",
    "quantise_nearest",
    "radial_power_spectrum",
    "banding_metrics",
]


def channel_offsets_xy(size: int) -> tuple[tuple[int, int], ...]:
    """(x, y) offsets at which channels R, G, B read a size-``s`` mask:
    ``(0, 0), (s//2, s//3), (s//3, s//2)`` (integer division, as in the GLSL shader)."""
    return ((0, 0), (size // 2, size // 3), (size // 3, size // 2))


def _toroidal_gaussian(size: int, sigma: float) -> np.ndarray:
    d = np.minimum(np.arange(size), size - np.arange(size)).astype(float)
    return np.exp(-(d[:, None] ** 2 + d[None, :] ** 2) / (2.0 * sigma * sigma))


@lru_cache(maxsize=8)
def _void_and_cluster(size: int, seed: int, sigma: float, initial_fraction: float) -> np.ndarray:
    n = size * size
    kernel = _toroidal_gaussian(size, sigma)
    # kernel tiled 2×2: the kernel centred on (i, j) is the view [s-i:2s-i, s-j:2s-j]
    big = np.tile(kernel, (2, 2))

    def centred(idx: int) -> np.ndarray:
        i, j = divmod(idx, size)
        return big[size - i: 2 * size - i, size - j: 2 * size - j]

    rng = np.random.default_rng(seed)
    ones = max(1, int(round(initial_fraction * n)))
    pattern = np.zeros((size, size), bool)
    pattern.flat[rng.choice(n, ones, replace=False)] = True
    energy = np.real(np.fft.ifft2(np.fft.fft2(pattern.astype(float)) * np.fft.fft2(kernel)))

    # 1. initial binary pattern: move the tightest cluster into the largest void until stable
    for _ in range(10 * n):
        c = int(np.argmax(np.where(pattern, energy, -np.inf)))
        pattern.flat[c] = False
        energy -= centred(c)
        v = int(np.argmin(np.where(pattern, np.inf, energy)))
        pattern.flat[v] = True
        energy += centred(v)
        if v == c:
            break
    rank = np.empty(n, np.int64)
    # 2. phase 1: remove tightest clusters from the initial pattern, ranks ones-1 … 0
    p, e = pattern.copy(), energy.copy()
    for r in range(ones - 1, -1, -1):
        c = int(np.argmax(np.where(p, e, -np.inf)))
        p.flat[c] = False
        e -= centred(c)
        rank[c] = r
    # 3. phases 2 and 3: fill the largest voids, ranks ones … n-1.  (Ulichney's phase 3,
    # "tightest cluster of minority zeros", picks the same pixel: for a toroidal kernel the
    # zeros' energy is the kernel sum minus the ones' energy.)
    p, e = pattern.copy(), energy.copy()
    for r in range(ones, n):
        v = int(np.argmin(np.where(p, np.inf, e)))
        p.flat[v] = True
        e += centred(v)
        rank[v] = r
    mask = ((rank.reshape(size, size) + 0.5) / n).astype(np.float64)
    mask.setflags(write=False)
    return mask


def blue_noise(size: int = 64, *, seed: int = 0, sigma: float = 1.5,
               initial_fraction: float = 0.1) -> np.ndarray:
    """Blue-noise threshold mask by void-and-cluster (deterministic).

    Parameters
    ----------
    size
        Side of the square tile in pixels (4–256; 64 takes ~0.2 s, 128 ~1.5 s; cached).
    seed
        Seed of the initial random pattern.
    sigma
        Standard deviation of the Gaussian energy filter, px (Ulichney: 1.5).
    initial_fraction
        Fraction of minority pixels in the initial pattern.

    Returns
    -------
    numpy.ndarray
        (size, size) float64, read-only; every value ``(rank + 0.5)/size²`` occurs once.
    """
    size = int(size)
    if not 4 <= size <= 256:
        raise ValueError(f"blue-noise size must be 4..256, got {size}")
    if not 0 < initial_fraction < 0.5:
        raise ValueError("initial_fraction must be in (0, 0.5)")
    return _void_and_cluster(size, int(seed), float(sigma), float(initial_fraction))


#: Alias: the name the rest of the project uses for the generator.
blue_noise_mask = blue_noise


def white_noise_mask(size: int = 64, *, seed: int = 0) -> np.ndarray:
    """Baseline: the same thresholds ``(rank + ½)/N²`` in a random (white-noise) order."""
    rng = np.random.default_rng(seed)
    n = size * size
    return ((rng.permutation(n) + 0.5) / n).reshape(size, size)


def _tiled(mask: np.ndarray, height: int, width: int, dx: int, dy: int) -> np.ndarray:
    s0, s1 = mask.shape
    rows = (np.arange(height) + dy) % s0
    cols = (np.arange(width) + dx) % s1
    return mask[rows[:, None], cols[None, :]]


def dither_quantise(rgb_float, mask, *, levels: int = 255) -> np.ndarray:
    """Quantise drive values in [0, 1] to 8-bit codes with a threshold mask.

    ``code = clip(floor(levels·d + n), 0, levels)`` with ``n`` the mask tiled over
    the image (``mask`` may be ``None``: ``n = ½``, plain rounding).

    Parameters
    ----------
    rgb_float
        (H, W) or (H, W, C) drive values; NaN is not allowed.
    mask
        (s, s) thresholds in [0, 1) from :func:`blue_noise`, or None.
    levels
        Highest code (255 for 8 bits; above 255 the result is uint16).

    Returns
    -------
    numpy.ndarray
        uint8 codes of the same shape.
    """
    d = np.asarray(rgb_float, float)
    if d.ndim not in (2, 3):
        raise ValueError("rgb_float must be (H, W) or (H, W, C)")
    if not np.all(np.isfinite(d)):
        raise ValueError("rgb_float contains NaN or infinite values")
    if not 1 <= levels <= 65535:
        raise ValueError("levels must be 1..65535")
    h, w = d.shape[:2]
    if mask is None:
        n = np.full(d.shape, 0.5)
    else:
        m = np.asarray(mask, float)
        if m.ndim != 2 or m.shape[0] != m.shape[1]:
            raise ValueError("mask must be a square (s, s) array")
        offs = channel_offsets_xy(m.shape[0])
        if d.ndim == 2:
            n = _tiled(m, h, w, *offs[0])
        else:
            n = np.stack([_tiled(m, h, w, *offs[c % 3]) for c in range(d.shape[2])], axis=-1)
    return np.clip(np.floor(d * levels + n), 0, levels).astype(np.uint8 if levels <= 255 else np.uint16)


def quantise_nearest(rgb_float, *, levels: int = 255) -> np.ndarray:
    """Plain rounding to the nearest code (the banding baseline)."""
    return dither_quantise(rgb_float, None, levels=levels)


def radial_power_spectrum(mask) -> tuple[np.ndarray, np.ndarray]:
    """Radially averaged power spectrum of a square mask (mean removed).

    Returns
    -------
    (frequency, power)
        Frequencies in cycles/pixel (0 < f ≤ 0.5·√2, integer radii of the DFT
        divided by the size) and the mean |DFT|²/N² at each, normalised so that
        white noise of the same variance has power 1 at every frequency.
    """
    m = np.asarray(mask, float)
    s = m.shape[0]
    f = np.fft.fft2(m - m.mean())
    p = np.abs(f) ** 2 / m.size
    var = m.var()
    k = np.fft.fftfreq(s) * s
    r = np.rint(np.hypot(k[:, None], k[None, :])).astype(int)
    radii = np.arange(1, r.max() + 1)
    power = np.array([p[r == i].mean() for i in radii]) / var
    return radii / s, power


def banding_metrics(codes, target, *, strip_px: int = 8, sigma_px: float = 2.0,
                    levels: int = 255) -> dict:
    """How visible quantisation is on a horizontal gradient.

    Parameters
    ----------
    codes
        (H, W) quantised codes.
    target
        (H, W) or (W,) drive values in [0, 1] the codes stand for.
    strip_px
        Width of the column strips whose mean error is measured.
    sigma_px
        Gaussian blur (a stand-in for the eye's spatial averaging at viewing
        distance) before measuring the residual error.

    Returns
    -------
    dict
        ``mean_error_codes`` (overall), ``strip_mean_error_std_codes`` and
        ``strip_mean_error_max_codes`` (spread of the mean error over strips of
        ``strip_px`` columns: the banding), ``blurred_rms_codes`` (RMS of the
        blurred error) and ``pixel_rms_codes`` (RMS error per pixel, the noise
        added).  All in codes (1 = one 8-bit step).
    """
    from scipy.ndimage import gaussian_filter

    c = np.asarray(codes, float)
    t = np.broadcast_to(np.asarray(target, float) * levels, c.shape)
    err = c - t
    w = err.shape[1] // strip_px * strip_px
    strips = err[:, :w].reshape(err.shape[0], -1, strip_px).mean(axis=(0, 2))
    blurred = gaussian_filter(err, sigma_px, mode="wrap")
    return {
        "mean_error_codes": float(err.mean()),
        "strip_mean_error_std_codes": float(strips.std()),
        "strip_mean_error_max_codes": float(np.abs(strips).max()),
        "blurred_rms_codes": float(np.sqrt(np.mean(blurred ** 2))),
        "pixel_rms_codes": float(np.sqrt(np.mean(err ** 2))),
    }
