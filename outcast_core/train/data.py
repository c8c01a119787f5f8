"""Training pairs from the synthetic views: resizing, tone-mapping augmentation, batches.

A view (``outcast_core.data.load_view``) holds one scene seen by one camera under ``K`` suns:
``rgb`` (``K x H x W x 3`` linear HDR), ``shadow`` (``K x H x W``), ``depth`` (``H x W``, sky
``+inf``), ``normals``, ``sky``, ``sun`` (``K x 3``) and ``fov_deg``. A training pair picks an
original sun ``i`` and a new sun ``j`` of one view. Both images are tone-mapped to sRGB with the
*same* random exposure, saturation and gamma (the exposure keyed to the original image), so the
networks learn the change of light, not a change of camera settings.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from outcast_core.runtime.geometry.camera import (
    Camera,
    focal_from_fov,
    normals_from_depth,
    valid_depth,
    view_directions,
)
from outcast_core.runtime.geometry.colour import luminance, tonemap_aces

#: Middle grey the auto exposure maps the original image's mean log luminance to.
KEY = 0.18


@dataclass
class Prepared:
    """One view at the training resolution (all float32).

    Attributes:
        rgb: ``K x H x W x 3`` linear radiance.
        shadow: ``K x H x W`` ground-truth shadow images.
        depth: ``H x W`` z depth, ``+inf`` on sky.
        normals: ``H x W x 3`` normals from the (resized) depth, as the runtime computes them.
        sun: ``K x 3`` unit sun directions.
        focal: focal length in pixels at this resolution.
        exposure: the view's exposure (``rgb * exposure`` tone-maps to a plausible photo), or 0
            when the view has none (auto exposure is used then).
        normals_true: ``H x W x 3`` the renderer's normals (the cosine of the ground-truth
            shadow images), when the view has them.
    """

    rgb: np.ndarray
    shadow: np.ndarray
    depth: np.ndarray
    normals: np.ndarray
    sun: np.ndarray
    focal: float
    exposure: float = 0.0
    normals_true: np.ndarray | None = None

    @property
    def camera(self) -> Camera:
        return Camera(self.depth.shape[0], self.depth.shape[1], self.focal)


def _block(x: np.ndarray, n: int, reduce: Callable[..., np.ndarray]) -> np.ndarray:
    """Reduce ``n x n`` blocks of the two leading spatial axes at ``axes (a, a + 1)``."""
    h, w = x.shape[:2]
    y = x[: h - h % n, : w - w % n]
    y = y.reshape(h // n, n, w // n, n, *x.shape[2:])
    return reduce(reduce(y, axis=3), axis=1)


def resize_view(view: dict[str, Any], size: int) -> Prepared:
    """Shrink a view so that its longer side is ``size`` (integer factors only).

    Radiance and shadows are block-averaged; depth keeps each block's nearest surface (the max
    of disparity, as the S network's half-resolution volume does), so a block is sky only when
    all of it is sky. Normals are recomputed from the resized depth with the runtime's
    ``normals_from_depth``. The field of view is kept.
    """
    rgb = np.asarray(view["rgb"], np.float32)
    if rgb.ndim != 4 or rgb.shape[-1] != 3:
        raise ValueError(f"expected rgb of shape K x H x W x 3, got {rgb.shape}")
    h, w = rgb.shape[1:3]
    longer = max(h, w)
    n = longer // size
    if n < 1 or longer % size or h % n or w % n:
        raise ValueError(f"expected a view size that {size} divides, got {h} x {w}")
    depth = np.asarray(view["depth"], np.float32)
    shadow = np.asarray(view["shadow"], np.float32)
    if n > 1:
        rgb = _block(np.moveaxis(rgb, 0, 2), n, np.mean)  # h x w x K x 3
        rgb = np.moveaxis(rgb, 2, 0)
        shadow = np.moveaxis(_block(np.moveaxis(shadow, 0, 2), n, np.mean), 2, 0)
        ok = valid_depth(depth)
        disp = np.where(ok, 1.0 / np.where(ok, depth, 1.0), 0.0)
        disp = _block(disp, n, np.max)
        depth = np.where(disp > 0, 1.0 / np.where(disp > 0, disp, 1.0), np.inf)
    normals_true = view.get("normals")
    if normals_true is not None:
        normals_true = np.asarray(normals_true, np.float32)
        if n > 1:
            normals_true = _block(normals_true, n, np.mean)
            norm = np.linalg.norm(normals_true, axis=-1, keepdims=True)
            normals_true = np.where(norm > 1e-6, normals_true / np.maximum(norm, 1e-6), 0.0)
        normals_true = normals_true.astype(np.float32)
    depth = depth.astype(np.float32)
    focal = focal_from_fov(depth.shape[1], float(view["fov_deg"]))
    cam = Camera(depth.shape[0], depth.shape[1], focal)
    sun = np.asarray(view["sun"], np.float32)
    sun = sun / np.linalg.norm(sun, axis=1, keepdims=True)
    return Prepared(
        np.ascontiguousarray(rgb, dtype=np.float32), np.ascontiguousarray(shadow, np.float32),
        depth, normals_from_depth(depth, cam), sun.astype(np.float32), focal,
        float(view.get("exposure", 0.0) or 0.0), normals_true,
    )


def auto_exposure(radiance_lin: np.ndarray) -> float:
    """Exposure that maps the geometric mean luminance of ``radiance_lin`` to :data:`KEY`."""
    lum = luminance(radiance_lin)
    logmean = float(np.mean(np.log(np.maximum(lum, 1e-6))))
    return KEY / math.exp(logmean)


def tonemap(
    radiance_lin: np.ndarray, exposure: float, saturation: float = 1.0, gamma: float = 1.0
) -> np.ndarray:
    """Linear HDR -> sRGB [0, 1]: exposure, saturation about the luminance, ACES, then gamma."""
    x = np.asarray(radiance_lin, np.float32) * exposure
    if saturation != 1.0:
        lum = luminance(x)[..., None]
        x = np.maximum(lum + saturation * (x - lum), 0.0)
    out = tonemap_aces(x)
    if gamma != 1.0:
        out = np.power(out, gamma)
    return out.astype(np.float32)


def tonemap_pair(
    original_lin: np.ndarray, new_lin: np.ndarray, rng: np.random.Generator | None,
    exposure_stops: float = 1.0, saturation: tuple[float, float] = (0.8, 1.2),
    gamma: tuple[float, float] = (0.9, 1.1), base_exposure: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Tone-map both images of a pair identically (random settings when ``rng`` is given).

    The base exposure is the view's own (``base_exposure > 0``: the data set's choice, the same
    for every sun of a view) or else the auto exposure of the original image.
    """
    e = base_exposure if base_exposure > 0 else auto_exposure(original_lin)
    s = g = 1.0
    if rng is not None:
        e *= 2.0 ** rng.uniform(-exposure_stops, exposure_stops)
        s = rng.uniform(*saturation)
        g = rng.uniform(*gamma)
    return tonemap(original_lin, e, s, g), tonemap(new_lin, e, s, g)


def perturb_sun(sun: np.ndarray, noise_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Rotate ``sun`` (``3``) by a random angle with std ``noise_deg`` about a random axis."""
    if noise_deg <= 0:
        return sun
    v = np.asarray(sun, np.float64) + rng.normal(size=3) * math.radians(noise_deg)
    return (v / np.linalg.norm(v)).astype(np.float32)


def _fractal_noise(h: int, w: int, rng: np.random.Generator, octaves: int = 5) -> np.ndarray:
    """Value noise in [0, 1]: random grids of doubling resolution, bilinearly upsampled, summed
    with halving amplitude."""
    import cv2

    out = np.zeros((h, w), np.float32)
    amp, total = 1.0, 0.0
    for o in range(octaves):
        cells = 2 ** (o + 1)
        gh, gw = max(2, cells * h // max(h, w) + 1), max(2, cells * w // max(h, w) + 1)
        grid = rng.random((gh, gw)).astype(np.float32)
        out += amp * cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)
        total += amp
        amp *= 0.5
    return np.clip(out / total, 0.0, 1.0)


def degrade_photo(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What a camera and a photo's path to the app do to an image, drawn at random: a white
    balance error, a little blur, sensor noise and JPEG compression (each drawn independently).

    The renders are clean; real photos are not, and the app shows ``Z`` and ``S`` a photo
    shrunk to their working size, where these survive as colour casts, softness and mottled
    flat areas. What a call draws from ``rng`` does not depend on the image (pixel noise comes
    from a generator seeded by one draw), so :meth:`PairSampler.skip` replays it on a 1 x 1
    stand-in.

    Args:
        image: ``H x W x 3`` float32 sRGB in ``[0, 1]``.
        rng: the sampler's generator.

    Returns:
        The degraded image, same shape, float32 in ``[0, 1]``.
    """
    import cv2

    gains = np.exp(rng.normal(0.0, 0.08, 3)).astype(np.float32)  # white balance, in sRGB
    blur = rng.uniform(0.3, 0.9) if rng.random() < 0.3 else 0.0
    noise = rng.uniform(0.004, 0.025) if rng.random() < 0.5 else 0.0
    quality = int(rng.integers(40, 96)) if rng.random() < 0.3 else 0
    pixel_seed = int(rng.integers(2**31))
    out = np.clip(np.asarray(image, np.float32) * gains, 0.0, 1.0)
    if blur > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur)
    if noise > 0:
        prng = np.random.default_rng(pixel_seed)
        grey = prng.normal(0.0, noise, out.shape[:2] + (1,))
        colour = prng.normal(0.0, noise * 0.5, out.shape)
        out = out + (grey + colour).astype(np.float32)
    out = np.clip(out, 0.0, 1.0)
    if quality:
        u8 = cv2.cvtColor((out * 255.0 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR)
        ok, buf = cv2.imencode(".jpg", u8, [cv2.IMWRITE_JPEG_QUALITY, quality])
        if ok:
            dec = cv2.imdecode(buf, cv2.IMREAD_COLOR)
            out = cv2.cvtColor(dec, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    return out.astype(np.float32)


def stain_photo(image: np.ndarray, surface: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Dark patches and fine texture painted into the surface's albedo, the geometry untouched.

    On real photos ``Z`` reads the photo's texture (gravel, deck boards, snow) and its own
    shadows' edges as relief, and the cosine term then marks textured flat ground as facing away
    from the sun (``models/EVAL.md``, evening notes of 2026-11-30: 21.7 % of the frame falsely
    shadowed by the cosine term at each dev photo's best sun). The renders' flat surfaces are
    plainer than a photo's, and their dark patches are almost always real shadows of real
    relief. This teaches the opposite: with the depth target unchanged, a pair's input photo
    gets, each drawn independently,

    - shadow-like stains: 1-5 dark, slightly blue patches (polygons like a building's or a
      pole's shadow, or foliage-like blobs), with soft or hard edges, that no geometry casts;
    - fine multiplicative albedo texture (speckle and streaks at 2-16 px) on the surface.

    Applied in linear light, on the surface only (never the sky). As :func:`degrade_photo`,
    what a call draws from ``rng`` does not depend on the image, so :meth:`PairSampler.skip`
    replays it on a 1 x 1 stand-in.

    Args:
        image: ``H x W x 3`` float32 sRGB in ``[0, 1]``.
        surface: ``H x W`` bool, not sky.
        rng: the sampler's generator.

    Returns:
        The stained image, same shape, float32 in ``[0, 1]``.
    """
    import cv2

    from outcast_core.runtime.geometry.colour import linear_to_srgb, srgb_to_linear

    stains = int(rng.integers(1, 6)) if rng.random() < 0.75 else 0
    dark = rng.uniform(0.2, 0.65)
    blue = rng.uniform(1.0, 1.5)
    soft = rng.uniform(0.0, 0.02) if rng.random() < 0.6 else 0.0
    texture = rng.uniform(0.08, 0.4) if rng.random() < 0.6 else 0.0
    pixel_seed = int(rng.integers(2**31))
    img = np.clip(np.asarray(image, np.float32), 0.0, 1.0)
    h, w = img.shape[:2]
    surface = np.asarray(surface, bool)
    if (not stains and not texture) or not surface.any():
        return img
    prng = np.random.default_rng(pixel_seed)
    side = max(h, w)
    log_gain = np.zeros((h, w, 3), np.float32)
    if stains:
        mask = np.zeros((h, w), np.float32)
        for _ in range(stains):
            if prng.random() < 0.5:  # a polygon: a building's, wall's, pole's or car's shadow
                centre = prng.uniform(0, 1, 2) * (w, h)
                length = prng.uniform(0.05, 0.6) * side
                width = length * prng.uniform(0.05, 0.8)
                angle = prng.uniform(0, np.pi)
                d = np.array([np.cos(angle), np.sin(angle)])
                n = np.array([-d[1], d[0]])
                corners = [centre + a * d * length / 2 + b * n * width / 2 * prng.uniform(0.6, 1.4)
                           for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
                cv2.fillPoly(mask, [np.round(np.array(corners)).astype(np.int32)], 1.0)
            else:  # foliage: a patch of thresholded noise
                n_field = _fractal_noise(h, w, prng, octaves=6)
                blob = (n_field > np.quantile(n_field, 1.0 - prng.uniform(0.05, 0.35)))
                cy, cx = prng.uniform(0, 1, 2) * (h, w)
                r = prng.uniform(0.15, 0.5) * side
                yy, xx = np.mgrid[0:h, 0:w]
                mask = np.maximum(mask, (blob & ((yy - cy) ** 2 + (xx - cx) ** 2 < r * r))
                                  .astype(np.float32))
        if soft > 0:
            mask = cv2.GaussianBlur(mask, (0, 0), max(0.5, soft * side))
        tint = np.array([blue ** -0.5, 1.0, blue ** 0.5], np.float32)
        log_gain += mask[..., None] * np.log(np.clip(dark * tint, 0.05, 1.0))[None, None]
    if texture:
        fine = np.zeros((h, w), np.float32)
        for cells in (side // 16, side // 8, side // 4, side // 2):
            cells = max(2, cells)
            grid = prng.normal(size=(max(2, cells * h // side), max(2, cells * w // side)))
            if prng.random() < 0.3:  # streaks (boards, furrows): stretched along one axis
                grid = np.repeat(grid[:, :1], grid.shape[1], axis=1) if prng.random() < 0.5 \
                    else np.repeat(grid[:1], grid.shape[0], axis=0)
            fine += cv2.resize(grid.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)
        std = float(fine.std())
        if std > 1e-6:
            fine = np.clip((fine - float(fine.mean())) / std, -3.0, 3.0)
            log_gain += (texture * fine)[..., None]
    stained = np.clip(linear_to_srgb(srgb_to_linear(img) * np.exp(log_gain)), 0.0, 1.0)
    return np.where(surface[..., None], stained, img).astype(np.float32)


def add_clouds(
    images: tuple[np.ndarray, ...], sky: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """Paint one random cloud layer into the sky of every image of a pair (clouds do not move).

    The synthetic data's skies are cloudless, so a depth network trained on them reads real
    clouds as near surfaces; this augmentation (``TrainConfig.cloud_prob``) shows it clouds that
    are still sky. Coverage, softness, brightness and grey shading are random; the cloud layer is
    white to mid-grey, darker on its underside (lower rows), and is blended only into ``sky``.

    Args:
        images: sRGB ``H x W x 3`` float32 images of one view.
        sky: ``H x W`` bool, no surface.
        rng: the sampler's generator.
    """
    if not sky.any():
        return images
    h, w = sky.shape
    n = _fractal_noise(h, w, rng)
    coverage = rng.uniform(0.2, 0.8)
    soft = rng.uniform(0.03, 0.15)
    thresh = np.quantile(n, 1.0 - coverage)
    alpha = np.clip((n - thresh) / soft, 0.0, 1.0) * rng.uniform(0.6, 1.0)
    alpha = np.where(sky, alpha, 0.0)[..., None].astype(np.float32)
    bright = rng.uniform(0.65, 1.0)
    shade = 1.0 - rng.uniform(0.0, 0.35) * _fractal_noise(h, w, rng, octaves=3)
    cloud = (bright * shade)[..., None] * np.array([1.0, 1.0, rng.uniform(1.0, 1.06)], np.float32)
    return tuple((img * (1.0 - alpha) + np.clip(cloud, 0, 1) * alpha).astype(np.float32)
                 for img in images)


def zoom_crop(
    arrays: tuple[np.ndarray, ...], factor: float, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """The same random window, ``1 / factor`` of each side, cut from every ``H x W [x C]`` array
    and brought back to ``H x W``: the scene seen ``factor`` times larger (a longer lens).

    ``Z`` runs on a photo shrunk to its training size, where every object is as small as in the
    training views; zooming shows it objects, and fields of view, it would otherwise never see.
    Nearest-neighbour resampling, so depth edges and the sky (inf) stay what they are.
    """
    h, w = arrays[0].shape[:2]
    if factor < 1.0:
        raise ValueError(f"expected a zoom factor >= 1, got {factor}")
    ch, cw = max(1, round(h / factor)), max(1, round(w / factor))
    y, x = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
    rows = y + (np.arange(h) * ch) // h
    cols = x + (np.arange(w) * cw) // w
    return tuple(np.ascontiguousarray(a[rows][:, cols]) for a in arrays)


def visibility_target(
    shadow: np.ndarray, normals_true: np.ndarray | None, sun: np.ndarray
) -> np.ndarray:
    """Sun visibility in [0, 1] behind a ground-truth shadow image (``shadow / cos_true``).

    The network's cosine comes from normals derived from depth, which differ from the
    renderer's at edges; training on ``cos_net * visibility`` keeps every target reachable (a
    target above the network's cosine pushes a sigmoid into saturation for good). Where the
    true cosine is ~0 the visibility is undefined and set to 0. Without true normals, a shadow
    image > 0 counts as visible.
    """
    if normals_true is None:
        return (shadow > 1e-3).astype(np.float32)
    cos = np.clip(normals_true @ np.asarray(sun, np.float32), 0.0, 1.0)
    vis = np.where(cos > 1e-3, shadow / np.maximum(cos, 1e-3), 0.0)
    return np.clip(vis, 0.0, 1.0).astype(np.float32)


def find_views(root: str | Path) -> list[Path]:
    """The view files of a data folder, sorted (``outcast_core.data.list_views`` if it exists)."""
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"expected a data folder, got {root}")
    from outcast_core import data as data_pkg

    lister = getattr(data_pkg, "list_views", None)
    if lister is not None:
        return [Path(p) for p in lister(root)]
    return sorted(p for p in root.rglob("*.npz"))


def load_prepared(
    root: str | Path, size: int, max_views: int = 0,
    loader: Callable[[Path], dict[str, Any]] | None = None, skip: set[Path] | None = None,
    allow_empty: bool = False, paths: list[Path] | None = None,
) -> list[Prepared]:
    """Load and resize every view of ``root`` (at most ``max_views`` when > 0).

    ``skip`` holds paths already loaded (they are left out, and the new ones are added to it).
    ``paths`` replaces :func:`find_views`'s listing of ``root`` (distributed training lists the
    folder once, on rank 0, so that every rank loads the same views while a data set grows).
    """
    if loader is None:
        from outcast_core.data import load_view as loader  # type: ignore[no-redef]
    paths = find_views(root) if paths is None else [Path(p) for p in paths]
    if max_views > 0:
        paths = paths[:max_views]
    if skip is not None:
        paths = [p for p in paths if p not in skip]
        skip.update(paths)
    if not paths and not allow_empty:
        raise ValueError(f"expected views in {root}, got none")
    return [resize_view(loader(p), size) for p in paths]


class PairSampler:
    """Draws augmented training pairs from prepared views, reproducibly from a seed.

    Args:
        views: prepared views.
        rng: the generator (its state goes into checkpoints).
        exposure_stops, saturation, gamma: tone-map augmentation ranges.
        flip: random horizontal flips.
        sun_noise_deg: noise on the original sun (``sun_old_noisy``).
        cloud_prob: probability of painting clouds into the sky of a pair (:func:`add_clouds`).
        zoom_prob, zoom_max: probability of a zoom, and its largest factor (:func:`zoom_crop`).
            A zoomed pair's principal point is off centre, which only the depth stage (image
            and depth alone) may ignore; the training config allows it for that stage only.
        stain_prob: probability that the input photo (``image``, never a target) gets dark
            stains and fine texture that no geometry explains (:func:`stain_photo`), after the
            zoom and before the camera's flaws.
        degrade_prob: probability that the input photo (``image``, never a target) goes
            through :func:`degrade_photo`, after every other augmentation.
    """

    def __init__(
        self, views: list[Prepared], rng: np.random.Generator, exposure_stops: float = 1.0,
        saturation: tuple[float, float] = (0.8, 1.2), gamma: tuple[float, float] = (0.9, 1.1),
        flip: bool = True, sun_noise_deg: float = 3.0, cloud_prob: float = 0.0,
        zoom_prob: float = 0.0, zoom_max: float = 1.5, degrade_prob: float = 0.0,
        stain_prob: float = 0.0,
    ) -> None:
        if not views:
            raise ValueError("expected at least one view, got none")
        self.views = views
        self.rng = rng
        self.aug = {"exposure_stops": exposure_stops, "saturation": saturation, "gamma": gamma}
        self.flip = flip
        self.sun_noise_deg = sun_noise_deg
        self.cloud_prob = cloud_prob
        self.zoom_prob = zoom_prob
        self.zoom_max = zoom_max
        self.degrade_prob = degrade_prob
        self.stain_prob = stain_prob

    def skip(self) -> tuple[int, int]:
        """Advance the generator exactly as :meth:`sample` does, without making the pair.

        Distributed training draws every item of a global batch on every process but makes
        only its own (:meth:`batch`'s ``keep``); the draws here are :meth:`sample`'s, in its
        order, on stand-ins that cost nothing (none of them depends on pixel values; the
        cloud and zoom draws depend on the image size only). A test holds the two to the same
        generator state with every augmentation on.

        Returns:
            The pair's image size ``(H, W)``.
        """
        v = self.views[int(self.rng.integers(len(self.views)))]
        k = v.rgb.shape[0]
        i, _ = (int(x) for x in self.rng.integers(k, size=2))
        tonemap_pair(v.rgb[i][:1, :1], v.rgb[i][:1, :1], self.rng, **self.aug,
                     base_exposure=v.exposure)
        if self.cloud_prob > 0 and self.rng.random() < self.cloud_prob:
            add_clouds((), ~(np.isfinite(v.depth) & (v.depth > 0)), self.rng)
        if self.flip:
            self.rng.random()
        perturb_sun(v.sun[i], self.sun_noise_deg, self.rng)
        if self.zoom_prob > 0 and self.rng.random() < self.zoom_prob:
            zoom_crop((v.depth,), float(self.rng.uniform(1.0, self.zoom_max)), self.rng)
        if self.stain_prob > 0 and self.rng.random() < self.stain_prob:
            stain_photo(np.zeros((1, 1, 3), np.float32), np.ones((1, 1), bool), self.rng)
        if self.degrade_prob > 0 and self.rng.random() < self.degrade_prob:
            degrade_photo(np.zeros((1, 1, 3), np.float32), self.rng)
        return int(v.rgb.shape[1]), int(v.rgb.shape[2])

    def sample(self) -> dict[str, np.ndarray]:
        """One pair as ``C x H x W`` / vector float32 arrays (keys as in :meth:`batch`)."""
        v = self.views[int(self.rng.integers(len(self.views)))]
        k = v.rgb.shape[0]
        i, j = (int(x) for x in self.rng.integers(k, size=2))
        c_o, c_n = tonemap_pair(v.rgb[i], v.rgb[j], self.rng, **self.aug,
                                base_exposure=v.exposure)
        depth, normals = v.depth, v.normals
        if self.cloud_prob > 0 and self.rng.random() < self.cloud_prob:
            c_o, c_n = add_clouds((c_o, c_n), ~(np.isfinite(depth) & (depth > 0)), self.rng)
        sun_o, sun_n = v.sun[i].copy(), v.sun[j].copy()
        s_o, s_n = v.shadow[i], v.shadow[j]
        vis_o = visibility_target(s_o, v.normals_true, v.sun[i])
        vis_n = visibility_target(s_n, v.normals_true, v.sun[j])
        psi = view_directions(v.camera)
        if self.flip and self.rng.random() < 0.5:
            c_o, c_n, s_o, s_n, depth, vis_o, vis_n = (
                a[:, ::-1] for a in (c_o, c_n, s_o, s_n, depth, vis_o, vis_n)
            )
            normals = normals[:, ::-1] * np.array([-1, 1, 1], np.float32)
            psi = psi[:, ::-1] * np.array([-1, 1, 1], np.float32)
            sun_o[0], sun_n[0] = -sun_o[0], -sun_n[0]
        sun_o_noisy = perturb_sun(sun_o, self.sun_noise_deg, self.rng)
        focal = v.focal
        if self.zoom_prob > 0 and self.rng.random() < self.zoom_prob:
            factor = float(self.rng.uniform(1.0, self.zoom_max))
            c_o, c_n, s_o, s_n, depth, vis_o, vis_n, normals, psi = zoom_crop(
                (c_o, c_n, s_o, s_n, depth, vis_o, vis_n, normals, psi), factor, self.rng)
            focal = focal * factor
        if self.stain_prob > 0 and self.rng.random() < self.stain_prob:
            c_o = stain_photo(c_o, np.isfinite(depth) & (depth > 0), self.rng)
        if self.degrade_prob > 0 and self.rng.random() < self.degrade_prob:
            c_o = degrade_photo(c_o, self.rng)

        def chw(a: np.ndarray) -> np.ndarray:
            a = np.ascontiguousarray(a, dtype=np.float32)
            return a[None] if a.ndim == 2 else np.ascontiguousarray(np.moveaxis(a, -1, 0))

        return {
            "image": chw(c_o), "target": chw(c_n), "shadow_old": chw(s_o),
            "shadow_new": chw(s_n), "visibility_old": chw(vis_o), "visibility_new": chw(vis_n),
            "depth": chw(depth), "normals": chw(normals),
            "view_dirs": chw(psi), "sun_old": sun_o, "sun_old_noisy": sun_o_noisy,
            "sun_new": sun_n, "focal": np.array([focal], np.float32),
        }

    def batch(self, n: int, keep: slice | None = None) -> dict[str, np.ndarray]:
        """``n`` pairs stacked: images ``B x C x H x W``, suns ``B x 3``, focal ``B x 1``.

        Views of different sizes cannot share a batch; the pairs are drawn until ``n`` of the
        first one's size are found.

        Args:
            n: the batch size.
            keep: make only these items of the batch (e.g. ``slice(4, 8)``: a process's part of
                a global batch); the others are only drawn (:meth:`skip`), so the kept items
                are those of the whole batch and the generator ends where it does after it.
        """
        if keep is None:
            items = [self.sample()]
            while len(items) < n:
                s = self.sample()
                if s["image"].shape == items[0]["image"].shape:
                    items.append(s)
            return {key: np.stack([it[key] for it in items]) for key in items[0]}
        wanted = range(n)[keep]
        if not wanted:
            raise ValueError(f"expected some of the {n} items to keep, got {keep}")
        kept: list[dict[str, np.ndarray]] = []
        first: tuple[int, ...] | None = None
        count = 0
        while count < n:
            item = self.sample() if count in wanted else None
            size = tuple(item["image"].shape[1:]) if item is not None else self.skip()
            first = size if first is None else first
            if size == first:
                if item is not None:
                    kept.append(item)
                count += 1
        return {key: np.stack([it[key] for it in kept]) for key in kept[0]}
