"""Procedural albedo textures (linear RGB, numpy) for the synthetic scenes.

Each generator returns a :class:`Texture`: a small tileable image and the size in metres of one
tile, so a material can map mesh texture coordinates (metres) onto it. Colours are linear albedo,
kept within what real materials reflect (about 0.03-0.85).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Texture:
    """A tileable albedo image.

    Attributes:
        image: ``H x W x 3`` float32 linear albedo in [0, 1].
        period: ``(u, v)`` size of one tile in metres.
    """

    image: np.ndarray
    period: tuple[float, float]


def periodic_noise(rng: np.random.Generator, size: int, beta: float = 2.0) -> np.ndarray:
    """Tileable ``size x size`` noise with a ``1/f^beta`` power spectrum, zero mean, unit std."""
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.fftfreq(size)[None, :]
    f = np.sqrt(fx**2 + fy**2)
    f[0, 0] = 1.0
    spectrum = (rng.normal(size=(size, size)) + 1j * rng.normal(size=(size, size))) / f ** (
        beta / 2
    )
    spectrum[0, 0] = 0.0
    out = np.real(np.fft.ifft2(spectrum))
    return (out / (out.std() + 1e-12)).astype(np.float32)


def _clip(img: np.ndarray) -> np.ndarray:
    return np.clip(img, 0.02, 0.9).astype(np.float32)


def random_colour(
    rng: np.random.Generator, lo: float = 0.05, hi: float = 0.7, saturation: float = 0.5
) -> np.ndarray:
    """A random linear albedo: a grey level times a tint of limited saturation."""
    grey = rng.uniform(lo, hi)
    tint = 1.0 + saturation * rng.uniform(-1.0, 1.0, 3)
    c = grey * tint / tint.mean()
    return np.clip(c, 0.02, 0.9)


def plain(
    rng: np.random.Generator, colour: np.ndarray, variation: float = 0.08, period: float = 4.0
) -> Texture:
    """A colour with faint low-frequency variation (paint, plaster, concrete)."""
    n = periodic_noise(rng, 32, 2.5)[..., None]
    return Texture(_clip(colour * (1 + variation * n)), (period, period))


def grainy(
    rng: np.random.Generator,
    colour: np.ndarray,
    variation: float = 0.25,
    period: float = 1.0,
    size: int = 64,
    beta: float = 1.0,
) -> Texture:
    """High-frequency noise around a colour (asphalt, gravel, sand, grass, snow)."""
    n = periodic_noise(rng, size, beta)[..., None]
    low = periodic_noise(rng, size, 3.0)[..., None]
    img = colour * (1 + variation * n) * (1 + 0.1 * low)
    return Texture(_clip(img), (period, period))


def bricks(
    rng: np.random.Generator,
    colour: np.ndarray,
    mortar: np.ndarray,
    brick: tuple[float, float] = (0.24, 0.075),
    joint: float = 0.012,
) -> Texture:
    """Running-bond brickwork: 8 courses of 4 bricks per tile, per-brick colour jitter."""
    px = 16  # pixels per brick height
    bw, bh = brick
    w_px = int(round(px * bw / bh))
    rows, cols = 8, 4
    img = np.empty((rows * px, cols * w_px, 3), np.float32)
    jpx = max(1, int(round(px * joint / bh)))
    for r in range(rows):
        offset = (w_px // 2) * (r % 2)
        for c in range(cols + 1):
            col = colour * rng.uniform(0.75, 1.2) * (1 + 0.08 * rng.uniform(-1, 1, 3))
            x0 = c * w_px - offset
            xs = np.arange(x0, x0 + w_px) % img.shape[1]
            img[r * px : (r + 1) * px, xs] = col
        img[r * px : r * px + jpx] = mortar
    for r in range(rows):
        offset = (w_px // 2) * (r % 2)
        for c in range(cols + 1):
            x = (c * w_px - offset) % img.shape[1]
            img[r * px : (r + 1) * px, x : x + jpx] = mortar
    img *= 1 + 0.06 * rng.normal(size=img.shape[:2])[..., None]
    return Texture(_clip(img[::-1]), (cols * bw, rows * bh))


def tiles(
    rng: np.random.Generator,
    colour: np.ndarray,
    grout: np.ndarray,
    tile: float = 0.4,
    n: int = 4,
    jitter: float = 0.15,
    checker: np.ndarray | None = None,
) -> Texture:
    """Square paving / floor tiles with grout lines, optional checkerboard second colour."""
    px = 16
    img = np.empty((n * px, n * px, 3), np.float32)
    for i in range(n):
        for j in range(n):
            base = checker if (checker is not None and (i + j) % 2) else colour
            img[i * px : (i + 1) * px, j * px : (j + 1) * px] = base * rng.uniform(
                1 - jitter, 1 + jitter
            )
    g = max(1, px // 12)
    for i in range(n):
        img[i * px : i * px + g] = grout
        img[:, i * px : i * px + g] = grout
    img *= 1 + 0.08 * periodic_noise(rng, n * px, 1.0)[..., None]
    return Texture(_clip(img), (n * tile, n * tile))


def stripes(
    rng: np.random.Generator,
    a: np.ndarray,
    b: np.ndarray,
    width: float = 0.3,
    vertical: bool = True,
) -> Texture:
    """Two-colour stripes (awnings, painted walls, wood cladding)."""
    img = np.empty((32, 32, 3), np.float32)
    img[:, :16] = a
    img[:, 16:] = b
    img *= 1 + 0.04 * periodic_noise(rng, 32, 1.5)[..., None]
    if not vertical:
        img = img.transpose(1, 0, 2)
    return Texture(_clip(img), (2 * width, 2 * width))


def planks(rng: np.random.Generator, colour: np.ndarray, width: float = 0.12) -> Texture:
    """Wood: planks along u with grain noise."""
    h, w = 64, 64
    img = np.empty((h, w, 3), np.float32)
    n_planks = 4
    for k in range(n_planks):
        img[k * h // n_planks : (k + 1) * h // n_planks] = colour * rng.uniform(0.8, 1.15)
        img[k * h // n_planks] = colour * 0.4
    grain = periodic_noise(rng, 64, 1.2)
    grain = np.repeat(grain[:, :8], 8, axis=1) if rng.random() < 0.5 else grain
    img *= 1 + 0.12 * grain[..., None]
    return Texture(_clip(img), (4 * width * 2, n_planks * width))


def facade(
    rng: np.random.Generator,
    wall: Texture,
    bay: float,
    storey: float,
    win_w: float,
    win_h: float,
    sill: float,
    glass: np.ndarray,
    frame: np.ndarray,
    shutters: np.ndarray | None = None,
) -> Texture:
    """One window bay (``bay x storey`` metres) over a wall texture; tiles into a window grid."""
    px_per_m = 24
    W, H = max(8, int(bay * px_per_m)), max(8, int(storey * px_per_m))
    base = wall.image
    ys = (np.arange(H) / px_per_m / wall.period[1] * base.shape[0]).astype(int) % base.shape[0]
    xs = (np.arange(W) / px_per_m / wall.period[0] * base.shape[1]).astype(int) % base.shape[1]
    img = base[ys][:, xs].copy()
    x0 = int((bay - win_w) / 2 * px_per_m)
    x1 = x0 + int(win_w * px_per_m)
    y0 = int(sill * px_per_m)
    y1 = min(H - 1, y0 + int(win_h * px_per_m))
    f = 2
    img[y0 - f : y1 + f, x0 - f : x1 + f] = frame
    ny, nx = y1 - y0, x1 - x0
    sky_reflection = np.linspace(1.6, 0.6, max(ny, 1))[:, None, None]  # brighter at the top
    g = glass * sky_reflection * (1 + 0.15 * rng.normal(size=(max(ny, 1), max(nx, 1), 1)))
    img[y0:y1, x0:x1] = g
    if rng.random() < 0.5:  # mullion / transom
        xm = (x0 + x1) // 2
        img[y0:y1, xm - 1 : xm + 1] = frame
    if shutters is not None:
        sw = max(2, (x1 - x0) // 2)
        img[y0:y1, max(0, x0 - f - sw) : x0 - f] = shutters
        img[y0:y1, x1 + f : min(W, x1 + f + sw)] = shutters
    # Image row 0 is the bottom of the tile in uv space (v up): flip.
    return Texture(_clip(img[::-1]), (bay, storey))


# --------------------------------------------------------------------------------------------
# Named material families
# --------------------------------------------------------------------------------------------


def ground_texture(rng: np.random.Generator, kind: str) -> Texture:
    """A ground material: asphalt, paving, tiles, grass, gravel, sand, snow, concrete, field."""
    c = rng.uniform
    if kind == "asphalt":
        return grainy(rng, np.array([0.07, 0.07, 0.075]) * c(0.7, 1.6), 0.35, c(0.6, 1.5))
    if kind == "paving":
        col = random_colour(rng, 0.15, 0.45, 0.25)
        return tiles(rng, col, col * 0.6, tile=c(0.2, 0.6), jitter=0.12)
    if kind == "tiles":
        a = random_colour(rng, 0.1, 0.6, 0.6)
        b = random_colour(rng, 0.1, 0.6, 0.6) if rng.random() < 0.4 else None
        return tiles(rng, a, a * 0.5 + 0.1, tile=c(0.25, 0.8), jitter=0.06, checker=b)
    if kind == "grass":
        col = np.array([0.07, 0.14, 0.03]) * c(0.6, 1.5) * (1 + 0.3 * c(-1, 1, 3))
        return grainy(rng, col, 0.45, c(0.4, 1.0), beta=0.8)
    if kind == "gravel":
        return grainy(rng, random_colour(rng, 0.15, 0.4, 0.2), 0.5, c(0.3, 0.6), beta=0.3)
    if kind == "sand":
        col = np.array([0.45, 0.36, 0.22]) * c(0.6, 1.2)
        return grainy(rng, col, 0.12, c(0.5, 2.0), beta=1.5)
    if kind == "snow":
        return grainy(rng, np.array([0.78, 0.8, 0.85]) * c(0.9, 1.05), 0.05, c(1.0, 3.0), beta=2)
    if kind == "field":  # ripe or green crops, stubble: not in GROUND_KINDS (landscapes only)
        col = (
            np.array([0.42, 0.32, 0.13]) * c(0.6, 1.2)
            if rng.random() < 0.6
            else np.array([0.12, 0.2, 0.05]) * c(0.6, 1.5)
        )
        return grainy(rng, col, 0.35, c(0.3, 1.0), beta=0.7)
    # concrete
    return grainy(rng, random_colour(rng, 0.2, 0.5, 0.1), 0.15, c(1.0, 3.0), beta=1.8)


GROUND_KINDS = ("asphalt", "paving", "tiles", "grass", "gravel", "sand", "snow", "concrete")


def wall_texture(rng: np.random.Generator) -> Texture:
    """A random wall finish: plaster, bricks, stripes, concrete or cladding."""
    r = rng.random()
    if r < 0.35:
        return plain(rng, random_colour(rng, 0.15, 0.75, 0.45))
    if r < 0.6:
        col = (
            np.array([0.3, 0.11, 0.06]) * rng.uniform(0.6, 1.6)
            if rng.random() < 0.7
            else random_colour(rng, 0.1, 0.5, 0.5)
        )
        return bricks(rng, col, random_colour(rng, 0.3, 0.6, 0.1))
    if r < 0.7:
        return stripes(
            rng,
            random_colour(rng),
            random_colour(rng),
            rng.uniform(0.1, 0.5),
            vertical=bool(rng.random() < 0.5),
        )
    if r < 0.85:
        return grainy(rng, random_colour(rng, 0.2, 0.5, 0.1), 0.12, 2.0, beta=1.8)
    return planks(rng, random_colour(rng, 0.08, 0.45, 0.5), rng.uniform(0.08, 0.2))


def object_texture(rng: np.random.Generator) -> Texture:
    """Anything for props: plain paint mostly, sometimes stripes, noise or wood."""
    r = rng.random()
    if r < 0.6:
        return plain(rng, random_colour(rng, 0.03, 0.75, 0.7), 0.05)
    if r < 0.72:
        return stripes(rng, random_colour(rng), random_colour(rng), rng.uniform(0.05, 0.3))
    if r < 0.86:
        return grainy(rng, random_colour(rng, 0.05, 0.6, 0.5), 0.2, 0.5)
    return planks(rng, random_colour(rng, 0.1, 0.45, 0.4))
