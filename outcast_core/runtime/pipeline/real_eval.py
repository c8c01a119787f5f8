"""Real-photo evaluation: does the shadow overlay lie on a photo's own shadows?

``outcast eval real DIR`` runs the app's own
:class:`~outcast_core.runtime.pipeline.session.RelightSession`
on every ``NAME_image.*`` with a ``NAME_mask.png`` (255 = shadow) in ``DIR`` and measures, per
photo and on average (DESIGN.md, "Real photographs: how we measure"):

* ``overlay_ber``: the balanced error rate (:func:`balanced_error_rate`) of the overlay's shadow
  mask (``S < SHADOW_THRESHOLD`` off the sky mask) against the human mask, at the best of
  :data:`SWEEP_SUNS` (the sun an ideal user would align);
* ``opposite_ber``: the overlay's BER at the opposite azimuth, same elevation. An overlay that
  follows the sun gets clearly worse there; one that paints the photo's dark areas does not;
* ``refined_ber``: the BER of the refined original shadow ``S_o`` (after "Confirm sun") at the
  best sun, as the session finds it for its full-resolution outputs
  (``found_shadows_detail``: up to 1024 px; the working size before 2026-11-30 late night);
* ``otsu_ber``: Otsu's threshold on luminance, a photometric anchor that knows no sun;
* ``shuffled_ber``: the other photos' best overlays laid on this photo's mask (a control: an
  overlay that knows the photo sits far below it);
* ``swept_shuffled_ber``: the same control given the same choice as the ideal user: each other
  photo's overlay masks at all :data:`SWEEP_SUNS`, off *this* photo's sky, the best sun taken
  against this photo's mask, averaged over the other photos; and ``swept_own_ber``, this
  photo's own best of the 24 scored the same way. Both are compared on a grid of
  :data:`SWEEP_GRID` px (longer side; each mask thresholded first, then a grid cell is shadow
  when over half of it is). ``shuffled_ber`` lays one mask per other photo, chosen for that
  photo, while the overlay is the best of 24, and picking the best of 24 lowers any
  prediction's BER, a wrong photo's geometry too: ``swept_shuffled_ber - swept_own_ber`` is how
  much the geometry knows about the photo beyond that choice (added 2026-12-01, seventh
  session);
* ``sky_claim``: the fraction of the mask's shadow pixels the sky mask claims;
* ``deshadow_in`` / ``deshadow_out`` (photos with a shadow-free twin ``NAME_free.*``): the
  de-shadowed photo's RMSE in CIE Lab against the twin inside the mask, as a ratio to the
  unchanged input's, and outside the mask the excess over the input's own RMSE;
* ``relit_chroma`` / ``relit_sky``: relit to the sun :data:`RELIGHT_TURN` degrees of azimuth
  away at the same elevation above the horizon (:func:`relit_check_sun`), the mean change of
  chroma (Lab ``a*, b*`` distance) over the pixels lit under both suns (``S_o`` and ``S_n``
  both above :data:`LIT_BOTH`), and the mean Lab change on the sky when neither sun is in
  the frame (brightness may follow the new shading, colour may not; the sky stays as it is);
* ``new_shade``: how dark the relit photo makes the surface the new sun newly shadows
  (``S_o`` above 0.5, ``S_n`` below the overlay's threshold), as the median change of log
  luminance there over the photo's own shade (the median log luminance of its found shadows
  minus that of its lit surface): 1 is as dark as the photo's own shadows, 0 unchanged;
* ``shade_colour``: whether that new shade has the colour of the photo's own: the distance
  (log units) between the chromaticity shift ``(log R/G, log B/G)`` the relighting gives the
  surface the new sun newly shadows (relit over the photo, the median there) and the shift of
  the photo's own shade, the median inside the human-marked shadows (within
  :data:`OLD_SHADE_RING` of their edge) minus that of the lit ring just outside them. 0 is
  the photo's own shade colour; daylight shade is bluer than the lit surface, by ``log
  B/R`` 0.67 on the dev photos' medians (added 2026-12-02, fifteenth session);
* ``old_shade``: how much of the photo's own shadows stays in that relit photo where the new
  sun lights them: the log luminance ratio between the lit ring just outside the human-marked
  shadow (:data:`OLD_SHADE_RING` of the longer side) and the shadow itself, both where
  ``S_n`` is above :data:`LIT_BOTH`, as a fraction of the photo's own ratio there: 0 is the old
  shadow gone, 1 unchanged (added 2026-12-01);
* ``relit_detail``: how much fine texture that relit photo keeps where both suns light the
  surface (as ``relit_chroma``): the standard deviation of log luminance's finest band (its
  difference from a Gaussian blur of :data:`DETAIL_BAND` of the longer side) there, relit over
  the photo's. Only the sun's cosine changes on such a surface, so 1 is right; below it the
  relit photo is blurred and looks hazy, above it the relighting embosses (added 2026-12-01,
  fourth session);
* ``false_lift``: how much that relit photo brightens what the photo's found shadows wrongly
  include (``S_o`` below the overlay's threshold, off the sky, more than
  :data:`OLD_SHADE_RING` of the longer side from any human-marked shadow: dark materials,
  dark foliage, self-shaded sides) where the new sun lights it (``S_n`` above
  :data:`LIT_BOTH`): the mean natural-log luminance gain there. 0 is unchanged; ``ln 2``
  (0.69) doubles it. Some of these surfaces do turn to the new sun, so 0 is no target; a large
  value is the pale, bleached look of dark materials lifted as if they were shade (added
  2026-12-04, twenty-third session);
* ``seconds``: wall time for the photo (depth, 24 suns, confirmation, de-shadowing, one relight).

Masks are compared at the mask's size: shadow images are resized to it (bilinear) before the
threshold. The numbers are for notes and ``models/EVAL.md``; pictures made from a research data
set (the contact sheet) belong outside the repository.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from outcast_core.runtime.geometry.camera import sun_angles, sun_in_frame, sun_vector
from outcast_core.runtime.geometry.colour import log_chromaticity, luminance, srgb_to_linear
from outcast_core.runtime.pipeline.photo_shadows import shadow_edge_bands

#: Shadow images below this are "in shadow" (the overlay's display threshold).
SHADOW_THRESHOLD = 0.15
#: The 24-sun sweep: azimuth every 30 deg at elevations 20 and 45 (camera-relative).
SWEEP_SUNS: tuple[tuple[float, float], ...] = tuple(
    (float(az), float(el)) for el in (20, 45) for az in range(0, 360, 30)
)
#: Azimuth turn of the relighting check, and the shadow level above which a pixel counts as lit.
RELIGHT_TURN = 120.0
LIT_BOTH = 0.3
#: ``old_shade``: width of the lit ring outside a marked shadow (fraction of the longer side).
OLD_SHADE_RING = 0.03
#: ``relit_detail``: Gaussian sigma (fraction of the longer side) under which texture counts as
#: fine, and the fewest both-lit pixels it needs.
DETAIL_BAND = 1.0 / 128
DETAIL_MIN_PIXELS = 100
#: ``swept_shuffled_ber``: the longer side (px) of the grid its masks are compared on.
SWEEP_GRID = 128
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp")

Progress = Callable[[str, float], None]


def balanced_error_rate(pred: np.ndarray, truth: np.ndarray) -> float:
    """``BER = 1 - (TP / P + TN / N) / 2`` of a boolean prediction against a boolean truth.

    0 is perfect, 0.5 is chance (the SBU benchmark's measure). A class absent from ``truth``
    counts as fully right on that side.

    Args:
        pred: ``H x W`` bool; truth: ``H x W`` bool (True = shadow).

    Example:
        >>> t = np.array([[True, False]]); balanced_error_rate(t, t)
        0.0
    """
    pred = np.asarray(pred, bool)
    truth = np.asarray(truth, bool)
    if pred.shape != truth.shape:
        raise ValueError(f"expected masks of one shape, got {pred.shape} and {truth.shape}")
    p, n = int(truth.sum()), int((~truth).sum())
    tpr = float((pred & truth).sum()) / p if p else 1.0
    tnr = float((~pred & ~truth).sum()) / n if n else 1.0
    return 1.0 - 0.5 * (tpr + tnr)


def otsu_shadow_mask(image_srgb: np.ndarray) -> np.ndarray:
    """Otsu's threshold on 8-bit luminance: the darker side is shadow (``H x W`` bool)."""
    img = np.asarray(image_srgb, np.float32)
    lum = cv2.cvtColor(np.clip(img, 0.0, 1.0), cv2.COLOR_RGB2GRAY)
    lum8 = np.round(lum * 255.0).astype(np.uint8)
    t, _ = cv2.threshold(lum8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return lum8 <= t


def shadow_mask(shadow: np.ndarray, sky: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A shadow image and sky mask (one size) to the boolean shadow mask at ``shape``."""
    h, w = shape
    s = cv2.resize(np.asarray(shadow, np.float32), (w, h), interpolation=cv2.INTER_LINEAR)
    sk = cv2.resize(np.asarray(sky, np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    return (s < SHADOW_THRESHOLD) & ~sk


@dataclass(frozen=True)
class RealItem:
    """One photo of an evaluation folder: its image, human mask and optional shadow-free twin."""

    name: str
    image: Path
    mask: Path
    free: Path | None = None


def find_items(folder: str | Path) -> list[RealItem]:
    """Every ``NAME_image.*`` with a ``NAME_mask.png`` in ``folder``, sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"expected a folder of NAME_image.* and NAME_mask.png, got {folder}")
    items = []
    for img in sorted(folder.iterdir()):
        stem = img.stem
        if img.suffix.lower() not in IMAGE_SUFFIXES or not stem.endswith("_image"):
            continue
        name = stem[: -len("_image")]
        mask = folder / f"{name}_mask.png"
        if not mask.is_file():
            continue
        free = next((folder / f"{name}_free{s}" for s in IMAGE_SUFFIXES
                     if (folder / f"{name}_free{s}").is_file()), None)
        items.append(RealItem(name, img, mask, free))
    if not items:
        raise ValueError(f"expected NAME_image.* files with NAME_mask.png in {folder}, found none")
    return items


def read_mask(path: Path) -> np.ndarray:
    """A mask PNG as ``H x W`` bool (True where > 127)."""
    m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if m is None:
        raise ValueError(f"could not read the mask {path}")
    return m > 127


def lab_rmse(a_srgb: np.ndarray, b_srgb: np.ndarray, where: np.ndarray) -> float:
    """RMSE in CIE Lab (OpenCV's float Lab: L in 0-100) over the pixels ``where`` is True."""
    la = cv2.cvtColor(np.clip(a_srgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)
    lb = cv2.cvtColor(np.clip(b_srgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)
    if not where.any():
        return float("nan")
    d = (la - lb)[where]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=-1))))


@dataclass
class PhotoResult:
    """Per-photo figures (see the module docstring)."""

    name: str
    best_sun: tuple[float, float]
    overlay_ber: float
    opposite_ber: float
    refined_ber: float
    otsu_ber: float
    sky_claim: float
    shadow_fraction: float
    overlay_fraction: float
    seconds: float
    shuffled_ber: float = float("nan")
    swept_shuffled_ber: float = float("nan")
    swept_own_ber: float = float("nan")
    deshadow_in: float | None = None
    deshadow_out: float | None = None
    relit_chroma: float | None = None
    relit_sky: float | None = None
    new_shade: float | None = None
    shade_colour: float | None = None
    old_shade: float | None = None
    relit_detail: float | None = None
    false_lift: float | None = None
    depth_source: str = ""
    extra: dict[str, float] = field(default_factory=dict)


def evaluate_photo(
    session: Any,
    item: RealItem,
    *,
    suns: Sequence[tuple[float, float]] = SWEEP_SUNS,
    keep: dict[str, Any] | None = None,
) -> PhotoResult:
    """Sweep ``suns`` on one photo with a ready-made session and measure it.

    Args:
        session: a :class:`~outcast_core.runtime.pipeline.session.RelightSession`.
        item: the photo, its mask and its twin.
        suns: ``(azimuth, elevation)`` pairs in degrees.
        keep: if given, filled with the pictures of the photo (``image``, ``overlay``,
            ``refined``, ``deshadowed``, ``truth``) for a contact sheet, and with ``sweep``:
            the overlay's masks at every sun, the sky and the human mask on the grid of
            :func:`swept_shuffled_control`.
    """
    from outcast_core.runtime.io.imageio import read_image

    t0 = time.perf_counter()
    loaded = read_image(item.image, keep_uint8=True)  # as the app reads it: the same session
    photo = loaded.image_srgb  # uint8 from an 8-bit file, else float
    image = photo.astype(np.float32) / 255.0 if photo.dtype == np.uint8 else photo
    truth = read_mask(item.mask)
    shape = truth.shape
    if image.shape[:2] != shape:
        raise ValueError(f"{item.name}: expected a mask of the image's size "
                         f"{image.shape[:2]}, got {shape}")
    session.set_image(photo, focal_35mm=loaded.exif.focal_35mm)
    sky = session.sky
    grid = _grid_shape(shape)
    scores, swept = [], []
    for az, el in suns:
        shadow = session.shadow(sun_vector(az, el))
        scores.append(balanced_error_rate(shadow_mask(shadow, sky, shape), truth))
        swept.append(_on_grid(np.asarray(shadow) < SHADOW_THRESHOLD, grid))
    best = int(np.argmin(scores))
    az, el = suns[best]
    opp = (az + 180.0) % 360.0
    opp_idx = next((i for i, s in enumerate(suns) if abs(s[0] - opp) < 1e-6 and s[1] == el), None)
    w_best = sun_vector(az, el)
    if opp_idx is not None:
        opposite = scores[opp_idx]
    else:
        opposite = balanced_error_rate(
            shadow_mask(session.shadow(sun_vector(opp, el)), sky, shape), truth)
    overlay = shadow_mask(session.shadow(w_best), sky, shape)
    refined_img = session.set_original_sun(w_best)
    refined_sky = sky
    if hasattr(session, "found_shadows_detail"):  # S_o as the app exports it (full-res uses)
        detail = session.found_shadows_detail()
        refined_img, refined_sky = detail["original_shadow"], detail["sky"]
    refined = shadow_mask(refined_img, refined_sky, shape)
    sky_full = cv2.resize(sky.astype(np.uint8), (shape[1], shape[0]),
                          interpolation=cv2.INTER_NEAREST) > 0
    n_true = max(1, int(truth.sum()))
    res = PhotoResult(
        name=item.name,
        best_sun=(az, el),
        overlay_ber=float(scores[best]),
        opposite_ber=float(opposite),
        refined_ber=balanced_error_rate(refined, truth),
        otsu_ber=balanced_error_rate(otsu_shadow_mask(image), truth),
        sky_claim=float((sky_full & truth).sum()) / n_true,
        shadow_fraction=float(truth.mean()),
        overlay_fraction=float(overlay.mean()),
        seconds=0.0,
    )
    res.depth_source = str(getattr(session, "depth_source", ""))
    deshadowed = None
    if item.free is not None and hasattr(session, "deshadow_full"):
        free = read_image(item.free).image_srgb
        if free.shape != image.shape:
            free = cv2.resize(free, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
        deshadowed = session.deshadow_full()
        base_in = lab_rmse(image, free, truth)
        res.deshadow_in = lab_rmse(deshadowed, free, truth) / max(base_in, 1e-6)
        res.deshadow_out = (lab_rmse(deshadowed, free, ~truth)
                            - lab_rmse(image, free, ~truth))
        res.extra["input_lab_rmse_in"] = base_in
    if hasattr(session, "relight"):
        _relight_checks(session, res, az, el, truth)
    res.seconds = time.perf_counter() - t0
    if keep is not None:
        if deshadowed is None and hasattr(session, "deshadow"):
            deshadowed = session.deshadow()  # working resolution is enough for a thumbnail
        keep.update(image=image, truth=truth, overlay=overlay, refined=refined,
                    deshadowed=deshadowed,
                    sweep={"masks": np.stack(swept), "sky": _on_grid(sky, grid),
                           "truth": _on_grid(truth, grid)})
        if hasattr(session, "relight"):  # the checks' sun (cached in the session) and its mirror
            keep["relit"] = [session.relight(relit_check_sun(session, az, el, turn))
                             for turn in (RELIGHT_TURN, -RELIGHT_TURN)]
    return res


def _relight_checks(session: Any, res: PhotoResult, az: float, el: float,
                    truth: np.ndarray) -> None:
    """``relit_chroma``, ``relit_sky``, ``new_shade``, ``shade_colour``, ``old_shade``,
    ``relit_detail`` and ``false_lift`` of :class:`PhotoResult` (module docstring)."""
    w_o = sun_vector(az, el)
    w_n = relit_check_sun(session, az, el)
    relit = session.relight(w_n)
    image = session.image_srgb
    lab_a = cv2.cvtColor(np.clip(image, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)
    lab_b = cv2.cvtColor(np.clip(relit, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)
    lit = (session.original_shadow > LIT_BOTH) & (session.shadow(w_n) > LIT_BOTH) & ~session.sky
    if lit.any():
        d = lab_b[lit, 1:] - lab_a[lit, 1:]
        res.relit_chroma = float(np.mean(np.hypot(d[:, 0], d[:, 1])))
    res.relit_detail = detail_ratio(image, relit, lit)
    if session.sky.any() and not (sun_in_frame(w_o, session.camera)
                                  or sun_in_frame(w_n, session.camera)):
        d = lab_b[session.sky] - lab_a[session.sky]
        res.relit_sky = float(np.mean(np.sqrt(np.sum(d * d, axis=-1))))
    res.new_shade = new_shade_ratio(image, relit, session.original_shadow, session.shadow(w_n),
                                    getattr(session, "shadow_probability", None), session.sky)
    h, w = image.shape[:2]
    marked = cv2.resize(truth.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    res.old_shade = old_shade_ratio(image, relit, marked, session.shadow(w_n), session.sky)
    res.shade_colour = shade_colour_gap(image, relit, marked, session.original_shadow,
                                        session.shadow(w_n), session.sky)
    res.false_lift = false_lift(image, relit, marked, session.original_shadow,
                                session.shadow(w_n), session.sky)


def relit_check_sun(session: Any, az: float, el: float, turn: float = RELIGHT_TURN
                    ) -> np.ndarray:
    """The relighting checks' new sun: the sun ``(az, el)`` (camera-relative) turned ``turn``
    (:data:`RELIGHT_TURN`) degrees about the horizon's up (the session's ``horizon_tilt``: the
    fitted ground plane's, the camera's vertical without one), so both suns stand at one
    elevation above the horizon and the light's strength and colour are the same
    (``RelightSession.daylight``). Until 2026-12-01 (tenth session) the turn was about the
    camera's vertical, which for a camera pitched down put the new sun at another elevation
    (up to 38 degrees apart for a camera pitched 22 degrees down, the dev photos' median)."""
    tilt = session.horizon_tilt() if hasattr(session, "horizon_tilt") else (0.0, 0.0)
    a, e = sun_angles(sun_vector(az, el), *tilt)  # the sun against the horizon
    return sun_vector(a + turn, e, *tilt)


#: Least pixels of each kind :func:`new_shade_ratio` needs (and :func:`false_lift`).
MIN_PIXELS = 50


def new_shade_ratio(
    image_srgb: np.ndarray, relit_srgb: np.ndarray, shadow_old: np.ndarray,
    shadow_new: np.ndarray, probability: np.ndarray | None, sky: np.ndarray,
) -> float | None:
    """``new_shade`` (module docstring); None when a photo has too few pixels of a kind.

    Example:
        >>> img = np.full((10, 20, 3), 0.8, np.float32); img[:, :10] = 0.3
        >>> so = np.ones((10, 20), np.float32); so[:, :10] = 0.0
        >>> sn = np.ones((10, 20), np.float32); sn[:, 15:] = 0.0
        >>> relit = img.copy(); relit[:, 15:] = 0.3
        >>> p = 1.0 - so; sky = np.zeros((10, 20), bool)
        >>> round(new_shade_ratio(img, relit, so, sn, p, sky), 2)
        1.0
    """
    if probability is None:
        return None
    surface = ~np.asarray(sky, bool)
    log_y = np.log(luminance(srgb_to_linear(np.clip(image_srgb, 0, 1))) + 1e-3)
    log_r = np.log(luminance(srgb_to_linear(np.clip(relit_srgb, 0, 1))) + 1e-3)
    shade, lit = surface & (probability > 0.5), surface & (probability < 0.5)
    newly = surface & (shadow_old > 0.5) & (shadow_new < SHADOW_THRESHOLD)
    if min(shade.sum(), lit.sum(), newly.sum()) < MIN_PIXELS:
        return None
    own = float(np.median(log_y[shade]) - np.median(log_y[lit]))
    if own > -1e-3:
        return None
    return float(np.median((log_r - log_y)[newly]) / own)


def shade_colour_gap(
    image_srgb: np.ndarray, relit_srgb: np.ndarray, marked: np.ndarray, shadow_old: np.ndarray,
    shadow_new: np.ndarray, sky: np.ndarray,
) -> float | None:
    """``shade_colour`` (module docstring); None when a photo has too few pixels of a kind or
    its marked shadows no edge band against a lit ring.

    Example:
        >>> img = np.full((40, 40, 3), 0.8, np.float32); img[5:20, 5:20] = (0.2, 0.25, 0.3)
        >>> m = np.zeros((40, 40), bool); m[5:20, 5:20] = True
        >>> so = np.where(m, 0.0, 1.0).astype(np.float32)
        >>> sn = so.copy(); sn[25:, :] = 0.0; sky = np.zeros((40, 40), bool)
        >>> relit = img.copy(); relit[25:, :] = (0.2, 0.25, 0.3)  # the photo's shade colour
        >>> round(shade_colour_gap(img, relit, m, so, sn, sky), 3)
        0.0
        >>> grey = img.copy(); grey[25:, :] = 0.25  # as dark, not as blue
        >>> bool(shade_colour_gap(img, grey, m, so, sn, sky) > 0.3)
        True
    """
    surface = ~np.asarray(sky, bool)
    inner, ring = shadow_edge_bands(marked, surface, OLD_SHADE_RING, edge_only=True)
    newly = surface & (np.asarray(shadow_old) > 0.5) & (np.asarray(shadow_new)
                                                        < SHADOW_THRESHOLD)
    if min(inner.sum(), ring.sum(), newly.sum()) < MIN_PIXELS:
        return None

    def chroma(x: np.ndarray) -> np.ndarray:
        return log_chromaticity(srgb_to_linear(np.clip(np.asarray(x, np.float32), 0, 1)), 1e-3)

    c_photo, c_relit = chroma(image_srgb), chroma(relit_srgb)
    own = np.median(c_photo[inner], axis=0) - np.median(c_photo[ring], axis=0)
    new = np.median((c_relit - c_photo)[newly], axis=0)
    return float(np.hypot(*(new - own)))


def detail_ratio(image_srgb: np.ndarray, relit_srgb: np.ndarray,
                 where: np.ndarray) -> float | None:
    """``relit_detail`` (module docstring) over the pixels ``where``; None below
    :data:`DETAIL_MIN_PIXELS` of them or on a photo without texture there.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> img = np.clip(0.5 + 0.1 * rng.standard_normal((128, 128, 3)), 0, 1)
        >>> every = np.ones((128, 128), bool)
        >>> detail_ratio(img, img, every)
        1.0
        >>> bool(detail_ratio(img, cv2.GaussianBlur(img, (0, 0), 1.0), every) < 0.5)
        True
    """
    where = np.asarray(where, bool)
    if where.sum() < DETAIL_MIN_PIXELS:
        return None
    sigma = DETAIL_BAND * max(where.shape)

    def band_std(x: np.ndarray) -> float:
        y = np.log(luminance(srgb_to_linear(np.clip(np.asarray(x, np.float32), 0.0, 1.0)))
                   + 1e-3)
        return float(np.std((y - cv2.GaussianBlur(y, (0, 0), sigma))[where]))

    own = band_std(image_srgb)
    return None if own < 1e-4 else round(band_std(relit_srgb) / own, 6)


def old_shade_ratio(
    image_srgb: np.ndarray, relit_srgb: np.ndarray, marked: np.ndarray, shadow_new: np.ndarray,
    sky: np.ndarray,
) -> float | None:
    """``old_shade`` (module docstring); None when a photo has too few pixels of a kind.

    ``marked`` is the human shadow mask at the images' size.

    Example:
        >>> img = np.full((40, 40, 3), 0.8, np.float32); img[10:30, 10:30] = 0.2
        >>> m = np.zeros((40, 40), bool); m[10:30, 10:30] = True
        >>> lit, sky = np.ones((40, 40), np.float32), np.zeros((40, 40), bool)
        >>> round(old_shade_ratio(img, img, m, lit, sky), 2)  # unchanged
        1.0
        >>> round(old_shade_ratio(img, np.full_like(img, 0.8), m, lit, sky), 2)  # gone
        0.0
    """
    lit = (np.asarray(shadow_new) > LIT_BOTH) & ~np.asarray(sky, bool)
    inner, ring = shadow_edge_bands(marked, lit, OLD_SHADE_RING)
    if min(inner.sum(), ring.sum()) < MIN_PIXELS:
        return None

    def log_ratio(x: np.ndarray) -> float:
        y = luminance(srgb_to_linear(np.clip(x, 0.0, 1.0)))
        return float(np.log(y[ring].mean() / max(float(y[inner].mean()), 1e-4)))

    own = log_ratio(image_srgb)
    if own < 0.1:  # the marked shadow is not darker than its surroundings here
        return None
    return log_ratio(relit_srgb) / own


def false_lift(
    image_srgb: np.ndarray, relit_srgb: np.ndarray, marked: np.ndarray, shadow_old: np.ndarray,
    shadow_new: np.ndarray, sky: np.ndarray,
) -> float | None:
    """``false_lift`` (module docstring); None when a photo has fewer than
    :data:`MIN_PIXELS` such pixels. ``marked`` is the human shadow mask at the images' size.

    Example:
        >>> img = np.full((40, 40, 3), 0.5, np.float32); img[:, :10] = 0.05  # a dark material
        >>> so = np.ones((40, 40), np.float32); so[:, :10] = 0.0  # found as shadow
        >>> m, sky = np.zeros((40, 40), bool), np.zeros((40, 40), bool)
        >>> lifted = img.copy(); lifted[:, :10] = 0.4
        >>> round(false_lift(img, img, m, so, so * 0 + 1, sky), 2)
        0.0
        >>> bool(false_lift(img, lifted, m, so, so * 0 + 1, sky) > 1.0)
        True
    """
    marked = np.asarray(marked, bool)
    reach = max(1, round(OLD_SHADE_RING * max(marked.shape)))
    near = cv2.dilate(marked.astype(np.uint8), np.ones((2 * reach + 1,) * 2, np.uint8)) > 0
    where = ((np.asarray(shadow_old) < SHADOW_THRESHOLD) & (np.asarray(shadow_new) > LIT_BOTH)
             & ~np.asarray(sky, bool) & ~near)
    if where.sum() < MIN_PIXELS:
        return None

    def log_y(x: np.ndarray) -> np.ndarray:
        return np.log(np.maximum(luminance(srgb_to_linear(np.clip(x, 0.0, 1.0)))[where], 1e-4))

    return float(np.mean(log_y(relit_srgb) - log_y(image_srgb)))


def shuffled_control(
    masks: dict[str, np.ndarray], truths: dict[str, np.ndarray]
) -> dict[str, float]:
    """For each photo, the mean BER of every other photo's best overlay laid on its mask."""
    out: dict[str, float] = {}
    for name, truth in truths.items():
        h, w = truth.shape
        bers = [
            balanced_error_rate(
                cv2.resize(m.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0, truth)
            for other, m in masks.items() if other != name
        ]
        out[name] = float(np.mean(bers)) if bers else float("nan")
    return out


def _grid_shape(shape: tuple[int, int]) -> tuple[int, int]:
    """``(h, w)`` of the :data:`SWEEP_GRID` grid for a mask of ``shape`` (aspect kept)."""
    h, w = shape
    k = SWEEP_GRID / max(h, w)
    return max(1, round(h * k)), max(1, round(w * k))


def _on_grid(mask: np.ndarray, grid: tuple[int, int]) -> np.ndarray:
    """A boolean mask brought to ``grid`` (the share of each cell it covers, over half)."""
    m = cv2.resize(np.asarray(mask, np.float32), grid[::-1], interpolation=cv2.INTER_AREA)
    return m > 0.5


def _best_of(masks: np.ndarray, sky: np.ndarray, truth: np.ndarray) -> float:
    """The least :func:`balanced_error_rate` of ``K x h x w`` predicted masks, off ``sky``."""
    return min(balanced_error_rate(m & ~sky, truth) for m in masks)


def swept_shuffled_control(sweeps: dict[str, dict[str, np.ndarray]]
                           ) -> dict[str, tuple[float, float]]:
    """For each photo, the mean over the other photos of the best BER of their overlay masks
    at every sun laid on this photo's mask, and this photo's own best scored the same way
    (``swept_shuffled_ber``, ``swept_own_ber``: module docstring).

    Args:
        sweeps: per photo, ``masks`` (``K x h x w`` bool, the overlay's shadow masks at the
            swept suns, sky not yet removed), ``sky`` and ``truth`` (``h x w`` bool), all on
            its :data:`SWEEP_GRID` grid.

    Returns:
        Per photo, ``(control, own)`` (the control NaN for a lone photo).
    """
    out: dict[str, tuple[float, float]] = {}
    for name, own in sweeps.items():
        truth, sky = own["truth"], own["sky"]
        h, w = truth.shape
        bests = []
        for other, theirs in sweeps.items():
            if other == name:
                continue
            masks = np.stack([cv2.resize(m.astype(np.uint8), (w, h),
                                         interpolation=cv2.INTER_NEAREST) > 0
                              for m in theirs["masks"]])  # K x h x w
            bests.append(_best_of(masks, sky, truth))
        out[name] = (float(np.mean(bests)) if bests else float("nan"),
                     _best_of(np.asarray(own["masks"], bool), sky, truth))
    return out


SUMMARY_KEYS = ("overlay_ber", "opposite_ber", "refined_ber", "otsu_ber", "shuffled_ber",
                "swept_shuffled_ber", "swept_own_ber",
                "sky_claim", "overlay_fraction", "shadow_fraction", "seconds",
                "deshadow_in", "deshadow_out", "relit_chroma", "relit_sky", "new_shade",
                "shade_colour", "old_shade", "relit_detail", "false_lift")


def summarize(results: Sequence[PhotoResult]) -> dict[str, float]:
    """Means of the per-photo figures (those a photo lacks are left out of its mean)."""
    out: dict[str, float] = {"photos": float(len(results))}
    for key in SUMMARY_KEYS:
        vals = [getattr(r, key) for r in results]
        vals = [v for v in vals if v is not None and math.isfinite(v)]
        if vals:
            out[key] = float(np.mean(vals))
    out["opposite_gap"] = out.get("opposite_ber", math.nan) - out.get("overlay_ber", math.nan)
    out["shuffled_gap"] = out.get("shuffled_ber", math.nan) - out.get("overlay_ber", math.nan)
    out["swept_shuffled_gap"] = (out.get("swept_shuffled_ber", math.nan)
                                 - out.get("swept_own_ber", math.nan))
    return out


def evaluate_real(
    folder: str | Path,
    *,
    session_factory: Callable[[], Any],
    limit: int = 0,
    progress: Progress | None = None,
    sheet: str | Path | None = None,
) -> dict[str, Any]:
    """Run :func:`evaluate_photo` on every photo of ``folder``; per-photo results and means.

    Args:
        folder: a folder of ``NAME_image.*`` + ``NAME_mask.png`` (+ ``NAME_free.*``).
        session_factory: makes the session (one for the whole folder).
        limit: use the first ``limit`` photos (0: all).
        progress: called with ``(photo name, fraction done)``.
        sheet: where to write a contact sheet (PNG/JPEG), or None.

    Returns:
        ``{"photos": [per-photo dicts], "mean": {...}, "skipped": [{"name", "error"}]}``: a
        photo that cannot be evaluated (its mask of another size, an unreadable file) is
        skipped with its reason and the others are done (one bad mask stopped a whole run in a
        user trial).

    Raises:
        ValueError: no photo could be evaluated.
    """
    items = find_items(folder)
    if limit > 0:
        items = items[:limit]
    session = session_factory()
    results: list[PhotoResult] = []
    masks: dict[str, np.ndarray] = {}
    truths: dict[str, np.ndarray] = {}
    sweeps: dict[str, dict[str, np.ndarray]] = {}
    rows: list[list[np.ndarray]] = []
    skipped: list[dict[str, str]] = []
    for i, item in enumerate(items):
        if progress:
            progress(item.name, i / len(items))
        keep: dict[str, Any] = {}
        try:
            res = evaluate_photo(session, item, keep=keep)
        except (ValueError, OSError) as exc:  # (a mask of another size, a file not an image)
            why = str(exc)
            why = why[len(item.name) + 2:] if why.startswith(f"{item.name}: ") else why
            skipped.append({"name": item.name, "error": why})
            continue
        results.append(res)
        masks[item.name] = keep["overlay"]
        truths[item.name] = keep["truth"]
        sweeps[item.name] = keep["sweep"]
        if sheet is not None:
            rows.append(_sheet_row(keep))
    if not results:
        raise ValueError("no photo could be evaluated: " + "; ".join(
            f"{k['name']}: {k['error']}" for k in skipped))
    shuffled = shuffled_control(masks, truths)
    swept = swept_shuffled_control(sweeps)
    for r in results:
        r.shuffled_ber = shuffled[r.name]
        r.swept_shuffled_ber, r.swept_own_ber = swept[r.name]
    if sheet is not None and rows:
        _write_sheet(Path(sheet), rows)
    if progress:
        progress("done", 1.0)
    return {"photos": [asdict(r) for r in results], "mean": summarize(results),
            "skipped": skipped}


_THUMB = 160


def _thumb(img: np.ndarray) -> np.ndarray:
    """A thumbnail :data:`_THUMB` pixels high (grey images made RGB)."""
    img = np.asarray(img, np.float32)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    h, w = img.shape[:2]
    size = (max(1, round(w * _THUMB / h)), _THUMB)
    return cv2.resize(img, size, interpolation=cv2.INTER_AREA)


def _tint(image: np.ndarray, mask: np.ndarray, colour: tuple[float, float, float]) -> np.ndarray:
    out = np.asarray(image, np.float32).copy()
    out[mask] = 0.5 * out[mask] + 0.5 * np.asarray(colour, np.float32)
    return out


def _sheet_row(keep: dict[str, Any]) -> list[np.ndarray]:
    img = keep["image"]
    row = [_thumb(img), _thumb(_tint(img, keep["truth"], (0.0, 1.0, 0.0))),
           _thumb(_tint(img, keep["overlay"], (1.0, 0.0, 0.0))),
           _thumb(_tint(img, keep["refined"], (0.0, 0.3, 1.0)))]
    if keep.get("deshadowed") is not None:
        row.append(_thumb(keep["deshadowed"]))
    row += [_thumb(r) for r in keep.get("relit", [])]
    return row


def _write_sheet(path: Path, rows: list[list[np.ndarray]]) -> None:
    """Rows of thumbnails: photo, human mask (green), overlay (red), S_o (blue), de-shadowed,
    relit at azimuth +-:data:`RELIGHT_TURN`."""
    from outcast_core.runtime.io.imageio import write_image

    lines = [np.concatenate(r, axis=1) for r in rows]
    width = max(line.shape[1] for line in lines)
    grid = np.concatenate(
        [np.pad(line, ((0, 2), (0, width - line.shape[1]), (0, 0))) for line in lines], axis=0)
    write_image(path, grid, force=True)


def render_table(report: dict[str, Any]) -> str:
    """The per-photo results and their means as a Markdown table."""
    head = ("| Photo | Best sun | Overlay BER | Opposite | S_o BER | Otsu | "
            "Shuffled / swept (own) | Sky claim | De-shadow in / out | "
            "Relit chroma / sky / new shade (colour) / old shade / detail / false lift | s |")
    lines = [head, "|---|---|---|---|---|---|---|---|---|---|---|"]

    def f(v: Any, d: int = 3) -> str:
        return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{d}f}"

    for r in report["photos"]:
        ds = ("-" if r["deshadow_in"] is None
              else f"{f(r['deshadow_in'], 2)} / {f(r['deshadow_out'], 2)}")
        lines.append(
            f"| {r['name']} | {r['best_sun'][0]:.0f},{r['best_sun'][1]:.0f} | "
            f"{f(r['overlay_ber'])} | {f(r['opposite_ber'])} | {f(r['refined_ber'])} | "
            f"{f(r['otsu_ber'])} | {f(r['shuffled_ber'])} / {f(r.get('swept_shuffled_ber'))} "
            f"({f(r.get('swept_own_ber'))}) | "
            f"{f(r['sky_claim'])} | {ds} | "
            f"{f(r['relit_chroma'], 2)} / {f(r['relit_sky'], 2)} / {f(r.get('new_shade'), 2)} "
            f"({f(r.get('shade_colour'), 2)}) / "
            f"{f(r.get('old_shade'), 2)} / {f(r.get('relit_detail'), 2)} / "
            f"{f(r.get('false_lift'), 2)} | "
            f"{f(r['seconds'], 1)} |")
    m = report["mean"]
    ds = ("-" if "deshadow_in" not in m
          else f"{f(m['deshadow_in'], 2)} / {f(m.get('deshadow_out'), 2)}")
    lines.append(
        f"| **mean ({int(m['photos'])})** | | **{f(m.get('overlay_ber'))}** | "
        f"{f(m.get('opposite_ber'))} | **{f(m.get('refined_ber'))}** | {f(m.get('otsu_ber'))} | "
        f"{f(m.get('shuffled_ber'))} / {f(m.get('swept_shuffled_ber'))} "
        f"({f(m.get('swept_own_ber'))}) | "
        f"{f(m.get('sky_claim'))} | {ds} | "
        f"{f(m.get('relit_chroma'), 2)} / {f(m.get('relit_sky'), 2)} / "
        f"{f(m.get('new_shade'), 2)} ({f(m.get('shade_colour'), 2)}) / "
        f"{f(m.get('old_shade'), 2)} / "
        f"{f(m.get('relit_detail'), 2)} / {f(m.get('false_lift'), 2)} | "
        f"{f(m.get('seconds'), 1)} |")
    for k in report.get("skipped", ()):  # (not in the means)
        lines.append(f"\nSkipped {k['name']}: {k['error']}")
    return "\n".join(lines)


REPORT_BEGIN = ("<!-- real-photos: written by `outcast eval real --report`; "
                "kept by `outcast eval` -->")
REPORT_END = "<!-- real-photos: end -->"


def real_section(text: str) -> str:
    """The real-photo section of a report (markers included), or ``""``."""
    i, j = text.find(REPORT_BEGIN), text.find(REPORT_END)
    return text[i: j + len(REPORT_END)] if 0 <= i < j else ""


def update_report(path: str | Path, section: str) -> Path:
    """Put ``section`` between :data:`REPORT_BEGIN` / :data:`REPORT_END` in the Markdown file
    ``path`` (replacing the previous one, or appended; the file is created if missing)."""
    path = Path(path)
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    block = f"{REPORT_BEGIN}\n{section.strip()}\n{REPORT_END}"
    old = real_section(text)
    before = text.rstrip("\n") + ("\n\n" if text else "")
    text = text.replace(old, block) if old else before + block
    tmp = path.with_name(f".{path.name}.part")
    tmp.write_text(text + ("" if text.endswith("\n") else "\n"), encoding="utf-8")
    tmp.replace(path)
    return path


def write_json(path: str | Path, report: dict[str, Any]) -> None:
    """The report as JSON (NaN written as null)."""
    def clean(v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    Path(path).write_text(json.dumps(clean(report), indent=1))


__all__ = [
    "SHADOW_THRESHOLD",
    "SWEEP_SUNS",
    "PhotoResult",
    "RealItem",
    "balanced_error_rate",
    "evaluate_photo",
    "evaluate_real",
    "find_items",
    "lab_rmse",
    "read_mask",
    "otsu_shadow_mask",
    "real_section",
    "render_table",
    "update_report",
    "shadow_mask",
    "shuffled_control",
    "summarize",
    "swept_shuffled_control",
]
