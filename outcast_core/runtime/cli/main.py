"""The ``outcast`` command line.

Runtime commands (``shadow``, ``relight``, ``deshadow``, ``depth``, ``sun``, ``timelapse``,
``batch``, ``models``, ``eval real``) import only the runtime.
Commands of the training side (``data``, ``train``, ``export``, ``eval``) are registered from their
packages only when those import (they need torch / mitsuba, installed with ``.[dev]``).
Errors exit with status 2 and one readable line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import re
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np

from outcast_core.runtime.geometry.camera import normalize_sun, sun_vector

#: Optional command groups: (module, function adding sub-commands). Missing ones are skipped.
OPTIONAL_COMMANDS: list[tuple[str, str]] = [
    ("outcast_core.runtime.cli.timelapse_cli", "register"),
    ("outcast_core.runtime.cli.real_eval_cli", "register"),
    ("outcast_core.runtime.cli.auto_sun_cli", "register"),
    ("outcast_core.runtime.cli.models_cli", "register"),
    ("outcast_core.runtime.cli.batch_cli", "register"),
    ("outcast_core.data.cli", "register"),
    ("outcast_core.train.cli", "register"),
    ("outcast_core.export.cli", "register"),
    ("outcast_core.eval.cli", "register"),
]

#: Every runtime command's ``--preset`` default (its working resolution and march length).
DEFAULT_CLI_PRESET = "balanced"


#: Most Direct march steps ``--steps`` accepts (4 steps per pixel at the accurate preset's
#: 512 px; 100 000 steps took a minute).
MAX_DIRECT_STEPS = 2048


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM handler so every ``finally`` and context manager cleans up."""


#: A sun below the horizon lights nothing directly; OutCast renders sunlight and its cast
#: shadows, not twilight, so ``--sun``, ``--from`` and ``--to`` refuse it (time-lapse paths that
#: dip below the horizon render those frames with the sun at the horizon instead).
BELOW_HORIZON = (
    "expected a sun at or above the horizon (elevation 0 to 90), got {text!r}: OutCast renders "
    "sunlight and cast shadows, not twilight; use elevation 0 for the lowest sun"
)


def sun_pair(text: str) -> tuple[float, float]:
    """The argparse type of every command's still sun (``--from``, ``--to``, ``--sun``):
    ``(az, el)`` by :func:`azel_angles`, so that a bad value is refused naming its flag, by one
    rule in every command."""
    try:
        return azel_angles(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def sun_dir_option(text: str) -> np.ndarray:
    """``--sun-dir``'s argparse type: :func:`parse_vector`, refused naming the flag."""
    try:
        return parse_vector(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def azel_angles(text: str) -> tuple[float, float]:
    """``"AZ,EL"`` in degrees -> ``(az, el)``: a finite azimuth (any: 400 is 40) and an
    elevation from 0 to 90 (a sun below the horizon is refused); ValueError otherwise."""
    parts = text.split(",")
    if len(parts) != 2:
        raise ValueError(f"expected AZ,EL in degrees (e.g. 135,40), got {text!r}")
    try:
        az, el = (float(p) for p in parts)
    except ValueError as exc:
        raise ValueError(f"expected AZ,EL in degrees (e.g. 135,40), got {text!r}") from exc
    if math.isfinite(az) and math.isfinite(el) and el < 0.0:
        raise ValueError(BELOW_HORIZON.format(text=text))
    if not (math.isfinite(az) and math.isfinite(el)) or el > 90.0:
        raise ValueError(f"expected AZ,EL with a finite azimuth and an elevation from 0 (the "
                         f"horizon) to 90 (overhead), got {text!r}")
    return az, el


def parse_vector(text: str) -> np.ndarray:
    """``"X,Y,Z"`` -> normalised camera-space sun vector."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"expected X,Y,Z (camera space, toward the sun), got {text!r}")
    try:
        v = [float(p) for p in parts]
    except ValueError as exc:
        raise ValueError(f"expected X,Y,Z (camera space, toward the sun), got {text!r}") from exc
    w = normalize_sun(v)
    if w[1] > 0.0:  # y points down: below the (camera's) horizon, refused as --sun's is
        raise ValueError(f"expected a sun at or above the horizon (Y <= 0: y points down), got "
                         f"{text!r}: OutCast renders sunlight and the shadows it casts, not "
                         "twilight")
    return w


def _sun_from_args(args: argparse.Namespace) -> np.ndarray:
    if args.sun is not None:
        return sun_vector(*args.sun)
    return args.sun_dir


def _load(path: str, max_pixels: int | None = None, **kw):  # -> LoadedImage
    from outcast_core.runtime.io.imageio import read_image

    loaded = read_image(path, max_pixels=max_pixels, **kw)
    if loaded.has_alpha:  # said even with -q: the output differs from the input there
        print(f"outcast: note: '{path}' has transparency; it is filled with white and the "
              "output has none", file=sys.stderr)
    return loaded


def _make_session(args: argparse.Namespace, *, shadow_mode: str, relight_mode: str = "auto"):
    from outcast_core.runtime.pipeline.session import RelightSession

    thickness = getattr(args, "thickness", math.inf)
    session = RelightSession(
        preset=args.preset, shadow_mode=shadow_mode, relight_mode=relight_mode,
        thickness=thickness, refine=getattr(args, "refine", "photo"),
    )
    session.exposure = getattr(args, "exposure", "photo")
    session.daylight = not getattr(args, "keep_light", False)
    return session


#: ``--exposure``'s choices: :data:`outcast_core.runtime.pipeline.relight.EXPOSURES` (a test
#: keeps them equal; that module is not imported for ``--help``).
EXPOSURE_CHOICES = ("photo", "metered")


def add_exposure_option(p: argparse.ArgumentParser, help_text: str = "",
                        default: str | None = "photo") -> None:
    """``--exposure``: the relit photo keeps the photo's exposure, or is metered again."""
    p.add_argument("--exposure", choices=EXPOSURE_CHOICES, default=default,
                   help=help_text or "keep the photo's exposure (default: a scene the new sun "
                   "puts in shade comes out dark), or meter the new light again as a camera would")


def add_light_option(p: argparse.ArgumentParser, help_text: str = "",
                     overrides: bool = False) -> None:
    """``--keep-light``: the photo's light kept instead of the new sun's daylight
    (``RelightSession.daylight``). ``overrides``: also ``--no-keep-light``, and None when
    neither is given (a setting that otherwise comes from elsewhere: ``batch``'s projects)."""
    help_text = help_text or ("keep the photo's light, its strength and colour, whatever the "
                              "new sun's height (default: the new sun's daylight: near the "
                              "horizon the sunlight is weaker and redder and the sky dimmer)")
    if overrides:
        p.add_argument("--keep-light", action=argparse.BooleanOptionalAction, default=None,
                       help=help_text)
    else:
        p.add_argument("--keep-light", action="store_true", help=help_text)


def parse_point(text: str) -> tuple[float, float]:
    """``"X,Y"``: a point as fractions (0-1) of the upright photo's width and height, from its
    top left."""
    parts = text.split(",")
    try:
        x, y = (float(v) for v in parts)
    except ValueError:
        x = y = math.nan
    if len(parts) != 2 or not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0):
        raise ValueError(f"expected X,Y as fractions 0-1 of the photo's width and height from "
                         f"its top left (e.g. 0.3,0.6), got {text!r}")
    return x, y


def parse_shadow_edit(text: str, shadow: bool):
    """``"X,Y"`` (a click) or ``"X,Y,R"`` (a brush dab of radius R, a fraction of the photo's
    longer side): a :class:`~outcast_core.runtime.pipeline.photo_shadows.ShadowEdit`.

    Raises:
        ValueError: not two or three numbers, the point outside the photo or R not above 0
            and at most :data:`~outcast_core.runtime.pipeline.photo_shadows.MAX_BRUSH_RADIUS`
            (the app's largest brush). ``R = 0`` is refused, not taken for a click: the note
            that one changed nothing would name it ``X,Y``.

    Example:
        >>> parse_shadow_edit("0.3,0.6,0.02", shadow=False)
        ShadowEdit(x=0.3, y=0.6, shadow=False, radius=0.02)
        >>> parse_shadow_edit("0.3", shadow=False)
        Traceback (most recent call last):
        ...
        ValueError: expected X,Y (a click) or X,Y,R (a brush dab) with X,Y fractions 0-1 of \
the photo's width and height from its top left (e.g. 0.3,0.6 or 0.3,0.6,0.02), got '0.3'
    """
    from outcast_core.runtime.pipeline.photo_shadows import MAX_BRUSH_RADIUS, ShadowEdit

    parts = text.split(",")
    if len(parts) not in (2, 3):
        raise ValueError(f"expected X,Y (a click) or X,Y,R (a brush dab) with X,Y fractions "
                         f"0-1 of the photo's width and height from its top left (e.g. "
                         f"0.3,0.6 or 0.3,0.6,0.02), got {text!r}")
    if len(parts) == 2:
        return ShadowEdit(*parse_point(text), shadow=shadow)
    try:
        x, y = parse_point(",".join(parts[:2]))
    except ValueError:
        raise ValueError(f"expected X,Y,R with X,Y fractions 0-1 of the photo's width and "
                         f"height from its top left (e.g. 0.3,0.6,0.02), got {text!r}") from None
    try:
        r = float(parts[2])
    except ValueError:
        r = math.nan
    if r == 0.0:
        raise ValueError(f"expected X,Y,R with the brush radius R above 0 (omit R for a "
                         f"click: X,Y), got {text!r}")
    if not (math.isfinite(r) and 0.0 < r <= MAX_BRUSH_RADIUS):
        raise ValueError(f"expected X,Y,R with the brush radius R a fraction 0-"
                         f"{MAX_BRUSH_RADIUS} of the photo's longer side (e.g. 0.3,0.6,0.02), "
                         f"got {text!r}")
    return ShadowEdit(x, y, shadow=shadow, radius=r)


class _ShadowEditAction(argparse.Action):
    """``--shadow`` / ``--not-shadow X,Y[,R]``: one edit each, kept in command-line order."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from outcast_core.runtime.pipeline.photo_shadows import shadow_edit_limit

        try:
            edit = parse_shadow_edit(str(values), shadow=self.const)
        except ValueError as exc:
            raise argparse.ArgumentError(self, str(exc)) from None
        edits = list(getattr(namespace, "shadow_edits", None) or [])
        edits.append(edit)
        if limit := shadow_edit_limit(edits):  # --shadow and --not-shadow together
            raise argparse.ArgumentError(self, f"expected {limit}, counting --shadow and "
                                               f"--not-shadow together; got more")
        namespace.shadow_edits = edits


def add_shadow_edit_options(p: argparse.ArgumentParser) -> None:
    """``--not-shadow`` / ``--shadow X,Y[,R]``: correct the photo's found shadows, as the
    app's "Not a shadow" and "Mark shadow" clicks and brush dabs do (applied in order)."""
    from outcast_core.runtime.pipeline.photo_shadows import (
        MAX_BRUSH_RADIUS,
        MAX_SHADOW_CLICKS,
        MAX_SHADOW_EDITS,
    )

    p.set_defaults(shadow_edits=[])
    p.add_argument("--not-shadow", action=_ShadowEditAction, const=False, metavar="X,Y[,R]",
                   help="the found shadow at this point is not one (a dark object, foliage): "
                   "X,Y as fractions 0-1 of the photo's width and height from its top left; "
                   f"with R (a fraction of the longer side, above 0, at most "
                   f"{MAX_BRUSH_RADIUS}: the app's largest brush), a brush dab: all within R "
                   f"of the point, where it holds a found shadow; repeatable (at most "
                   f"{MAX_SHADOW_CLICKS} clicks and {MAX_SHADOW_EDITS} in all, with --shadow)")
    p.add_argument("--shadow", action=_ShadowEditAction, const=True, metavar="X,Y[,R]",
                   help="a shadow the app did not find: the region of even brightness round "
                   "this point; with R, a brush dab: the shadow within R (a run of dabs, each "
                   "within R of the one before, is a stroke: only its darker pixels are "
                   "added, and nothing on lit ground); repeatable")


def say_unused_shadow_edits(session, args: argparse.Namespace) -> str:
    """After the original sun is set: a note for each click (``--shadow`` / ``--not-shadow``)
    and each stroke (dabs ``X,Y,R`` as :func:`~outcast_core.runtime.pipeline.photo_shadows.
    shadow_edit_strokes` groups them) that changed nothing, and the words for the "wrote" line
    (``""`` without corrections): the clicks and strokes that changed something, counted as
    the app counts them."""
    from outcast_core.runtime.pipeline.photo_shadows import shadow_edit_strokes

    edits = getattr(args, "shadow_edits", None) or []
    used = session.shadow_edits_used
    if not edits or len(used) != len(edits):
        return ""
    n = 0
    for start, stop in shadow_edit_strokes(edits, session.image_srgb.shape[:2]):
        if any(used[start:stop]):
            n += 1
            continue
        edit = edits[start]
        flag = "--shadow" if edit.shadow else "--not-shadow"
        why = ("the sky, lit ground (not darker than round it) or a shadow already"
               if edit.shadow else "no found shadow there, or one already dropped")
        if edit.radius > 0:
            why = ("no shadow under the stroke: the sky, lit ground or painted already"
                   if edit.shadow else "no found shadow within R, or dropped already")
        point = f"{edit.x:g},{edit.y:g}" + (f",{edit.radius:g}" if edit.radius > 0 else "")
        if stop - start > 1:
            point += f" and the {stop - start - 1} dabs after it (a stroke)"
        _say(args, f"note: {flag} {point} changed nothing ({why})")
    return f"{n} shadow correction{'s' if n != 1 else ''}; "


def _set_depth_source(session, loaded, args: argparse.Namespace) -> None:
    """Give the session ``--depth-model``, else the photo's own depth map (unless
    ``--no-phone-depth``); a broken embedded map is said in one line and the depth model used."""
    if getattr(args, "depth", None):
        return  # a depth file replaces every estimate
    from outcast_core.runtime.io.depth_models import pick_depth_source

    width, height = loaded.original_size
    provider, note = pick_depth_source(
        loaded.path, (height, width), model_path=getattr(args, "depth_model", None),
        use_phone=not getattr(args, "no_phone_depth", False), photo_srgb=loaded.image_srgb,
    )
    if note:
        _say(args, f"note: {note}; using the depth model")
    session.depth_provider = provider


def _set_image(session, loaded, args: argparse.Namespace, progress=None, *,
               small_note: bool = True) -> None:
    """Give ``session`` the photo and the depth the options ask for, then warn of what may
    make the output meaningless; ``small_note``: whether a photo too small to relight is
    said (``outcast sun`` says in its own words that its shadows are too small to read)."""
    depth = None
    if getattr(args, "depth", None):
        from outcast_core.runtime.io.imageio import read_depth

        depth = read_depth(args.depth)
    _set_depth_source(session, loaded, args)
    focal35 = None if args.fov is not None else loaded.exif.focal_35mm
    session.set_image(loaded.image_srgb, fov_deg=args.fov, focal_35mm=focal35, depth=depth,
                      progress=progress, photo_path=getattr(args, "image", None))
    getattr(progress, "end_line", lambda: None)()  # (the warnings below on their own lines)
    from outcast_core.runtime.pipeline.batch import photo_warnings

    # Said even with -q: the output is made, and may be meaningless (the transparency was
    # said as the photo was read).
    for note in photo_warnings(loaded, session, transparency=False, small=small_note):
        print(f"outcast: warning: {note}", file=sys.stderr)


#: :class:`ProgressLine` says the time left once a stage has run this long (seconds).
ETA_AFTER_S = 3.0


class ProgressLine:
    """A ``(stage, fraction)`` progress callback that prints to stderr (nothing when
    ``quiet``), with the time left at the stage's pace so far once it has run
    :data:`ETA_AFTER_S` seconds.

    On a terminal, one line rewritten in place with ``\r``. Anywhere else (a log file, a pipe)
    ``\r`` runs every update into one line (a user trial's log), so each stage gets separate
    lines: its first update, then one each time it passes another ``step`` (a tenth by
    default), and its end: at most a dozen lines a stage.

    Call :meth:`end_line` before printing anything else: it ends a line left open on a
    terminal (and does nothing otherwise).

    Example:
        >>> import io
        >>> log = io.StringIO()
        >>> progress = ProgressLine(log)
        >>> for i in range(1, 101):
        ...     progress("frames", i / 100)
        >>> log.getvalue().splitlines()[:3], len(log.getvalue().splitlines())
        (['frames:   1 %', 'frames:  10 %', 'frames:  20 %'], 11)
    """

    def __init__(self, stream: object = None, *, quiet: bool = False, step: float = 0.1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.stream = stream
        self.quiet = quiet
        self.step = step
        self.clock = clock
        self._stage: str | None = None
        self._mark = -1
        self._width = 0  # of the line open on a terminal (0: none)
        self._began: tuple[str, float, float] | None = None  # stage, time, fraction at start
        self._last = 0.0  # the last fraction seen

    def _out(self):  # sys.stderr when called, as print's default (pytest swaps it)
        return self.stream if self.stream is not None else sys.stderr

    def _tty(self) -> bool:
        isatty = getattr(self._out(), "isatty", None)
        try:
            return bool(isatty and isatty())
        except (OSError, ValueError):
            return False

    def __call__(self, stage: str, fraction: float) -> None:
        if self.quiet:
            return
        fraction = min(1.0, max(0.0, float(fraction)))
        out = self._out()
        if stage == self._stage and fraction < self._last:
            self._mark = -1  # the stage started over: its lines too
        left = self._time_left(stage, fraction)
        if self._tty():
            text = f"{stage}: {100.0 * fraction:5.1f} %{left}"
            print("\r" + text.ljust(self._width), end="", file=out, flush=True)
            self._width = len(text)
            return
        mark = math.floor(fraction / self.step + 1e-9) if self.step > 0 else 0
        if stage == self._stage and mark <= self._mark:
            return
        self._stage, self._mark = stage, mark
        print(f"{stage}: {100.0 * fraction:3.0f} %{left}", file=out, flush=True)

    def _time_left(self, stage: str, fraction: float) -> str:
        """``", about 40 s left"`` from the stage's own pace so far, once it has run
        :data:`ETA_AFTER_S` seconds (before that, and at its end, nothing)."""
        now = self.clock()
        if self._began is None or self._began[0] != stage or fraction < self._last:
            self._began = (stage, now, fraction)  # a new stage, or one started over
            self._last = fraction
            return ""
        self._last = fraction
        _, t0, f0 = self._began
        elapsed, done = now - t0, fraction - f0
        if elapsed < ETA_AFTER_S or done <= 0.0 or fraction >= 1.0:
            return ""
        from outcast_core.runtime.pipeline.timelapse import describe_seconds

        return f", {describe_seconds(elapsed * (1.0 - fraction) / done)} left"

    def end_line(self) -> None:
        """End the terminal line the progress left open, if any."""
        if self._width:
            print(file=self._out(), flush=True)
            self._width = 0


def _say(args: argparse.Namespace, text: str) -> None:
    if not getattr(args, "quiet", False):
        print(text, file=sys.stderr)


def cmd_shadow(args: argparse.Namespace) -> int:
    from outcast_core.runtime.io.imageio import write_shadow_png
    from outcast_core.runtime.pipeline.session import PRESETS

    w = _sun_from_args(args)
    preset = PRESETS[args.preset]
    loaded = _load(args.image, max_pixels=4 * preset.working_size**2)
    session = _make_session(args, shadow_mode=args.mode)
    if args.steps is not None and session.shadow_mode != "direct":
        _say(args, f"note: --steps applies to Direct shadows only; {session.shadow_mode} "
                   f"shadows use the preset's {preset.steps} steps")
    if args.steps is not None and session.shadow_mode == "direct":
        from outcast_core.runtime.pipeline.session import Preset

        session.preset = Preset(
            "custom", preset.working_size, args.steps, 1.0 / args.steps, preset.preview_size,
            preset.preview_steps,
        )
    _set_image(session, loaded, args)
    t0 = time.perf_counter()
    shadow = session.shadow(w)
    write_shadow_png(args.output, shadow, force=args.force)
    _say(args, f"wrote {args.output} ({shadow.shape[1]}x{shadow.shape[0]}, "
               f"{session.shadow_mode} shadows, depth: {session.depth_source}, "
               f"{time.perf_counter() - t0:.2f} s)")
    return 0


def _original_sun(args: argparse.Namespace, session, loaded,
                  given: np.ndarray | None) -> np.ndarray:
    """The photo's original sun for ``relight`` and ``deshadow``: ``--from`` (``given``), else
    the sun the photo shows, else its EXIF sun (GPS, capture time and compass heading, in the
    camera's frame), as the app's "Sun from EXIF" and ``outcast batch``'s ``exif`` source take
    it (a project file's sun is ``outcast batch``'s); said on stderr. Raises
    :class:`CliError` when the photo has neither."""
    if given is not None:
        return given
    from outcast_core.runtime.geometry.camera import sun_angles
    from outcast_core.runtime.pipeline.timelapse import exif_sun, exif_sun_problem

    seen = session.sun_seen
    if seen is not None:
        az, el = sun_angles(seen.w)
        _say(args, f"original sun: azimuth {az:.1f}, elevation {el:.1f}, the sun in the photo")
        return np.asarray(seen.w, np.float64)
    sun = exif_sun(loaded.exif, tilt=session.photo_tilt()[:2])
    if sun is None:
        problem = exif_sun_problem(loaded.exif) or "no EXIF sun"
        raise CliError(f"no --from and no sun from the photo ({problem}): give --from AZ,EL "
                       f"(outcast sun {args.image} looks for it in the photo's shadows)")
    _say(args, f"original sun: azimuth {sun[0]:.1f}, elevation {sun[1]:.1f}, from the photo's "
               "EXIF (GPS, time and compass heading)")
    return sun_vector(*sun)


def cmd_relight(args: argparse.Namespace) -> int:
    from outcast_core.runtime.io.imageio import in_file_channels, output_bit_depth, write_image

    w_from = None if args.from_sun is None else sun_vector(*args.from_sun)
    w_to = sun_vector(*args.to_sun)
    loaded = _load(args.image, keep_uint8=True)  # 8-bit photos stay 8-bit end to end
    bit_depth = output_bit_depth(args.output, loaded.bit_depth)
    session = _make_session(args, shadow_mode=args.shadows, relight_mode=args.mode)
    _set_image(session, loaded, args)  # the daylight's horizon: the photo's tilt, as the app's
    w_from = _original_sun(args, session, loaded, w_from)
    session.set_shadow_edits(args.shadow_edits)
    session.set_original_sun(w_from)
    corrections = say_unused_shadow_edits(session, args)
    out = session.relight_full(w_to, dtype=np.uint8 if bit_depth == 8 else np.float32)
    # GPS and time, as the app's export.
    write_image(args.output, in_file_channels(out, loaded), bit_depth=bit_depth,
                force=args.force, exif=loaded.exif_bytes)
    t = session.timings
    _say(args, f"wrote {args.output} ({out.shape[1]}x{out.shape[0]}; {corrections}shadows: "
               f"{session.shadow_mode}, refinement: {session.refinement}, "
               f"relighting: {session.relight_mode}, depth: "
               f"{session.depth_source}; " + ", ".join(f"{k} {v:.2f}s" for k, v in t.items())
         + ")")
    return 0


def cmd_deshadow(args: argparse.Namespace) -> int:
    from outcast_core.runtime.io.imageio import (
        in_file_channels,
        output_bit_depth,
        write_image,
        write_shadow_png,
    )

    w_from = None if args.from_sun is None else sun_vector(*args.from_sun)
    if args.mask:  # the main output is checked before the work by _check_output
        check_output_path(args.mask, extensions=(".png",), force=args.force,
                          inputs=[args.image, args.depth], outputs=[args.output])
    loaded = _load(args.image, keep_uint8=True)  # as the app reads it
    session = _make_session(args, shadow_mode="auto")
    _set_image(session, loaded, args)
    w_from = _original_sun(args, session, loaded, w_from)
    session.set_shadow_edits(args.shadow_edits)
    session.set_original_sun(w_from)
    corrections = say_unused_shadow_edits(session, args)
    bit_depth = output_bit_depth(args.output, loaded.bit_depth)
    out = session.deshadow_full(dtype=np.uint8 if bit_depth == 8 else np.float32)
    write_image(args.output, in_file_channels(out, loaded), bit_depth=bit_depth, force=args.force,
                exif=loaded.exif_bytes)
    if args.mask:  # what the de-shadow lifted, at the photo's size
        write_shadow_png(args.mask, session.lifted_shadows_full(), force=args.force)
    t = session.timings
    _say(args, f"wrote {args.output} ({out.shape[1]}x{out.shape[0]}; {corrections}shadows "
               f"found at the photo's sun with {session.shadow_mode} S as the prior, depth: "
               f"{session.depth_source}; " + ", ".join(f"{k} {v:.2f}s" for k, v in t.items())
         + ")")
    if args.mask:
        _say(args, f"wrote {args.mask} (the shadows lifted: a 16-bit grey PNG, "
                   "65535 = shadow)")
    return 0


def cmd_depth(args: argparse.Namespace) -> int:
    from outcast_core.runtime.io.imageio import write_depth
    from outcast_core.runtime.io.models import ModelRegistry
    from outcast_core.runtime.pipeline.session import PRESETS, RelightSession

    registry = ModelRegistry()
    preset = PRESETS[args.preset]
    loaded = _load(args.image, max_pixels=4 * preset.working_size**2)
    session = RelightSession(registry=registry, preset=args.preset, shadow_mode="direct",
                             relight_mode="physics")
    _set_depth_source(session, loaded, args)
    if session.depth_provider is None:
        registry.load("depth")  # ModelError naming the file when the model is missing or corrupt
    focal35 = None if args.fov is not None else loaded.exif.focal_35mm
    session.set_image(loaded.image_srgb, fov_deg=args.fov, focal_35mm=focal35)
    depth = np.where(session.sky, np.inf, session.depth).astype(np.float32)
    write_depth(args.output, depth, force=args.force)
    _say(args, f"wrote {args.output} ({depth.shape[1]}x{depth.shape[0]}, sky = inf; depth: "
               f"{session.depth_source}, {session.timings.get('depth', 0.0):.2f} s)")
    return 0


def add_input_options(p: argparse.ArgumentParser, *, depth: bool = True) -> None:
    """The options every command that reads a photo shares: where depth comes from, the field
    of view and the preset (``outcast sun`` adds its own output options)."""
    g = p.add_mutually_exclusive_group()
    if depth:
        g.add_argument("--depth", help="depth map (.npy float32 H x W, 16-bit PNG or .exr) "
                                       "to use instead of the depth model")
    g.add_argument("--depth-model", metavar="MODEL.onnx",
                   help="a monocular ONNX depth model to use instead of the shipped one "
                        "(Depth Anything, MiDaS, ...; settings in MODEL.onnx.json)")
    p.add_argument("--no-phone-depth", action="store_true",
                   help="ignore a depth map stored inside the photo (phone portrait photos)")
    p.add_argument("--fov", type=_fov, default=None,
                   help="horizontal field of view in degrees (default: EXIF, else 60)")
    p.add_argument("--preset", choices=["fast", "balanced", "accurate"],
                   default=DEFAULT_CLI_PRESET, help="speed/accuracy preset")


def _add_common(p: argparse.ArgumentParser, *, depth: bool = True) -> None:
    add_input_options(p, depth=depth)
    p.add_argument("-o", "--output", required=True, help="output file")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every other error of ``outcast``
    (argparse printed its usage block first: 11-14 lines for a mistyped ``--frames``; a user
    trial). ``--help`` still gives the usage."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(
    optional: Sequence[tuple[str, str]] = OPTIONAL_COMMANDS,
) -> argparse.ArgumentParser:
    """The ``outcast`` argument parser (optional command groups added when importable)."""
    parser = OneLineParser(
        prog="outcast", description="Relight outdoor photographs with correct cast shadows."
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser(
        "shadow", help="write the shadow image (16-bit grey PNG at the working resolution)"
    )
    p.add_argument("image")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--sun", type=sun_pair, help="AZ,EL in degrees relative to the camera")
    g.add_argument("--sun-dir", type=sun_dir_option,
                   help="X,Y,Z camera-space vector toward the sun "
                                     "(write --sun-dir=-X,Y,Z when X is negative)")
    p.add_argument("--mode", choices=["auto", "direct", "learned"], default="auto",
                   help="learned S network (default when installed) or Direct ray marching")
    p.add_argument("--thickness", default=math.inf, type=_thickness,
                   help="Direct occluder thickness relative to depth, or 'inf' (default)")
    p.add_argument("--steps", type=int_in(1, MAX_DIRECT_STEPS, "step count"), default=None,
                   help=f"Direct march steps across one image side, 1..{MAX_DIRECT_STEPS} "
                        "(default: from the preset; --mode direct only)")
    _add_common(p)
    p.set_defaults(func=cmd_shadow)

    p = sub.add_parser("relight", help="relight a photo from its original sun to a new one")
    p.add_argument("image")
    p.add_argument("--from", dest="from_sun", metavar="AZ,EL", type=sun_pair,
                   help="the photo's original sun (default: the sun in the photo, else its "
                        "EXIF sun from GPS, time and compass heading)")
    p.add_argument("--to", dest="to_sun", required=True, metavar="AZ,EL", type=sun_pair,
                   help="the new sun")
    p.add_argument("--mode", choices=["auto", "physics", "learned"], default="auto",
                   help="learned relighting (default when installed) or physics ratios")
    p.add_argument("--refine", choices=["photo", "learned"], default="photo",
                   help="how the photo's own shadows are found at its sun: from the photo with "
                   "the predicted shadows as the prior (default), or the learned R network")
    p.add_argument("--shadows", choices=["auto", "direct", "learned"], default="auto",
                   help="shadow method (default: learned when installed, else Direct)")
    p.add_argument("--thickness", default=math.inf, type=_thickness, help=argparse.SUPPRESS)
    add_exposure_option(p)
    add_light_option(p)
    add_shadow_edit_options(p)
    _add_common(p)
    p.set_defaults(func=cmd_relight)

    p = sub.add_parser("deshadow", help="lift the photo's own shadows (found at its sun)")
    p.add_argument("image")
    p.add_argument("--from", dest="from_sun", metavar="AZ,EL", type=sun_pair,
                   help="the photo's sun (the shadows are found where it can cast them; "
                        "default: the sun in the photo, else its EXIF sun from GPS, time and "
                        "compass heading)")
    p.add_argument("--mask", default="", metavar="MASK.png",
                   help="also write the shadows it lifted (as the app's \"Shadows found\" "
                        "shows them) as a 16-bit grey PNG at the photo's size (white = shadow)")
    add_shadow_edit_options(p)
    _add_common(p)
    p.set_defaults(func=cmd_deshadow)

    p = sub.add_parser("depth", help="estimate depth (the photo's own map, --depth-model or the "
                                     "shipped depth model)")
    p.add_argument("image")
    _add_common(p, depth=False)
    p.set_defaults(func=cmd_depth)

    for module, func in optional:
        try:
            mod = importlib.import_module(module)
        except ImportError:
            continue
        register: Callable[[argparse._SubParsersAction], None] = getattr(mod, func)
        register(sub)
    return parser


def _thickness(text: str) -> float:
    from outcast_core.runtime.geometry.shadows import parse_thickness

    try:
        return parse_thickness(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc


def int_in(low: int, high: int, what: str) -> Callable[[str], int]:
    """An argparse ``type`` accepting an integer in ``[low, high]``, or saying the range.

    Example:
        >>> int_in(1, 4, "worker count")("3")
        3
    """
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = low - 1
        if not low <= n <= high:
            raise argparse.ArgumentTypeError(f"expected a {what} in [{low}, {high}], got {text!r}")
        return n

    return parse


def names_in(names: Sequence[str], what: str) -> Callable[[str], tuple[str, ...]]:
    """An argparse ``type`` accepting a comma-separated list of ``names`` (at least one).

    Example:
        >>> names_in(("fast", "balanced"), "presets")("fast, balanced")
        ('fast', 'balanced')
    """
    def parse(text: str) -> tuple[str, ...]:
        got = tuple(n.strip() for n in text.split(",") if n.strip())
        if not got or any(n not in names for n in got):
            raise argparse.ArgumentTypeError(
                f"expected {what} from {', '.join(names)} separated by commas, got {text!r}")
        return got

    return parse


def _fov(text: str) -> float:
    try:
        fov = float(text)
    except ValueError:
        fov = math.nan
    if not (math.isfinite(fov) and 0.0 < fov < 180.0):
        raise argparse.ArgumentTypeError(
            f"expected a field of view in (0, 180) degrees, got {text!r}"
        )
    return fov


def _output_extensions(command: str) -> tuple[str, ...] | None:
    """The extensions ``command`` writes, or None for a command this module does not check."""
    from outcast_core.runtime.io.imageio import DEPTH_EXTENSIONS, WRITE_EXTENSIONS

    return {"shadow": (".png",), "relight": tuple(WRITE_EXTENSIONS),
            "deshadow": tuple(WRITE_EXTENSIONS), "depth": tuple(DEPTH_EXTENSIONS)}.get(command)


def check_output_path(
    output: str,
    *,
    extensions: Sequence[str] | None,
    force: bool,
    inputs: Sequence[str | None] = (),
    folder_ok: bool = False,
    outputs: Sequence[str | None] = (),
) -> Path:
    """Check, before any work, that ``output`` can be written; return it as a ``Path``.

    Args:
        output: the output file as the user typed it. Its folder must exist: a missing one is
            refused, not made (a typo in its name would go unseen), as the app refuses it.
        extensions: accepted lower-case extensions, or None to accept any.
        force: whether an existing file may be replaced.
        inputs: input files; the output may never be one of them, even with ``force``.
        folder_ok: the output is a folder (PNG frames): an existing folder is like a file, and
            a new one is made by the command (in an existing folder).
        outputs: the command's other outputs; ``output`` may not be one of them.

    Raises:
        CliError: wrong extension, a folder, an input file, a missing folder, a parent that is
            a file, or a folder that cannot be written.
        FileExistsError: the file exists and ``force`` is False.
    """
    path = Path(output).expanduser()
    named_folder = output.endswith(("/", os.sep)) or path.is_dir()
    if named_folder and not folder_ok:  # (said first: "-o out/" has no extension either)
        example = f" (e.g. {path / 'output'}{extensions[0]})" if extensions else ""
        raise CliError(f"cannot write '{output}': it "
                       f"{'is' if path.is_dir() else 'names'} a folder; give a file name in "
                       f"it{example}")
    if extensions is not None and path.suffix.lower() not in extensions:
        raise CliError(f"cannot write '{output}': expected an extension in "
                       f"{', '.join(extensions)}, got '{path.suffix}'")
    if path.exists() and not path.is_dir() and not path.is_file():
        raise CliError(f"cannot write '{output}': it is not a regular file (a device or pipe)")
    from outcast_core.runtime.io.imageio import same_file

    for source in inputs:
        if same_file(path, source):
            raise CliError(f"cannot write '{output}': it is the input file '{source}'; "
                           "choose another output name")
    for other in outputs:  # neither may exist yet: compare the paths themselves
        if other and Path(other).expanduser().resolve() == path.resolve():
            raise CliError(f"cannot write '{output}': the command writes '{other}' there too; "
                           "choose another name")
    if path.exists() and not force:
        raise FileExistsError(f"'{output}' already exists; use --force to overwrite it")
    check_folder_writable(path.parent, f"cannot write '{output}'")
    return path


def check_folder_writable(folder: Path, what: str) -> None:
    """Check that files can be made in ``folder``, which must exist; ``what`` starts the error
    message.

    No command makes the folders above its output (``-o typo/sub/x.mp4`` made the whole tree,
    where the app refuses a missing folder; a user trial): a missing one is named.

    Raises:
        CliError: ``folder`` does not exist, is a file, or is not writable.
    """
    folder = Path(folder).expanduser()
    above = folder
    while not above.exists() and above != above.parent:
        above = above.parent
    if above.exists() and not above.is_dir():  # "afile/deeper/s.png": say what is wrong
        raise CliError(f"{what}: '{above}' is a file, not a folder")
    if not folder.exists():
        raise CliError(f"{what}: folder '{folder}' does not exist")
    if not folder.is_dir():
        raise CliError(f"{what}: '{folder}' is a file, not a folder")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        import errno

        if isinstance(exc, PermissionError) or exc.errno == errno.EROFS:
            raise CliError(f"{what}: folder '{folder}' is not writable "
                           f"({exc.strerror or exc})") from exc
        # Not a permission (a system folder such as /proc: "No such file or directory"): the
        # folder exists, so "not writable (No such file ...)" read as a contradiction.
        raise CliError(f"{what}: no file can be made in folder '{folder}' "
                       f"({exc.strerror or exc})") from exc


def _check_output(args: argparse.Namespace) -> None:
    """:func:`check_output_path` for the commands whose outputs this module knows.

    A command registered elsewhere can set its own check with
    ``parser.set_defaults(check_output=fn)``; ``fn(args)`` then runs instead.
    """
    custom = getattr(args, "check_output", None)
    if custom is not None:
        custom(args)
        return
    output = getattr(args, "output", None)
    extensions = _output_extensions(args.command)
    if isinstance(output, str) and output and extensions is not None:
        check_output_path(output, extensions=extensions, force=args.force,
                          inputs=[getattr(args, "image", None), getattr(args, "depth", None),
                                  getattr(args, "depth_model", None)])


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def _catch_sigterm() -> object:
    """Turn SIGTERM into :class:`Terminated` (main thread only); returns the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _on_sigterm)


#: A value that starts with a minus sign and a digit: ``-90,30``, ``-90,30:90,30``, ``-5``.
_NEGATIVE_VALUE = re.compile(r"-\d[\d.,:eE+-]*")


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """``--to -90,30`` as ``--to=-90,30``: argparse takes a value that starts with ``-`` for an
    option unless it is a plain number, so a sun west of the camera was refused with "expected
    one argument". Every ``--option`` followed by such a value is joined to it.

    Example:
        >>> join_negative_values(["relight", "p.jpg", "--to", "-90,30", "-o", "x.jpg"])
        ['relight', 'p.jpg', '--to=-90,30', '-o', 'x.jpg']
    """
    out: list[str] = []
    args = list(argv)
    i = 0
    while i < len(args):
        a = args[i]
        nxt = args[i + 1] if i + 1 < len(args) else None
        if (a.startswith("--") and "=" not in a and a != "--" and nxt is not None
                and _NEGATIVE_VALUE.fullmatch(nxt)):
            out.append(f"{a}={nxt}")
            i += 2
            continue
        if a == "--":  # everything after it is positional
            out.extend(args[i:])
            break
        out.append(a)
        i += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``outcast``; returns the exit status.

    While a command runs, SIGTERM raises :class:`Terminated` (a ``KeyboardInterrupt``), so
    temporary and partial files are removed as on Ctrl+C; the exit status is then 143.
    """
    from outcast_core.runtime.io.models import ModelError

    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:2] == ["eval", "real"]:
        # ``outcast eval real DIR`` (runtime only) beside ``outcast eval`` (synthetic, torch).
        argv = ["eval-real", *argv[2:]]
    args = parser.parse_args(join_negative_values(argv))
    previous_sigterm = _catch_sigterm()
    try:
        _check_output(args)  # before the work: extension, existing file, folder, input
        return int(args.func(args) or 0)
    except (ValueError, ModelError, FileExistsError, FileNotFoundError, CliError) as exc:
        # A photo that cannot be read (ImageReadError, a ValueError) in plain words, as in
        # the app: its str leaves the decoder's own out.
        print(f"outcast {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"outcast {args.command}: error: out of memory; try --preset fast or a smaller "
              "image", file=sys.stderr)
        return 2
    except OSError as exc:
        where = exc.filename or getattr(args, "output", None)
        print(f"outcast {args.command}: error: " + (f"'{where}': " if where else "")
              + f"{exc.strerror or exc}", file=sys.stderr)
        return 2
    except Terminated:
        print(f"outcast {args.command}: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"outcast {args.command}: interrupted", file=sys.stderr)
        return 130
    finally:
        if previous_sigterm is not None:
            signal.signal(signal.SIGTERM, previous_sigterm)


if __name__ == "__main__":
    sys.exit(main())
