"""Qt-free state of the app: steps, suns, time-lapse settings, project files, recent files, timings.

Project files are JSON next to the photo (``photo.jpg`` -> ``photo.outcast.json``). They hold
the image path (relative to the project file when possible), what identifies the photo (its
pixel size and a fingerprint of its content, :class:`PhotoIdentity`: a project warns when the
photo at its path is another one), the depth source, the original and target suns, the preset,
view settings, the time-lapse settings, the exposure, the light (``daylight``: the new sun's
daylight, or false for step 2's "Keep the photo's light"; ``RelightSession.daylight``), the
relighting (``learned`` or ``physics``; ``RelightSession.relight_mode``) and the user's
corrections of the photo's found shadows (``shadow_edits``, the runtime's format:
:func:`~outcast_core.runtime.pipeline.photo_shadows.shadow_edits_to_json`).

Keys added since version 1 are read with their defaults when missing, so older projects open
as they were saved (the version stays 1: batch reads projects too).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any

from outcast_core.runtime.io.photo_identity import PhotoIdentity

if TYPE_CHECKING:

    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit

PROJECT_SUFFIX = ".outcast.json"
PROJECT_VERSION = 1
PRESET_NAMES = ("fast", "balanced", "accurate")
#: The step-2 views (:data:`app.panels.VIEW_CHOICES`; a test keeps them equal).
BUFFER_VIEWS = (
    "output", "shadows_removed", "shadows_found", "depth", "normals", "original_shadow",
    "new_shadow", "all",
)  # fmt: skip
MAX_PROJECT_BYTES = 1_000_000  # project files are a few kB
#: Time-lapse ranges: the dialog's spin boxes (a project outside them does not load).
MAX_TIMELAPSE_FRAMES = 2000
MIN_TIMELAPSE_FPS = 1.0
MAX_TIMELAPSE_FPS = 60.0
#: Easing names of :data:`outcast_core.runtime.pipeline.timelapse.EASINGS` (a test keeps them
#: equal).
EASING_NAMES = ("linear", "ease-in-out", "ease-in", "ease-out")
#: Frame sizes of :data:`outcast_core.runtime.pipeline.timelapse.FRAME_SIZES` (a test keeps them
#: equal).
FRAME_SIZE_NAMES = ("working", "720p", "1080p", "4k", "full")
#: Exposure modes of :data:`outcast_core.runtime.pipeline.relight.EXPOSURES` (a test keeps them
#: equal).
EXPOSURE_NAMES = ("photo", "metered")
#: Step 2's relighting modes (``RelightSession.relight_mode``'s, "auto" resolved).
RELIGHTINGS = ("learned", "physics")
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".heic", ".heif", ".webp", ".bmp")


class Step(Enum):
    """Where the user is in the workflow."""

    EMPTY = "empty"  # no photo
    ALIGN = "align"  # step 1: find the original sun
    RELIGHT = "relight"  # step 2: choose a new sun


@dataclass
class Sun:
    """A sun relative to the camera, in degrees."""

    azimuth: float
    elevation: float

    def __post_init__(self) -> None:
        for name in ("azimuth", "elevation"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not _finite(v):
                raise ValueError(f"expected a finite sun {name}, got {v!r}")
        if not -90.0 <= self.elevation <= 90.0:
            raise ValueError(f"expected an elevation in [-90, 90], got {self.elevation}")
        self.azimuth = float(self.azimuth) % 360.0
        self.elevation = float(self.elevation)

    def as_tuple(self) -> tuple[float, float]:
        return self.azimuth, self.elevation

    @classmethod
    def from_any(cls, value: Any) -> Sun | None:
        """From ``None``, a ``{"azimuth", "elevation"}`` dict or an ``(az, el)`` pair."""
        if value is None:
            return None
        if isinstance(value, dict):
            try:
                return cls(value["azimuth"], value["elevation"])
            except KeyError as exc:
                raise ValueError(f"expected a sun with azimuth and elevation, got {value}") from exc
        if isinstance(value, list | tuple) and len(value) == 2:
            return cls(value[0], value[1])
        raise ValueError(f"expected a sun as {{azimuth, elevation}}, got {value!r}")


@dataclass
class TimelapseSettings:
    """What the time-lapse dialog shows; stored in the project file."""

    kind: str = "sweep"  # "sweep" | "sun"
    sweep_from: Sun = field(default_factory=lambda: Sun(80.0, 15.0))
    sweep_to: Sun = field(default_factory=lambda: Sun(280.0, 50.0))
    way: str = "shorter"  # "shorter" | "longer": which way around the azimuth goes
    frames: int = 48
    easing: str = "ease-in-out"
    date: str = ""  # ISO date; empty: the photo's capture date or today
    latitude: float | None = None
    longitude: float | None = None
    heading: float | None = None
    start: str = ""  # HH:MM local; empty: sunrise
    end: str = ""  # HH:MM local; empty: sunset
    utc_offset: float | None = None
    fps: float = 12.0
    format: str = "mp4"
    full_resolution: bool = False  # read from older projects (size "full"); ``size`` wins
    size: str = "1080p"  # one of FRAME_SIZE_NAMES

    def validate(self) -> TimelapseSettings:
        """Check every field (type and range); ``ValueError`` naming the first bad one.

        Ranges are the time-lapse dialog's (frames 2..2000, fps 1..60, ...), so settings that
        pass open in the dialog as they are. ``heading`` is wrapped into ``[0, 360)``.
        """
        _choice(self.kind, ("sweep", "sun"), "timelapse.kind")
        for name in ("sweep_from", "sweep_to"):
            if not isinstance(getattr(self, name), Sun):
                raise ValueError(f"timelapse.{name}: expected a sun, got {getattr(self, name)!r}")
        _choice(self.way, ("shorter", "longer"), "timelapse.way")
        self.frames = _int_in(self.frames, 2, MAX_TIMELAPSE_FRAMES, "timelapse.frames")
        _choice(self.easing, EASING_NAMES, "timelapse.easing")
        _iso(self.date, dt.date.fromisoformat, "an ISO date YYYY-MM-DD", "timelapse.date")
        self.latitude = _number_in(self.latitude, -90.0, 90.0, "timelapse.latitude", True)
        self.longitude = _number_in(self.longitude, -180.0, 180.0, "timelapse.longitude", True)
        self.heading = _number_in(self.heading, -math.inf, math.inf, "timelapse.heading", True)
        if self.heading is not None:
            self.heading %= 360.0
        for name in ("start", "end"):
            _iso(getattr(self, name), dt.time.fromisoformat, "a time HH:MM", f"timelapse.{name}")
        self.utc_offset = _number_in(self.utc_offset, -14.0, 14.0, "timelapse.utc_offset", True)
        self.fps = _number_in(self.fps, MIN_TIMELAPSE_FPS, MAX_TIMELAPSE_FPS, "timelapse.fps")
        _choice(self.format, ("mp4", "gif", "webp", "png"), "timelapse.format")
        if not isinstance(self.full_resolution, bool):
            raise ValueError(
                f"timelapse.full_resolution: expected true or false, got {self.full_resolution!r}"
            )
        _choice(self.size, FRAME_SIZE_NAMES, "timelapse.size")
        return self

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["sweep_from"] = asdict(self.sweep_from)
        d["sweep_to"] = asdict(self.sweep_to)
        d["full_resolution"] = self.size == "full"  # for older versions of OutCast
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TimelapseSettings:
        if not isinstance(d, dict):
            raise ValueError(
                f"timelapse: expected the time-lapse settings as an object, got {type(d).__name__}"
            )
        known = {k: v for k, v in d.items() if k in cls.__dataclass_fields__}
        if "size" not in known and known.get("full_resolution") is True:  # an older project
            known["size"] = "full"
        for key in ("sweep_from", "sweep_to"):
            if key in known:
                known[key] = _named(Sun.from_any, known[key], f"timelapse.{key}")
                if known[key] is None:
                    raise ValueError(f"timelapse.{key}: expected a sun, got null")
        return cls(**known).validate()


@dataclass(frozen=True)
class RelitLook:
    """What a relighting takes from step 2 when it is asked for (a job runs with these, not
    with what is ticked by the time it runs): the exposure (:data:`EXPOSURE_NAMES`), the light
    (``daylight``: the new sun's, or the photo's kept) and the relighting
    (:data:`RELIGHTINGS`)."""

    exposure: str = "photo"
    daylight: bool = True
    relighting: str = "learned"

    def apply(self, session: Any) -> None:
        """Set the light and the relighting on ``session`` (in the worker: the setters wait
        for a relighting under way). The exposure is passed per call."""
        session.daylight = self.daylight
        session.relight_mode = self.relighting


@dataclass
class ProjectState:
    """Everything needed to reopen a session."""

    image_path: str = ""
    #: The photo's pixel size and fingerprint when the project was saved (None: a project saved
    #: before OutCast recorded them, or not known).
    photo: PhotoIdentity | None = None
    preset: str = "balanced"
    depth_source: str = ""  # e.g. "model:depth v1" or "direct"; informative
    depth_path: str = ""  # a depth map from elsewhere (phone, another estimator), if loaded
    original_sun: Sun | None = None
    #: Where step 1's dial stands (what a project saved before "Confirm sun" reopens with).
    align_sun: Sun | None = None
    #: Saved in step 1 while re-aligning a confirmed sun: ``original_sun`` is the one confirmed
    #: before (the new sun is kept when the sun is confirmed again), the dial at ``align_sun``.
    realigning: bool = False
    target_sun: Sun | None = None
    overlay_opacity: float = 0.6
    split: float = 0.5
    buffer_view: str = "output"
    timelapse: TimelapseSettings = field(default_factory=TimelapseSettings)
    #: The camera's compass heading typed in step 1 (degrees from true north); it replaces the
    #: one the photo's EXIF records, if any. None when not typed.
    heading: float | None = None
    #: How relit photos are exposed (:data:`EXPOSURE_NAMES`: the photo's, or metered again).
    exposure: str = "photo"
    #: Whether relit photos take the new sun's daylight (step 2's "Keep the photo's light"
    #: clear; ``RelightSession.daylight``); a project saved before the setting: on.
    daylight: bool = True
    #: Step 2's relighting (:data:`RELIGHTINGS`; ``RelightSession.relight_mode``); a project
    #: saved before the choice: learned, the default then as now (physics where ``L`` is
    #: missing, as then).
    relighting: str = "learned"
    #: The user's corrections of the photo's found shadows, in order (step 2's "Not a shadow"
    #: / "Mark shadow" clicks); ``()`` (and a project saved before them): none.
    shadow_edits: tuple[ShadowEdit, ...] = ()

    @property
    def step(self) -> Step:
        if not self.image_path:
            return Step.EMPTY
        return (Step.RELIGHT if self.original_sun is not None and not self.realigning
                else Step.ALIGN)

    def to_dict(self, relative_to: Path | None = None) -> dict[str, Any]:
        image = self.image_path
        if relative_to is not None and image:
            try:
                image = os.path.relpath(image, relative_to)
            except ValueError:  # another drive on Windows
                image = os.path.abspath(image)
        return {
            "outcast_project": PROJECT_VERSION,
            "image": image,
            "image_absolute": os.path.abspath(self.image_path) if self.image_path else "",
            "photo": self.photo.to_dict() if self.photo is not None else None,
            "preset": self.preset,
            "depth_source": self.depth_source,
            "depth_path": _relative(self.depth_path, relative_to),
            "original_sun": asdict(self.original_sun) if self.original_sun else None,
            "align_sun": asdict(self.align_sun) if self.align_sun else None,
            "realigning": self.realigning,
            "target_sun": asdict(self.target_sun) if self.target_sun else None,
            "overlay_opacity": self.overlay_opacity,
            "split": self.split,
            "buffer_view": self.buffer_view,
            "timelapse": self.timelapse.to_dict(),
            "heading": self.heading,
            "exposure": self.exposure,
            "daylight": self.daylight,
            "relighting": self.relighting,
            "shadow_edits": _shadow_edits_json(self.shadow_edits),
        }

    @classmethod
    def from_dict(cls, d: Any, base: Path | None = None) -> ProjectState:
        if not isinstance(d, dict) or "outcast_project" not in d:
            raise ValueError("expected an OutCast project (a JSON object with 'outcast_project')")
        if d["outcast_project"] != PROJECT_VERSION:
            raise ValueError(
                f"expected project version {PROJECT_VERSION}, got {d['outcast_project']!r}"
            )
        image = _text(d, "image")
        if image and base is not None and not os.path.isabs(image):
            image = str((base / image).resolve())
        image_absolute = _text(d, "image_absolute")
        if image and not os.path.exists(image) and image_absolute:
            image = image_absolute
        preset = d.get("preset", "balanced")
        if not isinstance(preset, str) or preset not in PRESET_NAMES:
            raise ValueError(f"preset: expected one of {PRESET_NAMES}, got {preset!r}")
        exposure = d.get("exposure", "photo")
        _choice(exposure, EXPOSURE_NAMES, "exposure")
        relighting = d.get("relighting", "learned")
        _choice(relighting, RELIGHTINGS, "relighting")
        view = d.get("buffer_view", "output")
        if not isinstance(view, str) or view not in BUFFER_VIEWS:
            raise ValueError(f"buffer_view: expected one of {BUFFER_VIEWS}, got {view!r}")
        return cls(
            image_path=image,
            photo=_named(PhotoIdentity.from_any, d.get("photo"), "photo"),
            preset=preset,
            depth_source=_text(d, "depth_source"),
            depth_path=_absolute(_text(d, "depth_path"), base),
            original_sun=_named(Sun.from_any, d.get("original_sun"), "original_sun"),
            align_sun=_named(Sun.from_any, d.get("align_sun"), "align_sun"),
            realigning=_flag(d.get("realigning", False), "realigning"),
            target_sun=_named(Sun.from_any, d.get("target_sun"), "target_sun"),
            overlay_opacity=_fraction(d.get("overlay_opacity", 0.6), "overlay_opacity"),
            split=_fraction(d.get("split", 0.5), "split"),
            buffer_view=view,
            timelapse=TimelapseSettings.from_dict(d.get("timelapse", {})),
            heading=_heading(d.get("heading")),
            exposure=exposure,
            daylight=_flag(d.get("daylight", True), "daylight"),
            relighting=relighting,
            shadow_edits=_shadow_edits(d.get("shadow_edits")),
        )


def _shadow_edits_json(edits: tuple[ShadowEdit, ...]) -> list[dict[str, Any]]:
    from outcast_core.runtime.pipeline.photo_shadows import shadow_edits_to_json

    return shadow_edits_to_json(edits)


def _shadow_edits(v: Any) -> tuple[ShadowEdit, ...]:
    """A project's shadow corrections (None or missing: none); ``ValueError`` naming the
    field for anything else than the runtime's list of ``{x, y, shadow}``."""
    from outcast_core.runtime.pipeline.photo_shadows import shadow_edits_from_json

    try:
        return shadow_edits_from_json(v)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"shadow_edits: {exc}") from None


def _flag(v: Any, name: str) -> bool:
    if not isinstance(v, bool):
        raise ValueError(f"{name}: expected true or false, got {v!r}")
    return v


def _heading(v: Any) -> float | None:
    """A project's typed compass heading: None, or degrees in [0, 360] (360 read as 0)."""
    if v is None:
        return None
    return float(_number_in(v, 0.0, 360.0, "heading")) % 360.0


def _relative(path: str, base: Path | None) -> str:
    if not path or base is None:
        return path
    try:
        return os.path.relpath(path, base)
    except ValueError:  # another drive on Windows
        return os.path.abspath(path)


def _absolute(path: str, base: Path | None) -> str:
    if path and base is not None and not os.path.isabs(path):
        return str((base / path).resolve())
    return path


def _fraction(v: Any, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
        raise ValueError(f"{name}: expected a number in [0, 1], got {v!r}")
    return float(v)


def _finite(v: int | float) -> bool:
    """``math.isfinite`` that says False (instead of raising) for ints too large for a float."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _text(d: dict[str, Any], key: str) -> str:
    """``d[key]`` as a string: absent or null is ``""``; anything but a string is an error."""
    v = d.get(key)
    if v is None:
        return ""
    if not isinstance(v, str):
        raise ValueError(f"{key}: expected a string, got {v!r}")
    return v


def _named(parse: Any, value: Any, name: str) -> Any:
    """``parse(value)`` with a ``ValueError`` message that starts with the field's name."""
    try:
        return parse(value)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{name}: {exc}") from exc


def _choice(v: Any, choices: tuple[str, ...], name: str) -> None:
    if not isinstance(v, str) or v not in choices:
        raise ValueError(f"{name}: expected one of {choices}, got {v!r}")


def _int_in(v: Any, lo: int, hi: int, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise ValueError(f"{name}: expected a whole number in [{lo}, {hi}], got {v!r}")
    return v


def _number_in(v: Any, lo: float, hi: float, name: str, optional: bool = False) -> Any:
    """A finite number in ``[lo, hi]`` as a float (``None`` passes when ``optional``)."""
    if v is None and optional:
        return None
    ok = not isinstance(v, bool) and isinstance(v, int | float) and _finite(v)
    if not ok or not lo <= v <= hi:
        where = "a finite number" if math.isinf(lo) else f"a number in [{lo:g}, {hi:g}]"
        raise ValueError(f"{name}: expected {where}, got {v!r}")
    return float(v)


def _iso(v: Any, parse: Any, what: str, name: str) -> None:
    """An empty string, or a string ``parse`` (``date``/``time.fromisoformat``) accepts."""
    if not isinstance(v, str):
        raise ValueError(f"{name}: expected {what} as a string, got {v!r}")
    if v:
        try:
            parse(v)
        except ValueError as exc:
            raise ValueError(f"{name}: expected {what}, got {v!r}") from exc


def with_filter_extension(path: str, name_filter: str, accepted: Iterable[str]) -> str:
    """``path`` as a save dialog returned it, with the chosen file type's extension (the first
    of ``name_filter``, as ``"PNG image (*.png)"``) added unless its own is one of ``accepted``
    (lower case, with the dot): a user trial's "mine" was refused as a name without an
    extension, and "v1.2" or "mine." would have been too. A filter without an extension (a
    folder's ``(*)``) leaves the name as it is.

    Example:
        >>> with_filter_extension("/p/mine", "JPEG image (*.jpg *.jpeg)", {".jpg", ".png"})
        '/p/mine.jpg'
        >>> with_filter_extension("/p/v1.2", "PNG image (*.png)", {".png", ".tif"})
        '/p/v1.2.png'
        >>> with_filter_extension("/p/mine.", "PNG image (*.png)", {".png"})
        '/p/mine.png'
        >>> with_filter_extension("/p/MINE.TIF", "PNG image (*.png)", {".png", ".tif"})
        '/p/MINE.TIF'
        >>> with_filter_extension("/p/frames", "Folder name (*)", ())
        '/p/frames'
    """
    inside = name_filter[name_filter.find("(") + 1:name_filter.rfind(")")]
    ext = next((p[1:] for p in inside.split() if p.startswith("*.") and len(p) > 2), "")
    if not ext:
        return path
    if os.path.basename(path).endswith("."):
        path = path[:-1]
    if os.path.splitext(os.path.basename(path))[1].lower() in set(accepted):
        return path
    return path + ext


def project_path_for(image_path: str | os.PathLike[str]) -> Path:
    """The project file next to a photo: ``dir/photo.jpg`` -> ``dir/photo.outcast.json``."""
    p = Path(image_path)
    return p.with_name(p.stem + PROJECT_SUFFIX)


def is_project_file(path: str | os.PathLike[str]) -> bool:
    return str(path).lower().endswith(PROJECT_SUFFIX)


def save_project(state: ProjectState, path: str | os.PathLike[str]) -> Path:
    """Write a project file atomically (temp file, then rename), with the umask's permissions."""
    from outcast_core.runtime.io.imageio import atomic_output

    path = Path(path)
    data = state.to_dict(relative_to=path.parent)
    with atomic_output(path, force=True) as tmp:
        tmp.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return path


def load_project(path: str | os.PathLike[str]) -> ProjectState:
    """Read a project file; ``ValueError`` when it is not a valid OutCast project."""
    path = Path(path)
    if path.is_file() and path.stat().st_size > MAX_PROJECT_BYTES:
        raise ValueError(
            f"expected a project file under {MAX_PROJECT_BYTES // 1_000_000} MB, "
            f"got {path.stat().st_size} bytes in '{path}'"
        )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"expected a JSON project file, got invalid JSON: {exc}") from exc
    except RecursionError as exc:
        raise ValueError("expected a JSON project file, got JSON nested too deeply") from exc
    try:
        return ProjectState.from_dict(data, base=path.parent)
    except ValueError as exc:
        raise ValueError(f"invalid project '{path.name}': {exc}") from exc


class RecentFiles:
    """Most-recent-first list of paths without duplicates."""

    def __init__(self, paths: list[str] | None = None, limit: int = 8):
        self.limit = limit
        self._paths: list[str] = []
        for p in reversed(paths or []):
            self.add(p)

    def add(self, path: str) -> None:
        path = os.path.abspath(path)
        if path in self._paths:
            self._paths.remove(path)
        self._paths.insert(0, path)
        del self._paths[self.limit :]

    def remove(self, path: str) -> None:
        path = os.path.abspath(path)
        if path in self._paths:
            self._paths.remove(path)

    def paths(self) -> list[str]:
        return list(self._paths)


@dataclass
class StageTimings:
    """Seconds per stage of the last run, in the order stages were first seen."""

    seconds: dict[str, float] = field(default_factory=dict)

    def update(self, timings: dict[str, float]) -> None:
        for k, v in timings.items():
            if isinstance(v, int | float) and math.isfinite(v):
                self.seconds[k] = float(v)

    def summary(self, limit: int = 6) -> str:
        """``"depth 0.41 s · shadow 0.05 s"``; milliseconds under 0.1 s."""
        parts = []
        for k, v in list(self.seconds.items())[-limit:]:
            parts.append(f"{k} {v * 1000:.0f} ms" if v < 0.1 else f"{k} {v:.2f} s")
        return " · ".join(parts)
