"""The relighting session: set the photo once, then query shadows and relit images many times.

``set_image`` runs every light-independent stage once at the working resolution (depth, sky mask,
normals, view directions, the ray sampler's per-pixel set-up). Moving a sun re-runs only what
depends on it, and results are cached per sun direction, so going back to a sun the user has
already seen costs nothing. The original sun's refined shadow and the light estimate are computed
once per original sun.

Modes: ``learned`` uses the shipped ONNX models (depth ``Z``, shadow ``S``, refine ``R``,
relight ``L``); ``direct`` / ``physics`` are the non-learned screen-space shadows and
shading-ratio relighting; ``auto`` picks learned where the model is installed.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from outcast_core.runtime.geometry.camera import (
    DEFAULT_FOV_DEG,
    Camera,
    camera_rotation,
    cosine_term,
    focal_from_35mm,
    network_depth,
    normalize_sun,
    normals_from_depth,
    project,
    sun_in_frame,
    view_directions,
)
from outcast_core.runtime.geometry.colour import (
    grey_like,
    is_greyscale,
    linear_to_srgb,
    srgb_to_linear,
)
from outcast_core.runtime.geometry.fullres import resize_to_working
from outcast_core.runtime.geometry.raymarch import RaySampler
from outcast_core.runtime.geometry.shadows import DepthEdgeFill, DirectStats, direct_shadow
from outcast_core.runtime.io.models import ModelError, ModelRegistry
from outcast_core.runtime.pipeline.auto_sun import SunInPhoto, photo_camera_tilt, sun_in_photo
from outcast_core.runtime.pipeline.daylight import (
    DaylightChange,
    daylight_change,
    daylight_gain,
    elevation_above,
    in_new_daylight,
    sky_change,
)
from outcast_core.runtime.pipeline.depth_post import postprocess_z, run_depth_model
from outcast_core.runtime.pipeline.photo_shadows import (
    LIT_FLOOR,
    PRIOR_RADIUS,
    PRIOR_THRESHOLD,
    SKY_SHADE_SHIFT,
    ShadowEdit,
    apply_edit_masks,
    deshadow,
    edit_masks_at,
    filled_share,
    found_shade_marks,
    lift_probability,
    lit_surface_colour,
    marked_weight,
    material_guard,
    near_predicted_shadow,
    original_shadow_from_photo,
    photo_shade_shift,
    photo_shadow_probability,
    shadow_edit_masks,
)
from outcast_core.runtime.pipeline.relight import (
    EXPOSURES,
    FILL_MIN,
    LIFT_COLOUR_SIGMA,
    LIFT_PRIOR_RADIUS,
    LIFT_SHADE_SHIFT,
    SUN_CORE_DEG,
    LightEstimate,
    NormalTrust,
    add_sun,
    estimate_light,
    facing_up,
    glare_gone_full,
    guard_learned_relight,
    meter_exposure,
    original_share,
    physics_relight,
    remove_sun_glare,
    shade_coloured_light,
    shadow_toward_original,
    smooth_new_shadow,
    snap_shadow_to_photo,
    sun_core_px,
    toward_photo,
    transfer_to_full_resolution,
)
from outcast_core.runtime.pipeline.sun_look import SunLook, read_sun

Progress = Callable[[str, float], None]

#: Longer side (pixels) at which :meth:`RelightSession.found_shadows_detail` finds the photo's
#: own shadows for full-resolution outputs (smaller photos: their own size).
DETAIL_SIDE = 1024


@dataclass(frozen=True)
class Preset:
    """A speed/accuracy setting.

    Attributes:
        name: preset name.
        working_size: longer side of the working resolution in pixels.
        steps: march steps of the learned S network.
        direct_step: Direct mode's step (fraction of the longer side); it marches up to one
            image side and stops early when no pixel can change.
        preview_size: longer side used while the user drags a sun.
        preview_steps: march steps while dragging.
        relight_preview_size: longer side at which the new shadow and the relighting network
            run while the user drags the new sun in step 2; the result is moved onto the
            working-size photo (its detail kept), like the full-resolution pass.
    """

    name: str
    working_size: int
    steps: int
    direct_step: float
    preview_size: int
    preview_steps: int
    relight_preview_size: int = 128


PRESETS: dict[str, Preset] = {
    "fast": Preset("fast", 256, 16, 1 / 128, 128, 8, 80),
    "balanced": Preset("balanced", 384, 32, 1 / 256, 192, 16, 112),
    "accurate": Preset("accurate", 512, 64, 1 / 512, 256, 32, 192),
}

_CACHE_SIZE = 16
#: onnxruntime threads for the step-2 drag preview's small inputs (measured: one thread was
#: 2-3x faster than two on two shared cores, and leaves a core to the GUI thread).
PREVIEW_THREADS = 1


def working_shape(height: int, width: int, longer_side: int) -> tuple[int, int]:
    """Size at which a ``height x width`` image is processed (never upscaled)."""
    if height < 1 or width < 1:
        raise ValueError(f"expected a non-empty image, got {height}x{width}")
    scale = min(1.0, longer_side / max(height, width))
    return max(1, round(height * scale)), max(1, round(width * scale))


#: Longer over shorter side beyond which a photo is said to be too elongated for the depth.
MAX_ASPECT = 4.0


def elongation_note(width: int, height: int) -> str:
    """A warning for a photo much longer than it is wide (a panorama), else "": the depth
    network sees the whole photo at its own small size, so a 4000 x 300 strip becomes a
    handful of rows.

    Example:
        >>> elongation_note(4000, 300)[:40]
        'the photo is 13.3:1 (4000 x 300): depth '
    """
    long, short = max(width, height), max(1, min(width, height))
    if long / short <= MAX_ASPECT:
        return ""
    return (f"the photo is {long / short:.1f}:1 ({width} x {height}): depth and shadows are "
            f"estimated on a strip only a few pixels {'high' if width > height else 'wide'}; "
            "crop it to its part of interest for useful shadows")


def resize(image: np.ndarray, shape: tuple[int, int], *, nearest: bool = False) -> np.ndarray:
    """Resize ``H x W [x C]`` to ``shape`` (area when shrinking, linear when enlarging)."""
    h, w = shape
    if image.shape[:2] == (h, w):
        return image
    if nearest:
        interp = cv2.INTER_NEAREST
    elif h < image.shape[0] or w < image.shape[1]:
        interp = cv2.INTER_AREA
    else:
        interp = cv2.INTER_LINEAR
    return cv2.resize(image, (w, h), interpolation=interp)


def check_given_depth(depth: np.ndarray, photo_shape: tuple[int, int]) -> np.ndarray:
    """A depth map from elsewhere, checked against its photo (``H x W``): two-dimensional,
    with the photo's aspect ratio (any resolution) and at least one valid pixel.

    Returns:
        The depth as float32.

    Raises:
        ValueError: saying which of those it is not.
    """
    depth = np.asarray(depth, np.float32)
    if depth.ndim != 2:
        raise ValueError(f"expected depth of shape H x W, got shape {depth.shape}")
    h, w = photo_shape
    ar_img, ar_d = w / h, depth.shape[1] / depth.shape[0]
    if abs(ar_img - ar_d) > 0.02 * ar_img + 1.0 / min(depth.shape):
        raise ValueError(
            f"expected depth with the photo's aspect ratio (width / height {ar_img:.3f}),"
            f" got {depth.shape[1]}x{depth.shape[0]} ({ar_d:.3f})"
        )
    if not (np.isfinite(depth) & (depth > 0)).any():
        raise ValueError(
            "expected depth with at least one valid pixel (finite and > 0), got none "
            "(the whole frame would be sky)"
        )
    return depth


def ground_plane_depth(
    camera: Camera, camera_height: float = 1.6
) -> tuple[np.ndarray, np.ndarray]:
    """A depth prior for when no depth model or depth file exists: a level ground plane.

    Rows below the horizon get the depth of a ground plane ``camera_height`` below a level
    camera (capped at 200 m); rows at or above the horizon are treated as sky, so the relighting
    leaves them alone. It casts no shadows; it only keeps the pipeline running (and is reported
    as such by :attr:`RelightSession.depth_source`).

    Returns:
        ``(depth, sky)``, ``H x W`` float32 and bool.
    """
    v = np.arange(camera.height, dtype=np.float64) + 0.5
    dv = (v - camera.cy) / camera.focal
    far = 200.0
    z = np.minimum(camera_height / np.maximum(dv, 1e-6), far)
    sky_rows = camera_height / np.maximum(dv, 1e-6) > far
    depth = np.repeat(z[:, None], camera.width, axis=1).astype(np.float32)
    sky = np.repeat(sky_rows[:, None], camera.width, axis=1)
    return depth, sky


def _key(w: Any) -> tuple[float, float, float]:
    v = normalize_sun(w)
    return (round(float(v[0]), 6), round(float(v[1]), 6), round(float(v[2]), 6))


class _LRU(OrderedDict):
    def get_or(self, key: Any, make: Callable[[], Any]) -> Any:
        if key in self:
            self.move_to_end(key)
            return self[key]
        value = make()
        self[key] = value
        while len(self) > _CACHE_SIZE:
            self.popitem(last=False)
        return value


def _same_masks(a: tuple[np.ndarray, np.ndarray] | None,
                b: tuple[np.ndarray, np.ndarray] | None) -> bool:
    """Whether two :func:`~outcast_core.runtime.pipeline.photo_shadows.shadow_edit_masks`
    results (None: no edits) change the found shadows alike."""
    def parts(m: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray] | None:
        return None if m is None or not (m[0].any() or m[1].any()) else m

    a, b = parts(a), parts(b)
    if a is None or b is None:
        return a is b
    return all(x.shape == y.shape and np.array_equal(x, y) for x, y in zip(a, b, strict=True))


#: What :attr:`RelightSession.relight_mode` may be set to.
RELIGHT_MODES = ("auto", "learned", "physics")


def _check_relight_mode(mode: str) -> str:
    if mode not in RELIGHT_MODES:
        raise ValueError(f"expected relight mode auto, learned or physics, got {mode!r}")
    return mode


def _with_user_marks(found: np.ndarray, user: np.ndarray | None) -> np.ndarray | None:
    """``found`` (``H x W``, bool or a weight in [0, 1]) and the user's marks (``user``, of the
    same size, or None), the larger per pixel, as float32; None when both are empty."""
    if not found.any():
        return user
    marks = np.asarray(found, np.float32)
    return marks if user is None else np.maximum(user, marks)


class RelightSession:
    """Set once, query many.

    Args:
        registry: where the ONNX models come from (default: the shipped ``models/``).
        preset: one of :data:`PRESETS`.
        mode: ``auto``, ``learned`` or ``classic`` (Direct shadows + physics relighting).
        shadow_mode: overrides ``mode`` for shadows: ``auto``, ``learned`` or ``direct``.
        relight_mode: overrides ``mode`` for relighting: ``auto``, ``learned`` or ``physics``.
        thickness: Direct mode's occluder thickness (relative to depth; ``inf`` = solid).
        refine: how the original shadow ``S_o`` is found at "Confirm sun": ``photo`` (the
            photo's own shadows, with ``S`` as the prior: :mod:`~outcast_core.runtime.
            photo_shadows`; measured best on real photos) or ``learned`` (the ``R`` network
            where installed, else ``S`` snapped to the photo's edges).
        depth_mode: ``auto`` (a given depth, else the depth model when installed, else the
            ground-plane prior), ``model`` (the depth model; :class:`ModelError` if missing) or
            ``prior`` (never the model: for when it is broken).

    Example:
        >>> s = RelightSession(mode="classic", preset="fast")
        >>> s.set_image(np.full((32, 48, 3), 0.5, np.float32), depth=np.ones((32, 48), np.float32))
        >>> s.shadow((0.0, -0.7, -0.7)).shape
        (32, 48)
    """

    def __init__(
        self,
        registry: ModelRegistry | None = None,
        preset: str = "balanced",
        mode: str = "auto",
        *,
        shadow_mode: str | None = None,
        relight_mode: str | None = None,
        thickness: float = math.inf,
        depth_mode: str = "auto",
        refine: str = "photo",
    ) -> None:
        if depth_mode not in {"auto", "model", "prior"}:
            raise ValueError(f"expected depth mode auto, model or prior, got {depth_mode!r}")
        if refine not in {"photo", "learned"}:
            raise ValueError(f"expected refine photo or learned, got {refine!r}")
        self.refine = refine
        #: Learned relighting keeps the photo's colour where both suns light a surface
        #: (:func:`~outcast_core.runtime.pipeline.relight.keep_photo_colour`); the photo's sky
        #: is kept whatever this says (:meth:`_sun_in_sky` handles a sun in the frame).
        self.colour_guard = True
        #: Learned relighting darkens newly shadowed surfaces at least as much as physics does
        #: (:func:`~outcast_core.runtime.pipeline.relight.shadow_contrast_floor`).
        self.contrast_floor = True
        #: Learned relighting takes its exposure from physics on the surfaces both suns light
        #: (:func:`~outcast_core.runtime.pipeline.relight.anchor_exposure`).
        self.exposure_anchor = True
        #: Learned relighting keeps the photo's fine texture where no shadow changes (``L``
        #: blurs it; :func:`~outcast_core.runtime.pipeline.relight.restore_detail`).
        self.keep_detail = True
        #: With the floor, learned relighting also brightens newly lit surfaces toward physics
        #: (:func:`~outcast_core.runtime.pipeline.relight.shadow_contrast_floor`'s ``lift``),
        #: only where the photo's found shadow is shade and not dark material and the geometry
        #: puts a shadow (:meth:`_lift_guard`), and no brighter than the de-shadowed photo
        #: relit by physics (:meth:`_lift_inputs`; measured in that docstring).
        self.lift_new_light = True
        #: A new sun lights a surface whose normals the photo contradicts (lit in the photo,
        #: turned away from its sun by the geometry) no more than the trusted lit surface round
        #: it, in both modes (:class:`~outcast_core.runtime.pipeline.relight.NormalTrust`).
        #: Like the other switches here, set it before the relighting: relit images already
        #: cached, and the drag preview's inputs once built, keep what they were made with.
        self.trust_normals = True
        #: With the colour guard, learned relighting gives newly shadowed surfaces the photo's
        #: colour turned by the shift of its own shade's colour
        #: (:func:`~outcast_core.runtime.pipeline.relight.shaded_colour`,
        #: :func:`~outcast_core.runtime.pipeline.photo_shadows.photo_shade_shift`); physics
        #: relighting takes a light of that colour (:meth:`_relight_light`).
        self.shade_colour = True
        self._daylight = True
        self._tilt: tuple[float, float] | None = None
        self._photo_path: str | None = None
        self._exposure = "photo"
        if mode not in {"auto", "learned", "classic"}:
            raise ValueError(f"expected mode auto, learned or classic, got {mode!r}")
        shadow_mode = shadow_mode or {"classic": "direct"}.get(mode, mode)
        relight_mode = relight_mode or {"classic": "physics"}.get(mode, mode)
        if shadow_mode not in {"auto", "learned", "direct"}:
            raise ValueError(f"expected shadow mode auto, learned or direct, got {shadow_mode!r}")
        _check_relight_mode(relight_mode)
        self.registry = registry if registry is not None else ModelRegistry()
        self.thickness = thickness
        self.depth_mode = depth_mode
        if depth_mode == "model":
            self.registry.load("depth")
        self._lock = threading.RLock()
        self.shadow_mode = self._resolve(shadow_mode, "shadow", "direct")
        self._relight_mode = self._resolve(relight_mode, "relight", "physics")
        self.preset = self._check_preset(preset)
        self.timings: dict[str, float] = {}
        #: Whether :meth:`sun_look` reads the photo with ``D`` when ``models/sun.onnx`` is there
        #: (the search for the sun then weighs its suns by it); not in the classic mode, which
        #: uses no learned network but ``Z``.
        self.use_sun_look = mode != "classic"
        self.full_image_srgb: np.ndarray | None = None
        self.greyscale = False
        self._given_depth: np.ndarray | None = None
        self._focal_full: float | None = None
        self.depth_source = "none"
        #: Optional depth source used instead of the depth model (not instead of a given
        #: depth): ``(image_srgb, camera) -> (depth, sky)`` with a ``name`` shown as "depth: ...";
        #: see :mod:`~outcast_core.runtime.io.depth_models` (phone maps, ONNX depth models).
        self.depth_provider: Any = None
        self.original_sun: np.ndarray | None = None
        self.original_shadow: np.ndarray | None = None
        #: The user's corrections of the found shadows (:meth:`set_shadow_edits`), for this
        #: photo: kept across presets and original suns, cleared by :meth:`set_image`.
        self.shadow_edits: tuple[ShadowEdit, ...] = ()
        #: Per edit of :attr:`shadow_edits`, whether it changed the found shadows (set with an
        #: original sun: a click on the sky, on lit ground or on what is already dropped
        #: changes nothing, nor does a brush dab with nothing of its kind to change under it).
        self.shadow_edits_used: tuple[bool, ...] = ()
        self._reset_working()

    @property
    def exposure(self) -> str:
        """How relit photos are exposed: ``"photo"``, the photo's exposure kept (the light
        changes, the camera does not: a scene put in shade comes out dark), or ``"metered"``,
        exposed again as a camera meters the new light
        (:func:`~outcast_core.runtime.pipeline.relight.meter_exposure`). Relit images are
        cached per exposure; setting it takes no lock (the app sets it while a relighting
        runs), and a relighting already started keeps the exposure it started with."""
        return self._exposure

    @exposure.setter
    def exposure(self, mode: str) -> None:
        self._exposure = self._checked_exposure(mode)

    def _checked_exposure(self, mode: str | None) -> str:
        """``mode``, checked; :attr:`exposure` for None."""
        if mode is None:
            return self._exposure
        if mode not in EXPOSURES:
            raise ValueError(f"expected exposure {' or '.join(EXPOSURES)}, got {mode!r}")
        return mode

    @property
    def relight_mode(self) -> str:
        """How the photo is relit: ``"learned"`` (``L`` with the guards that keep the
        photo's colours, texture and exposure: the default where ``models/relight.onnx`` is
        installed, measured best on real photos) or ``"physics"`` (the photo times the change
        of light each pixel gets). Set ``"auto"`` for the default; ``"learned"`` raises
        :class:`ModelError` naming the file when ``L`` cannot be loaded, and the mode stays.
        Relit images are cached per mode (both stay cached); a relighting under way keeps the
        mode it started with (setting it waits for the session's lock)."""
        return self._relight_mode

    @relight_mode.setter
    def relight_mode(self, mode: str) -> None:
        resolved = self._resolve(_check_relight_mode(mode), "relight", "physics")
        with self._lock:
            self._relight_mode = resolved

    # ------------------------------------------------------------------ set-up
    def _resolve(self, requested: str, model: str, classic: str) -> str:
        if requested == "auto":
            return "learned" if self.registry.available(model) else classic
        if requested == "learned":
            self.registry.load(model)  # raises ModelError naming the file
        return requested

    @staticmethod
    def _check_preset(name: str) -> Preset:
        if name not in PRESETS:
            raise ValueError(f"expected a preset in {sorted(PRESETS)}, got {name!r}")
        return PRESETS[name]

    @property
    def daylight(self) -> bool:
        """Whether a relighting carries the photo's light to the new sun's elevation: the
        sunlight weaker and redder and the sky dimmer near the horizon
        (:func:`~outcast_core.runtime.pipeline.daylight.in_new_daylight`); on by default.
        Two suns at one elevation are unchanged by it."""
        return self._daylight

    @daylight.setter
    def daylight(self, on: bool) -> None:
        with self._lock:
            self._daylight = bool(on)  # in the relit cache's key: both stay cached

    def set_camera_tilt(self, pitch: float | None, roll: float = 0.0) -> None:
        """The camera's pitch and roll (degrees) given instead of :meth:`photo_tilt`'s (the
        photo's file is not at hand, or the caller knows better), which :meth:`horizon_up`
        takes; ``None``: :meth:`photo_tilt`'s again. Kept for this photo across presets
        (:meth:`set_image` forgets it)."""
        with self._lock:
            tilt = None if pitch is None else (float(pitch), float(roll))
            if tilt is not None and not all(math.isfinite(v) for v in tilt):
                raise ValueError(f"expected a finite camera pitch and roll, got {tilt}")
            if tilt != self._tilt:
                self._tilt = tilt
                self._up = None
                self._relight_cache = _LRU()
                if self.original_shadow is not None:  # the lift's marks face the new up
                    self._lift_guards = self._new_lift_guards(self.original_shadow)

    def photo_tilt(self) -> tuple[float, float, str]:
        """The camera's ``(pitch, roll, source)`` (degrees) found for this photo
        (:func:`~outcast_core.runtime.pipeline.auto_sun.photo_camera_tilt`): its file's
        metadata pose (``set_image``'s ``photo_path``), else the pitch that puts the sun seen in
        the frame at the capture's true elevation, else the fitted ground plane, else level.
        The app, the time-lapse and batch place their EXIF suns with it. Made once per photo
        and preset."""
        with self._lock:
            self._require_image()
            if self._photo_tilt is None:
                found = photo_camera_tilt(self, self._photo_path)
                self._photo_tilt = (float(found[0]), float(found[1]), str(found[2]))
            return self._photo_tilt

    def sun_look(self) -> SunLook | None:
        """``D``'s reading of the photo (:func:`~outcast_core.runtime.pipeline.sun_look.read_sun`:
        where its look puts the sun, a distribution over directions), or None without a
        ``sun`` model or when :attr:`use_sun_look` is off. Made once per photo and working
        size. ``D`` is an optional extra: a model file that cannot be loaded or run gives
        None too, and :attr:`sun_look_error` says why (the sun is then found from the shadows
        alone, as without it)."""
        with self._lock:
            self._require_image()
            if not self.use_sun_look or not self.registry.available("sun"):
                return None
            if self._sun_look is None and not self.sun_look_error:
                assert self.image_srgb is not None
                t0 = time.perf_counter()
                try:
                    self._sun_look = read_sun(self.registry.load("sun"), self.image_srgb)
                except (ModelError, ValueError, OSError) as exc:
                    self.sun_look_error = f"the sun model could not be used: {exc}"
                self._time("sun look", t0)
            return self._sun_look

    def horizon_tilt(self) -> tuple[float, float]:
        """The camera's ``(pitch, roll)`` (degrees) against the horizon, as :meth:`horizon_up`
        takes it: :meth:`set_camera_tilt`'s, else :meth:`photo_tilt`'s. Suns turned or placed
        with it (:func:`~outcast_core.runtime.geometry.camera.sun_vector`'s ``pitch_deg``,
        ``roll_deg``) keep their elevation above the horizon."""
        with self._lock:
            if self._tilt is not None:
                return self._tilt
            return self.photo_tilt()[:2]

    def horizon_up(self) -> np.ndarray:
        """The horizon's upward direction in camera space (unit ``(3,)``), against which a
        sun's elevation is taken for :attr:`daylight`: :meth:`horizon_tilt`'s (a level
        camera's ``(0, -1, 0)`` without one). Made once per photo and preset; needs
        :meth:`set_image`."""
        with self._lock:
            if self._up is None:
                self._up = camera_rotation(*self.horizon_tilt()) @ np.array([0.0, -1.0, 0.0])
            return self._up

    @staticmethod
    def _daylight_change(on: bool, w_old: np.ndarray, w_new: np.ndarray, up: np.ndarray
                         ) -> DaylightChange | None:
        """How the light changes from the photo's sun to ``w_new`` (:func:`~outcast_core.
        runtime.pipeline.daylight.daylight_change`, elevations above the horizon ``up``); None
        when ``on`` (the caller's :attr:`daylight`) is False or both suns stand at one
        elevation."""
        if not on:
            return None
        change = daylight_change(elevation_above(w_old, up), elevation_above(w_new, up))
        return None if change.is_identity else change

    @staticmethod
    def _daylight_gain(change: DaylightChange | None, s_new: np.ndarray, sky: np.ndarray,
                       light: LightEstimate, up: np.ndarray, view_dirs: np.ndarray,
                       relight_mode: str) -> np.ndarray | None:
        """The gain that carries a relighting in ``relight_mode`` (made with the photo's
        light; ``view_dirs``: its pixels' rays) to the new sun's daylight ``change``
        (:meth:`_daylight_change`; :func:`~outcast_core.runtime.pipeline.daylight.
        daylight_gain`, the sky by :func:`~outcast_core.runtime.pipeline.daylight.
        sky_change`); None without a change."""
        if change is None:
            return None
        if relight_mode == "learned":  # as the guards' physics image takes it
            s_new = smooth_new_shadow(s_new)
        sky_gain = None
        if sky.any():
            sky_gain = np.ones(sky.shape + (3,), np.float32)
            sky_gain[sky] = sky_change(view_dirs[sky], up, change.elevation_old,
                                       change.elevation_new)
        return daylight_gain(s_new, sky, light.ratio, change, sky_gain)

    def _reset_working(self) -> None:
        self._up: np.ndarray | None = None
        self._photo_tilt: tuple[float, float, str] | None = None
        self._sun_look: SunLook | None = None
        #: Why :meth:`sun_look` gave None for this photo although a ``sun`` model is there
        #: ("": it did not); per photo, as its reading (a review: one failure silenced ``D``
        #: for every later photo, and its note stayed on their fits).
        self.sun_look_error = ""
        self.image_srgb: np.ndarray | None = None
        self.camera: Camera | None = None
        self.depth: np.ndarray | None = None
        self.sky: np.ndarray | None = None
        self.normals: np.ndarray | None = None
        self.view_dirs: np.ndarray | None = None
        self._sampler: RaySampler | None = None
        #: The learned shadow's fill at depth edges (DepthEdgeFill) at the working size.
        self._edge_fill: DepthEdgeFill | None = None
        self._preview: dict[str, Any] | None = None
        self._relight_preview: dict[str, Any] | None = None
        #: :meth:`_normal_trust`'s: ``(S_o, normals, NormalTrust)`` at the working size.
        self._trust: tuple[np.ndarray, np.ndarray, NormalTrust] | None = None
        #: How many times the light-independent inputs of the step-2 drag preview were built
        #: (once per photo, original sun and preset; tests count it).
        self.relight_preview_builds = 0
        self._shadow_cache = _LRU()
        self._relight_cache = _LRU()
        self._light: LightEstimate | None = None
        #: The photo's shade colour shift (photo_shadows.photo_shade_shift), at its sun.
        self._shade_shift: tuple[float, float] = SKY_SHADE_SHIFT
        self._deshadowed: np.ndarray | None = None
        self._lifted: np.ndarray | None = None
        #: Where the photo's own shadows are (``H x W`` in [0, 1]), set by set_original_sun().
        self.shadow_probability: np.ndarray | None = None
        #: The lift's material guard (:meth:`_lift_guard`), per size, and what the de-shadow
        #: (``"marks"``, :meth:`_deshadow_marks`) and the lift (``"lift_marks"``) take as
        #: marked shadows at the working size, for one ``S_o``.
        self._lift_guards: dict[Any, Any] = {}
        #: The shadow network's ``S`` at the original sun (the geometry's prior for ``S_o``).
        self._original_geometry: np.ndarray | None = None
        #: The sun the photo shows (:func:`~outcast_core.runtime.pipeline.auto_sun.sun_in_photo`)
        #: at working size, or None.
        self.sun_seen: SunInPhoto | None = None
        #: :meth:`found_shadows_detail`'s arrays, for one ``S_o``, and their lift probability
        #: (:meth:`_detail_lifted`).
        self._detail: dict[str, Any] | None = None
        self._detail_lift: np.ndarray | None = None
        #: ``S_o`` and the shadow probability as found, before :attr:`shadow_edits`.
        self._found: tuple[np.ndarray, np.ndarray] | None = None
        #: :meth:`found_shadows_detail`'s probability as found and cosine term, per ``S_o``.
        self._detail_found: tuple[np.ndarray, np.ndarray] | None = None
        #: :meth:`_found_shade_marks`, per size: ``(excluded, marks)`` for :attr:`_found`.
        self._found_marks: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        #: What the lift's statistics and guards leave out at working size: the sky, and what
        #: the user marked "not a shadow" (dark materials are no lit surface either).
        self._lift_excluded: np.ndarray | None = None
        #: :attr:`shadow_edits` as regions at working size (added, dropped), or None: made
        #: where the user sees the found shadows and brought to :meth:`found_shadows_detail`.
        self._edit_masks: tuple[np.ndarray, np.ndarray] | None = None

    def _time(self, stage: str, t0: float) -> None:
        self.timings[stage] = time.perf_counter() - t0

    def set_image(
        self,
        image_srgb: np.ndarray,
        *,
        fov_deg: float | None = None,
        focal_35mm: float | None = None,
        depth: np.ndarray | None = None,
        progress: Progress | None = None,
        photo_path: str | os.PathLike[str] | None = None,
    ) -> None:
        """Set the photo and run every light-independent stage once.

        Args:
            image_srgb: ``H x W x 3`` sRGB at full resolution: float in [0, 1], or uint8 (kept
                as it is, without a float copy: the full-resolution stages read it in bands).
            fov_deg: horizontal field of view (default 60 deg, or from ``focal_35mm``).
            focal_35mm: EXIF 35 mm equivalent focal length.
            depth: optional ``h x w`` depth from elsewhere (any resolution with the photo's
                aspect ratio; non-finite or <= 0 marks sky). Replaces the depth model.
            progress: called with ``(stage, fraction)``.
            photo_path: the photo's file, whose metadata (a pose; the capture time and place
                for the sun seen in the frame) give the camera's tilt (:meth:`photo_tilt`).
        """
        img = np.asarray(image_srgb)
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
            raise ValueError(f"expected an H x W x 3 image, got shape {img.shape}")
        if img.dtype == np.uint8:
            img = np.ascontiguousarray(img)  # kept as it is: a quarter of float32's memory
        else:
            img = np.array(img, dtype=np.float32)  # one copy, cleaned in place
            np.clip(img, 0.0, 1.0, out=img)
            img[np.isnan(img)] = 0.0
        h, w = img.shape[:2]
        if focal_35mm is not None and fov_deg is None:
            focal = focal_from_35mm(w, h, focal_35mm)
        else:
            focal = Camera.from_fov(h, w, DEFAULT_FOV_DEG if fov_deg is None else fov_deg).focal
        if depth is not None:
            depth = check_given_depth(depth, (h, w))
        with self._lock:
            self.full_image_srgb = img
            # A black-and-white photo: every image made from it stays black and white (``L``
            # and the guards tint it a little otherwise).
            self.greyscale = is_greyscale(img)
            self._focal_full = focal
            self._given_depth = depth
            self._photo_path = None if photo_path is None else os.fspath(photo_path)
            self._tilt = None  # another photo: a tilt given for the last one is not its own
            self.original_sun = None
            self.original_shadow = None
            self.shadow_edits, self.shadow_edits_used = (), ()
            self._prepare(progress)

    def set_preset(self, name: str, progress: Progress | None = None) -> None:
        """Switch preset; light-independent stages re-run only if the working size changes."""
        preset = self._check_preset(name)
        with self._lock:
            old = self.preset
            self.preset = preset
            if self.full_image_srgb is None:
                return
            if old.working_size != preset.working_size:
                w_o = self.original_sun
                self._prepare(progress)
                if w_o is not None:
                    self.set_original_sun(w_o)
            else:
                self._shadow_cache.clear()
                self._relight_cache.clear()
                self._preview = None
                self._relight_preview = None

    def _prepare(self, progress: Progress | None) -> None:
        assert self.full_image_srgb is not None and self._focal_full is not None
        report = progress or (lambda stage, frac: None)
        full = self.full_image_srgb
        h, w = working_shape(full.shape[0], full.shape[1], self.preset.working_size)
        self._reset_working()
        t0 = time.perf_counter()
        self.image_srgb = resize_to_working(full, (h, w))
        self.camera = Camera(h, w, self._focal_full * w / full.shape[1])
        self._time("resize", t0)
        report("depth", 0.1)
        t0 = time.perf_counter()
        depth, sky = self._estimate_depth()
        self.depth, self.sky = depth, sky
        self._up = None  # the horizon of this depth's ground plane (horizon_up)
        self._photo_tilt = None
        # The sun itself in the frame, if the photo shows it: relit to a sun outside the frame,
        # its disc and glare go (relight.remove_sun_glare).
        self.sun_seen = sun_in_photo(self.image_srgb, sky, self.camera)
        self._time("depth", t0)
        report("normals", 0.6)
        t0 = time.perf_counter()
        depth_sky = np.where(sky, np.inf, depth).astype(np.float32)
        self.normals = normals_from_depth(depth_sky, self.camera)
        self.view_dirs = view_directions(self.camera)
        self._sampler = RaySampler(depth_sky, self.camera)
        self._time("normals", t0)
        self.original_sun = None
        self.original_shadow = None
        report("ready", 1.0)

    def _estimate_depth(self) -> tuple[np.ndarray, np.ndarray]:
        cam = self.camera
        assert cam is not None and self.image_srgb is not None
        if self._given_depth is not None:
            d = self._given_depth
            sky_src = ~(np.isfinite(d) & (d > 0))
            d_fill = np.where(sky_src, 0.0, d).astype(np.float32)
            depth = resize(d_fill, (cam.height, cam.width), nearest=True)
            sky = resize(sky_src.astype(np.uint8), (cam.height, cam.width), nearest=True) > 0
            self.depth_source = "given"
            return np.where(sky, np.inf, depth).astype(np.float32), sky
        if self.depth_provider is not None:
            depth, sky = self.depth_provider(self.image_srgb, cam)
            self.depth_source = str(self.depth_provider.name)
            return depth, sky
        if self.depth_mode != "prior" and self.registry.available("depth"):
            # Z at the scale it was trained at, then the sky prior, edge-aware smoothing and
            # the ground plane for real photos (runtime.pipeline.depth_post).
            raw, sky_prob = run_depth_model(self.registry.load("depth"), self.image_srgb)
            depth, sky = postprocess_z(raw, sky_prob, self.image_srgb, cam,
                                       greyscale=self.greyscale)
            self.depth_source = "model"
            return depth, sky
        self.depth_source = "ground-plane prior (no depth model)"
        return ground_plane_depth(cam)

    def _require_image(self) -> None:
        if self.image_srgb is None:
            raise RuntimeError("set_image() must be called before asking for shadows or relighting")

    # ------------------------------------------------------------------ preview buffers
    def _preview_state(self) -> dict[str, Any]:
        if self._preview is None:
            assert self.image_srgb is not None and self.camera is not None
            h, w = working_shape(self.camera.height, self.camera.width, self.preset.preview_size)
            cam = self.camera.resized(h, w)
            depth = resize(np.where(self.sky, np.inf, self.depth).astype(np.float32), (h, w),
                           nearest=True)
            self._preview = {
                "camera": cam,
                "image": resize(self.image_srgb, (h, w)),
                "depth": depth,
                "sky": resize(self.sky.astype(np.uint8), (h, w), nearest=True) > 0,
                "normals": normals_from_depth(depth, cam),
                "sampler": RaySampler(depth, cam),
            }
        return self._preview

    # ------------------------------------------------------------------ shadows
    def shadow(self, w: Any, *, preview: bool = False) -> np.ndarray:
        """The shadow image for sun ``w`` at working resolution (``H x W`` float32 in [0, 1]).

        ``preview=True`` computes it at the preset's preview size and fewer steps (for dragging)
        and upsamples it.
        """
        key = (_key(w), preview, self.preset.name)
        with self._lock:
            self._require_image()
            return self._shadow_cache.get_or(key, lambda: self._compute_shadow(w, preview))

    def relit_shadow(self, w: Any) -> np.ndarray:
        """The new shadow a relighting for sun ``w`` uses (``H x W`` in [0, 1], working size):
        the geometry's :meth:`shadow`, drawn toward the photo's found shadows near its sun
        (:func:`~outcast_core.runtime.pipeline.relight.shadow_toward_original`) and capped where
        the photo contradicts the normals (:class:`~outcast_core.runtime.pipeline.relight.
        NormalTrust`). This is what the "New shadow" view shows: the plain :meth:`shadow` is
        the geometry's alone (step 1's overlay, the search's)."""
        wv = normalize_sun(w)
        with self._lock:
            self._require_image()
            if self.original_shadow is None or self.original_sun is None:
                raise RuntimeError("set_original_sun() must be called before relit_shadow()")
            s_new = self.shadow(wv)
            share = original_share(self.original_sun, wv)
            return shadow_toward_original(s_new, self.original_shadow, self._original_geometry,
                                          share, self._normal_trust())

    def _compute_shadow(self, w: Any, preview: bool) -> np.ndarray:
        t0 = time.perf_counter()
        wv = normalize_sun(w)
        assert self.camera is not None
        if preview:
            st = self._preview_state()
            cam, image, depth, sky, normals, sampler = (
                st["camera"], st["image"], st["depth"], st["sky"], st["normals"], st["sampler"]
            )
        else:
            cam, image, sky, normals, sampler = (
                self.camera, self.image_srgb, self.sky, self.normals, self._sampler
            )
            depth = np.where(self.sky, np.inf, self.depth).astype(np.float32)
        if self.shadow_mode == "learned":
            out = self._learned_shadow(image, depth, normals, cam, wv)
            out = self._depth_edge_fill(preview, depth, image)(out)
        else:
            step = self.preset.direct_step * (2.0 if preview else 1.0)
            stats = DirectStats(0, 0, "")
            out = direct_shadow(
                depth, cam, wv, normals=normals, sky=sky, steps=int(math.ceil(1.0 / step)),
                step=step, thickness=self.thickness, sampler=sampler, stats=stats,
            )
            self.last_direct_stats = stats
        if out.shape != (self.camera.height, self.camera.width):
            out = np.clip(resize(out, (self.camera.height, self.camera.width)), 0.0, 1.0)
        self._time("shadow_preview" if preview else "shadow", t0)
        return out.astype(np.float32)

    def _depth_edge_fill(self, preview: bool, depth: np.ndarray, image: np.ndarray
                         ) -> DepthEdgeFill:
        """The learned shadow's fill at depth edges for this depth and ``image`` (the photo
        at the depth's size, whose luminance edges confirm a small depth step; made once per
        depth map and size: the preview's is kept with the preview's inputs)."""
        if preview:
            st = self._preview_state()
            if "edge_fill" not in st:
                st["edge_fill"] = DepthEdgeFill(depth, image)
            return st["edge_fill"]
        return self._working_edge_fill()

    def _working_edge_fill(self) -> DepthEdgeFill:
        """:meth:`_depth_edge_fill` at the working size: built on first use from the working
        depth and photo, kept until :meth:`_reset_working`."""
        if self._edge_fill is None:
            self._edge_fill = DepthEdgeFill(
                np.where(self.sky, np.inf, self.depth).astype(np.float32), self.image_srgb)
        return self._edge_fill

    def _learned_shadow(
        self, image: np.ndarray, depth: np.ndarray, normals: np.ndarray, cam: Camera,
        w: np.ndarray,
    ) -> np.ndarray:
        model = self.registry.load("shadow")
        d = network_depth(depth)
        out = model.run({
            "image": image.transpose(2, 0, 1)[None],
            "depth": d[None, None],
            "normals": normals.transpose(2, 0, 1)[None],
            "sun": w.astype(np.float32)[None],
            "focal": np.array([[cam.focal]], np.float32),
        })
        return np.clip(_first(out)[0, 0], 0.0, 1.0)

    # ------------------------------------------------------------------ original sun
    def set_original_sun(self, w: Any) -> np.ndarray:
        """Fix the photo's original sun; computes the (refined) original shadow ``S_o``."""
        wv = normalize_sun(w)
        with self._lock:
            self._require_image()
            t0 = time.perf_counter()
            s = geometry = self.shadow(wv)
            prob = None
            if self.refinement == "photo":
                prob = photo_shadow_probability(self.image_srgb, self.sky, s)
                s = original_shadow_from_photo(prob, cosine_term(self.normals, wv), self.sky)
            elif self.refinement == "learned":
                model = self.registry.load("refine")
                out = model.run({
                    "shadow": s[None, None],
                    "image": self.image_srgb.transpose(2, 0, 1)[None],
                    "sun": wv.astype(np.float32)[None],
                })
                s = np.clip(_first(out)[0, 0], 0.0, 1.0)
            else:
                s = snap_shadow_to_photo(s, self.image_srgb)
            if prob is None:  # the photo's shadows as S_o describes them
                lit = np.maximum(cosine_term(self.normals, wv), LIT_FLOOR)
                prob = np.where(self.sky, 0.0, np.clip(1.0 - s / lit, 0.0, 1.0))
            self.original_sun = wv
            self._original_geometry = geometry
            self._found = (s.astype(np.float32), prob.astype(np.float32))
            self._detail_found = None
            self._found_marks = {}
            self._apply_found()
            self._time("original_sun", t0)
            return self.original_shadow

    def set_shadow_edits(self, edits: Sequence[ShadowEdit]) -> None:
        """Set the user's corrections of the photo's found shadows (:class:`~outcast_core.
        runtime.pipeline.photo_shadows.ShadowEdit`: "a shadow" / "not a shadow" at a point, or
        a brush stroke's dabs), in order; ``()`` clears them. They apply to ``S_o`` and the
        shadow probability at every size (working, :meth:`found_shadows_detail`), so to
        de-shadowing and relighting; with an original sun set, what depends on them is redone
        now (cheap: no network runs).
        """
        edits = tuple(edits)
        for e in edits:
            if not isinstance(e, ShadowEdit):
                raise ValueError(f"expected ShadowEdit items, got {type(e).__name__}")
        with self._lock:
            if edits == self.shadow_edits:
                return
            used = self.shadow_edits_used
            if len(used) == len(self.shadow_edits) and edits == tuple(
                    e for e, u in zip(self.shadow_edits, used, strict=True) if u):
                # Only edits that changed nothing are gone: nothing to redo.
                self.shadow_edits, self.shadow_edits_used = edits, (True,) * len(edits)
                return
            self.shadow_edits = edits
            self.shadow_edits_used = ()
            if self._found is not None and self.original_sun is not None:
                self._apply_found(same_found=True)

    def _apply_found(self, same_found: bool = False) -> None:
        """``S_o`` and the shadow probability from the found ones and :attr:`shadow_edits`;
        everything made from them is dropped. ``same_found``: only the edits changed since
        the last call; when their masks are the same as before (an edit that changed
        nothing), everything is kept (the full-resolution de-shadow was made again for a
        stroke on lit ground)."""
        assert self._found is not None and self.original_sun is not None
        s, prob = self._found
        used: list[bool] = []
        masks = (shadow_edit_masks(prob, self.image_srgb, self.sky, self.shadow_edits, used)
                 if self.shadow_edits else None)
        if same_found and self.original_shadow is not None and _same_masks(masks,
                                                                           self._edit_masks):
            self.shadow_edits_used = tuple(used)
            return
        self._lift_excluded, self._edit_masks = self.sky, masks
        if masks is not None:
            edited, not_shadow = apply_edit_masks(prob, self.sky, *masks)
            changed = np.abs(edited - prob) > 1e-4
            redone = original_shadow_from_photo(
                edited, cosine_term(self.normals, self.original_sun), self.sky)
            s, prob = np.where(changed, redone, s).astype(np.float32), edited
            self._lift_excluded = self.sky | not_shadow
        self.shadow_edits_used = tuple(used)
        guards = self._new_lift_guards(s)  # first: S_o and its guards back to back
        self.original_shadow = s
        self.shadow_probability = prob
        # What the user calls "not a shadow" is no lit surface either (a dark material).
        self._light = estimate_light(srgb_to_linear(self.image_srgb), s, self._lift_excluded)
        self._shade_shift = photo_shade_shift(self.image_srgb, prob > 0.5, ~self._lift_excluded)
        self._relight_cache.clear()
        self._deshadowed = None
        self._lifted = None
        self._lift_guards = guards
        self._detail = None
        self._detail_lift = None

    def _new_lift_guards(self, s_o: np.ndarray) -> dict[Any, Any]:
        """A fresh :attr:`_lift_guards` for ``S_o`` (``s_o``): the marked shadows the de-shadow
        (``"marks"``) and the relighting's lift (``"lift_marks"``: the found ones on surfaces facing
        up, :func:`~outcast_core.runtime.pipeline.relight.facing_up`) take, and the user's own
        (``"user"``), made under the lock with ``S_o`` (about 25 ms), as a relighting stream reads
        them lock-free."""
        assert self._lift_excluded is not None and self.sky is not None
        assert self._found is not None
        user = self._marked(self.sky)
        found = self._found_shade_marks(self.image_srgb, self._found[1], self._lift_excluded)
        facing = facing_up(self.normals, self.horizon_up()) if found.any() else found
        return {"of": s_o, "user": user, "marks": _with_user_marks(found, user),
                "lift_marks": _with_user_marks(found * facing, user)}

    @property
    def refinement(self) -> str:
        """How ``S_o`` is refined: ``"photo"`` (the photo's own shadows, ``refine="photo"``),
        ``"learned"`` (the R network, with learned shadows and ``refine.json`` installed) or
        ``"guided filter"`` (said, not dropped silently)."""
        if self.refine == "photo":
            return "photo"
        learned = self.shadow_mode == "learned" and self.registry.available("refine")
        return "learned" if learned else "guided filter"

    def deshadow(self) -> np.ndarray:
        """The photo with its own shadows lifted, at working resolution (``H x W x 3`` sRGB).

        Needs :meth:`set_original_sun` (the shadows are found at the photo's sun).
        """
        with self._lock:
            self._require_image()
            if self.shadow_probability is None:
                raise RuntimeError("set_original_sun() must be called before deshadow()")
            if self._deshadowed is None:
                t0 = time.perf_counter()
                self._deshadowed = self._in_photo_colours(
                    deshadow(self.image_srgb, self.shadow_probability, self._lift_excluded,
                             marked=self._working_marks(), lifted=self.lifted_shadows()))
                self._time("deshadow", t0)
            return self._deshadowed

    def lifted_shadows(self) -> np.ndarray:
        """How much :meth:`deshadow` lifts each working-size pixel as shadow (``H x W``
        float32 in [0, 1]: :func:`~outcast_core.runtime.pipeline.photo_shadows.
        lift_probability` of :attr:`shadow_probability`), what the app shows as the photo's
        found shadows.

        Needs :meth:`set_original_sun`.
        """
        with self._lock:
            self._require_image()
            if self.shadow_probability is None:
                raise RuntimeError("set_original_sun() must be called before lifted_shadows()")
            if self._lifted is None:
                self._lifted = lift_probability(self.image_srgb, self.shadow_probability,
                                                self._lift_excluded,
                                                marked=self._working_marks())
            return self._lifted

    def _working_marks(self) -> np.ndarray | None:
        """:meth:`_deshadow_marks` at the working size, made with ``S_o`` (after
        :meth:`set_original_sun`)."""
        return self._lift_guards.get("marks")

    def _deshadow_marks(self, image: np.ndarray, probability: np.ndarray,
                        excluded: np.ndarray, sky: np.ndarray) -> np.ndarray | None:
        """What the de-shadow lifts as marked shadows, each to the lit surface round it (``H x W``
        float32 in [0, 1] at the size of ``sky``, or None: none): the user's "Mark shadow"
        (:meth:`_marked`) and the found shadows whose own lit ring says they are its shade
        (:func:`~outcast_core.runtime.pipeline.photo_shadows.found_shade_marks`, of ``probability``
        before the user's marks, so a brushed mark keeps its soft edge and a found shadow its whole
        extent), the larger per pixel. The relighting's lift takes them as shade, lifts them whole
        into its ceiling and lets the lift reach it there (:meth:`_lift_inputs`), the found ones on
        surfaces that face up (:func:`~outcast_core.runtime.pipeline.relight.facing_up`)."""
        return _with_user_marks(self._found_shade_marks(image, probability, excluded),
                                self._marked(sky))

    def _found_shade_marks(self, image: np.ndarray, unedited: np.ndarray, excluded: np.ndarray
                           ) -> np.ndarray:
        """:func:`~outcast_core.runtime.pipeline.photo_shadows.found_shade_marks` of the shadows
        as found (``unedited``), kept per size for this ``S_o`` while ``excluded`` is the same:
        a "Mark shadow" edit does not change them (25 ms at the working size, 0.14 s at the
        export's 1024 px, made again on every edit otherwise)."""
        key = tuple(unedited.shape[:2])
        kept = self._found_marks.get(key)
        if kept is None or not np.array_equal(kept[0], excluded):
            kept = (np.array(excluded, bool), found_shade_marks(image, unedited, excluded))
            self._found_marks[key] = kept
        return kept[1]

    def relight_fills(self, sky: np.ndarray | None = None) -> np.ndarray | None:
        """Where a relighting may have filled crushed shade rather than lifted it (``H x W``
        float32 in [0, 1] at the size of ``sky``, the working size without one; None: nowhere):
        the marked shadows its lift takes (the user's, and the found ones on surfaces facing
        up), off the sky. What goes to full size takes the working result there
        (:func:`~outcast_core.runtime.pipeline.photo_shadows.keep_fills`), not the photo's
        noise times the gain. Needs :meth:`set_original_sun`."""
        marks = self._lift_guards.get("lift_marks")  # once: a new S_o replaces the dict
        if marks is None:
            return None
        sky = self.sky if sky is None else sky
        if marks.shape != sky.shape:
            marks = np.clip(resize(marks, sky.shape), 0.0, 1.0)
        return np.where(sky, 0.0, marks).astype(np.float32)

    def lifted_shadows_full(self) -> np.ndarray:
        """How much :meth:`deshadow_full` lifts each pixel as shadow, at the photo's full size
        (``H x W`` float32 in [0, 1]): what ``outcast deshadow --mask`` writes, the quantity
        :meth:`lifted_shadows` gives at working size (what the app's "Shadows found" tints).

        :func:`~outcast_core.runtime.pipeline.photo_shadows.lift_probability` at
        :meth:`found_shadows_detail`'s size, where ``deshadow_full`` lifts the shadows
        (:meth:`lifted_shadows` for a photo found at the working size), upsampled bilinearly
        to the photo's size, as the lift's gain is. Needs :meth:`set_original_sun`.
        """
        d = self.found_shadows_detail()
        lifted = self._detail_lifted(d)
        full = self.full_image_srgb
        assert full is not None
        if lifted.shape != full.shape[:2]:
            lifted = resize(lifted, full.shape[:2])
        return np.clip(lifted, 0.0, 1.0).astype(np.float32)

    def _detail_lifted(self, d: dict[str, Any]) -> np.ndarray:
        """:func:`~outcast_core.runtime.pipeline.photo_shadows.lift_probability` of ``d``
        (:meth:`found_shadows_detail`'s arrays, as the caller holds them; :meth:`lifted_shadows`
        when found at the working size): made once per ``S_o`` for the full-size de-shadow and
        its mask. A ``d`` that another ``S_o`` has replaced meanwhile is lifted for the caller
        and not kept, so a lift never goes with another ``S_o``'s probability."""
        with self._lock:
            if d is not self._detail:
                return lift_probability(d["image"], d["probability"], d["excluded"],
                                        marked=d["marked"])
            if d["image"] is self.image_srgb:  # found at the working size: lifted there
                return self.lifted_shadows()
            if self._detail_lift is None:
                self._detail_lift = lift_probability(d["image"], d["probability"],
                                                     d["excluded"], marked=d["marked"])
            return self._detail_lift

    def marked_share(self, edits: Sequence[ShadowEdit] | None = None) -> float:
        """The share of the photo (its whole frame) that the user's "Mark shadow" regions
        cover at the working size (0 without one): the app says how much a click marked when
        it is much (a click on a shadow's soft edge filled a whole blue court, darker than
        the green round it, in a user trial). ``edits``: those corrections instead of
        :attr:`shadow_edits`, measured without being applied (0 before an original sun)."""
        with self._lock:
            if edits is None or tuple(edits) == self.shadow_edits:
                masks = self._edit_masks
            elif self._found is None or self.sky is None or self.image_srgb is None:
                return 0.0
            else:
                masks = (shadow_edit_masks(self._found[1], self.image_srgb, self.sky,
                                           tuple(edits)) if edits else None)
        if masks is None or not masks[0].any():
            return 0.0
        return float(np.mean(np.asarray(masks[0], np.float32) > 0.5))

    def _marked(self, sky: np.ndarray) -> np.ndarray | None:
        """How much the user's "Mark shadow" counts at each pixel (float32 in [0, 1],
        :func:`~outcast_core.runtime.pipeline.photo_shadows.marked_weight`: a stroke's edge
        soft) at the size of ``sky``, off it; None without such a mark."""
        masks = self._edit_masks  # once: another thread's _apply_found may reset it
        if masks is None or not masks[0].any():
            return None
        added = marked_weight(edit_masks_at(*masks, sky.shape)[0])
        return np.where(sky, 0.0, added).astype(np.float32)

    def found_shadows_detail(self) -> dict[str, np.ndarray]:
        """The photo's own shadows found at up to :data:`DETAIL_SIDE` pixels (the photo's
        size if smaller), for what leaves the app at full resolution (the de-shadowed photo,
        the exported shadow mask) and for ``outcast eval real``.

        With the photo refinement the photometric stage runs on the photo at that size, gated
        by the geometry's prior made at working size (:func:`~outcast_core.runtime.pipeline.
        photo_shadows.near_predicted_shadow`, upsampled: it is coarse by design), so shadow
        edges follow the photo's own rather than the working size's upsampled pixels. Other
        refinements upsample the working-size result.

        Returns:
            ``{"image", "sky", "probability", "original_shadow", "excluded", "marked"}`` at
            that size (``h x w x 3`` sRGB float32, ``h x w`` bool, ``h x w`` float32, ``h x w``
            float32, ``h x w`` bool: the sky and what the user marked "not a shadow", which the
            lift leaves out; ``h x w`` float32 in [0, 1] or None: what the de-shadow lifts as
            marked shadows, :meth:`_deshadow_marks`).
        """
        with self._lock:
            self._require_image()
            if self.shadow_probability is None or self.original_sun is None:
                raise RuntimeError("set_original_sun() must be called before "
                                   "found_shadows_detail()")
            if self._detail is not None:
                return self._detail
            t0 = time.perf_counter()
            full = self.full_image_srgb
            assert full is not None and self.normals is not None
            shape = working_shape(full.shape[0], full.shape[1],
                                  min(DETAIL_SIDE, max(full.shape[:2])))
            working = shape == self.image_srgb.shape[:2]
            if working:  # a photo no larger than the working size: already found there
                image, sky = self.image_srgb, self.sky
            else:
                image = resize_to_working(full, shape)
                sky = resize(self.sky.astype(np.uint8), shape, nearest=True) > 0
            assert self._lift_excluded is not None
            excluded = (self._lift_excluded if working else
                        resize(self._lift_excluded.astype(np.uint8), shape, nearest=True) > 0)
            assert self._found is not None
            unedited = self._found[1]  # what the found marks read (not the user's marks)
            if working or self.refinement != "photo" or self._original_geometry is None:
                prob = np.clip(resize(self.shadow_probability, shape), 0.0, 1.0)
                s_o = np.clip(resize(self.original_shadow, shape), 0.0, 1.0)
                if not working:
                    unedited = np.clip(resize(unedited, shape), 0.0, 1.0)
            else:
                if self._detail_found is None:  # once per S_o: the edits do not change it
                    cosine = np.clip(resize(cosine_term(self.normals, self.original_sun),
                                            shape), 0.0, 1.0)
                    gate = near_predicted_shadow(self._original_geometry, self.sky,
                                                 PRIOR_RADIUS)
                    if gate.shape != shape:
                        gate = np.clip(resize(gate, shape), 0.0, 1.0)
                    self._detail_found = (photo_shadow_probability(image, sky) * gate, cosine)
                prob, cosine = self._detail_found
                unedited = prob
                if self._edit_masks is not None:  # the regions the user marked, this size
                    prob, not_shadow = apply_edit_masks(prob, sky, *self._edit_masks)
                    excluded = sky | not_shadow
                s_o = original_shadow_from_photo(prob, cosine, sky)
            marked = (self._working_marks() if working
                      else self._deshadow_marks(image, unedited, excluded, sky))
            self._detail = {"image": image, "sky": sky, "probability": prob.astype(np.float32),
                            "original_shadow": s_o.astype(np.float32), "excluded": excluded,
                            "marked": marked}
            self._time("found_shadows_detail", t0)
            return self._detail

    def deshadow_full(self, *, dtype: type | np.dtype = np.float32) -> np.ndarray:
        """:meth:`deshadow` at the photo's full resolution: the shadows found and lifted at
        :meth:`found_shadows_detail`'s size, the lift then upsampled and applied to the
        full-resolution photo, so its own detail survives. ``dtype``: as
        :meth:`relight_full`'s (``np.uint8``: no full-size float buffer for an 8-bit photo;
        a user trial measured 2.1 GB for a 48-megapixel de-shadow against 0.79 GB for its
        relighting)."""
        d = self.found_shadows_detail()
        t0 = time.perf_counter()
        with self._lock:
            if d["image"] is self.image_srgb:  # found at the working size: lifted there already
                out = self.deshadow()
            else:
                out = self._in_photo_colours(
                    deshadow(d["image"], d["probability"], d["excluded"], marked=d["marked"],
                             lifted=self._detail_lifted(d)))
            full = transfer_to_full_resolution(self.full_image_srgb, d["image"], out,
                                               sky=d["sky"], fills=d["marked"],
                                               out_dtype=dtype)
        self._time("deshadow_full", t0)
        return full

    @property
    def light_estimate(self) -> LightEstimate | None:
        return self._light

    def _relight_light(self) -> LightEstimate | None:
        """The light a relighting takes: the measured one (:attr:`light_estimate`), in
        physics mode with :attr:`shade_colour` turned to the photo's own shade colour
        (:func:`~outcast_core.runtime.pipeline.relight.shade_coloured_light`); the learned
        relighting's guards give new shade that colour themselves (``shade_shift``)."""
        light = self._light
        if light is None or self.relight_mode == "learned" or not self.shade_colour:
            return light
        return shade_coloured_light(light, self._shade_shift)

    # ------------------------------------------------------------------ relighting
    def relight(self, w_new: Any, *, preview: bool = False,
                exposure: str | None = None) -> np.ndarray:
        """The photo relit under ``w_new`` at working resolution (``H x W x 3`` sRGB).

        ``preview=True`` is for dragging the new sun: the new shadow and the relighting run at
        the preset's ``relight_preview_size`` on inputs prepared once per photo and original sun,
        and the result is moved onto the working-size photo (sharp, but its shading coarser;
        quantised to 8 bits, as it is for the screen). ``exposure``: this call's (default
        :attr:`exposure`; the app passes the one the user saw when asking).
        """
        exposure = self._checked_exposure(exposure)
        with self._lock:  # the key too: a light or mode set meanwhile is not cached as this one
            key = (_key(w_new), preview, self.preset.name, exposure, self._daylight,
                   self._relight_mode)
            self._require_image()
            if self.original_sun is None or self.original_shadow is None:
                raise RuntimeError("set_original_sun() must be called before relight()")
            return self._relight_cache.get_or(
                key, lambda: self._compute_relight(w_new, preview, exposure))

    def _relight_preview_state(self) -> dict[str, Any]:
        """Everything the step-2 drag preview needs that the new sun does not change, at the
        preset's ``relight_preview_size``, as the networks take it (``1 x C x h x w``): the
        photo, ``S_o``, normals, view directions, depth, sky. Built once per photo, original
        sun and preset."""
        st = self._relight_preview
        if st is not None and st["original_shadow"] is self.original_shadow:
            return st
        assert self.image_srgb is not None and self.camera is not None
        assert self.original_shadow is not None and self.depth is not None
        h, w = working_shape(self.camera.height, self.camera.width,
                             self.preset.relight_preview_size)
        cam = self.camera.resized(h, w)
        depth = resize(np.where(self.sky, np.inf, self.depth).astype(np.float32), (h, w),
                       nearest=True)
        sky = resize(self.sky.astype(np.uint8), (h, w), nearest=True) > 0
        image = resize(self.image_srgb, (h, w))
        normals = normals_from_depth(depth, cam)
        view_dirs = view_directions(cam)
        s_o = np.clip(resize(self.original_shadow, (h, w)), 0.0, 1.0).astype(np.float32)
        assert self._original_geometry is not None
        geometry_o = np.clip(resize(self._original_geometry, (h, w)), 0.0, 1.0).astype(np.float32)

        def nchw(a: np.ndarray) -> np.ndarray:
            a = a[..., None] if a.ndim == 2 else a
            return np.ascontiguousarray(a.transpose(2, 0, 1)[None], dtype=np.float32)

        self._relight_preview = st = {
            "original_shadow": self.original_shadow,
            "camera": cam, "image": image, "sky": sky, "depth": depth, "normals": normals,
            "shadow_old": s_o, "geometry_old": geometry_o,
            "trust": (NormalTrust(s_o, normals, self.original_sun, sky, geometry_o,
                                  self.horizon_up()) if self.trust_normals else None),
            "sampler": RaySampler(depth, cam) if self.shadow_mode != "learned"
            else None,
            "edge_fill": DepthEdgeFill(depth, image) if self.shadow_mode == "learned" else None,
            # The working-size photo in 8 bits: the preview is moved onto it by tables only.
            "working_u8": np.rint(self.image_srgb * 255.0).astype(np.uint8),
            "view_dirs": view_dirs,
            "feeds_s": {"image": nchw(image), "depth": nchw(network_depth(depth)),
                        "normals": nchw(normals),
                        "focal": np.array([[cam.focal]], np.float32)},
            "feeds_l": {"image": nchw(image), "shadow_old": nchw(s_o),
                        "normals": nchw(normals),
                        "view_dirs": nchw(view_dirs),
                        "sun_old": self.original_sun.astype(np.float32)[None],
                        "light_ratio": self._light.ratio.astype(np.float32)[None]},
        }
        self.relight_preview_builds += 1
        return st

    def prepare_relight_preview(self) -> None:
        """Get the step-2 drag preview ready before the first drag: its light-independent
        inputs and its one-thread network sessions (the app calls this at "Confirm sun")."""
        with self._lock:
            self._require_image()
            if self.original_shadow is None:
                raise RuntimeError("set_original_sun() must be called before "
                                   "prepare_relight_preview()")
            st = self._relight_preview_state()
            self.horizon_up()  # not on the first drag frame
            if self.relight_mode == "learned" and (
                    self.lift_new_light and self.contrast_floor or self.keep_detail):
                shape = tuple(st["shadow_old"].shape)
                self._lift_inputs(shape)  # not on the first drag frame
                self._lift_guards.setdefault(("detail", shape), {})
            if self.shadow_mode == "learned":
                self.registry.load("shadow", threads=PREVIEW_THREADS)
            if self.relight_mode == "learned":
                self.registry.load("relight", threads=PREVIEW_THREADS)

    def _compute_relight_preview(self, wv: np.ndarray, exposure: str) -> np.ndarray:
        """The step-2 drag preview: only what the new sun changes (its shadow, the relighting
        network) runs, at ``relight_preview_size``; the gain it makes is moved onto the
        working-size photo (:func:`~outcast_core.runtime.geometry.fullres.apply_gain`)."""
        t0 = time.perf_counter()
        st = self._relight_preview_state()
        share = original_share(self.original_sun, wv)
        if share >= 1.0:  # the photo's own sun: the photo, nothing to compute
            return st["working_u8"].astype(np.float32) * np.float32(1.0 / 255.0)
        if self.shadow_mode == "learned":
            out = self.registry.load("shadow", threads=PREVIEW_THREADS).run({**st["feeds_s"],
                                                    "sun": wv.astype(np.float32)[None]})
            s_new = st["edge_fill"](np.clip(_first(out)[0, 0], 0.0, 1.0))
        else:
            step = self.preset.direct_step * 2.0
            s_new = direct_shadow(
                st["depth"], st["camera"], wv, normals=st["normals"], sky=st["sky"],
                steps=int(math.ceil(1.0 / step)), step=step, thickness=self.thickness,
                sampler=st["sampler"],
            )
        s_new = shadow_toward_original(s_new.astype(np.float32), st["shadow_old"],
                                       st["geometry_old"], share, st["trust"])
        t1 = time.perf_counter()
        self.timings["shadow_preview"] = t1 - t0
        image = st["image"]
        up = self.horizon_up()
        change = self._daylight_change(self._daylight, self.original_sun, wv, up)
        light = self._relight_light()
        mode = self._relight_mode  # (under the session's lock: relight())
        gain = self._daylight_gain(change, s_new, st["sky"], light, up, st["view_dirs"], mode)
        if mode == "learned":
            out = self.registry.load("relight", threads=PREVIEW_THREADS).run({
                **st["feeds_l"], "shadow_new": s_new[None, None],
                "sun_new": wv.astype(np.float32)[None],
            })
            relit = np.clip(_first(out)[0].transpose(1, 2, 0), 0.0, 1.0)
            relit = self._guard(image, relit, st["shadow_old"], s_new, st["sky"], light,
                                keep_old=share, daylight=gain)
        else:
            relit = physics_relight(image, st["shadow_old"], s_new, st["sky"],
                                    light=light, snap=False)
            relit = self._physics_fills(relit, s_new, st["sky"], light)
            if gain is not None:
                relit = in_new_daylight(relit, gain)
        relit = self._finish(image, relit, share, st["sky"], self.sun_seen, st["camera"], wv,
                             st["camera"].width / self.camera.width, exposure, self.greyscale,
                             self.original_sun, None if change is None else change.sun)
        # (with the sky: the skyline keeps each side's gain, as the full pass's does)
        out = transfer_to_full_resolution(st["working_u8"], image, relit, out_dtype=np.uint8,
                                          threads=1, fills=self.relight_fills(st["sky"]),
                                          sky=st["sky"])
        self._time("relight_preview", t1)
        return out.astype(np.float32) * np.float32(1.0 / 255.0)  # 8 bits: it is for the screen

    def _compute_relight(self, w_new: Any, preview: bool, exposure: str) -> np.ndarray:
        wv = normalize_sun(w_new)
        if preview:
            return self._compute_relight_preview(wv, exposure)
        s_new = self.shadow(wv)
        t0 = time.perf_counter()
        img = self._relight_from({**self._working_inputs(), "exposure": exposure}, wv, s_new)
        self._time("relight", t0)
        return img

    def _working_inputs(self) -> dict[str, Any]:
        """The working-size state a relighting reads (a snapshot: set_image and set_preset
        replace these arrays, they never change them in place)."""
        return {
            "image": self.image_srgb, "camera": self.camera, "sky": self.sky,
            "normals": self.normals, "view_dirs": self.view_dirs, "depth": self.depth,
            "sampler": self._sampler, "original_sun": self.original_sun,
            "original_shadow": self.original_shadow, "light": self._relight_light(),
            "original_geometry": self._original_geometry, "preset": self.preset,
            "sun_seen": self.sun_seen, "greyscale": self.greyscale, "exposure": self._exposure,
            "up": self.horizon_up(), "daylight": self._daylight,
            "relight_mode": self._relight_mode,
            "trust": self._normal_trust(),
            # (the learned shadow's fill at depth edges, built once: the stream's shadows
            # need it as :meth:`shadow`'s have it)
            "edge_fill": (self._working_edge_fill() if self.shadow_mode == "learned"
                          else None),
        }

    def _normal_trust(self) -> NormalTrust | None:
        """Where the photo contradicts the normals, at the working size (made once per found
        shadow; None before the original sun, or with :attr:`trust_normals` off)."""
        s_o, normals = self.original_shadow, self.normals
        if not self.trust_normals or s_o is None or normals is None or self.sky is None:
            return None
        if self._trust is None or self._trust[0] is not s_o or self._trust[1] is not normals:
            assert self.original_sun is not None
            self._trust = (s_o, normals, NormalTrust(s_o, normals, self.original_sun, self.sky,
                                                     self._original_geometry, self.horizon_up()))
        return self._trust[2]

    def _relight_from(
        self, inp: dict[str, Any], wv: np.ndarray, s_new: np.ndarray, threads: int | None = None
    ) -> np.ndarray:
        """The relighting of ``inp`` (:meth:`_working_inputs`) for sun ``wv`` with its shadow
        ``s_new`` (the geometry's), drawn toward the photo near its own sun
        (:func:`~outcast_core.runtime.pipeline.relight.original_share`)."""
        image, s_o, w_o = inp["image"], inp["original_shadow"], inp["original_sun"]
        share = original_share(w_o, wv)
        if share >= 1.0:  # the photo's own sun: the photo, no network runs
            return np.array(image, np.float32)
        s_new = shadow_toward_original(s_new, s_o, inp["original_geometry"], share,
                                       inp.get("trust"))
        change = self._daylight_change(inp["daylight"], w_o, wv, inp["up"])
        gain = self._daylight_gain(change, s_new, inp["sky"], inp["light"], inp["up"],
                                   inp["view_dirs"], inp["relight_mode"])
        if inp["relight_mode"] == "learned":
            model = self.registry.load("relight", threads=threads)
            out = model.run({
                "image": image.transpose(2, 0, 1)[None],
                "shadow_old": s_o[None, None],
                "shadow_new": s_new[None, None],
                "normals": inp["normals"].transpose(2, 0, 1)[None],
                "sun_old": w_o.astype(np.float32)[None],
                "sun_new": wv.astype(np.float32)[None],
                "view_dirs": inp["view_dirs"].transpose(2, 0, 1)[None],
                # Used by L with the physics base only (Model.run feeds a graph's own inputs).
                "light_ratio": inp["light"].ratio.astype(np.float32)[None],
            })
            img = np.clip(_first(out)[0].transpose(1, 2, 0), 0.0, 1.0)
            img = self._guard(image, img, s_o, s_new, inp["sky"], inp["light"], keep_old=share,
                              daylight=gain)
        else:
            img = physics_relight(image, s_o, s_new, inp["sky"], light=inp["light"], snap=False)
            img = self._physics_fills(img, s_new, inp["sky"], inp["light"])
            if gain is not None:
                img = in_new_daylight(img, gain)
        img = self._finish(image, img, share, inp["sky"], inp["sun_seen"], inp["camera"], wv,
                           1.0, inp["exposure"], inp["greyscale"], w_o,
                           None if change is None else change.sun)
        return img.astype(np.float32)

    def _finish(self, image: np.ndarray, relit: np.ndarray, share: float, sky: np.ndarray,
                seen: SunInPhoto | None, cam: Camera, w_new: np.ndarray, scale: float,
                exposure: str, greyscale: bool, w_old: np.ndarray | None = None,
                sun_colour: np.ndarray | None = None) -> np.ndarray:
        """What every relighting (the drag preview's and the working size's) ends with, in
        this order: drawn toward the photo near its own sun, the sun in the sky
        (:meth:`_sun_in_sky`, on the blend too), metered when asked, and black and white for
        such a photo."""
        relit = toward_photo(image, relit, share)
        relit = self._sun_in_sky(relit, sky, seen, cam, w_new, scale, w_old, share, sun_colour)
        if exposure == "metered":
            relit = meter_exposure(image, relit)
        return self._in_photo_colours(relit, greyscale)

    def _in_photo_colours(self, img: np.ndarray, greyscale: bool | None = None) -> np.ndarray:
        """``img`` made black and white when the photo is (:attr:`greyscale`, or the
        snapshot's ``greyscale``: a time-lapse's photo, whatever was set since)."""
        grey = self.greyscale if greyscale is None else greyscale
        return grey_like(img) if grey else img

    @staticmethod
    def _sun_to_draw(seen: SunInPhoto | None, cam: Camera, w_new: np.ndarray,
                     w_old: np.ndarray | None, share: float, sky_shape: tuple[int, int]
                     ) -> tuple[float, float, float, float] | None:
        """Where and how a new sun is drawn into an image of camera ``cam`` (:meth:`_sun_in_sky`):
        ``(u, v, strength, core_deg)``, or None when none is. A photo that shows its sun
        (``seen``) has it drawn at its own core's size, as a photo whose sun ``w_old`` stood
        outside the frame has it at :data:`~outcast_core.runtime.pipeline.relight.SUN_CORE_DEG`
        (none when the photo's sun stood in the frame unseen: behind something); faded in by
        ``1 - share`` near the photo's own sun, and with the share of its disc inside the
        frame as it enters it (the sky is the photo's until the sun enters it, and a sweep
        has no pop at the edge)."""
        core_deg = SUN_CORE_DEG
        if seen is not None:
            core_px = seen.core_radius(sky_shape)
            core_deg = math.degrees(math.atan(core_px / max(cam.focal, 1e-6)))
        elif w_old is None or sun_in_frame(w_old, cam):
            return None
        wn = normalize_sun(w_new)
        if wn[2] <= 0:
            return None
        u1, v1 = (float(c) for c in project(wn, cam))
        core = sun_core_px(cam.focal, core_deg)
        out = math.hypot(max(0.0, -u1, u1 - cam.width), max(0.0, -v1, v1 - cam.height))
        strength = (1.0 - share) * min(max(1.0 - out / max(core, 1.0), 0.0), 1.0)
        if strength <= 0.0:
            return None
        return u1, v1, strength, core_deg

    @classmethod
    def _sun_in_sky(cls, img: np.ndarray, sky: np.ndarray, seen: SunInPhoto | None,
                    cam: Camera, w_new: np.ndarray, scale: float,
                    w_old: np.ndarray | None = None, share: float = 0.0,
                    colour: np.ndarray | None = None) -> np.ndarray:
        """The sun in the relit sky (which is the photo's): the sun the photo shows leaves
        with the old sun, its glare moved to a new sun in the frame
        (:func:`~outcast_core.runtime.pipeline.relight.remove_sun_glare`), and a new sun is
        drawn where :meth:`_sun_to_draw` says (:func:`~outcast_core.runtime.pipeline.relight.
        add_sun`, in ``colour``), so near the photo's own sun the photo's glare alone moves.
        ``scale``: this image's size over the working size (the drag preview's is smaller)."""
        draw = cls._sun_to_draw(seen, cam, w_new, w_old, share, sky.shape)
        if seen is not None:
            to = None
            if draw is not None and sun_in_frame(w_new, cam):
                to = (draw[0], draw[1])
            img = remove_sun_glare(img, sky, seen.u * scale, seen.v * scale,
                                   seen.core_radius(sky.shape), to=to)
        if draw is None:
            return img
        u1, v1, strength, core_deg = draw
        return add_sun(img, sky, u1, v1, cam.focal, colour, strength=strength,
                       core_deg=core_deg)

    def _guard(
        self, image: np.ndarray, relit: np.ndarray, s_o: np.ndarray, s_new: np.ndarray,
        sky: np.ndarray, light: LightEstimate, keep_old: float = 0.0,
        daylight: np.ndarray | None = None,
    ) -> np.ndarray:
        """The learned relighting with the guards this session turns on
        (:func:`~outcast_core.runtime.pipeline.relight.guard_learned_relight`), with the
        photo's sky (in the new daylight): L's own sky is a flat pale wash on photos, and a sun
        in the frame is moved, taken out or drawn in by :meth:`_finish`."""
        lift = self.lift_new_light and self.contrast_floor
        # The detail's lifted texture is the lift's de-shadowed photo, lift or not; the
        # photo's bands are kept per size with the lift's inputs (per S_o).
        inputs = self._lift_inputs(s_o.shape) if lift or self.keep_detail else {}
        inputs.pop("physics_fill", None)  # physics mode's (_physics_fills)
        cache = self._lift_guards.setdefault(("detail", tuple(s_o.shape)), {})
        return guard_learned_relight(image, relit, s_o, s_new, sky, light, keep_sky=True,
                                     colour=self.colour_guard, floor=self.contrast_floor,
                                     anchor=self.exposure_anchor, detail=self.keep_detail,
                                     lift=lift, keep_old=keep_old, detail_cache=cache,
                                     physics_at=self._user_materials(s_o.shape),
                                     daylight=daylight,
                                     shade_shift=self._shade_shift if self.shade_colour
                                     else None,
                                     **inputs)

    def _physics_fills(self, relit: np.ndarray, s_new: np.ndarray, sky: np.ndarray,
                       light: LightEstimate) -> np.ndarray:
        """Physics relighting (``relit``, at the size of ``sky``) where a crushed shadow the
        user marked was filled (:meth:`_lift_inputs`' ``physics_fill``): the filled photo relit
        from the old sun's lit level, as the learned relighting's lift ceiling is. Physics
        multiplies the photo's noise there, so the marked shadow stayed black (a test wall:
        L* 11.7 against 68 round it, the learned relighting 64.7)."""
        if self._lift_guards.get("user") is None:
            return relit
        inputs = self._lift_inputs(tuple(relit.shape[:2]))
        if not inputs or inputs["physics_fill"] is None:
            return relit
        base, lit_old = inputs["lift_base"]
        cap = physics_relight(base, lit_old, s_new, sky, light=light, snap=False)
        k = inputs["physics_fill"][..., None]
        out = (1.0 - k) * srgb_to_linear(relit) + k * srgb_to_linear(cap)
        return linear_to_srgb(out).astype(np.float32)

    def _user_materials(self, shape: tuple[int, int]) -> np.ndarray | None:
        """What the user marked "not a shadow" (dark materials), softened by a working pixel,
        at ``shape`` (float32 in [0, 1]), where the learned relighting takes physics'
        (:func:`~outcast_core.runtime.pipeline.relight.guard_learned_relight`'s
        ``physics_at``); None without such a mark. Made once per set of corrections and
        size, and kept with the masks it was made from (another thread's ``_apply_found`` may
        publish new masks before the caches it resets)."""
        masks = self._edit_masks  # once: another thread's _apply_found may reset it
        if masks is None or not masks[1].any():
            return None
        key = ("materials", tuple(shape))
        kept = self._lift_guards.get(key)
        if kept is None or kept[0] is not masks:
            held = cv2.GaussianBlur(masks[1].astype(np.float32), (0, 0), 1.0)
            if held.shape != key[1]:
                held = np.clip(resize(held, key[1]), 0.0, 1.0)
            kept = (masks, held.astype(np.float32))
            self._lift_guards[key] = kept
        return kept[1]

    def _lift_inputs(self, shape: tuple[int, int]) -> dict[str, Any]:
        """:func:`guard_learned_relight`'s ``lift_guard``, ``lift_base`` and ``lift_colour`` at
        ``shape``: where the lift may act (:meth:`_lift_guard`), the photo de-shadowed with the
        clear-sky shade colour (:data:`~outcast_core.runtime.pipeline.relight.LIFT_SHADE_SHIFT`)
        with the lit level of the old sun, which physics relights into the lift's ceiling, and
        the lit surroundings' colour the lifted surface takes; its ``lift_fill``, where the
        lift may reach that ceiling (what the de-shadow filled, and the marked shadows:
        :meth:`_deshadow_marks`); and ``physics_fill``, what it filled alone (physics mode's,
        :meth:`_physics_fills`). Made once at working size per ``S_o``, resized per
        ``shape``."""
        guard = self._lift_guard(shape)
        if guard is None:
            return {}
        guards = self._lift_guards
        if "base" not in guards:
            assert self.original_sun is not None and self.normals is not None
            assert self.shadow_probability is not None
            # Unbounded: its fine band is the relit photo's texture where the new sun
            # lights the surface (photo_shadows.LIFT_ABOVE_LIT says what the bound cost there).
            # A marked shadow (the user's, or a found one its own lit ring says is shade, on
            # a surface facing up: relight.LIFT_MARK_FACING) is lifted whole, not only as far
            # as its found probability goes, and the lift may rise to this ceiling there
            # ("trust" below): its reference is the lit surface round it, where physics has
            # the photo's one sun/sky ratio.
            marks = guards.get("lift_marks")
            lifted = None
            if marks is not None:
                lifted = np.maximum(lift_probability(
                    self.image_srgb, self.shadow_probability, self._lift_excluded,
                    LIFT_SHADE_SHIFT, marks), marks)
            base = deshadow(self.image_srgb, self.shadow_probability, self._lift_excluded,
                            LIFT_SHADE_SHIFT, marked=marks, above_lit=None, lifted=lifted)
            lit_old = np.maximum(cosine_term(self.normals, self.original_sun), LIT_FLOOR)
            lit_old = np.where(self.sky, 0.0, lit_old)
            guards["colour"] = lit_surface_colour(self.image_srgb, self.shadow_probability,
                                                  self._lift_excluded, LIFT_COLOUR_SIGMA)
            # What the de-shadow filled of a crushed shadow the user marked (None elsewhere):
            # physics mode's (the found marks are filled in the ceiling too).
            fill, user = None, guards.get("user")
            if user is not None:
                fill = filled_share(self.image_srgb, base) * (user > 0)
                fill = np.where(fill > FILL_MIN, fill, 0.0).astype(np.float32)
                fill = fill if fill.any() else None
            guards["fill"] = fill
            guards["trust"] = (fill if marks is None else marks if fill is None
                               else np.maximum(fill, marks))
            # Last: a thread that finds "base" finds "colour", "fill" and "trust" too.
            guards["base"] = (base.astype(np.float32), lit_old.astype(np.float32))
        key = ("base", tuple(shape))
        if key not in guards:
            base, lit_old = guards["base"]
            colour, fill, trust = guards["colour"], guards["fill"], guards["trust"]
            if base.shape[:2] != tuple(shape):
                base = np.clip(resize(base, tuple(shape)), 0.0, 1.0)
                lit_old = np.clip(resize(lit_old, tuple(shape)), 0.0, 1.0)
                colour = resize(colour, tuple(shape))
                if fill is not None:
                    fill = np.clip(resize(fill, tuple(shape)), 0.0, 1.0)
                if trust is not None:
                    trust = np.clip(resize(trust, tuple(shape)), 0.0, 1.0)
            guards[key] = (base, lit_old, colour, fill, trust)
        base, lit_old, colour, fill, trust = guards[key]
        out = {"lift_guard": guard, "lift_base": (base, lit_old), "lift_colour": colour,
               "lift_fill": trust, "physics_fill": fill}
        if guard is not None:  # the geometry's cast shadows, where the lift may reach physics
            out["lift_ceiling"] = self._lift_ceiling(guard, tuple(shape))
        return out

    def _lift_ceiling(self, guard: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """The lift's guard times :meth:`_cast_at_photo_sun` at ``shape``, made once per
        ``S_o`` and size (every relighting and drag frame asks for it)."""
        key = ("ceiling", shape)
        guards = self._lift_guards
        if key not in guards:
            guards[key] = (guard * self._cast_at_photo_sun(shape)).astype(np.float32)
        return guards[key]

    def _cast_at_photo_sun(self, shape: tuple[int, int]) -> np.ndarray:
        """Where the geometry casts a shadow at the photo's sun on a surface facing it (``S``
        below :data:`~outcast_core.runtime.pipeline.photo_shadows.PRIOR_THRESHOLD`, cosine
        above 0), 0-1 at ``shape``: :func:`~outcast_core.runtime.pipeline.relight.
        shadow_contrast_floor`'s ``lift_ceiling`` with the lift's guard. Made once per ``S_o``
        and size."""
        guards = self._lift_guards
        key = ("cast", shape)
        if key not in guards:
            assert self.normals is not None and self.original_sun is not None
            cast = ((self._original_geometry < PRIOR_THRESHOLD)
                    & (cosine_term(self.normals, self.original_sun) > 0.0)).astype(np.float32)
            if cast.shape != shape:
                cast = np.clip(resize(cast, shape), 0.0, 1.0)
            guards[key] = cast
        return guards[key]

    def _lift_guard(self, shape: tuple[int, int]) -> np.ndarray | None:
        """Where a newly lit surface may be lifted to physics' brightness: the photo's found
        shadows that are shade, not dark material (:func:`~outcast_core.runtime.pipeline.
        photo_shadows.material_guard`), at ``shape`` (working size or the drag preview's).
        Made once per ``S_o`` and size; a worker thread that races another makes the same
        array."""
        guards = self._lift_guards
        if self.shadow_probability is None or guards.get("of") is not self.original_shadow:
            return None
        if "working" not in guards:
            guard = (material_guard(self.image_srgb, self.shadow_probability,
                                    self._lift_excluded, LIFT_SHADE_SHIFT)
                     * near_predicted_shadow(self._original_geometry, self.sky,
                                             LIFT_PRIOR_RADIUS))
            marked = guards.get("lift_marks")  # the user's word, or its own ring: shade
            if marked is not None:
                guard = (guard + marked * (1.0 - guard)).astype(np.float32)
            guards["working"] = guard
        key = tuple(shape)
        if key not in guards:
            g = guards["working"]
            guards[key] = g if g.shape == key else np.clip(resize(g, key), 0.0, 1.0)
        return guards[key]

    def _shadow_from(self, inp: dict[str, Any], wv: np.ndarray, threads: int | None) -> np.ndarray:
        """:meth:`shadow` (full quality, working size) of the snapshot ``inp``, for
        :meth:`relight_stream`'s shadow thread (no lock held, nothing cached)."""
        depth = np.where(inp["sky"], np.inf, inp["depth"]).astype(np.float32)
        if self.shadow_mode == "learned":
            cam = inp["camera"]
            out = self.registry.load("shadow", threads=threads).run({
                "image": inp["image"].transpose(2, 0, 1)[None],
                "depth": network_depth(depth)[None, None],
                "normals": inp["normals"].transpose(2, 0, 1)[None],
                "sun": wv.astype(np.float32)[None],
                "focal": np.array([[cam.focal]], np.float32),
            })
            out = inp["edge_fill"](np.clip(_first(out)[0, 0], 0.0, 1.0))
        else:
            step = inp["preset"].direct_step
            out = direct_shadow(
                depth, inp["camera"], wv, normals=inp["normals"], sky=inp["sky"],
                steps=int(math.ceil(1.0 / step)), step=step, thickness=self.thickness,
                sampler=inp["sampler"], stats=DirectStats(0, 0, ""),
            )
        return out.astype(np.float32)

    def relight_stream(self, suns: Any, exposure: str | None = None) -> Iterator[np.ndarray]:
        """:meth:`relight` for many suns in order (a time-lapse), two stages at once.

        The next sun's shadow is computed in a second thread while this sun's relighting
        runs, each network on one onnxruntime thread, so the two cores are both busy. Frames
        are the same as ``[relight(w) for w in suns]`` (tested); suns already cached are
        taken from the cache.

        Args:
            suns: ``N x 3`` sun directions (or a sequence of them).
            exposure: as :meth:`relight`'s (taken when the stream starts).

        Yields:
            ``H x W x 3`` float32 sRGB at working resolution, one per sun.
        """
        with self._lock:
            self._require_image()
            if self.original_sun is None or self.original_shadow is None:
                raise RuntimeError("set_original_sun() must be called before relight_stream()")
            inp = {**self._working_inputs(), "exposure": self._checked_exposure(exposure)}
            preset = self.preset.name
        suns = [normalize_sun(w) for w in suns]

        def cached(wv: np.ndarray) -> np.ndarray | None:
            with self._lock:
                return self._relight_cache.get((_key(wv), False, preset, inp["exposure"],
                                                inp["daylight"], inp["relight_mode"]))

        def shadow_of(wv: np.ndarray) -> np.ndarray | None:
            if cached(wv) is not None:
                return None
            with self._lock:
                hit = self._shadow_cache.get((_key(wv), False, preset))
            return hit if hit is not None else self._shadow_from(inp, wv, PREVIEW_THREADS)

        if not suns:
            return
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="outcast-shadow") as pool:
            pending = pool.submit(shadow_of, suns[0])
            for i, wv in enumerate(suns):
                s_new = pending.result()
                if i + 1 < len(suns):
                    pending = pool.submit(shadow_of, suns[i + 1])
                hit = cached(wv)
                if hit is not None:
                    yield hit
                    continue
                yield self._relight_from(inp, wv, s_new, PREVIEW_THREADS)

    def relight_full(self, w_new: Any, *, dtype: type | np.dtype = np.float32,
                     exposure: str | None = None) -> np.ndarray:
        """The photo relit under ``w_new`` at its full input resolution (detail transfer).

        Args:
            w_new: the new sun.
            dtype: ``np.float32`` (sRGB in [0, 1]) or ``np.uint8`` (for writing 8-bit files:
                with an 8-bit photo no full-size float buffer is made at all).
            exposure: as :meth:`relight`'s.
        """
        relit = self.relight(w_new, exposure=exposure)  # (not under the lock: the drag preview)
        t0 = time.perf_counter()
        with self._lock:
            out = transfer_to_full_resolution(self.full_image_srgb, self.image_srgb, relit,
                                              out_dtype=dtype, sky=self.sky,
                                              fills=self.relight_fills())
            out = self.without_old_sun_full(out, relit, w_new)
        self._time("full_resolution", t0)
        return out

    def without_old_sun_full(self, out: np.ndarray, relit: np.ndarray, w_new: Any
                             ) -> np.ndarray:
        """``out``, the working-size relighting ``relit`` for ``w_new`` moved to a larger size,
        with the photo's sun gone pixel by pixel when ``w_new`` takes it out of the frame
        (:func:`~outcast_core.runtime.pipeline.relight.glare_gone_full`: no halo of its glare
        round a bar or a branch against it). Unchanged at the photo's own sun (the relighting
        is the photo there), for a photo that shows no sun, and while the new sun is in the
        frame or entering it (:meth:`_sun_to_draw`): the clean-up takes whatever is brighter
        than the sky round the old sun, the new sun too when it stands near."""
        seen, wv = self.sun_seen, normalize_sun(w_new)
        if seen is None or self.original_sun is None:
            return out
        share = original_share(self.original_sun, wv)
        if (share >= 1.0 or sun_in_frame(wv, self.camera)
                or self._sun_to_draw(seen, self.camera, wv, self.original_sun, share,
                                     self.sky.shape) is not None):
            return out
        return glare_gone_full(out, relit, self.sky, seen.u, seen.v,
                               seen.core_radius(self.sky.shape))

    def buffers(self, w_new: Any) -> dict[str, np.ndarray]:
        """Display-ready intermediate buffers for the paper-style figure.

        Returns:
            ``depth`` (``H x W`` in [0, 1], near = bright, sky 0), ``normals`` (``H x W x 3`` in
            [0, 1]), ``original_shadow``, ``new_shadow`` (``H x W``), ``output`` (``H x W x 3``).
        """
        with self._lock:
            self._require_image()
            if self.original_shadow is None:
                raise RuntimeError("set_original_sun() must be called before buffers()")
            out = self.relight(w_new)
            return {
                "depth": depth_for_display(self.depth, self.sky),
                "normals": normals_for_display(self.normals),
                "original_shadow": self.original_shadow,
                "new_shadow": self.relit_shadow(w_new),
                "output": out,
            }


def _first(outputs: dict[str, np.ndarray]) -> np.ndarray:
    """A single-output model's result (ONNX output names may not repeat input names, so the
    refine and relight models call theirs ``shadow_out`` / ``image_out``)."""
    return next(iter(outputs.values()))


def depth_for_display(depth: np.ndarray, sky: np.ndarray) -> np.ndarray:
    """Inverse depth normalised to [0, 1] by robust percentiles (sky 0)."""
    ok = ~sky & np.isfinite(depth) & (depth > 0)
    out = np.zeros(depth.shape, np.float32)
    if ok.any():
        inv = 1.0 / depth[ok]
        lo, hi = np.percentile(inv, [1, 99])
        out[ok] = np.clip((inv - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    return out


def normals_for_display(normals: np.ndarray) -> np.ndarray:
    """Normals mapped to [0, 1] colours (x right = red, y up = green, toward camera = blue)."""
    n = normals * np.array([1.0, -1.0, -1.0], np.float32)
    valid = np.any(normals != 0, axis=-1, keepdims=True)
    return np.where(valid, n * 0.5 + 0.5, 0.0).astype(np.float32)


__all__ = [
    "PRESETS",
    "ModelError",
    "Preset",
    "RelightSession",
    "depth_for_display",
    "elongation_note",
    "check_given_depth",
    "ground_plane_depth",
    "normals_for_display",
    "working_shape",
]
