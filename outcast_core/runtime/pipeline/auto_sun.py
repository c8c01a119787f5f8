"""Automatic sun: find the photo's sun from its own shadows and, where it has them, its EXIF.

:func:`find_sun` searches the visible hemisphere for the sun whose predicted shadows (the
session's shadow network, or Direct in classic mode) best agree with the shadows found in the
photo itself (:func:`~outcast_core.runtime.pipeline.photo_shadows.photo_shadow_probability`, no
prior, without the surface's fine dark texture:
:func:`~outcast_core.runtime.pipeline.photo_shadows.without_texture`, as the de-shadow lifts
them; on the real dev photos this took the share within 0.03 of the sweep from 68.1 % to
70.2 %, one photo, on 2026-12-01).
The agreement of a sun is ``1 - BER`` between the overlay's mask (``S < 0.15`` off the sky, as
the app draws it and ``outcast eval real`` scores it) and the found shadows, each pixel counted
on the shadow side with its probability and on the lit side with the rest (a soft error,
:func:`agreement`; until 2026-12-05 against the mask ``p > 0.5``): 1 is a perfect match, 0.5 is
chance.

The search may also rank by the shading (``measure="shading"``, :func:`shading_agreement`: the
correlation of ``S`` with the photo's linear luminance, attached shading and cast shadows
together, with no found mask) or by both (``"mask+shading"``); the default stays the mask
(:data:`MEASURE`), chosen by the numbers below.

Coarse to fine, cheap where it can be:

1. the light-independent buffers (depth, sky, normals, photo, its luminance) at each small size
   (:data:`COARSE_SIZE`, :data:`FINE_SIZE`), made once per call from the session's working
   buffers;
2. a coarse grid over the dome (:data:`COARSE_AZIMUTHS` x :data:`COARSE_ELEVATIONS`), all suns
   in batches through the shadow network at :data:`COARSE_SIZE` px: this is the map the app
   shows as a heat map;
3. the :data:`RECHECK` best separated peaks (:data:`PEAK_SEPARATION`) scored again at
   :data:`RECHECK_SIZE` px, and around the :data:`SEEDS` best of them 3 x 3 patterns at half
   the grid step at :data:`FINE_SIZE` px (:data:`FINE_PATTERNS`);
4. the last :data:`FINAL_CANDIDATES` at the session's working size (cached by the session, so
   the overlay the app then draws costs nothing), except those more than :data:`FINAL_MARGIN`
   behind the best at the small size (early rejection).

EXIF: GPS and capture time fix the sun's true elevation above the horizon (astral); with it the
search runs on that ring only (:class:`SunPrior`), in the camera's frame: its pitch and roll
from the photo's metadata where it records them (:mod:`~outcast_core.runtime.io.camera_pose`: XMP
GPano or DJI gimbal angles, Exif ``CameraElevationAngle``), else from the fitted ground plane
(:attr:`SunFit.pose_source` says which). A compass heading also gives the azimuth:
a full guess that pulls the search toward it (:attr:`SunPrior.azimuth_weight`) but loses when
the shadows clearly say otherwise (compasses are often off, sometimes wildly: the ski-slope
sample's heading puts the sun 130° from where it is in the frame), and that stands when the
photo has no clear shadows.

The sun in the frame (:func:`sun_in_photo`): when the photo shows the sun itself, its direction
is exact; :func:`find_sun` returns it (source ``"sun in the frame"``, confidence 1) after the
search, which still draws the heat map of what the shadows say, and :func:`photo_camera_tilt`
takes the camera's pitch from it and the EXIF elevation (:func:`sun_frame_pitch`).

Confidence (:attr:`SunFit.confidence`, 0-1) is the product of how clearly the photo has sun and
shade (the gap between the lit and shaded surface's log luminance, and a shade fraction that is
neither nothing nor everything), how clearly one part of the dome explains them (the best
agreement against the dome's median) and how well the best sun explains them at all (its
agreement between :data:`WEAK_AGREEMENT` and :data:`STRONG_AGREEMENT`; on the real dev photos
the best of the 24-sun sweep agrees at 0.57 / 0.68 / 0.74 at the 10th / 50th / 75th
percentile). Below :data:`CONFIDENT` the fit says so (:attr:`SunFit.found` is False) instead of
offering a guess, and says which: no clear shadows in the photo, or none that any sun's
predicted shadows fit (rough depth).

Measured on 2026-11-30 (``scripts/eval_auto_sun.py``; shipped models, balanced preset, 2 shared
cores at load 3-10; seconds are under that load; ``models/EVAL.md`` has the table):

* real dev photos (47, human masks; ``python scripts/eval_auto_sun.py ../shared/realdev
  --sweep-cache C [--measure M] [--set NAME=VALUE]``): share of photos whose found sun's
  overlay BER is within 0.03 of the best of the 24-sun sweep. Ranked by the mask, dome at 64 px,
  3 seeds refined at 96, all 3 finalists checked (the earlier search, with today's photo
  shadows): 72.3 % (mean gap +0.007). Ranked by the shading correlation: 29.8 %. Speed variants
  (mask): dome 48 + finalists more than 0.03 behind skipped: 74.5 %; the same with 2 seeds:
  74.5 % (mean gap +0.004); margin 0.01: 66.0 %; 2 finalists: 70.2 %; dome 32 and refine at 64:
  63.8 %; dome 32, two patterns at 64: 59.6 %; dome 32, refine at 96: 68.1 %; **dome 32, the 12
  best peaks rechecked at 64, 2 refined at 96 (the default): 70.2 % (33), mean gap +0.012,
  mean BER 0.319 vs the sweep's 0.307**; the same rechecked at 48: 68.1 %. Differences of
  2-4 points are one or two photos. Its 12 MP time (``bench_runtime --only find_sun``) is
  about 5-6 working-size shadow images, against 8-8.5 for the earlier search. Ranked against
  the found shadows' probability instead of the mask (2026-12-05, the default): **80.9 %
  (38), mean gap +0.003** (the mask: 70.2 %, +0.0154, re-measured that day).
* held-out synthetic views (``outcast data make --seed 1000000``, 128 px; ``--synthetic
  ~/.cache/outcast/data/test --limit 60 [--given-depth] [--measure shading]``, the first 15
  views x 4 suns): median angle to the true sun with the default search: 65° with the
  estimated depth, 39° with the renderer's exact depth (10 % / 15 % within 15°; the earlier
  search 60° / 44°); ranked by the shading: 43° (estimated) and 30° (exact; 20 % within 15°).
  4.4 s per view at load 7-10 (depth excluded). Why, from a dense 10° grid of every sun at
  64 px on 40 pairs (nothing fitted): with the exact depth even the *true* shadow mask
  (``S_true < 0.15``) as the photo's shadows puts the best sun 18° off (13° with Direct at
  128 px), the photo's found mask 40°, the shading 28°; with the estimated depth the true mask
  gives 49°, the found mask 62°, the shading 42°: the estimated geometry is what fails (its
  normals are 22° off the renderer's, median of 10 views, 3-56°), not the search, the found
  shadows (BER 0.18 against the true mask) or the azimuth ambiguity (12-16 % of the errors
  are > 135° in azimuth). Scoring cast shadows only (pixels facing the sun, cos >= 0.15) was
  worse (62-76°), as was the mask + shading sum (27-63°). The mask stays the default: the
  shading gains on synthetic views and loses badly on real photos.
* samples, elevation vs astral's (``--samples samples``): with the EXIF prior -1.0° on all
  three (in the ground plane's frame, or level where none fits: none of the samples records a
  pose); from the shadows alone -23.8° (pool), -2.9° (ski slope), -31.1° (field path).
"""

from __future__ import annotations

import datetime as dt
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from outcast_core.runtime.geometry.camera import (
    Camera,
    network_depth,
    normals_from_depth,
    project,
    sun_angles,
    sun_vector,
)
from outcast_core.runtime.geometry.colour import luminance, srgb_to_linear
from outcast_core.runtime.pipeline.photo_shadows import photo_shadow_probability, without_texture
from outcast_core.runtime.pipeline.relight import SUN_CORE_DEG, sun_core_px

#: The overlay's threshold: ``S`` below it is a predicted shadow (as ``real_eval``).
SHADOW_THRESHOLD = 0.15
#: Longer side (px) of the coarse grid's, the recheck's and the fine patterns' shadow images.
COARSE_SIZE = 32
RECHECK_SIZE = 64
FINE_SIZE = 96
#: How many separated peaks of the coarse grid are scored again at :data:`RECHECK_SIZE` before
#: the best :data:`SEEDS` of them are refined (early rejection of the rest of the dome).
RECHECK = 12
#: The coarse grid over the dome (degrees, camera-relative, or in the ground's frame with a
#: known pitch and roll).
COARSE_AZIMUTHS: tuple[float, ...] = tuple(float(a) for a in range(0, 360, 20))
COARSE_ELEVATIONS: tuple[float, ...] = (8.0, 22.0, 36.0, 50.0, 64.0, 78.0)
#: With an elevation prior: the azimuth step of the ring.
RING_AZIMUTH_STEP = 10.0
#: Seeds taken from the coarse grid (local peaks at least :data:`PEAK_SEPARATION` degrees apart)
#: and candidates checked at the session's working size.
SEEDS = 2
PEAK_SEPARATION = 30.0
FINAL_CANDIDATES = 3
#: A candidate more than this behind the best (in the ranking score at the small sizes) is not
#: checked at the working size.
FINAL_MARGIN = 0.03
#: The fine patterns: ``(seeds, step[, size])``: 3 x 3 suns around the best ``seeds`` so far,
#: ``step`` times the coarse grid's step apart (step 0: the seeds alone), at ``size`` px
#: (default :data:`FINE_SIZE`). The first pattern's ``seeds`` are the coarse grid's separated
#: peaks; a pattern at another size than the one before starts a new list of candidates.
FINE_PATTERNS: tuple[tuple[int, float] | tuple[int, float, int], ...] = (
    (RECHECK, 0.0, RECHECK_SIZE), (SEEDS, 0.5, FINE_SIZE))
#: The lowest elevation tried (a grazing sun puts the whole ground in shadow).
MIN_ELEVATION = 5.0
#: Shadow images per network call.
BATCH = 36
#: Below this confidence the photo's shadows do not tell the sun (:attr:`SunFit.found`).
CONFIDENT = 0.3
#: Gap (natural log units) between the mean log luminance of the photo's lit surface and of its
#: found shade at which the photo starts / stops counting as clearly sun and shade. A sunlit
#: cast shadow is 1-3 stops (0.7-2.1) darker; the real dev photos' gaps are 1.1-3.7; Otsu's
#: split of an overcast photo's texture gives a few tenths.
SEPARATION_LOW = 0.7
SEPARATION_HIGH = 1.2
#: Agreement of the best sun above the dome's median at which a peak counts as clear.
PEAK_CONTRAST = 0.08
#: Agreement of the best sun at which the confidence starts from 0 / reaches its full value.
WEAK_AGREEMENT = 0.55
STRONG_AGREEMENT = 0.7
#: Shade fractions (of the surface) below / above which the photo has no usable shadows.
MIN_SHADE = 0.005
MAX_SHADE = 0.85
#: What the search ranks suns by (:func:`ranking`): ``"mask"`` (the overlay's agreement with
#: the photo's found shadows), ``"shading"`` (the correlation of ``S`` with the photo's
#: luminance) or ``"mask+shading"`` (the agreement plus :data:`SHADING_WEIGHT` times the
#: correlation).
MEASURES = ("mask", "shading", "mask+shading")
#: :attr:`SunFit.source` when no shadows told the sun and the EXIF sun stands, and when the
#: photo shows the sun itself.
SOURCE_EXIF = "EXIF"
SOURCE_SUN_IN_FRAME = "sun in the frame"
#: :attr:`SunFit.source` of a sun the shadows found: alone, within the EXIF's elevation, or
#: with the EXIF's compass heading too.
SOURCE_SHADOWS = "shadows"
SOURCE_SHADOWS_EXIF_ELEVATION = "shadows + EXIF elevation"
SOURCE_SHADOWS_EXIF = "shadows + EXIF"
#: :attr:`SunFit.unfound`: the photo is too small or narrow for its shadows, it has no clear
#: shadows, or no sun's predicted shadows fit them.
UNFOUND_REASONS = ("too-small", "no-clear-shadows", "no-fit", "open-sky")
MEASURE = "mask"
SHADING_WEIGHT = 0.5
#: Shorter side (pixels of the working image, where shadows are read) below which / from which
#: the confidence is scaled down to 0 / kept whole (:func:`legibility`): a thumbnail or a
#: narrow strip has too few pixels of shadow to tell a sun by (a user trial: a 16 x 16 image
#: and a 600 x 4000 strip were "found" with confidence 1.0).
LEGIBLE_LOW = 24
LEGIBLE_HIGH = 64
#: Shorter side (working pixels) under which no ground plane is fitted for the camera's tilt
#: (:func:`ground_plane_tilt`): too few rows of depth to hold one. A user trial's 64 x 48
#: copy of the pool sample was "pitched 21.8 degrees down", which moved its EXIF sun 37
#: degrees; copies 96 x 72 and 112 x 84 were pitched 14.8 degrees, while 128 x 96, 160 x 120,
#: 200 x 150 and the photo itself have no plane (the fast preset, classic and learned alike).
PLANE_MIN_SIDE = 96
#: The photo's look (``D``, :meth:`~outcast_core.runtime.pipeline.session.RelightSession.sun_look`)
#: in the ranking: each sun's score gains ``LOOK_WEIGHT * log(max(likelihood, LOOK_FLOOR))``
#: (likelihood 1 at ``D``'s peak), so a sun the look rules out loses at most
#: ``LOOK_WEIGHT * log(1 / LOOK_FLOOR)`` of agreement. 0 (the default) leaves the shadows alone
#: and does not run ``D``: on held-out synthetic views ``D`` alone puts the sun 26 degrees off
#: (median; the shadows alone 56-58), but on the 47 dev photos every weight tried made the
#: found sun's overlay worse (``models/EVAL.md``, twelfth session), so no ``sun.onnx`` ships.
LOOK_WEIGHT = 0.0
LOOK_FLOOR = 1e-3
#: :func:`find_sun` rules out a sun whose disc (:data:`HIDDEN_SUN_DEG` of radius) would stand
#: wholly on the photo's open sky when the photo shows no sun there
#: (:func:`open_sky_suns`): such a sun's score loses this much (more than any score spans:
#: agreements and correlations lie in [-1, 1]).
HIDDEN_SUN_PENALTY = 10.0
#: The radius (degrees) of the sun's bright disc that a photo of a clear sky would show: a
#: camera's clipped core (its glare reaches further).
HIDDEN_SUN_DEG = SUN_CORE_DEG
#: :func:`open_sky_suns`: a sky at least this bright in every channel (sRGB) where a sun
#: would stand may hide it in haze or thin cloud, and rules nothing out.
HAZE_LEVEL = 0.95
#: Camera tilts (degrees) from the fitted ground plane beyond which it is not trusted.
MAX_PLANE_TILT = 25.0

Progress = Callable[[str, float], None]


class FindSunCancelledError(RuntimeError):
    """Raised by :func:`find_sun` when its ``cancel`` callback says so."""


@dataclass(frozen=True)
class SunPrior:
    """What the photo's EXIF says about its sun.

    Attributes:
        elevation: the sun's true elevation above the horizon in degrees (GPS + time).
        azimuth: its azimuth relative to the camera in degrees when a compass heading is known
            (a full guess), else None.
        elevation_tolerance: how far (degrees) the search may leave ``elevation``.
        azimuth_weight: how much agreement a sun opposite ``azimuth`` gives up in the search
            (``weight * (1 - cos(deviation)) / 2``): the compass heading decides between suns
            the shadows fit about equally well, and loses when they clearly disagree (phone
            compasses are often tens of degrees off, and a wrong heading is not rare). Chosen
            on 48 held-out synthetic pairs with the estimated depth, the true elevation and a
            compass off by 0 / 30 / 60 / 120 degrees (median angle to the true sun; /tmp
            script, 2026-12-01): weight 0.05 18.4 / 28.8 / 43.3 / 60.4, 0.1 16.5 / 26.5 /
            41.2 / 62.2, 0.15 15.4 / 26.5 / 41.2 / 64.6, 0.25 10.7 / 25.6 / 45.1 / 75.0. 0.15
            gains where compasses usually are and gives up little to a wild one; on the pool
            sample (its compass right) the shadows no longer move the sun 61 degrees away
            (they did at 0.05, for 0.03 of agreement). No dev photo records a heading.
        description: words for the user ("elevation 38° from the photo's time and place").
        heading_words: what gave ``azimuth``, for the notes: the EXIF's "compass heading" or
            the "camera heading given" (typed by the user; a review: the notes called it the
            compass heading).
    """

    elevation: float
    azimuth: float | None = None
    elevation_tolerance: float = 2.0
    azimuth_weight: float = 0.15
    description: str = ""
    heading_words: str = "compass heading"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.elevation) and -90.0 <= self.elevation <= 90.0):
            raise ValueError(f"expected a prior elevation in [-90, 90], got {self.elevation}")
        if self.azimuth is not None and not math.isfinite(self.azimuth):
            raise ValueError(f"expected a finite prior azimuth, got {self.azimuth}")
        for name in ("elevation_tolerance", "azimuth_weight"):
            val = getattr(self, name)
            if not (math.isfinite(val) and val >= 0.0):
                raise ValueError(f"expected {name} >= 0, got {val}")


#: :func:`exif_sun_prior`: a capture time without a time zone is read at its longitude's
#: (:func:`~outcast_core.runtime.pipeline.timelapse.exif_capture_time`), and the search may
#: leave its elevation by as much as the sun moves in this many hours either way (national zones
#: and summer time are an hour or two from the longitude's; China's west three).
GUESSED_ZONE_HOURS = 1.0


def exif_sun_prior(metadata: Any, heading: float | None = None) -> SunPrior | None:
    """The sun prior of a photo's EXIF (:class:`~outcast_core.runtime.io.exif.PhotoMetadata`).

    Args:
        metadata: the photo's metadata.
        heading: a compass heading the user gave: it replaces the EXIF's (phone compasses
            are often off by tens of degrees) or stands in for a missing one.

    Returns:
        None without GPS and capture time, or when the sun was below the horizon then; else the
        true elevation, with the azimuth relative to the camera's heading when a compass heading
        is recorded or given (both in the horizon's frame: :func:`find_sun` turns them into the
        camera's).
    """
    from outcast_core.runtime.pipeline.timelapse import (
        exif_capture_time,
        relative_azimuth,
        true_sun_position,
    )

    when, guessed = exif_capture_time(metadata)
    lat, lon = getattr(metadata, "latitude", None), getattr(metadata, "longitude", None)
    if when is None or lat is None or lon is None:
        return None
    true_az, el = true_sun_position(when, lat, lon)
    if el <= 0.0:
        return None
    tolerance, zone = SunPrior.elevation_tolerance, ""
    if guessed:  # the zone of the longitude, perhaps hours from the photo's own
        spread = max(abs(true_sun_position(when + dt.timedelta(hours=h), lat, lon)[1] - el)
                     for h in (-GUESSED_ZONE_HOURS, GUESSED_ZONE_HOURS))
        tolerance += spread
        hours = when.utcoffset().total_seconds() / 3600.0  # type: ignore[union-attr]
        zone = f" (time zone UTC{hours:+g} guessed from the longitude: ±{spread:.0f}°)"
    recorded = getattr(metadata, "heading_deg", None)
    if recorded is None and heading is None:
        return SunPrior(el, elevation_tolerance=tolerance,
                        description=f"elevation {el:.0f}° from the photo's time and place{zone}")
    az = relative_azimuth(true_az, heading if heading is not None else recorded)
    words = "camera heading given" if heading is not None else "compass heading"
    return SunPrior(el, az, elevation_tolerance=tolerance,
                    description=f"azimuth {az:.0f}°, elevation {el:.0f}° from the photo's time, "
                                f"place and {'the ' if heading is not None else ''}{words}{zone}",
                    heading_words=words)


@dataclass
class AgreementMap:
    """The coarse suns' ranking score over the dome (with the default measure the agreement,
    ``1 - BER``, 0.5 = chance).

    Attributes:
        azimuths: ``(A,)`` degrees.
        elevations: ``(E,)`` degrees (camera-relative).
        scores: ``E x A`` in [0, 1]; NaN where no sun was tried.
    """

    azimuths: np.ndarray
    elevations: np.ndarray
    scores: np.ndarray

    def normalised(self) -> np.ndarray:
        """``E x A`` in [0, 1]: 0 at the dome's median agreement (or below), 1 at its best."""
        s = self.scores
        if not np.isfinite(s).any():
            return np.zeros(s.shape, np.float32)
        lo, hi = float(np.nanmedian(s)), float(np.nanmax(s))
        out = np.clip((s - lo) / max(hi - lo, 1e-6), 0.0, 1.0)
        return np.nan_to_num(out, nan=0.0).astype(np.float32)

    def at(self, azimuth: float, elevation: float) -> float:
        """:meth:`normalised` at the cell nearest to a sun (how warm the dial draws it)."""
        i = int(np.argmin(np.abs(self.elevations - elevation)))
        j = int(np.argmin(np.abs((self.azimuths - azimuth + 180.0) % 360.0 - 180.0)))
        return float(self.normalised()[i, j])

    def best(self) -> tuple[float, float]:
        """``(azimuth, elevation)`` of the warmest cell."""
        s = np.nan_to_num(self.scores, nan=-np.inf)
        i, j = np.unravel_index(int(np.argmax(s)), s.shape)
        return float(self.azimuths[j]), float(self.elevations[i])


@dataclass
class SunFit:
    """What :func:`find_sun` found.

    Attributes:
        azimuth: camera-relative azimuth of the best sun (degrees, level camera convention).
        elevation: camera-relative elevation (degrees, 0-90).
        w: camera-space unit vector toward it.
        agreement: ``1 - BER`` of its overlay against the photo's found shadows.
        shading: the correlation of its ``S`` with the photo's luminance
            (:func:`shading_agreement`).
        measure: what the search ranked suns by (:data:`MEASURES`).
        confidence: 0-1 (see the module docstring).
        found: whether the confidence reaches :data:`CONFIDENT`.
        source: ``"shadows"``, ``"shadows + EXIF elevation"``, ``"shadows + EXIF"``,
            ``"EXIF"`` (no clear shadows; the EXIF sun stands) or ``"sun in the frame"``
            (:data:`SOURCE_EXIF`, :data:`SOURCE_SUN_IN_FRAME`).
        note: one line for the user.
        unfound: why the shadows could not tell the sun (:data:`UNFOUND_REASONS`:
            ``"too-small"``, ``"no-clear-shadows"``, ``"no-fit"``, ``"open-sky"``: every sun
            they fit would stand in the photo's open sky, which shows none), or ``""`` when
            they could;
            for choosing what to tell the user without reading :attr:`note`'s words.
        map: the coarse agreement map (the dial's heat map).
        candidates: ``(azimuth, elevation, agreement)`` of the last candidates, best first
            as the search ranks them: agreement, the shading term and the EXIF prior's pull
            together, so a candidate with a little more agreement may follow one the prior
            prefers.
        true_elevation: the found sun's elevation above the ground's horizon (differs from
            ``elevation`` when the camera is pitched or rolled). With an EXIF prior the search
            may leave the prior's elevation by its ``elevation_tolerance`` (2 degrees by
            default: the EXIF clock and the refraction are not exact), so it can differ from
            ``outcast sun --json``'s ``exif_elevation`` by that much.
        pitch: camera pitch used (degrees; 0 without a prior).
        roll: camera roll used (degrees).
        pose_source: where ``pitch`` and ``roll`` came from: ``""`` (no prior: not used), the
            metadata's (e.g. ``"XMP GPano"``, see :mod:`~outcast_core.runtime.io.camera_pose`),
            ``"given"``, ``"ground plane"`` or ``"level (no ground plane)"``.
        evaluations: shadow images computed.
        compass_decided: found where a compass heading put it, among suns the shadows fit
            about alike: the map (coarser, without the prior) is cold there
            (:data:`COLD_ON_MAP`), and its warm area is what the shadows alone say.
        below_level: how far (degrees) the sun seen in the frame stands below the height of
            the picture's centre (the plane through the camera's axis and its rows, measured
            in the camera's own frame, whatever the photo's pitch), which ``elevation`` (0)
            does not show: the camera was tilted up, or the photo is cropped off-centre or on
            its side; 0 otherwise.
        seconds: wall time.
        stage_seconds: wall time per stage (``photo shadows``, ``dome``, ``ring``, ``refine``,
            ``finals``).
    """

    azimuth: float
    elevation: float
    w: np.ndarray
    agreement: float
    confidence: float
    found: bool
    source: str
    note: str
    map: AgreementMap
    candidates: list[tuple[float, float, float]] = field(default_factory=list)
    true_elevation: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    pose_source: str = ""
    shading: float = 0.0
    measure: str = MEASURE
    evaluations: int = 0
    seconds: float = 0.0
    stage_seconds: dict[str, float] = field(default_factory=dict)
    compass_decided: bool = False
    unfound: str = ""
    below_level: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        """Plain values for JSON (the map is left out)."""
        return {
            "azimuth": round(self.azimuth, 2), "elevation": round(self.elevation, 2),
            "confidence": round(self.confidence, 3), "found": self.found,
            "agreement": round(self.agreement, 4), "shading": round(self.shading, 4),
            "measure": self.measure, "source": self.source, "note": self.note,
            "true_elevation": round(self.true_elevation, 2), "pitch": round(self.pitch, 2),
            "roll": round(self.roll, 2), "pose_source": self.pose_source,
            "compass_decided": self.compass_decided, "unfound": self.unfound,
            "below_level": round(self.below_level, 2), "evaluations": self.evaluations,
            "seconds": round(self.seconds, 3), "stage_seconds": self.stage_seconds,
            "candidates": [[round(a, 2), round(e, 2), round(s, 4)] for a, e, s in self.candidates],
            "candidates_ranked_by": "agreement, shading and the EXIF prior's pull",
        }  # fmt: skip


# ---------------------------------------------------------------------------------- evidence
def agreement(predicted: np.ndarray, found: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``1 - BER`` of predicted shadow masks against the photo's shadows, over the valid pixels.

    Args:
        predicted: ``N x H x W`` (or ``H x W``) bool: the overlays' shadow masks.
        found: ``H x W``: the photo's shadows, a bool mask or the probability (0-1) that each
            pixel is shadow. A probability makes the error soft: each pixel counts on the
            shadow side with its probability and on the lit side with the rest, so the pixels
            the photo leaves in doubt weigh little on either (:func:`find_sun` ranks suns so:
            on the real dev photos the found sun came within 0.03 of the sweep's best on
            80.9 % of them, 70.2 % against the mask ``p > 0.5``; EVAL.md, 2026-12-05).
        valid: ``H x W`` bool: pixels that count (off the sky).

    Returns:
        ``(N,)`` float64 (a 0-d array for one mask); a class absent from ``found`` counts as
        fully right on that side, as
        :func:`~outcast_core.runtime.pipeline.real_eval.balanced_error_rate`.
    """
    pred = np.asarray(predicted, bool)
    found = np.asarray(found)
    valid = np.asarray(valid, bool)
    if pred.shape[-2:] != found.shape or found.shape != valid.shape:
        raise ValueError(f"expected masks of one size, got {pred.shape}, {found.shape} and "
                         f"{valid.shape}")
    shade = np.clip(np.nan_to_num(found.astype(np.float64)), 0.0, 1.0)  # (NaN: lit)
    pos = np.where(valid, shade, 0.0).ravel()  # each pixel's weight on the shadow side
    neg = np.where(valid, 1.0 - shade, 0.0).ravel()  # and on the lit side
    p, n = float(pos.sum()), float(neg.sum())
    flat = pred.reshape(-1, pos.size).astype(np.float64)
    tp = flat @ pos
    tn = n - flat @ neg
    tpr = tp / p if p > 0 else np.ones(tp.shape)
    tnr = tn / n if n > 0 else np.ones(tn.shape)
    return (0.5 * (tpr + tnr)).reshape(pred.shape[:-2])


def shading_agreement(shadows: np.ndarray, luminance_: np.ndarray, valid: np.ndarray
                       ) -> np.ndarray:
    """Pearson correlation of each predicted shadow image ``S`` with the photo's linear
    luminance over the valid pixels (``(N,)`` in [-1, 1]).

    A sunlit surface's radiance is its albedo times ``E_sun * S + E_sky``, so under the right
    sun the photo's luminance rises with ``S``: through the cast shadows *and* the attached
    shading (the cosine term), without the photo's shadows having to be found first.
    """
    s = np.asarray(shadows, np.float32)
    if s.ndim == 2:
        s = s[None]
    valid = np.asarray(valid, bool)
    x = s[:, valid]  # N x P
    y = np.asarray(luminance_, np.float32)[valid].astype(np.float64)
    if x.shape[1] < 2:
        return np.zeros(len(s))
    x = x - x.mean(axis=1, keepdims=True)
    y = y - y.mean()
    den = np.linalg.norm(x, axis=1) * float(np.linalg.norm(y))
    return np.where(den > 1e-9, (x @ y) / np.maximum(den, 1e-9), 0.0)


def measures(shadows: np.ndarray, found: np.ndarray, valid: np.ndarray, luminance_: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(agreement, shading)`` of ``N x H x W`` predicted shadow images: the overlay mask's
    ``1 - BER`` against the photo's found shadows (:func:`agreement`) and the shading
    correlation (:func:`shading_agreement`)."""
    pred = (shadows < SHADOW_THRESHOLD) & valid[None]
    return agreement(pred, found, valid), shading_agreement(shadows, luminance_, valid)


def ranking(agree: np.ndarray, shading: np.ndarray, measure: str) -> np.ndarray:
    """The score :func:`find_sun` ranks suns by (higher is better), by :data:`MEASURES` name."""
    if measure == "mask":
        return np.asarray(agree, np.float64)
    if measure == "shading":
        return np.asarray(shading, np.float64)
    if measure == "mask+shading":
        return np.asarray(agree, np.float64) + SHADING_WEIGHT * np.asarray(shading, np.float64)
    raise ValueError(f"expected a measure in {MEASURES}, got {measure!r}")


def shade_clarity(image_srgb: np.ndarray, sky: np.ndarray, found: np.ndarray) -> float:
    """How clearly the photo splits into sun and shade (0-1).

    The gap between the mean log luminance of the lit surface and of the found shade, mapped
    from :data:`SEPARATION_LOW` (0) to
    :data:`SEPARATION_HIGH` (1); 0 when the shade covers under :data:`MIN_SHADE` or over
    :data:`MAX_SHADE` of the surface.
    """
    surface = ~np.asarray(sky, bool)
    if surface.sum() < 16:
        return 0.0
    shade = np.asarray(found, bool) & surface
    lit = ~shade & surface
    frac = shade.sum() / surface.sum()
    if not MIN_SHADE <= frac <= MAX_SHADE or lit.sum() < 8 or shade.sum() < 8:
        return 0.0
    log_y = np.log(luminance(srgb_to_linear(np.clip(image_srgb, 0.0, 1.0))) + 1e-3)
    a, b = log_y[shade], log_y[lit]
    sep = float(b.mean() - a.mean())
    return float(np.clip((sep - SEPARATION_LOW) / (SEPARATION_HIGH - SEPARATION_LOW), 0.0, 1.0))


def legibility(shape: tuple[int, int]) -> float:
    """How well shadows can be read at a working image of ``shape`` (0-1): its shorter side
    mapped from :data:`LEGIBLE_LOW` (0) to :data:`LEGIBLE_HIGH` (1), times its elongation
    mapped from the session's ``MAX_ASPECT`` (1, where the app starts to warn) to twice that
    (0: the depth network then sees a strip a handful of pixels across).

    Example:
        >>> legibility((192, 256)), legibility((16, 16)), legibility((44, 60))
        (1.0, 0.0, 0.5)
        >>> round(legibility((600, 4000)), 2)  # 6.7:1
        0.33
    """
    from outcast_core.runtime.pipeline.session import MAX_ASPECT

    short, long = sorted(shape[:2])
    size = np.clip((short - LEGIBLE_LOW) / (LEGIBLE_HIGH - LEGIBLE_LOW), 0.0, 1.0)
    shape_ok = np.clip((2.0 * MAX_ASPECT - long / max(short, 1)) / MAX_ASPECT, 0.0, 1.0)
    return float(size * shape_ok)


# ---------------------------------------------------------------------------------- levels
def _resize(image: np.ndarray, shape: tuple[int, int], *, nearest: bool = False) -> np.ndarray:
    from outcast_core.runtime.pipeline.session import resize

    return resize(image, shape, nearest=nearest)


class _Level:
    """The session's light-independent buffers at one small size, and shadows for many suns."""

    def __init__(self, session: Any, longer_side: int, prob: np.ndarray) -> None:
        from outcast_core.runtime.pipeline.session import working_shape

        cam: Camera = session.camera
        h, w = working_shape(cam.height, cam.width, longer_side)
        self.shape = (h, w)
        self.camera = cam.resized(h, w)
        depth_sky = np.where(session.sky, np.inf, session.depth).astype(np.float32)
        self.depth = _resize(depth_sky, (h, w), nearest=True)  # H x W
        self.sky = _resize(session.sky.astype(np.uint8), (h, w), nearest=True) > 0
        self.image = _resize(session.image_srgb, (h, w))  # H x W x 3
        self.normals = normals_from_depth(self.depth, self.camera)  # H x W x 3
        self.found = np.clip(_resize(prob, (h, w)), 0.0, 1.0)  # soft (:func:`agreement`)
        self.valid = ~self.sky
        self.luminance = luminance(srgb_to_linear(np.clip(self.image, 0.0, 1.0)))
        self.session = session
        self._sampler: Any = None

    def shadows(self, suns: np.ndarray) -> np.ndarray:
        """``N x H x W`` shadow images for ``N x 3`` sun vectors."""
        s = self.session
        if s.shadow_mode == "learned":
            model = s.registry.load("shadow")
            out = []
            for i in range(0, len(suns), BATCH):
                chunk = suns[i:i + BATCH].astype(np.float32)  # B x 3
                b = len(chunk)
                res = model.run({
                    "image": np.repeat(self.image.transpose(2, 0, 1)[None], b, 0),  # B x 3 x H x W
                    "depth": np.repeat(network_depth(self.depth)[None, None], b, 0),
                    "normals": np.repeat(self.normals.transpose(2, 0, 1)[None], b, 0),
                    "sun": chunk,
                    "focal": np.full((b, 1), self.camera.focal, np.float32),
                })
                out.append(np.clip(next(iter(res.values()))[:, 0], 0.0, 1.0))  # B x H x W
            return np.concatenate(out, axis=0)
        from outcast_core.runtime.geometry.raymarch import RaySampler
        from outcast_core.runtime.geometry.shadows import direct_shadow

        if self._sampler is None:
            self._sampler = RaySampler(self.depth, self.camera)
        step = max(float(s.preset.direct_step), 1.0 / max(self.shape))
        return np.stack([
            direct_shadow(self.depth, self.camera, w, normals=self.normals, sky=self.sky,
                          steps=int(math.ceil(1.0 / step)), step=step, thickness=s.thickness,
                          sampler=self._sampler)
            for w in suns
        ])  # fmt: skip

    def score(self, suns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(agreement, shading)`` of each sun (``(N,)`` each): see :func:`measures`."""
        if len(suns) == 0:
            return np.zeros(0), np.zeros(0)
        return measures(self.shadows(suns), self.found, self.valid, self.luminance)


# ---------------------------------------------------------------------------------- search
@dataclass
class _Frame:
    """Search coordinates: azimuth/elevation in a (possibly tilted) frame, to camera vectors."""

    pitch: float = 0.0
    roll: float = 0.0

    def vector(self, az: float, el: float) -> np.ndarray:
        return sun_vector(az, el, self.pitch, self.roll)

    def vectors(self, points: Sequence[tuple[float, float]]) -> np.ndarray:
        return np.stack([self.vector(a, e) for a, e in points]) if points else np.zeros((0, 3))


def open_sky_suns(session: Any, vectors: np.ndarray) -> np.ndarray:
    """Which camera-space suns (``N x 3``) would stand in the photo's open sky, their disc of
    :data:`HIDDEN_SUN_DEG` inside the frame and on the sky mask all round, where a photo
    that shows no sun (``session.sun_seen`` None) says the sun is not (bool, ``N``; all False
    when the photo shows one, or has no sky). Not where the sky at the disc's centre is near
    white (:data:`HAZE_LEVEL`): a sun in haze or thin cloud may go unseen there.

    Example:
        >>> from types import SimpleNamespace
        >>> from outcast_core.runtime.geometry.camera import Camera
        >>> sky = np.zeros((48, 64), bool); sky[:20] = True
        >>> img = np.full((48, 64, 3), 0.5, np.float32)
        >>> s = SimpleNamespace(sky=sky, camera=Camera.from_fov(48, 64, 60.0), sun_seen=None,
        ...                     image_srgb=img)
        >>> open_sky_suns(s, np.array([[0.0, -0.3, 1.0], [0.0, 0.2, 1.0], [0.0, -0.3, -1.0]]))
        array([ True, False, False])
    """
    v = np.asarray(vectors, np.float64).reshape(-1, 3)
    out = np.zeros(len(v), bool)
    sky = getattr(session, "sky", None)
    if getattr(session, "sun_seen", None) is not None or sky is None or not np.any(sky):
        return out
    cam = session.camera
    r = max(1, round(sun_core_px(cam.focal, HIDDEN_SUN_DEG)))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)
    # Wholly sky: the mask eroded by the disc, the frame's edge counting as not sky.
    open_sky = cv2.erode(np.asarray(sky, np.uint8), disc, borderType=cv2.BORDER_CONSTANT,
                         borderValue=0) > 0
    u, w = project(v, cam)  # NaN behind the camera
    ok = np.isfinite(u) & np.isfinite(w)
    u, w = np.where(ok, np.floor(u), -1.0), np.where(ok, np.floor(w), -1.0)
    inside = ok & (u >= 0) & (u < open_sky.shape[1]) & (w >= 0) & (w < open_sky.shape[0])
    idx = np.flatnonzero(inside)
    rows, cols = w[idx].astype(int), u[idx].astype(int)
    hazy = np.asarray(session.image_srgb)[rows, cols].min(axis=-1) >= HAZE_LEVEL
    out[idx] = open_sky[rows, cols] & ~hazy
    return out


def ground_plane_tilt(session: Any) -> tuple[float, float, str]:
    """Camera ``(pitch, roll, source)`` in degrees from the fitted ground plane; level without
    one (or with one tilted more than :data:`MAX_PLANE_TILT`), or when the working image's
    shorter side is under :data:`PLANE_MIN_SIDE` pixels."""
    from outcast_core.runtime.pipeline.depth_post import fit_ground_plane

    level = (0.0, 0.0, "level (no ground plane)")
    image = getattr(session, "image_srgb", None)
    if image is not None and min(np.shape(image)[:2]) < PLANE_MIN_SIDE:
        return level
    try:
        plane = fit_ground_plane(session.depth, session.sky, session.camera)
    except ValueError:
        return level
    if plane is None:
        return level
    n = plane.normal  # the ground's up in camera space: R @ (0, -1, 0)
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, float(n[2])))))
    roll = math.degrees(math.atan2(-float(n[0]), -float(n[1])))
    if math.hypot(pitch, roll) > MAX_PLANE_TILT:
        return level
    return pitch, roll, "ground plane"


def camera_tilt(session: Any, pose: Any = None) -> tuple[float, float, str]:
    """The camera's ``(pitch, roll, source)`` in degrees: the level frame in which EXIF suns
    (true elevation above the horizon) are given, as the camera saw it.

    Args:
        session: a session after ``set_image`` (its depth gives the ground plane).
        pose: a ``(pitch, roll)`` pair (or ``(pitch, roll, source)``: this function's own
            result), or a :class:`~outcast_core.runtime.io.camera_pose.CameraPose` from the
            photo's metadata;
            None, or a pose without a pitch: the fitted ground plane's (level without one).
            On held-out synthetic views whose plane is found (22 of 40), the plane's tilt puts
            a true sun a median 2.2° from where the camera saw it; taking the camera as level,
            4.7°.
    """
    if pose is not None and hasattr(pose, "pitch_roll"):
        pair = pose.pitch_roll()
        if pair is not None:
            return float(pair[0]), float(pair[1]), str(pose.source)
        return ground_plane_tilt(session)
    if pose is not None:
        vals = tuple(pose)
        if len(vals) not in (2, 3):
            raise ValueError(f"expected a camera (pitch, roll) or (pitch, roll, source), "
                             f"got {pose}")
        pitch, roll = float(vals[0]), float(vals[1])
        if not (math.isfinite(pitch) and math.isfinite(roll)):
            raise ValueError(f"expected a finite camera pitch and roll, got {pose}")
        return pitch, roll, str(vals[2]) if len(vals) == 3 else "given"
    return ground_plane_tilt(session)


def photo_camera_tilt(session: Any, path: str | os.PathLike[str] | None
                      ) -> tuple[float, float, str]:
    """:func:`camera_tilt` of a photo file: its metadata's pose (``None``: no file), else the
    pitch that puts the sun seen in the frame at the EXIF's true elevation
    (:func:`sun_frame_pitch`), else the session's ground plane."""
    from outcast_core.runtime.io.camera_pose import read_camera_pose

    pose = read_camera_pose(path) if path else None
    if (pose is None or pose.pitch_roll() is None) and path:
        pitch = sun_frame_pitch(session, path)
        if pitch is not None:
            return pitch, 0.0, "sun in the frame"
    return camera_tilt(session, pose)


def sun_frame_pitch(session: Any, path: str | os.PathLike[str]) -> float | None:
    """The camera's pitch (degrees, up positive; roll taken as 0) at which the sun seen in the
    frame (:func:`sun_in_photo`) stands at its true elevation from the photo's EXIF GPS and
    time; None without either, or with a time without a zone (its elevation is a guess:
    :func:`exif_sun_prior`). Depth cannot tell a slope from level ground, the sun can: on the
    ski-slope sample the ground plane (the slope) says 6.7° down, the sun about 10° up."""
    from outcast_core.runtime.io.imageio import read_metadata
    from outcast_core.runtime.pipeline.timelapse import true_sun_position

    seen = getattr(session, "sun_seen", None)  # found once, by set_image
    if seen is None:
        return None
    try:
        meta = read_metadata(path)  # (Pillow's own reader decodes a whole PNG for its EXIF)
    except (OSError, ValueError):
        return None
    when, lat, lon = meta.capture_time, meta.latitude, meta.longitude
    if when is None or when.tzinfo is None or lat is None or lon is None:
        return None  # (a zone-less time: the elevation too uncertain to set the pitch by)
    _, true_el = true_sun_position(when, lat, lon)
    if true_el <= 0.0:
        return None
    # Above the horizon the sun stands higher the further the camera looks up: bisect.
    lo, hi = -80.0, 80.0
    if not sun_angles(seen.w, lo, 0.0)[1] <= true_el <= sun_angles(seen.w, hi, 0.0)[1]:
        return None
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if sun_angles(seen.w, mid, 0.0)[1] < true_el:
            lo = mid
        else:
            hi = mid
    return round(0.5 * (lo + hi), 2)


#: A found sun whose cell of the agreement map is below this (0: the dome's median, 1: its best)
#: is said to be the compass heading's choice, with the map's own best (see :func:`find_sun`).
COLD_ON_MAP = 0.5

#: Below this (degrees of pitch and of roll) a camera counts as level wherever a tilt is shown
#: or drawn (the dial's horizon, the app's and the CLI's words).
LEVEL_TOLERANCE = 0.5


def is_tilted(pitch: float, roll: float) -> bool:
    """Whether a camera's tilt is worth showing (:data:`LEVEL_TOLERANCE`)."""
    return abs(pitch) >= LEVEL_TOLERANCE or abs(roll) >= LEVEL_TOLERANCE


def describe_tilt(pitch: float, roll: float, source: str) -> str:
    """The tilt in words ("camera pitched 6.7° down and rolled 7.8° clockwise (ground
    plane)"), or "" for a level camera."""
    if not is_tilted(pitch, roll):
        return ""
    words = []
    if abs(pitch) >= LEVEL_TOLERANCE:
        words.append(f"pitched {abs(pitch):.1f}° {'up' if pitch > 0 else 'down'}")
    if abs(roll) >= LEVEL_TOLERANCE:
        words.append(f"rolled {abs(roll):.1f}° {'clockwise' if roll > 0 else 'anticlockwise'}")
    return f"camera {' and '.join(words)} ({source})"


def at_true_elevation(azimuth: float, elevation: float, true_elevation: float,
                      tilt: tuple[float, float] = (0.0, 0.0)) -> tuple[float, float]:
    """A camera-frame sun moved onto the sun's true elevation (GPS and time), keeping its
    azimuth about the true horizon: where the app puts the sun when its photo's shadows do not
    tell it but its EXIF gives the elevation. ``tilt`` is the camera's ``(pitch, roll)``.

    Example:
        >>> at_true_elevation(120.0, 30.0, 52.0)
        (120.0, 52.0)
    """
    pitch, roll = tilt
    if not pitch and not roll:
        return azimuth % 360.0, float(true_elevation)
    horizon_az, _ = sun_angles(sun_vector(azimuth, elevation), pitch, roll)
    return sun_angles(sun_vector(horizon_az, true_elevation, pitch, roll))


def _angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(a, b))))))


def _peaks(points: list[tuple[float, float]], scores: np.ndarray, frame: _Frame, k: int,
           separation: float) -> list[int]:
    """Indices of the ``k`` best points at least ``separation`` degrees apart."""
    order = np.argsort(-scores, kind="stable")
    chosen: list[int] = []
    vecs = frame.vectors(points)
    for i in order:
        if all(_angle_between(vecs[i], vecs[j]) >= separation for j in chosen):
            chosen.append(int(i))
        if len(chosen) == k:
            break
    return chosen


def _pattern(centre: tuple[float, float], d_az: float, d_el: float, el_range: tuple[float, float],
             ) -> list[tuple[float, float]]:
    az0, el0 = centre
    out = []
    for de in ((-d_el, 0.0, d_el) if d_el > 0 else (0.0,)):
        for da in (-d_az, 0.0, d_az):
            el = min(el_range[1], max(el_range[0], el0 + de))
            out.append(((az0 + da) % 360.0, el))
    return out


def _dedupe(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    seen: set[tuple[float, float]] = set()
    out = []
    for a, e in points:
        key = (round(a % 360.0, 3), round(e, 3))
        if key not in seen:
            seen.add(key)
            out.append((a % 360.0, e))
    return out


#: :func:`sun_in_photo`: a sun in the frame is a white, clipped spot (every channel at least
#: ``SUN_SATURATED``) on or within ``SUN_SKY_REACH`` of the longer side of the sky, where the
#: sky is at least ``SUN_MIN_SKY`` of the frame and at least ``SUN_RING_SKY`` of a ring round
#: the spot; at least ``SUN_MIN_AREA`` and at most ``SUN_MAX_AREA`` of the frame, round
#: (circularity at least ``SUN_MIN_ROUND``), inside colourless glare (the ring's mean saturation
#: at most ``SUN_RING_SATURATION``: round a white cloud the sky is blue) that falls off outward
#: (the inner ring's linear brightness at least ``SUN_FALLOFF`` times the outer ring's: a white
#: wall is flat). Chosen on the samples and the 47 dev photos (/tmp scripts; nothing fitted):
#: the ski slope's sun is found, no other photo gives one (without the last three tests a white
#: cloud on the pool and field-path samples, a pipe's white label and a garage door did).
#: ``SUN_MAX_AREA`` was 0.06 until a user trial cropped the ski slope tight round its sun
#: (the spot 0.062-0.092 of the frame: missed, and the shadows put the sun behind the camera);
#: no dev photo or sample gives a sun at any limit up to 0.4 (2026-12-05, /tmp script).
SUN_SATURATED = 0.97
SUN_SKY_REACH = 0.03
SUN_MIN_SKY = 0.05
SUN_RING_SKY = 0.4
SUN_MIN_AREA = 2e-4
SUN_MAX_AREA = 0.15
SUN_MIN_ROUND = 0.4
SUN_RING_SATURATION = 0.15
SUN_FALLOFF = 1.2


@dataclass(frozen=True)
class SunInPhoto:
    """The sun seen in the photo (:func:`sun_in_photo`).

    Attributes:
        w: camera-space unit vector toward it.
        u: its column at the image's size (pixels, centre of the glare's brightest part).
        v: its row.
        area: the saturated spot's share of the frame.
    """

    w: np.ndarray
    u: float
    v: float
    area: float

    def core_radius(self, shape: tuple[int, ...]) -> float:
        """The clipped core's radius in pixels of an image of ``shape`` (``H x W``...)."""
        return math.sqrt(self.area * shape[0] * shape[1] / math.pi)


def sun_in_photo(image_srgb: np.ndarray, sky: np.ndarray, camera: Any) -> SunInPhoto | None:
    """The sun, when the photo shows it: then its direction is known exactly, whatever the
    shadows and the compass say (see the ``SUN_*`` constants for the tests).

    Args:
        image_srgb: ``H x W x 3`` sRGB in [0, 1] (the session's working image).
        sky: ``H x W`` bool sky mask.
        camera: the :class:`~outcast_core.runtime.geometry.camera.Camera` of that size.

    Returns:
        A :class:`SunInPhoto`, or None.
    """
    img = np.asarray(image_srgb, np.float32)
    sky = np.asarray(sky, bool)
    if img.ndim != 3 or img.shape[2] != 3 or sky.shape != img.shape[:2]:
        raise ValueError(f"expected an H x W x 3 image and an H x W sky, got {img.shape} and "
                         f"{sky.shape}")
    h, w = sky.shape
    if sky.mean() < SUN_MIN_SKY:
        return None
    side = max(h, w)
    lum = img.max(axis=2)
    low = img.min(axis=2)
    r = max(2, round(SUN_SKY_REACH * side))
    near_sky = cv2.dilate(sky.astype(np.uint8),
                          cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)) > 0
    # White, every channel clipped (a bright blue sky clips its blue channel alone).
    spots = ((low >= SUN_SATURATED) & near_sky).astype(np.uint8)
    if spots.sum() < max(3.0, SUN_MIN_AREA * h * w):
        return None
    # The brightest place of the sky at a wide scale: the sun's glare, not a bright cloud edge.
    glare = cv2.GaussianBlur(np.where(near_sky, lum, 0.0).astype(np.float32), (0, 0),
                             0.04 * side)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(spots, connectivity=8)
    y0, x0 = np.unravel_index(int(np.argmax(np.where(spots > 0, glare, -1.0))), glare.shape)
    k = int(labels[y0, x0])
    area = float(stats[k, cv2.CC_STAT_AREA])
    if k == 0 or not SUN_MIN_AREA * h * w <= area <= SUN_MAX_AREA * h * w:
        return None
    spot = labels == k
    contours, _ = cv2.findContours(spot.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    roundness = 4.0 * math.pi * area / max(cv2.arcLength(contours[0], True), 1.0) ** 2
    if roundness < SUN_MIN_ROUND:
        return None
    rad = math.sqrt(area / math.pi)
    yc = stats[k, cv2.CC_STAT_TOP] + stats[k, cv2.CC_STAT_HEIGHT] / 2.0
    xc = stats[k, cv2.CC_STAT_LEFT] + stats[k, cv2.CC_STAT_WIDTH] / 2.0
    yy, xx = np.mgrid[0:h, 0:w]
    dist = np.hypot(yy + 0.5 - yc, xx + 0.5 - xc)  # H x W
    ring = (dist > 1.5 * rad + 1.0) & (dist < 3.0 * rad + 3.0)
    outer = (dist > 3.0 * rad + 3.0) & (dist < 6.0 * rad + 6.0) & near_sky
    if (ring & sky).sum() < SUN_RING_SKY * ring.sum():
        return None
    ring &= near_sky
    if ring.sum() < 5 or not outer.any():
        return None
    saturation = float(np.mean((lum[ring] - low[ring]) / np.maximum(lum[ring], 1e-3)))
    linear = luminance(srgb_to_linear(img))  # H x W
    if saturation > SUN_RING_SATURATION or linear[ring].mean() < SUN_FALLOFF * linear[outer].mean():
        return None
    weights = glare[spot]
    ys, xs = np.nonzero(spot)
    u = float((xs + 0.5) @ weights / weights.sum())
    v = float((ys + 0.5) @ weights / weights.sum())
    ray = np.array([(u - camera.cx) / camera.focal, (v - camera.cy) / camera.focal, 1.0])
    return SunInPhoto(w=ray / np.linalg.norm(ray), u=u, v=v, area=area / (h * w))


def below_level_words(degrees: float) -> str:
    """What :attr:`SunFit.below_level` means, for a note (the command line's and the app's).

    Example:
        >>> below_level_words(7.3).startswith("it stands 7° below the height of the picture")
        True
    """
    return (f"it stands {degrees:.0f}° below the height of the picture's centre, so the camera "
            "was tilted up, or the photo is cropped off-centre or on its side (its elevation "
            "is taken as 0 in the camera's frame)")


def find_sun(
    session: Any,
    *,
    prior: SunPrior | None = None,
    pitch_roll: Any = None,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | None = None,
    measure: str = MEASURE,
) -> SunFit:
    """Find the sun whose predicted shadows best agree with the photo's own shadows.

    Args:
        session: a :class:`~outcast_core.runtime.pipeline.session.RelightSession` after
        ``set_image``.
        prior: the EXIF prior (:func:`exif_sun_prior`); None searches the whole dome.
        pitch_roll: the camera's ``(pitch, roll)`` in degrees for the prior's frame (or
            :func:`camera_tilt`'s ``(pitch, roll, source)``), or a
            :class:`~outcast_core.runtime.io.camera_pose.CameraPose` from the photo's metadata
            (:func:`~outcast_core.runtime.io.camera_pose.read_camera_pose`); None, or a pose
            without a pitch: from the fitted ground plane (level when there is none). Unused
            without a prior.
        progress: called with ``(stage, fraction)`` (the app's may raise to cancel).
        cancel: polled between stages; True raises :class:`FindSunCancelledError`.
        measure: what the search ranks suns by (:data:`MEASURES`, :func:`ranking`).

    Returns:
        A :class:`SunFit`.

    Raises:
        RuntimeError: before ``set_image``.

    Example:
        >>> fit = find_sun(session)  # doctest: +SKIP
        >>> fit.azimuth, fit.elevation, fit.confidence  # doctest: +SKIP
    """
    if getattr(session, "image_srgb", None) is None or getattr(session, "depth", None) is None:
        raise RuntimeError("set_image() must be called before find_sun()")
    if prior is not None and not isinstance(prior, SunPrior):
        raise ValueError(f"expected a SunPrior or None, got {type(prior).__name__}")
    if measure not in MEASURES:
        raise ValueError(f"expected a measure in {MEASURES}, got {measure!r}")
    t0 = time.perf_counter()
    report = progress or (lambda stage, frac: None)

    stages: dict[str, float] = {}
    lap = [t0]

    def check(stage: str, frac: float, done: str = "") -> None:
        if done:  # the stage that has just ended, timed
            now = time.perf_counter()
            stages[done] = stages.get(done, 0.0) + now - lap[0]
            lap[0] = now
        if cancel is not None and cancel():
            raise FindSunCancelledError("finding the sun was cancelled")
        report(stage, frac)

    check("finding the photo's shadows", 0.02)
    # Without the surface's fine dark texture (gravel gaps, furrows, grass), which no sun's
    # predicted shadows explain: the found shadows the de-shadow lifts. Suns are ranked against
    # the probability itself (a soft error, :func:`agreement`), not against ``prob > 0.5``.
    prob = without_texture(photo_shadow_probability(session.image_srgb, session.sky))
    clarity = shade_clarity(session.image_srgb, session.sky, prob > 0.5)
    coarse = _Level(session, COARSE_SIZE, prob)
    levels = {COARSE_SIZE: coarse}

    def level_of(size: int) -> _Level:
        if size not in levels:
            levels[size] = _Level(session, size, prob)
        return levels[size]

    frame, pose_source = _Frame(), ""
    if prior is not None:
        pitch, roll, pose_source = camera_tilt(session, pitch_roll)
        frame = _Frame(pitch, roll)
    sun_look = getattr(session, "sun_look", None)
    look = sun_look() if callable(sun_look) and LOOK_WEIGHT > 0 else None

    def look_term(vectors: np.ndarray) -> np.ndarray:
        """The photo's look's pull (:data:`LOOK_WEIGHT`) on camera-space suns."""
        if look is None or len(vectors) == 0:
            return np.zeros(len(vectors))
        return LOOK_WEIGHT * np.log(np.maximum(look.likelihood(vectors), LOOK_FLOOR))

    def hidden(vectors: np.ndarray) -> np.ndarray:
        """:data:`HIDDEN_SUN_PENALTY` for suns the photo's open sky would show
        (:func:`open_sky_suns`)."""
        return HIDDEN_SUN_PENALTY * open_sky_suns(session, vectors)

    def bias(pts: Sequence[tuple[float, float]]) -> np.ndarray:
        """The compass heading's soft pull (:attr:`SunPrior.azimuth_weight`), less the photo's
        look's (:func:`look_term`)."""
        # (no vectors made for a look that is off: the default)
        out = -look_term(frame.vectors(pts)) if look is not None else np.zeros(len(pts))
        if prior is None or prior.azimuth is None or not pts:
            return out
        dev = np.radians(np.array([a for a, _ in pts]) - prior.azimuth)
        return out + prior.azimuth_weight * (1.0 - np.cos(dev)) / 2.0

    # -- the coarse dome (the heat map), camera-relative
    check("trying suns over the dome", 0.08, "photo shadows")
    grid = [(a, e) for e in COARSE_ELEVATIONS for a in COARSE_AZIMUTHS]
    grid_w = _Frame().vectors(grid)
    dome_agree, dome_shading = coarse.score(grid_w)
    dome = ranking(dome_agree, dome_shading, measure)
    evaluations = len(grid)
    # The map is what the shadows say (the heat map the dial shows, and the compass's note);
    # the search ranks with the photo's look as well.
    amap = AgreementMap(np.array(COARSE_AZIMUTHS), np.array(COARSE_ELEVATIONS),
                        dome.reshape(len(COARSE_ELEVATIONS), len(COARSE_AZIMUTHS)))
    dome = dome + look_term(grid_w)
    d_az = COARSE_AZIMUTHS[1] - COARSE_AZIMUTHS[0]
    d_el = COARSE_ELEVATIONS[1] - COARSE_ELEVATIONS[0]
    el_range = (MIN_ELEVATION, 90.0)

    # -- the search space: the dome, or the prior's ring (and azimuth window)
    if prior is None:
        points, scores = grid, dome
    else:
        el_range = (prior.elevation - prior.elevation_tolerance,
                    prior.elevation + prior.elevation_tolerance)
        d_az, d_el = RING_AZIMUTH_STEP, prior.elevation_tolerance
        azs = np.arange(0.0, 360.0, RING_AZIMUTH_STEP)
        if prior.azimuth is not None:
            azs = np.unique(np.append(azs, prior.azimuth % 360.0))
        points = [(float(a), prior.elevation) for a in azs]
        check("trying suns on the EXIF elevation", 0.3, "dome")
        scores = ranking(*coarse.score(frame.vectors(points)), measure) - bias(points)
        evaluations += len(points)

    # -- fine patterns around the best separated peaks
    n_seeds = max([SEEDS, *(int(p[0]) for p in FINE_PATTERNS[:1])])
    seeds = [points[i] for i in _peaks(points, scores, frame, n_seeds, PEAK_SEPARATION)]
    cand: dict[tuple[float, float], float] = {}
    if not FINE_PATTERNS:
        cand.update(zip(points, scores.tolist(), strict=True))  # scores with the pull
    last_level: _Level | None = None
    for level, pattern in enumerate(FINE_PATTERNS):
        k, scale = int(pattern[0]), float(pattern[1])
        fine = level_of(int(pattern[2]) if len(pattern) > 2 else FINE_SIZE)  # type: ignore[misc]
        check("refining", 0.4 + 0.4 * level / len(FINE_PATTERNS),
              "dome" if level == 0 and prior is None else "ring" if level == 0 else "refine")
        pts = _dedupe([p for c in seeds[:k] for p in _pattern(c, d_az * scale, d_el * scale,
                                                               el_range)])
        sc = ranking(*fine.score(frame.vectors(pts)), measure) - bias(pts)
        evaluations += len(pts)
        if fine is not last_level:  # scores at another size do not compare: this level's only
            cand = {}
            last_level = fine
        cand.update(zip(pts, sc.tolist(), strict=True))
        ranked = sorted(cand, key=lambda p: -cand[p])
        seeds = ranked

    # -- the last candidates at the session's working size, as the overlay is drawn and scored
    #    (the shadow network's result depends on the size; cached there for the overlay)
    check("checking the best suns", 0.85, "refine" if FINE_PATTERNS else "dome")
    # The sky's veto (:func:`hidden`) on the last candidates only: in every stage it moved the
    # search's seeds on two dev photos, one of them out of the sweep's 0.03 (EVAL.md,
    # fifteenth session).
    points_left = list(cand)
    vetoed = dict(zip(points_left, hidden(frame.vectors(points_left)).tolist(), strict=True))
    cand = {p: c - vetoed[p] for p, c in cand.items()}
    ranked = sorted(cand, key=lambda p: -cand[p])
    finalists = [ranked[i] for i in _peaks(ranked, np.array([cand[p] for p in ranked]), frame,
                                           FINAL_CANDIDATES, 2.0)]
    # Early rejection: a candidate far behind the best at the small sizes is not checked.
    finalists = [p for p in finalists if cand[p] >= cand[finalists[0]] - FINAL_MARGIN]
    finals: list[tuple[float, float, float, float]] = []  # az, el, agreement, shading
    y_full = luminance(srgb_to_linear(np.clip(session.image_srgb, 0.0, 1.0)))
    for a, e in finalists:
        ag, sh = measures(session.shadow(frame.vector(a, e))[None], prob, ~session.sky,
                          y_full)
        finals.append((a, e, float(ag[0]), float(sh[0])))
        evaluations += 1
    pull = {p: b + vetoed[p] for p, b in zip(finalists, bias(finalists).tolist(), strict=True)}
    finals.sort(key=lambda t: -(float(ranking(np.array([t[2]]), np.array([t[3]]), measure)[0])
                                - pull[(t[0], t[1])]))
    best_a, best_e, best_score, best_shading = finals[0]
    w_best = frame.vector(best_a, best_e)

    # -- confidence (from the overlay's agreement, whatever the search ranked by)
    contrast = best_score - float(np.nanmedian(dome_agree))
    peak = float(np.clip(contrast / PEAK_CONTRAST, 0.0, 1.0))
    strength = float(np.clip((best_score - WEAK_AGREEMENT)
                             / (STRONG_AGREEMENT - WEAK_AGREEMENT), 0.0, 1.0))
    legible = legibility(session.image_srgb.shape[:2])
    # Every sun the shadows fit is one the photo's open sky would show: none is the sun.
    in_open_sky = vetoed[(best_a, best_e)] > 0
    confidence = 0.0 if in_open_sky else float(clarity * peak * strength * legible)
    found = confidence >= CONFIDENT
    source = SOURCE_SHADOWS
    if prior is not None:
        source = (SOURCE_SHADOWS_EXIF_ELEVATION if prior.azimuth is None
                  else SOURCE_SHADOWS_EXIF)
    if prior is not None and prior.azimuth is not None and not found:
        w_best = frame.vector(prior.azimuth, prior.elevation)
        best_a, best_e = prior.azimuth % 360.0, prior.elevation
        source = SOURCE_EXIF
    cam_az, cam_el = sun_angles(w_best)
    cam_el = min(90.0, max(0.0, cam_el))
    compass_decided = False
    unfound = ""
    below_level = 0.0
    if found:
        note = f"sun found from the photo's shadows (confidence {confidence:.2f})"
        if look is not None and amap.at(cam_az, cam_el) < COLD_ON_MAP and (
                prior is None or prior.azimuth is None):
            # The map is the shadows' alone: say what moved the sun off its warm area.
            note += ("; its shadows fit many suns almost as well and the photo's look chose "
                     "this one (the map shows the shadows' agreement alone)")
        if prior is not None:
            note += "; " + (prior.description or f"elevation {prior.elevation:.0f}° from EXIF")
        if prior is not None and prior.azimuth is not None:
            off = abs((best_a - prior.azimuth + 180.0) % 360.0 - 180.0)
            if off > 45.0:
                note += (f"; the shadows put the sun {off:.0f}° away from where the "
                         f"{prior.heading_words} puts it")
            elif amap.at(cam_az, cam_el) < COLD_ON_MAP:
                compass_decided = True
                # The compass chose it among suns its shadows fit; the map, at a coarser size
                # and without the prior, is cold there (the pool sample: found 1 deg from its
                # listed sun, in the map's coldest cell).
                map_az, map_el = amap.best()
                # Said first: "found from the photo's shadows" then "the compass chose it"
                # read as a contradiction (a user trial typed a wrong heading). The prior's
                # words come last: their own bracket (a guessed time zone) ends the note.
                # How far from the EXIF sun, in degrees of arc: a high sun's azimuth moves
                # fast (a user trial read 295° against the EXIF's 274° at 67° up, 8° of arc,
                # as a contradiction).
                arc = _angle_between(w_best, frame.vector(prior.azimuth, prior.elevation))
                note = (f"sun placed by the {prior.heading_words} among suns the photo's "
                        f"shadows fit about as well, {arc:.0f}° of arc from the EXIF sun "
                        f"(confidence {confidence:.2f}; alone they fit best near azimuth "
                        f"{map_az:.0f}°, elevation {map_el:.0f}°: the warm area of the map); "
                        + (prior.description or "from EXIF"))
    else:
        if legible < 1.0 and (legible < 0.5 or clarity * peak * strength >= CONFIDENT):
            h, w = session.image_srgb.shape[:2]
            unfound = "too-small"
            why = (f"the photo is too small or too narrow for its shadows to tell the sun "
                   f"({w} x {h} pixels where they are read)")
        elif clarity < CONFIDENT:
            unfound = "no-clear-shadows"
            why = "no clear shadows in the photo"
        elif in_open_sky:
            unfound = "open-sky"
            why = ("the suns the photo's shadows fit best would stand in its open sky, which "
                   "shows no sun (the depth may be too rough: try a depth map or another "
                   "depth model)")
        else:
            unfound = "no-fit"
            why = ("no sun makes the predicted shadows fit the photo's (the depth may be too "
                   "rough: try a depth map or another depth model)")
        if source == SOURCE_EXIF:
            note = f"{why}: the sun is the EXIF sun ({prior.description if prior else ''})"
        else:
            note = (f"{why}: its sun cannot be told from them (confidence {confidence:.2f}); "
                    "set it by eye")
    look_error = str(getattr(session, "sun_look_error", "") or "") if look is not None or (
        LOOK_WEIGHT > 0) else ""
    if look_error:  # an optional model that failed: said, and the shadows alone decided
        note += f"; {look_error}"
    true_el = float(best_e) if prior is not None else float(cam_el)
    # -- the sun itself in the frame: its direction is exact, whatever the shadows say (the
    #    search above still draws the heat map of what they say)
    seen = getattr(session, "sun_seen", None)  # found once, by set_image
    if seen is not None:
        w_best = seen.w
        cam_az, cam_el = sun_angles(seen.w)
        ag, sh = measures(session.shadow(seen.w)[None], prob, ~session.sky, y_full)
        best_score, best_shading = float(ag[0]), float(sh[0])
        evaluations += 1
        found, confidence, source = True, 1.0, SOURCE_SUN_IN_FRAME
        compass_decided, unfound = False, ""
        true_el = float(prior.elevation) if prior is not None else float(cam_el)
        # Where in the picture, in words a photographer reads (not the working image's pixels).
        h, w = session.sky.shape
        note = (f"the sun is in the frame ({100.0 * seen.u / w:.0f} % across, "
                f"{100.0 * seen.v / h:.0f} % down): its direction is taken from there")
        if prior is not None and prior.azimuth is not None:
            seen_az = sun_angles(seen.w, frame.pitch, frame.roll)[0]  # the horizon's frame
            off = abs((seen_az - prior.azimuth + 180.0) % 360.0 - 180.0)
            if off > 10.0:
                note += f"; the {prior.heading_words} puts it {off:.0f}° away"
        if cam_el < -0.5:  # (a user trial's sideways photo: elevation 0 said nothing more)
            below_level = -float(cam_el)
            note += f"; {below_level_words(below_level)}"
        cam_el = min(90.0, max(0.0, cam_el))
    stages["finals"] = time.perf_counter() - lap[0]
    report("done", 1.0)
    return SunFit(
        azimuth=float(cam_az), elevation=float(cam_el), w=w_best, agreement=best_score,
        confidence=confidence, found=found, source=source, note=note, map=amap,
        candidates=[(float(sun_angles(frame.vector(a, e))[0]),
                     float(max(0.0, sun_angles(frame.vector(a, e))[1])), s)
                    for a, e, s, _ in finals],
        shading=best_shading, measure=measure, true_elevation=true_el,
        pitch=frame.pitch, roll=frame.roll, pose_source=pose_source, evaluations=evaluations,
        stage_seconds={k: round(v, 4) for k, v in stages.items()},
        compass_decided=compass_decided, unfound=unfound, below_level=below_level,
        seconds=time.perf_counter() - t0,
    )


__all__ = [
    "SOURCE_EXIF",
    "SOURCE_SUN_IN_FRAME",
    "UNFOUND_REASONS",
    "AgreementMap",
    "FindSunCancelledError",
    "SunFit",
    "SunInPhoto",
    "SunPrior",
    "agreement",
    "at_true_elevation",
    "below_level_words",
    "camera_tilt",
    "describe_tilt",
    "exif_sun_prior",
    "sun_frame_pitch",
    "sun_in_photo",
    "find_sun",
    "ground_plane_tilt",
    "is_tilted",
    "photo_camera_tilt",
    "legibility",
    "shade_clarity",
]
