"""Running ``Z`` on real photos and post-processing its output: a classical sky prior,
edge-aware smoothing of the depth and a ground plane. :func:`run_depth_model` runs ``Z`` at the
scale it was trained at (a photo larger than its training views is shrunk to them: at 3x the
scale its error doubles); :func:`postprocess_z` is the one place that turns ``Z``'s raw outputs
into the depth and sky the runtime uses (the session and ``outcast eval`` both call it).

``Z`` learned the sky from synthetic renders whose skies are cloudless gradients, so on real
photos it reads clouds as near surfaces (which then cast and receive shadows) and misses parts of
the sky. The prior here uses what holds in almost every outdoor photo instead:

* sky is smooth: a low local colour gradient;
* sky is blue (clear) or white-grey (cloud, haze, overcast): bluish, or bright and unsaturated;
* sky touches the top of the frame: only smooth sky-coloured regions connected to the top rows
  count, so a white wall or a snowfield that does not reach the top is never taken for sky.

:func:`combine_sky` adds the prior's regions in which ``Z`` found some sky to ``Z``'s mask and
drops ``Z``'s low sky regions cut off from the top (pools). The runtime session uses it whenever
``Z`` supplies the depth (never for a depth map the user loaded, whose own sky is trusted).

``Z``'s depth also carries the texture of the photo (grass, gravel, tiles read as bumps), which
the normals turn into speckled shading and the marcher into speckled shadows.
:func:`smooth_depth` runs a guided filter on log depth with the photo as the guide: flat where
the photo is smooth or only textured, edges kept where the photo has them. On 6 held-out
synthetic views (72 pairs) S's shadow MSE on ``Z``'s depth went from 0.097 to 0.090 with radius
1/32 of the longer side and eps 1e-2 (r = 4 at 128 px); r = 8 and r = 16 were worse.

Smoothing leaves the ground's low-frequency bumps, which still cast and catch speckled shadows.
Almost every outdoor photo stands on a ground that is close to a plane, and little that is
visible lies below it. :func:`snap_ground` fits that plane to the lower half of the frame
(RANSAC; below the camera, its normal within :data:`GROUND_MAX_TILT_DEG` of the camera's up) and
moves the surface points just above or below it onto it, blending so that
objects standing on the ground keep their shape and no step or crease appears; a surface far
below (a valley seen from a terrace) is left alone. A frame with no such plane under at least
:data:`GROUND_MIN_INLIERS` of its lower half's points (a wall, a close-up, clutter) is left as it
is. Tuned on the dev split (seed 500000, not the held-out views), first 24 views (288 pairs): S's
shadow MSE on ``Z``'s depth went from 0.0878 to 0.0846 with these settings (a plane in 83 of the
96 photos; Z's silog unchanged at 0.362). Alternatives scored: inlier tolerance 0.03, 57 planes,
0.0856 (and no plane on the samples); 0.05, 0.0848; tilt limit 50 degrees, 0.0845 (but walls
under a camera pitched up 40 degrees pass); band 0.04 or 0.15 and below-limit 0.1 or 0.5, all
within 0.0007. On the sample photos the path's and the snowfield's speckled shadows are gone.

Tried and not kept (2026-11-22): a "pop-up" step after the plane, which pulls every pixel
standing above the plane (log gap over 0.15) toward the depth of its foot, the plane's depth at
the nearest ground pixel below it in its column (at most a factor e, guided-filtered against
column streaks), so thin objects that ``Z`` blurs into the ground behind them stand up and cast
shadows. With the shipped Z v3 and S v5, S's shadow MSE on Z's depth went 0.0789 -> 0.0752 on
the dev split (24 views, 288 pairs) but only 0.0812 -> 0.0798 on 20 held-out views (Direct's
0.0889 -> 0.0860), while Z's silog got worse (0.344 -> 0.363); on the sample photos the
relit images hardly changed. Too little for a heuristic that also turns overhead structures
(a pergola's roof) into walls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from outcast_core.runtime.geometry.camera import Camera, backproject, fill_invalid
from outcast_core.runtime.geometry.colour import LUMA_709, is_greyscale

#: :func:`sky_colour` in a black-and-white photo: the least sRGB luma of a sky (a blue sky
#: turns a mid grey; the field-path sample's in black and white: 5th percentile 0.41).
GREY_SKY_LUMA = 0.3
#: Longer side (pixels) the prior works at; the mask is resized back (nearest) to the input.
WORK_SIDE = 256
#: Largest mean gradient magnitude (largest colour channel, per pixel, [0, 1] units) that counts
#: as smooth.
SMOOTH = 0.03
#: Fraction of the height whose rows seed the region (the top rows).
SEED_ROWS = 0.02
#: Guided-filter radius as a fraction of the longer side, and its eps (regularisation in squared
#: units of the sRGB guide: larger smooths across weaker photo edges).
SMOOTH_RADIUS = 1.0 / 32.0
SMOOTH_EPS = 1e-2
#: Ground plane (:func:`snap_ground`): the bottom fraction of the rows it is fitted to; the
#: RANSAC inlier distance (log depth along the point's ray); the largest angle between its normal
#: and the camera's up; the least fraction of the fitted points that must lie on it; the
#: log-depth band above it that is blended onto it; RANSAC trials and the most points it uses.
GROUND_ROWS = 0.5
GROUND_TOL = 0.08
GROUND_MAX_TILT_DEG = 35.0
GROUND_MIN_INLIERS = 0.4
GROUND_BAND = 0.08
#: Log depth below the plane down to which points go fully onto it (fading out at twice this).
GROUND_BELOW = 0.2
GROUND_TRIALS = 200
GROUND_POINTS = 4000
#: Least fraction of a prior region that ``Z`` must call sky for the region to be added.
MIN_AGREEMENT = 0.05
#: Rows (fraction of the height) below ``Z``'s lowest sky row that the prior may still add.
HORIZON_MARGIN = 0.15
#: :func:`combine_sky`: a prior region at least this clear blue, spanning at least this share of
#: the top row, is sky without ``Z``'s agreement.
CLEAR_BLUE = 0.9
CLEAR_TOP = 0.9


def _clear_blue(image_srgb: np.ndarray, lum: np.ndarray | None = None) -> np.ndarray:
    """Clear-sky blue: blue above red and not below green, not dark (``H x W`` bool);
    ``lum``: the image's Rec. 709 luma when the caller has it."""
    img = np.asarray(image_srgb, dtype=np.float32)
    r, g, b = cv2.split(img)
    if lum is None:
        lum = cv2.transform(img, LUMA_709[None])
    return (b > r + 0.03) & (b >= g - 0.02) & (lum > 0.2)


def sky_colour(image_srgb: np.ndarray, greyscale: bool | None = None) -> np.ndarray:
    """Where a pixel has a sky's colour: bluish (clear sky), or bright and unsaturated (cloud,
    haze, overcast). ``H x W x 3`` sRGB -> ``H x W`` bool.

    In a black-and-white photo (:func:`~outcast_core.runtime.geometry.colour.is_greyscale`) a
    blue sky is a mid grey: there, any pixel of luma above :data:`GREY_SKY_LUMA` has a sky's
    colour (the prior's smoothness and top-edge tests still apply). Found by a user trial: the
    field-path sample in black and white had a sky prior of 4 % of the frame (54 % in colour),
    and dark shadows were cast across its sky.

    ``greyscale``: whether the photo is black and white, when the caller has decided it (once
    per photo, on the whole photo: :func:`postprocess_z` and the session do); None decides it
    from ``image_srgb``.
    """
    img = np.asarray(image_srgb, dtype=np.float32)  # NaN compares False: never sky-coloured
    r, g, b = cv2.split(img)
    lum = cv2.transform(img, LUMA_709[None])
    if greyscale is None:
        greyscale = is_greyscale(np.nan_to_num(img))
    if greyscale:
        return lum > GREY_SKY_LUMA
    lo, hi = np.minimum(np.minimum(r, g), b), np.maximum(np.maximum(r, g), b)
    bluish = _clear_blue(img, lum)
    cloudish = (lum > 0.5) & (hi - lo < 0.25 * hi)  # saturation < 0.25
    return bluish | cloudish


def sky_prior(image_srgb: np.ndarray, greyscale: bool | None = None) -> np.ndarray:
    """A boolean ``H x W`` sky mask from colour, smoothness and connection to the top edge.

    Args:
        image_srgb: ``H x W x 3`` float sRGB in ``[0, 1]``.
        greyscale: whether the photo is black and white (:func:`sky_colour`); None: decided
            from ``image_srgb``.

    Returns:
        ``H x W`` bool, True where the photo shows sky.
    """
    img = np.asarray(image_srgb, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] != 3 or min(img.shape[:2]) < 1:
        raise ValueError(f"expected an H x W x 3 image, got shape {img.shape}")
    h, w = img.shape[:2]
    scale = min(1.0, WORK_SIDE / max(h, w))
    sw, sh = max(1, round(w * scale)), max(1, round(h * scale))
    small = cv2.resize(img, (sw, sh), interpolation=cv2.INTER_AREA) if scale < 1 else img
    small = np.nan_to_num(np.clip(small, 0.0, 1.0))
    # Local texture: mean over a 5 x 5 window of the largest colour channel's gradient magnitude
    # (lightly blurred), so a pale wall against blue sky is an edge even at equal luminance.
    blurred = cv2.GaussianBlur(small, (3, 3), 0)
    gx = cv2.Sobel(blurred, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(blurred, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    texture = cv2.blur(np.hypot(gx, gy).max(axis=2), (5, 5))
    colour = sky_colour(small, greyscale)
    sky = _fill_holes(top_connected(colour & (texture < SMOOTH)), colour)
    if (sh, sw) != (h, w):
        sky = cv2.resize(sky.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    return sky


def top_connected(mask: np.ndarray) -> np.ndarray:
    """The parts of a boolean mask 4-connected to its top rows (:data:`SEED_ROWS`)."""
    mask = np.asarray(mask, dtype=bool)
    n, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=4)
    if n <= 1:
        return np.zeros_like(mask)
    seed_rows = max(1, round(mask.shape[0] * SEED_ROWS))
    top = np.unique(labels[:seed_rows][mask[:seed_rows]])
    return np.isin(labels, top[top > 0])


def _fill_holes(sky: np.ndarray, colour: np.ndarray) -> np.ndarray:
    """Close non-sky islands (8-connected) of two kinds:

    * small ones that sky encloses on every side (under 1 % of the frame: birds, lamp tops);
    * sky-coloured ones cut off from the bottom edge, under a quarter of the frame: textured
      cloud cores, also where a cloud runs off the top or a side.

    Anything standing on the bottom edge (ground, trees, poles) and anything not sky-coloured
    that reaches a border (foliage entering from a corner, eaves) stays.
    """
    if not sky.any() or sky.all():
        return sky
    n, labels = cv2.connectedComponents((~sky).astype(np.uint8), connectivity=8)
    area = np.bincount(labels.ravel(), minlength=n).astype(np.float64)
    coloured = np.bincount(labels.ravel(), weights=colour.ravel(), minlength=n)
    border = np.zeros(n, bool)
    border[np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))] = True
    bottom = np.zeros(n, bool)
    bottom[np.unique(labels[-1])] = True
    enclosed = ~border & (area < 0.01 * sky.size)
    cloud = ~bottom & (area < 0.25 * sky.size) & (coloured >= 0.6 * np.maximum(area, 1))
    fill = enclosed | cloud
    fill[0] = False  # label 0: the sky itself
    return sky | fill[labels]


def combine_sky(model_sky: np.ndarray, image_srgb: np.ndarray,
                greyscale: bool | None = None) -> np.ndarray:
    """``Z``'s sky mask combined with :func:`sky_prior` of the same photo (same ``H x W``).

    * A region of the prior is added only if ``Z`` marked at least :data:`MIN_AGREEMENT` of it
      as sky (a smooth pale wall filling the top of the frame is sky-like in colour and texture,
      but ``Z`` sees a surface there), and never more than :data:`HORIZON_MARGIN` below the
      lowest row of ``Z``'s kept sky (sky and a pale ground often meet without an edge).
    * A sky region of ``Z``'s is kept if it reaches the top of the frame (through the prior's
      regions too) or starts in the upper half; one cut off from the top that starts in the lower
      half is dropped (a pool or a window that ``Z`` took for sky).
    * A region of the prior that is clear blue (:func:`_clear_blue` on at least
      :data:`CLEAR_BLUE` of it) and spans at least :data:`CLEAR_TOP` of the top row is sky
      whatever ``Z`` says: ``Z`` missed the whole sky of a beach under a clear sky (dev photos:
      sky mask empty on 2 of 47, their blue sky and sea then read as the photo's shadows), and
      a smooth blue band across the whole top of a frame is almost never a surface. Shade on
      snow is bluish too, but does not span the top row (on the dev photos such regions touch
      at most 9 % of it).
    * Holes are closed as in :func:`sky_prior`.

    ``greyscale``: whether the photo is black and white (:func:`sky_colour`); None: decided
    here, once.
    """
    model_sky = np.asarray(model_sky, dtype=bool)
    image = np.asarray(image_srgb, dtype=np.float32)
    if model_sky.shape != image.shape[:2]:
        raise ValueError(
            f"expected a sky mask of the image's size {image.shape[:2]}, got {model_sky.shape}"
        )
    h = model_sky.shape[0]
    if greyscale is None:
        greyscale = is_greyscale(np.nan_to_num(image))
    prior = sky_prior(image, greyscale)
    clear = np.zeros_like(prior)
    n, labels = cv2.connectedComponents(prior.astype(np.uint8), connectivity=4)
    if n > 1:
        area = np.bincount(labels.ravel(), minlength=n)
        agree = np.bincount(labels.ravel(), weights=model_sky.ravel(), minlength=n)
        ok = agree >= MIN_AGREEMENT * np.maximum(area, 1)
        blue = np.bincount(labels.ravel(), weights=_clear_blue(image).ravel(), minlength=n)
        top = np.bincount(labels[0], minlength=n)
        sure = (blue >= CLEAR_BLUE * np.maximum(area, 1)) & (top >= CLEAR_TOP * labels.shape[1])
        ok[0] = sure[0] = False
        prior = ok[labels]
        clear = sure[labels]
    n, labels = cv2.connectedComponents(model_sky.astype(np.uint8), connectivity=8)
    keep = np.zeros(n, bool)
    if n > 1:
        reached = np.unique(labels[top_connected(model_sky | prior) & model_sky])
        keep[reached] = True
        rows = np.arange(h)[:, None].repeat(model_sky.shape[1], 1)
        first_row = np.full(n, h)
        np.minimum.at(first_row, labels.ravel(), rows.ravel())
        keep |= first_row < h / 2
        keep[0] = False
    z_kept = keep[labels]
    rows_with_sky = np.nonzero(z_kept.any(axis=1))[0]
    limit = rows_with_sky[-1] + 1 + round(HORIZON_MARGIN * h) if rows_with_sky.size else 0
    prior[limit:] = False
    return _fill_holes(z_kept | prior | clear, sky_colour(image, greyscale))


#: :func:`refine_sky_edge`: how far (fraction of the longer side) the sky may grow past the
#: combined mask's edge, and how close (largest sRGB channel difference) a pixel's colour must
#: be to the sky's around it.
SKY_EDGE_BAND = 0.03
SKY_EDGE_TOL = 0.08
#: :func:`refine_sky_edge`: a pixel's colour is also compared with the sky just beside it
#: (a Gaussian of this fraction of the band): the band-wide mean near the sun is its glare's
#: white, and the hazy grey sky between the ski-slope sample's tree tops, 0.10 from it, stayed
#: a surface that a new sun's glare left out as a grey staircase (a user trial).
SKY_EDGE_NEAR = 1.0 / 6.0
#: ... where that Gaussian's share of sky is at least this.
SKY_NEAR_PRESENT = 1e-6
#: ... and only for a pixel within this many :data:`SKY_EDGE_TOL` of the band-wide mean (a
#: glare moves the sky's colour a little from the wide mean: the ski slope's haze was 0.08-0.12
#: from it, 10th to 90th percentile, at the balanced preset's 384 px; this takes 298 of the 333
#: working pixels the near sky gains there, the glare's grey staircase gone but for a speck;
#: 1.75 took 328, and twice the sea's surf). Without this (until 2026-12-04) the near sky
#: took surfaces 0.16-0.34 from the sky's colour that match the sky at its edge: a sea's
#: surf below a pale horizon, the pale tops of a white building (dev photos), a few pixels of
#: the pool sample's far side; the held-out renders' sky IoU fell 0.9305 -> 0.9275 (0.9297
#: with this), and Find sun's dev figure moved by the sky it took.
SKY_NEAR_WIDE = 1.5
#: :func:`refine_sky_edge`: how many times the sky grows by the band, each time from the sky
#: grown so far (its colour always that of the sky it was given); after the first pass only
#: into sky-coloured regions cut off from the bottom edge, not into a pale ground. One pass left
#: the sky inside the ski-slope sample's pylon head and chair frames (more than a band from
#: the sky ``Z`` saw) a surface, and the relighting darkened it into grey rectangles in the
#: sky (a user trial). A third pass began to take the snow below the tree line there (unless
#: restricted, and even then a snow patch boxed in by the right-hand pylon and chairs).
SKY_EDGE_PASSES = 2
#: :func:`refine_sky_edge`'s later passes take a boxed-in region of sky colour only when at
#: least this share of it is as close to the sky's colour as the first pass asks, and it is
#: at least half a band squared: the sky seen through a frame is sky as a whole (the ski-slope
#: pylon head's, 67 %); a pale object against the sky (an aircraft's grey fuselage on a dev
#: photo) matches the sky in spots.
SKY_FRAMED_ALIKE = 0.6
#: ... and only when the pixels round it (off the sky) are darker than it by this factor (a
#: median): a frame of bars, not asphalt specks under a wrongly found "sky" (a dev photo).
SKY_FRAME_DARKER = 0.7
#: ... and only when it is at most this many bands squared: a frame's inside is small (the
#: ski slope's pylon head 1.8-2.0 at the balanced and accurate presets, its chairs' 3.4-4.3);
#: a pale wall under a white sky, boxed in by darker ground and edges, is larger (a review: a
#: white wall 20-50 px tall lost a second band). A rule by how much of the region's rim meets
#: the sky could not tell the two apart (the pylon head's 0.5-0.6, the walls' too). A pale
#: object boxed in by darker structure and smaller than this can still be taken.
SKY_FRAMED_MAX = 5.0


def refine_sky_edge(sky: np.ndarray, image_srgb: np.ndarray,
                    greyscale: bool | None = None) -> np.ndarray:
    """Grow a sky mask up to the photo's own sky edge.

    ``Z`` sees the sky at 128 px and :func:`sky_prior` needs a smooth window, so both stop a few
    pixels short of every object standing against the sky, and miss the sky between a
    chairlift's bars or a tree's branches. Relit, that band is a surface: it took the new
    shadows' darkening as blocky halos round the ski-slope sample's chairlift and tree tops.
    Here every pixel within :data:`SKY_EDGE_BAND` of the sky (straight-line distance, so sky
    seen through a closed frame counts: a chair's bars, a pylon's triangle) whose colour is a
    sky's (:func:`sky_colour`) and within :data:`SKY_EDGE_TOL` of the sky's around it (a
    Gaussian average of the sky pixels, sigma the band; or of the sky just beside it,
    :data:`SKY_EDGE_NEAR`, for a pixel not far from the first: a glare's gradient,
    :data:`SKY_NEAR_WIDE`) is sky, in :data:`SKY_EDGE_PASSES`
    passes (each from the sky grown so far, with the given sky's colour; after the first, only
    into the sky seen through a frame: small regions of sky colour that do not reach the
    bottom edge, are sky-like as a whole and framed by darker structure,
    :data:`SKY_FRAMED_ALIKE` to :data:`SKY_FRAMED_MAX`): a dark pole, a tree or a roof does
    not pass; a pale wall or snowfield next to a white sky can lose at most the band (a small
    pale object boxed in by darker structure, within two bands of a sky of its colour, two).
    Meant for the working size, as :func:`postprocess_z` runs it: its blur grows with the side
    (13 ms at 384 px, 0.3 s at 1024, seconds beyond).

    Args:
        sky: ``H x W`` bool.
        image_srgb: ``H x W x 3`` sRGB of the same size.
        greyscale: whether the photo is black and white (:func:`sky_colour`); None: decided
            from ``image_srgb``.

    Returns:
        ``H x W`` bool, a superset of ``sky``.
    """
    sky = np.asarray(sky, dtype=bool)
    img = np.nan_to_num(np.clip(np.asarray(image_srgb, np.float32), 0.0, 1.0))
    if img.shape[:2] != sky.shape:
        raise ValueError(f"expected a sky mask of the image's size {img.shape[:2]}, got "
                         f"{sky.shape}")
    band = round(SKY_EDGE_BAND * max(sky.shape))
    if band < 1 or not sky.any() or sky.all():
        return sky
    colour = sky_colour(img, greyscale)
    weight, local = _local_sky(sky, img, band)
    near_weight, near_local = _local_sky(sky, img, max(1, round(band * SKY_EDGE_NEAR)))
    # Only where the sky's weight is a weight: below, the mean's floor (1e-6) pulls it to 0.
    near_local = np.where((near_weight > SKY_NEAR_PRESENT)[..., None], near_local, np.inf)
    grown = sky
    for k in range(SKY_EDGE_PASSES):
        more = _grow_sky(grown, img, colour, weight, local, band, framed=k > 0,
                         near_local=near_local)
        if more is grown:
            break
        grown = more
    return grown


def _local_sky(sky: np.ndarray, img: np.ndarray, band: int) -> tuple[np.ndarray, np.ndarray]:
    """The sky's presence round each pixel and its mean colour there (a Gaussian of the sky's
    pixels, sigma the band, in pixels); every pass of
    :func:`refine_sky_edge` compares with the sky it was given, not with the sky grown so far
    (whose colour drifted toward a pale object it took: an aircraft's grey fuselage, grown
    into from its tail fin on a dev photo)."""
    sigma = float(band)
    weight = cv2.GaussianBlur(sky.astype(np.float32), (0, 0), sigma)
    local = cv2.GaussianBlur(img * sky[..., None], (0, 0), sigma) / np.maximum(weight, 1e-6)[
        ..., None]
    return weight, local


def _grow_sky(sky: np.ndarray, img: np.ndarray, colour: np.ndarray, weight: np.ndarray,
              local: np.ndarray, band: int, framed: bool,
              near_local: np.ndarray | None = None) -> np.ndarray:
    """One pass of :func:`refine_sky_edge` (``colour``: :func:`sky_colour` of ``img``;
    ``weight``, ``local``: :func:`_local_sky`; ``framed``: only into sky-coloured regions off
    the sky that do not reach the bottom edge and are :data:`SKY_FRAMED_ALIKE` sky-like); the
    same array when nothing grows."""
    diff = np.abs(img - local).max(axis=2)
    if near_local is not None:  # or the sky just beside it (the wide mean holds a glare)
        near = np.abs(img - near_local).max(axis=2)
        diff = np.where(diff < SKY_NEAR_WIDE * SKY_EDGE_TOL, np.minimum(diff, near), diff)
    close = (diff < SKY_EDGE_TOL) & (weight > 1e-3)
    candidate = close & colour & ~sky
    if framed and candidate.any():  # whole regions of sky colour, boxed in, sky as a whole
        off = colour & ~sky
        n, labels, stats, _ = cv2.connectedComponentsWithStats(off.astype(np.uint8),
                                                               connectivity=8)
        area = stats[:, cv2.CC_STAT_AREA]
        alike = np.bincount(labels[off & close], minlength=n)
        seen = ((alike >= SKY_FRAMED_ALIKE * np.maximum(area, 1))
                & (area >= 0.5 * band * band) & (area <= SKY_FRAMED_MAX * band * band))
        seen[labels[-1]] = False  # reaches the bottom edge: a pale ground
        seen[0] = False
        luma = img.mean(axis=2)
        h, w = sky.shape
        for k in np.nonzero(seen)[0]:  # framed by darker structure, not by more of the same
            x, y, bw, bh = stats[k, :4]  # (each in its box and a pixel round it: bounded work)
            box = np.s_[max(0, y - 1):min(h, y + bh + 1), max(0, x - 1):min(w, x + bw + 1)]
            region = labels[box] == k
            ring = (cv2.dilate(region.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
            ring &= ~region & ~sky[box]
            lum = luma[box]
            if ring.any() and np.median(lum[ring]) > SKY_FRAME_DARKER * np.median(lum[region]):
                seen[k] = False
        candidate &= seen[labels]
    if not candidate.any():
        return sky
    near = cv2.distanceTransform((~sky).astype(np.uint8), cv2.DIST_L2, 3) <= band
    return sky | (candidate & near)


def smooth_depth(depth: np.ndarray, sky: np.ndarray, image_srgb: np.ndarray) -> np.ndarray:
    """Edge-aware smoothing of a depth map guided by its photo (guided filter on log depth).

    Args:
        depth: ``H x W`` positive depth (any scale; values where ``sky`` is True are ignored).
        sky: ``H x W`` bool, no surface.
        image_srgb: ``H x W x 3`` sRGB ``[0, 1]``, the guide.

    Returns:
        ``H x W`` float32 depth: smoothed where the input is a finite positive surface, the
        input's values elsewhere (sky, and any non-finite or non-positive pixel).
    """
    depth = np.asarray(depth, dtype=np.float32)
    sky = np.asarray(sky, dtype=bool)
    image = np.asarray(image_srgb, dtype=np.float32)
    if depth.ndim != 2 or sky.shape != depth.shape or image.shape != (*depth.shape, 3):
        raise ValueError(
            f"expected depth H x W, sky H x W and an H x W x 3 image of one size, got "
            f"{depth.shape}, {sky.shape}, {image.shape}"
        )
    ok = ~sky & np.isfinite(depth) & (depth > 0)
    if not ok.any():
        return depth
    # Sky and invalid pixels take their nearest surface's depth, so a far horizon is not pulled
    # toward the image's median depth.
    log_d = fill_invalid(np.log(np.where(ok, depth, 1.0)), ok).astype(np.float32)
    radius = max(1, round(SMOOTH_RADIUS * max(depth.shape)))
    guide = np.nan_to_num(np.clip(image, 0.0, 1.0))
    out = cv2.ximgproc.guidedFilter(guide, log_d, radius, SMOOTH_EPS)
    return np.where(ok, np.exp(out), depth).astype(np.float32)


@dataclass(frozen=True, eq=False)
class GroundPlane:
    """A plane ``normal . X = offset`` in camera space (``normal`` unit, pointing up, i.e. toward
    ``-y``; ``offset < 0``: the camera is above it; in the depth map's units), and the fraction of
    the fitted points on it."""

    normal: np.ndarray
    offset: float
    inliers: float


def _log_gap(offset: float, n_dot_p: np.ndarray) -> np.ndarray:
    """``log t - log d`` of points at depth ``d`` whose rays meet the plane at depth ``t``, from
    ``n . p`` of the points (``t / d = offset / (n . p)``); NaN where the ray misses the plane."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = offset / n_dot_p
    return np.log(np.where(ratio > 0, ratio, np.nan))


def fit_ground_plane(
    depth: np.ndarray, sky: np.ndarray, camera: Camera, seed: int = 0
) -> GroundPlane | None:
    """The ground plane of the bottom :data:`GROUND_ROWS` of a depth map, or None.

    RANSAC over at most :data:`GROUND_POINTS` surface points (deterministic for a ``seed``).
    Only planes below the camera whose normal is within :data:`GROUND_MAX_TILT_DEG` of the
    camera's up count. The plane on which most points lie (depth along their ray within
    :data:`GROUND_TOL` in log) is refitted to those points by least squares. None when there are
    too few surface points, no plane qualifies, or fewer than :data:`GROUND_MIN_INLIERS` of the
    points lie on it.

    Depth alone cannot tell a wall seen by a camera pitched up from a slope seen by a level
    camera: the tilt limit takes a wall for ground only when the camera is pitched up by more
    than ``90 - GROUND_MAX_TILT_DEG`` degrees. (A test of the plane against the sky, whose rays
    should not meet a ground, was tried and dropped: an uphill slope's plane passes above its
    crest, and the ski-slope sample was rejected.)
    """
    depth = np.asarray(depth, np.float32)
    sky = np.asarray(sky, dtype=bool)
    if depth.shape != sky.shape or depth.shape != (camera.height, camera.width):
        raise ValueError(f"expected depth and sky of the camera's size "
                         f"{(camera.height, camera.width)}, got {depth.shape} and {sky.shape}")
    top = min(depth.shape[0] - 1, int(depth.shape[0] * (1.0 - GROUND_ROWS)))
    pts = backproject(np.where(sky, np.nan, depth), camera)[top:].reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)].astype(np.float64)  # surface points only
    if len(pts) < 24:
        return None
    rng = np.random.default_rng(seed)
    if len(pts) > GROUND_POINTS:
        pts = pts[rng.choice(len(pts), GROUND_POINTS, replace=False)]
    z = pts[:, 2]
    # Every trial at once: normals of random point triples, flipped to point up (-y).
    tri = pts[rng.integers(0, len(pts), (GROUND_TRIALS, 3))]  # T x 3 x 3
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    cos_max = np.cos(np.radians(GROUND_MAX_TILT_DEG))
    good = norm > 1e-12 * float(z.max()) ** 2
    n = n / np.where(good, norm, 1.0)[:, None] * np.where(n[:, 1] > 0, -1.0, 1.0)[:, None]
    offset = np.einsum("tj,tj->t", n, tri[:, 0])
    good &= (-n[:, 1] >= cos_max) & (offset < 0)
    if not good.any():
        return None
    n, offset = n[good], offset[good]
    inl = np.abs(_log_gap(offset[None], (pts @ n.T))) < GROUND_TOL  # P x T; NaN -> False
    best = inl[:, int(np.argmax(inl.sum(axis=0)))]
    if best.sum() < 3:
        return None
    q = pts[best]
    centre = q.mean(axis=0)
    normal = np.linalg.svd(q - centre, full_matrices=False)[2][-1]
    normal = -normal if normal[1] > 0 else normal
    offset = float(normal @ centre)
    if -normal[1] < cos_max or not offset < 0:
        return None
    frac = float((np.abs(_log_gap(offset, pts @ normal)) < GROUND_TOL).mean())
    if frac < GROUND_MIN_INLIERS:
        return None
    return GroundPlane(normal.astype(np.float64), offset, frac)


def plane_depth(plane: GroundPlane, camera: Camera) -> np.ndarray:
    """``H x W`` float32 z depth at which each pixel's ray meets ``plane`` (a plane below the
    camera, ``offset < 0``); ``inf`` where it never does (at and above the plane's horizon)."""
    x = ((np.arange(camera.width) + 0.5 - camera.cx) / camera.focal).astype(np.float32)
    y = ((np.arange(camera.height) + 0.5 - camera.cy) / camera.focal).astype(np.float32)
    nx, ny, nz = (np.float32(c) for c in plane.normal)
    den = nx * x[None, :] + (ny * y[:, None] + nz)  # H x W
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.float32(plane.offset) / den
    return np.where(np.isfinite(t) & (t > 0), t, np.float32(np.inf))


def _snap_weight(gap: np.ndarray) -> np.ndarray:
    """How far a point moves onto the plane (1: onto it) by its ``gap = log t - log d``."""
    above = np.clip(1.0 - gap / GROUND_BAND, 0.0, 1.0) ** 2
    below = np.clip(2.0 + gap / GROUND_BELOW, 0.0, 1.0)
    return np.where(gap >= 0, above, below)


def snap_ground(
    depth: np.ndarray, sky: np.ndarray, camera: Camera
) -> tuple[np.ndarray, GroundPlane | None]:
    """Surface points near the ground plane moved onto it.

    For a point at depth ``d`` whose ray meets the plane at ``t``, with ``g = log t - log d`` (its
    height above the plane in log depth), the new log depth is ``a log t + (1 - a) log d`` with:

    * above the plane, ``a = (1 - g / GROUND_BAND)^2`` within the band, 0 beyond it: points on
      the plane stay there, what stands on the ground keeps its shape, and the height above the
      plane, ``g (1 - a)``, rises smoothly from 0 and joins ``g`` with the same slope at the
      band's edge (no step, no crease at the foot of objects);
    * below the plane, ``a = 1`` down to ``GROUND_BELOW``, fading to 0 at twice that: the
      estimate's dips go onto the ground, while a surface far below it (a valley seen from a
      terrace) is left where it is.

    Returns:
        ``(depth, plane)``: ``H x W`` float32 (the input where no plane was found, on sky and on
        non-finite or non-positive pixels), and the plane or None.
    """
    depth = np.asarray(depth, np.float32)
    sky = np.asarray(sky, dtype=bool)
    plane = fit_ground_plane(depth, sky, camera)
    if plane is None:
        return depth, None
    t = plane_depth(plane, camera)
    ok = ~sky & np.isfinite(depth) & (depth > 0) & np.isfinite(t)
    log_d = np.log(np.where(ok, depth, np.float32(1.0)))
    log_t = np.log(np.where(ok, t, np.float32(1.0)))
    a = _snap_weight(log_t - log_d).astype(np.float32)
    out = np.exp(log_d + a * (log_t - log_d))
    return np.where(ok & (a > 0), out, depth).astype(np.float32), plane


def run_depth_model(
    model: Any, image_srgb: np.ndarray, side: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``Z`` on a photo at the scale it was trained at; raw depth and sky probability at the
    photo's size.

    ``Z`` is a CNN with a fixed receptive field, trained on ``model.input_side``-pixel views: on
    a larger image every object covers more pixels than any it saw and its field of view covers
    less of the scene. Measured on held-out views upsampled before ``Z`` (raw silog, first
    image of each view): 60 landscapes 0.26 at the training scale, 0.31 at 1.5x, 0.40 at 2x,
    0.54 at 3x (the balanced preset's 384 px is 3x); 20 standard test views 0.34, 0.39, 0.45,
    0.53. So a photo larger than that is shrunk to it (area filter), and the log depth and sky
    probability come back up bilinearly; :func:`postprocess_z`'s guided filter, with the
    full-size photo as its guide, then restores the photo's edges.

    Args:
        model: a loaded depth model (``run({"image": 1 x 3 x H x W})`` -> ``depth``, ``sky``)
            with an ``input_side`` (None: run at the photo's size).
        image_srgb: ``H x W x 3`` sRGB ``[0, 1]``.
        side: longer side to run at instead of ``model.input_side``.

    Returns:
        ``(depth, sky_prob)``: ``H x W`` float32 each.
    """
    image = np.asarray(image_srgb, np.float32)
    if image.ndim != 3 or image.shape[2] != 3 or min(image.shape[:2]) < 1:
        raise ValueError(f"expected an H x W x 3 image, got shape {image.shape}")
    h, w = image.shape[:2]
    side = side if side is not None else model.input_side
    small = image
    if side and max(h, w) > side:
        scale = side / max(h, w)
        size = (max(1, round(w * scale)), max(1, round(h * scale)))
        small = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    out = model.run({"image": small.transpose(2, 0, 1)[None]})
    depth = np.asarray(out["depth"][0, 0], np.float32)
    sky = np.asarray(out["sky"][0, 0], np.float32)
    if small is image:
        return depth, sky
    log_d = np.log(np.clip(np.nan_to_num(depth, nan=1e-6, posinf=1e6), 1e-6, None))
    log_d = cv2.resize(log_d, (w, h), interpolation=cv2.INTER_LINEAR)
    sky = cv2.resize(sky, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.exp(log_d).astype(np.float32), sky


def postprocess_z(
    depth: np.ndarray, sky_prob: np.ndarray, image_srgb: np.ndarray,
    camera: Camera | None = None, *, greyscale: bool | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``Z``'s raw outputs (``H x W`` depth and sky probability) to the runtime's depth and sky.

    The sky is ``Z``'s (probability > 0.5) combined with :func:`sky_prior`
    (:func:`combine_sky`), grown to the photo's sky edge (:func:`refine_sky_edge`); the depth is
    clamped to be positive and smoothed by :func:`smooth_depth`, and, given the ``camera``
    (intrinsics of the same size), its ground is snapped to a plane by :func:`snap_ground`. As
    everywhere for estimated depth (DESIGN.md), the depth stays finite on sky pixels and the
    mask says where the sky is. Whether the photo is black and white (its sky is then found by
    brightness: :func:`sky_colour`) is decided once: ``greyscale`` when the caller decided it on
    the whole photo (the session does), else here.

    Returns:
        ``(depth, sky)``: ``H x W`` float32, finite and > 0, and ``H x W`` bool.
    """
    raw = np.asarray(depth, np.float32)
    depth = np.clip(np.nan_to_num(raw, nan=1e-6, posinf=1e6, neginf=1e-6), 1e-6, None)
    if greyscale is None:
        greyscale = is_greyscale(np.nan_to_num(np.asarray(image_srgb, np.float32)))
    sky = refine_sky_edge(combine_sky(np.asarray(sky_prob) > 0.5, image_srgb, greyscale),
                          image_srgb, greyscale)
    depth = smooth_depth(depth, sky, image_srgb)
    if camera is not None:
        depth = snap_ground(depth, sky, camera)[0]
    return depth, sky
