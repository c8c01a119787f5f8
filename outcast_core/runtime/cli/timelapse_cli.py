"""``outcast timelapse``: relight a photo along a sun path from the command line.

The lead's ``outcast_core.runtime.cli.main`` calls :func:`register` with its sub-parser set; the
handler is :func:`run_timelapse_command` (set as ``args.func``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from outcast_core.runtime.cli.main import (
    ProgressLine,
    add_exposure_option,
    add_input_options,
    add_light_option,
    add_shadow_edit_options,
    int_in,
    say_unused_shadow_edits,
    sun_pair,
)
from outcast_core.runtime.geometry.camera import sun_vector
from outcast_core.runtime.pipeline.timelapse import (
    DEFAULT_FPS,
    DEFAULT_FRAME_SIZE,
    EASINGS,
    FRAME_FILE,
    FRAME_SIZES,
    GIF_LEAST_MS,
    MAX_FPS,
    MIN_FPS,
    MIN_RENDER_ELEVATION,
    SHORT_SIDES,
    SunBelowHorizonError,
    SunSample,
    default_utc_offset,
    format_from_path,
    frame_shape,
    frames_folder_problem,
    photo_utc_offset,
    real_sun_path,
    render_timelapse,
    solve_heading,
    sun_vectors,
    sweep_path,
)

# --------------------------------------------------------------------------------------------


#: Most frames a time-lapse renders (the app's dialog offers the same).
MAX_FRAMES = 2000


def _angles(text: str) -> tuple[float, float]:
    """``AZ,EL`` in degrees: a finite azimuth and an elevation in [-90, 90] (below the horizon
    too: a point of a sun path)."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected AZ,EL in degrees (e.g. 135,40), got {text!r}")
    try:
        az, el = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected AZ,EL in degrees (e.g. 135,40), got {text!r}") from None
    if not (math.isfinite(az) and math.isfinite(el)) or not -90.0 <= el <= 90.0:
        raise argparse.ArgumentTypeError(
            f"expected AZ,EL with a finite azimuth and an elevation in [-90, 90], got {text!r}"
        )
    return az, el


def sweep_ends(text: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """An argparse type for ``--sweep AZ1,EL1:AZ2,EL2`` (``outcast batch`` takes the same).

    An end may be below the horizon (elevation down to -90): a sweep is a sun path, and the
    frames where it dips below the horizon render with the sun at the horizon
    (:data:`~outcast_core.runtime.pipeline.timelapse.MIN_RENDER_ELEVATION`), like a real day's
    sunrise and sunset. Only a still's sun (:func:`~outcast_core.runtime.cli.main.sun_pair`)
    must be at or above it.
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected AZ1,EL1:AZ2,EL2, got {text!r}")
    return _angles(parts[0]), _angles(parts[1])


#: ``--sweep``'s help: the azimuths' rule and an end below the horizon.
SWEEP_HELP = ("the azimuth runs between the numbers as typed: 90,30:270,30 passes behind the "
              "camera (180), 90,30:-90,30 in front (0); an end may be below the horizon "
              f"(those frames render with the sun just above it, at {MIN_RENDER_ELEVATION:g} "
              "deg)")


def sweep_turn_note(ends: tuple[tuple[float, float], tuple[float, float]]) -> str:
    """What to say of a ``--sweep`` that turns the long way round (more than 180 and less
    than 360 degrees of azimuth, as typed), or "": a user trial's 320,15:30,15 went round
    behind the camera where the short way, in front, was meant. A turn of 360 degrees or
    more is taken as meant. The other way keeps the start as typed and is written
    ``--sweep=...``, which the parser takes even when it starts with a minus (a review:
    ``--sweep -40,15:30,15`` is read as an option).

    Example:
        >>> note = sweep_turn_note(((320.0, 15.0), (30.0, 15.0)))
        >>> note.startswith("the sweep turns 290° of azimuth as typed, through 175° (behind")
        True
        >>> note.endswith("--sweep=320,15:390,15 turns the other way, 70°")
        True
        >>> sweep_turn_note(((30.0, 15.0), (320.0, 15.0))).endswith("--sweep=30,15:-40,15 "
        ...                                                       "turns the other way, 70°")
        True
        >>> sweep_turn_note(((-40.0, 15.0), (30.0, 15.0))), sweep_turn_note(((0, 30), (360, 30)))
        ('', '')
    """
    (az0, el0), (az1, el1) = ends
    turn = abs(az1 - az0)
    if not 180.0 < turn < 360.0:
        return ""
    middle = ((az0 + az1) / 2.0) % 360.0
    where = "behind the camera" if 90.0 < middle < 270.0 else "in front of the camera"
    other = az1 + 360.0 if az1 < az0 else az1 - 360.0
    return (f"the sweep turns {turn:.0f}° of azimuth as typed, through {middle:.0f}° ({where}); "
            f"--sweep={az0:g},{el0:g}:{other:g},{el1:g} turns the other way, "
            f"{360.0 - turn:.0f}°")


def _number(lo: float, hi: float, what: str) -> Callable[[str], float]:
    """An argparse type: a finite number in ``[lo, hi]``."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"expected {what} in [{lo:g}, {hi:g}], got {text!r}")
        return value

    return parse


#: ``--fps``: what the video writers take (``outcast batch`` takes the same).
fps_value = _number(MIN_FPS, MAX_FPS, "frames per second")

#: ``--frames``: an integer in [2, MAX_FRAMES] (``outcast batch`` takes the same).
frame_count = int_in(2, MAX_FRAMES, "frame count")


def _date(text: str) -> dt.date:
    """``YYYY-MM-DD``; a day the month does not have is named as such (2018-02-30 was told
    "expected YYYY-MM-DD", which it is: a user trial)."""
    text = text.strip()
    try:
        return dt.date.fromisoformat(text)
    except ValueError as exc:
        import re

        if re.fullmatch(r"\d{4}-\d{2}-\d{2}", text):
            raise argparse.ArgumentTypeError(f"no such day: {text!r} ({exc})") from None
        raise argparse.ArgumentTypeError(f"expected YYYY-MM-DD, got {text!r}") from None


def _hhmm(text: str) -> dt.time:
    try:
        return dt.time.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HH:MM, got {text!r}") from None


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``outcast timelapse`` to an argparse sub-parser set; the handler is ``args.func(args)``.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers()``.

    Returns:
        The ``timelapse`` parser.
    """
    p = subparsers.add_parser(
        "timelapse",
        help="relight a photo along a sun path and write a video",
        description=(
            "Relight IMAGE along a sun sweep or the real sun path of a day and write MP4, GIF, "
            "WebP or a PNG folder. Angles are relative to the camera: azimuth 0 = straight ahead, "
            "90 = right; elevation 0 = horizon."
        ),
    )
    p.add_argument("image", metavar="IMAGE", help="the photo")
    p.add_argument(
        "--from",
        dest="from_sun",
        type=sun_pair,
        default=None,
        metavar="AZ,EL",
        help="the photo's original sun (aligned in the app; default: the sun in the photo, "
             "else its EXIF sun from GPS, time and compass heading, as relight takes it)",
    )
    p.add_argument("--sweep", type=sweep_ends, metavar="AZ1,EL1:AZ2,EL2",
                   help=f"sweep the sun A -> B; {SWEEP_HELP}")
    p.add_argument("--frames", type=frame_count, default=None,
                   help=f"frame count, 2..{MAX_FRAMES} (--sweep: required; --date: default 48)")
    p.add_argument("--easing", choices=EASINGS, default=None,
                   help="the sweep's pace (--sweep only; default ease-in-out)")
    p.add_argument("--date", type=_date, metavar="YYYY-MM-DD", help="real sun path of this day")
    p.add_argument("--lat", type=_number(-90.0, 90.0, "a latitude"),
                   help="latitude (default: EXIF GPS)")
    p.add_argument("--lon", type=_number(-180.0, 180.0, "a longitude"),
                   help="longitude (default: EXIF GPS)")
    p.add_argument(
        "--heading",
        type=_number(-360.0, 360.0, "a heading"),
        help="camera compass heading, deg from true north (default: solved from the --from sun "
             "and the photo's EXIF capture time and GPS)",
    )
    p.add_argument("--start", type=_hhmm, metavar="HH:MM", help="local start time (sunrise)")
    p.add_argument("--end", type=_hhmm, metavar="HH:MM", help="local end time (sunset)")
    p.add_argument(
        "--utc-offset",
        type=_number(-14.0, 14.0, "a UTC offset (hours)"),
        default=None,
        help="local time's offset from UTC in hours, for --start, --end and a capture time "
             "without a zone (default: the photo's own, from its EXIF; else from the "
             "longitude)",
    )
    p.add_argument(
        "-o", "--output", required=True, metavar="OUT", help="OUT.mp4, .gif, .webp or a folder"
    )
    p.add_argument("--fps", type=fps_value, default=DEFAULT_FPS,
                   help=f"{MIN_FPS:g}..{MAX_FPS:g} (default {DEFAULT_FPS:g})")
    p.add_argument(
        "--size", choices=FRAME_SIZES, default=None,
        help="frame size: the preset's working size (fastest), 720p / 1080p / 4k (shorter side "
             "720 / 1080 / 2160 px, never above the photo's) or the photo's full size "
             f"(default {DEFAULT_FRAME_SIZE})",
    )  # fmt: skip
    p.add_argument("--full-res", action="store_true", help="the same as --size full")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="print only warnings and errors (no estimate, progress or summary)")
    # Depth from a file, a model or the photo itself, the field of view and the preset, as
    # the other commands take them (a time-lapse's frames match a relit still).
    add_input_options(p)
    add_exposure_option(p)
    add_light_option(p)
    add_shadow_edit_options(p)
    p.set_defaults(func=run_timelapse_command, check_output=check_timelapse_output)
    return p


#: The options of a real day's sun path (``--date``), refused with ``--sweep``.
_DAY_ONLY = ("lat", "lon", "heading", "start", "end", "utc_offset")


def _check_sample_args(args: argparse.Namespace, exif: Any) -> None:
    """The sun path's arguments, checked before any work (ValueError naming what is missing)."""
    if (args.sweep is None) == (args.date is None):
        raise ValueError("expected exactly one of --sweep or --date")
    # An option of the other path is refused, not ignored (a user trial's sweep took --heading,
    # --lat and --start without a word; a day took --easing).
    other = ([f"--{name.replace('_', '-')}" for name in _DAY_ONLY
              if getattr(args, name, None) is not None] if args.sweep is not None
             else ["--easing"] if getattr(args, "easing", None) is not None else [])
    if other:
        path = "--date (a real day's sun path)" if args.sweep is not None else "--sweep"
        raise ValueError(f"{', '.join(other)} {'applies' if len(other) == 1 else 'apply'} to "
                         f"{path} only; remove {'it' if len(other) == 1 else 'them'}")
    if args.sweep is not None:
        if args.frames is None:
            raise ValueError("expected --frames N with --sweep")
        return
    start, end = getattr(args, "start", None), getattr(args, "end", None)
    # (said after the depth and the heading until a user trial; an offset typed with a time,
    # 06:00+02:00, is not the one the path takes: compared as the clock times they are)
    if start is not None and end is not None and end.replace(tzinfo=None) <= start.replace(
            tzinfo=None):
        raise ValueError(f"expected the end time after the start time, got {start:%H:%M} -> "
                         f"{end:%H:%M}")
    if _place(args, exif) is None:
        raise ValueError("expected --lat and --lon (the photo has no GPS position)")
    if args.heading is None and getattr(exif, "capture_time", None) is None:
        raise ValueError("expected --heading (the photo has no capture time to solve it from)")


def _place(args: argparse.Namespace, exif: Any) -> tuple[float, float] | None:
    lat = args.lat if args.lat is not None else getattr(exif, "latitude", None)
    lon = args.lon if args.lon is not None else getattr(exif, "longitude", None)
    return None if lat is None or lon is None else (lat, lon)


def local_zone(args: argparse.Namespace, exif: Any, longitude: float) -> tuple[float, str]:
    """The UTC offset (hours) at which ``--start``, ``--end`` and a capture time without a
    zone are read, and where it comes from: ``--utc-offset``; else a zone typed with
    ``--start``/``--end`` (``06:00+02:00``); else the photo's own (EXIF ``OffsetTime`` or its
    GPS stamp) unless ``--lon`` names a place more than 7.5 degrees from the photo's; else the
    zone of the longitude. The app's dialog takes the photo's the same way; the command took
    the longitude's, an hour off in summer time (a user trial's evening 20:00-20:50 at the
    field-path sample, UTC+2, was refused as after sunset).

    Raises:
        ValueError: ``--start`` and ``--end`` typed with different zones, or with one that
            ``--utc-offset`` contradicts.
    """
    typed = {t.utcoffset() for t in (args.start, args.end)
             if t is not None and t.utcoffset() is not None}
    if len(typed) > 1:
        raise ValueError("expected --start and --end in one time zone, got two: give them "
                         "without zones and the zone with --utc-offset")
    if typed:
        hours = next(iter(typed)).total_seconds() / 3600.0
        if args.utc_offset is not None and abs(args.utc_offset - hours) > 1e-9:
            raise ValueError(f"expected --utc-offset to agree with the zone typed with the "
                             f"times ({zone_words(hours)}), got {args.utc_offset:g}")
        return hours, "the zone typed with the times"
    if args.utc_offset is not None:
        return float(args.utc_offset), "--utc-offset"
    own, own_lon = photo_utc_offset(exif), getattr(exif, "longitude", None)
    if own is not None and (args.lon is None or own_lon is None
                            or abs((args.lon - own_lon + 180.0) % 360.0 - 180.0) <= 7.5):
        return own, "the photo's EXIF"
    if args.lon is None:
        return default_utc_offset(longitude), "its longitude (the photo gives none)"
    return default_utc_offset(longitude), "the longitude of --lon"


def zone_words(hours: float) -> str:
    """``UTC+02:00``, ``UTC-03:30``."""
    minutes = round(hours * 60)
    sign = "-" if minutes < 0 else "+"
    return f"UTC{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"


#: A compass heading in the photo's EXIF further than this (degrees) from the one solved from
#: the aligned sun is said, with how to take it instead.
HEADING_DISAGREES = 30.0


def _samples_from_args(
    args: argparse.Namespace, exif: Any, tilt: Callable[[], tuple[float, float, str]] | None = None
) -> list[SunSample]:
    """The sun path; ``tilt`` gives the camera's ``(pitch, roll, source)`` for the real sun's
    (:func:`~outcast_core.runtime.pipeline.auto_sun.camera_tilt`; level when None)."""
    _check_sample_args(args, exif)
    if args.sweep is not None:
        return sweep_path(args.sweep[0], args.sweep[1], args.frames,
                          args.easing or "ease-in-out")
    lat, lon = _place(args, exif)  # type: ignore[misc]
    from outcast_core.runtime.pipeline.auto_sun import describe_tilt

    pitch, roll, source = tilt() if tilt is not None else (0.0, 0.0, "level")
    words = describe_tilt(pitch, roll, source)
    quiet = getattr(args, "quiet", False)
    if words and not quiet:
        print(f"{words}: the real sun is turned into its frame", file=sys.stderr)
    offset, zone_from = local_zone(args, exif, lon)
    zone = f"{zone_words(offset)}, from {zone_from}"
    heading = args.heading
    if heading is None:
        when = exif.capture_time
        place = ("the photo's time and GPS" if args.lat is None and args.lon is None
                 else "the photo's time at the given --lat/--lon")
        read_at = "" if when.tzinfo is not None else f"; its time read at {zone}"
        guessed = when.tzinfo is None and args.utc_offset is None
        try:
            heading = solve_heading(when, lat, lon, args.from_sun[0], offset,
                                    original_elevation=args.from_sun[1], tilt=(pitch, roll))
            said = f"camera heading solved from the aligned sun and {place}: {heading:.1f} deg"
            said += read_at
            compass = getattr(exif, "heading_deg", None)
            if compass is not None:
                off = abs((compass - heading + 180.0) % 360.0 - 180.0)
                if off > HEADING_DISAGREES:  # (silently dropped: a user trial)
                    if getattr(exif, "heading_ref", None) == "M":  # (not a true heading)
                        said += (f"\nnote: the photo's EXIF compass heading is {compass:.1f} "
                                 f"deg from magnetic north, {off:.0f} deg from it (check the "
                                 "--from sun; --heading takes a true heading)")
                    else:
                        said += (f"\nnote: the photo's EXIF compass heading is {compass:.1f} "
                                 f"deg, {off:.0f} deg from it (check the --from sun; "
                                 f"--heading {compass:.1f} takes the compass's)")
        except SunBelowHorizonError as exc:  # a night-time EXIF clock: the compass, else ask
            heading = getattr(exif, "heading_deg", None)
            if heading is None:
                hint = " (or --utc-offset H: the zone is a guess)" if guessed else ""
                raise ValueError(f"{exc}{read_at}: give --heading DEG{hint}") from None
            said = f"{exc}{read_at}; the EXIF compass heading is taken: {heading:.1f} deg"
        if not quiet:
            print(said, file=sys.stderr)
    frames = 48 if args.frames is None else args.frames
    samples = real_sun_path(args.date, lat, lon, heading, frames, args.start, args.end,
                            offset, (pitch, roll))
    # (a few frames may all sit at sunrise and sunset: the window is probed finely)
    probe = samples if frames >= 49 else real_sun_path(
        args.date, lat, lon, heading, 49, args.start, args.end, offset, (pitch, roll))
    first, last = samples[0].time, samples[-1].time
    span = f" from {first:%H:%M} to {last:%H:%M}" if first and last else ""
    if all(s.elevation <= 0.0 for s in probe):  # every frame the same sun on the horizon
        raise ValueError(f"the sun is below the horizon for the whole time-lapse{span} "
                         f"on {args.date} ({zone}): choose daytime --start and --end")
    if not quiet:  # (the zone was not said: a user trial could not see it was an hour off)
        print(f"the sun of {args.date}{span} local time ({zone})", file=sys.stderr)
    return samples


def dark_frames_note(session: Any, samples: list[SunSample]) -> str:
    """What to say before rendering when the lowest sun's frame comes out dark with the photo's
    exposure kept (a day's first and last frames near black: a user trial): its level as a
    camera's meter reads it (:func:`~outcast_core.runtime.pipeline.relight.exposure_level`,
    working size), below the app's hint (:data:`~outcast_core.runtime.pipeline.relight.
    EXPOSURE_HINT_FACTOR` times darker); ``""`` when it is not, or the exposure is metered."""
    from outcast_core.runtime.pipeline.relight import EXPOSURE_HINT_FACTOR, exposure_level

    if session.exposure != "photo" or not samples:
        return ""
    low = min(samples, key=lambda s: s.elevation)
    level = exposure_level(session.image_srgb, session.relight(sun_vectors([low])[0]))
    if level * EXPOSURE_HINT_FACTOR > 1.0:
        return ""
    where = ("at the horizon" if low.elevation < 1.0 else
             f"at elevation {low.elevation:.0f} deg")  # (rendered no lower than the horizon)
    return (f"the lowest sun's frames ({where}) come out {1.0 / max(level, 1e-6):.1f}x darker "
            "than the photo, its exposure kept; --exposure metered meters each frame as a "
            "camera would")


def check_timelapse_output(args: argparse.Namespace) -> None:
    """Check ``-o`` before any work: a known extension (or none: PNG folder), not the photo,
    not an existing file without ``--force``, a folder that can be written; a PNG folder that
    exists must be empty or hold only an earlier sequence (:func:`frames_folder_problem`)."""
    from outcast_core.runtime.cli.main import CliError, check_output_path

    if (args.sweep is None) == (args.date is None):  # what is missing before what exists
        raise ValueError("expected exactly one of --sweep or --date")
    fmt = format_from_path(args.output)  # ValueError for out.avi
    force = args.force
    if fmt == "png":
        problem = frames_folder_problem(Path(args.output).expanduser())
        if problem:
            raise CliError(f"cannot write '{args.output}': {problem}")
        out = Path(args.output).expanduser()
        # A folder without frames (empty, or a file manager's files only) is a new one.
        force = force or (out.is_dir() and not any(FRAME_FILE.fullmatch(p.name)
                                                   for p in out.iterdir()))
    check_output_path(args.output, extensions=None, force=force, inputs=[args.image],
                      folder_ok=fmt == "png")


def run_timelapse_command(args: argparse.Namespace) -> int:
    """Handler of ``outcast timelapse``; returns the process exit code."""
    from outcast_core.runtime.cli.main import _load
    from outcast_core.runtime.pipeline.session import RelightSession

    check_timelapse_output(args)  # before the slow part
    loaded = _load(args.image, keep_uint8=True)  # 8-bit photos stay 8-bit (no float copy)
    exif = getattr(loaded, "exif", None)
    _check_sample_args(args, exif)  # before the slow part
    session = RelightSession(preset=args.preset)
    session.exposure = args.exposure
    session.daylight = not args.keep_light
    quiet = getattr(args, "quiet", False)
    # A line rewritten on a terminal; separate lines, a tenth of a stage apart, in a log.
    report = ProgressLine(quiet=quiet)
    try:
        return _run_timelapse(args, loaded, exif, session, report)
    finally:
        report.end_line()  # an error is not printed on the end of a progress line


def _run_timelapse(args: argparse.Namespace, loaded: Any, exif: Any, session: Any,
                   report: ProgressLine) -> int:
    from outcast_core.runtime.cli.main import _original_sun, _set_image

    quiet = report.quiet
    _set_image(session, loaded, args, progress=report)
    if args.from_sun is None:  # as relight and deshadow take it (a user trial asked why not)
        from outcast_core.runtime.geometry.camera import sun_angles

        report.end_line()
        az, el = sun_angles(_original_sun(args, session, loaded, None))
        args.from_sun = (az % 360.0, el)

    # The photo's tilt (set_image's photo_path) places the day's suns and is the daylight's
    # horizon, for a sweep too.
    samples = _samples_from_args(args, exif, session.photo_tilt)
    session.set_shadow_edits(args.shadow_edits)
    session.set_original_sun(sun_vector(*args.from_sun))
    corrections = say_unused_shadow_edits(session, args)  # (notes as relight and deshadow)
    size = args.size or ("full" if args.full_res else DEFAULT_FRAME_SIZE)
    if args.full_res and size != "full":
        raise ValueError(f"expected either --full-res or --size, got --full-res --size {size}")
    work = session.image_srgb.shape[:2]
    shape = frame_shape(size, session.full_image_srgb.shape[:2], work)
    odd = format_from_path(args.output) == "mp4" and (shape[0] % 2 or shape[1] % 2)
    padded = (f", written as {shape[1] + shape[1] % 2}x{shape[0] + shape[0] % 2} (H.264 needs "
              "even sides: the edge is repeated)" if odd else "")
    if not quiet:
        # No guess up front: a formula from the session's last stages was 4x off (the app
        # times a short export instead); the progress says the time left at the frames' pace.
        full = session.full_image_srgb.shape[:2]
        # A video size beyond the photo gives the photo's own size ("(4k)" beside a 2016-px
        # frame misled a user trial).
        label = (f"the photo's own size: {size} is larger"
                 if size in SHORT_SIDES and tuple(shape) == tuple(full)
                 and SHORT_SIDES[size] > min(full) else size)
        print(f"rendering {len(samples)} frames of {shape[1]}x{shape[0]} ({label}){padded}",
              file=sys.stderr)
    if not quiet and format_from_path(args.output) == "gif" and args.fps > 1000.0 / GIF_LEAST_MS:
        # (browsers play a GIF's shorter delays at 10 fps: a review)
        print(f"note: a GIF plays at most {1000.0 / GIF_LEAST_MS:g} fps: its frames are "
              f"written {GIF_LEAST_MS} ms apart (MP4 or WebP keep {args.fps:g} fps)",
              file=sys.stderr)
    if not quiet:
        dim = dark_frames_note(session, samples)
        if dim:
            print(f"note: {dim}", file=sys.stderr)
        turn = sweep_turn_note(args.sweep) if args.sweep is not None else ""
        if turn:
            print(f"note: {turn}", file=sys.stderr)
    render_timelapse(
        session,
        samples,
        args.output,
        fps=args.fps,
        size=size,
        force=args.force,
        progress=report,
    )
    report.end_line()
    if not quiet:
        counted = f" ({corrections.removesuffix('; ')})" if corrections else ""
        # The output as given, as relight and deshadow say it (a frames folder came back
        # absolute, a video relative: a user trial).
        print(f"wrote {len(samples)} frames to {args.output}{counted}", file=sys.stderr)
    return 0
