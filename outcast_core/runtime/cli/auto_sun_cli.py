"""``outcast sun IMAGE [--json]``: the photo's sun from its shadows (and its EXIF).

Prints the sun's azimuth and elevation relative to the camera and a confidence (a photo whose
EXIF time and place put the sun below the horizon is said so on stderr, in one line: the
shadows alone are searched); with no clear
shadows in the photo it says so on stderr instead of guessing and exits with
:data:`NO_SUN_STATUS` (with ``--json`` the JSON is printed all the same, with the best guess
under ``best_guess`` and ``azimuth`` and ``elevation`` null, and the same line on stderr),
unless the EXIF's compass heading gives a full sun. A sun seen in the frame, with the photo's
GPS and time, also gives the camera's compass heading (``camera heading`` / ``camera_heading``). See
:mod:`outcast_core.runtime.pipeline.auto_sun`.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

#: Exit status when the photo's sun cannot be told (no clear shadows, no EXIF heading): a
#: script can tell "no answer" from a sun and from an error (2).
NO_SUN_STATUS = 3


def cmd_sun(args: argparse.Namespace) -> int:
    """Run :func:`~outcast_core.runtime.pipeline.auto_sun.find_sun` on one photo and print the
    result."""
    from outcast_core.runtime.cli.main import CliError, _load, _make_session, _say, _set_image

    if args.heading is not None and args.no_exif:  # (a user trial's was ignored unsaid)
        raise CliError("--heading places the sun with the photo's EXIF GPS and time, which "
                       "--no-exif ignores: give one or the other")
    from outcast_core.runtime.pipeline.auto_sun import (
        SOURCE_EXIF,
        SOURCE_SUN_IN_FRAME,
        exif_sun_prior,
        find_sun,
    )
    from outcast_core.runtime.pipeline.timelapse import (
        exif_heading_from_sun,
        sun_below_horizon_at_capture,
    )

    loaded = _load(args.image, keep_uint8=True)  # as the app reads it: the same sun
    session = _make_session(args, shadow_mode=args.mode)
    _set_image(session, loaded, args, small_note=False)  # (find_sun's note says it)
    heading = None if args.heading is None else args.heading % 360.0
    prior = None if args.no_exif else exif_sun_prior(loaded.exif, heading=heading)
    night = None if args.no_exif else sun_below_horizon_at_capture(loaded.exif)
    if night is not None and not args.quiet:  # its EXIF gives no sun: say why, once
        print(f"outcast sun: note: {night}, so the EXIF gives no sun and the shadows alone are "
              "searched (if it was daylight, the camera's clock or time zone is wrong)"
              f"{'; --heading is not used' if heading is not None else ''}", file=sys.stderr)
    elif heading is not None and prior is None and not args.quiet:
        print("outcast sun: note: --heading is not used: the photo has no EXIF GPS position "
              "and capture time to place the sun with it", file=sys.stderr)
    # The camera's tilt as the app and batch take it: metadata, the sun in the frame, the
    # ground plane.
    tilt = None if args.no_exif else session.photo_tilt()
    fit = find_sun(session, prior=prior, pitch_roll=tilt)
    sure = fit.found or fit.source == SOURCE_EXIF
    # A sun seen in the frame and the photo's GPS and time give the compass heading.
    seen_heading = None
    if fit.source == SOURCE_SUN_IN_FRAME and tilt is not None:
        seen_heading = exif_heading_from_sun(loaded.exif, fit.azimuth, fit.elevation,
                                             tilt=tilt[:2])
    if args.json:
        out: dict[str, Any] = fit.as_dict()
        out["image"] = str(args.image)
        out["depth_source"] = str(session.depth_source)
        out["best_guess"] = [out["azimuth"], out["elevation"]]
        if not sure:
            out["azimuth"] = out["elevation"] = None
        out["exif_elevation"] = None if prior is None else round(prior.elevation, 2)
        out["exif_azimuth"] = (None if prior is None or prior.azimuth is None
                               else round(prior.azimuth, 2))
        # exif_azimuth / exif_elevation are against the horizon; the result is in the
        # camera's frame: the EXIF sun in that frame too (equal for a level camera)
        seen_as = _exif_sun_in_camera_frame(fit, prior)
        out["exif_camera_azimuth"], out["exif_camera_elevation"] = (
            (None, None) if seen_as is None else (round(seen_as[0], 2), round(seen_as[1], 2)))
        out["camera_heading"] = None if seen_heading is None else round(seen_heading, 2)
        # The heading the EXIF records (camera_heading is the one a seen sun gives; a user
        # trial looked for the recorded one there).
        recorded = None if loaded.exif is None else getattr(loaded.exif, "heading_deg", None)
        out["exif_heading"] = None if recorded is None else round(float(recorded), 2)
        out["note"] = note_for_the_cli(fit, prior)
        print(json.dumps(out, indent=2, ensure_ascii=False))
        if not sure:  # as without --json: a script's log says why there is no sun
            print(f"outcast sun: {out['note']}", file=sys.stderr)
        return 0 if sure else NO_SUN_STATUS
    if sure:
        heading = "" if seen_heading is None else f"  camera heading {seen_heading:.1f}"
        print(f"azimuth {fit.azimuth:.1f}  elevation {fit.elevation:.1f}  "
              f"confidence {fit.confidence:.2f}{heading}")
    else:
        print(f"outcast sun: {note_for_the_cli(fit, prior)}", file=sys.stderr)  # even with -q
    said = note_for_the_cli(fit, prior) if sure else (
        f"best guess: azimuth {fit.azimuth:.1f}, elevation {fit.elevation:.1f}")
    _say(args, f"{said} · source: {fit.source} · depth: {session.depth_source} · "
               f"{fit.evaluations} suns tried in {fit.seconds:.2f} s")
    return 0 if sure else NO_SUN_STATUS


#: :attr:`SunFit.note`'s words for the app's dial (the heat map), which the command line does
#: not show, and for setting the sun there by hand, with what the command line says instead.
_MAP_WORDS = ": the warm area of the map)"
_BY_EYE = ("set it by eye", "give it by hand (--from AZ,EL: where its shadows point from, as "
                            "outcast shadow --sun draws them)")


def _exif_sun_in_camera_frame(fit: Any, prior: Any) -> tuple[float, float] | None:
    """The EXIF sun (``prior``: azimuth and elevation against the horizon) in the frame of
    ``fit``'s tilted camera, where ``fit``'s own sun is given; None without a full EXIF sun."""
    if prior is None or prior.azimuth is None:
        return None
    from outcast_core.runtime.geometry.camera import sun_angles, sun_vector

    az, el = sun_angles(sun_vector(prior.azimuth, prior.elevation, fit.pitch, fit.roll))
    return float(az) % 360.0, float(el)


def note_for_the_cli(fit: Any, prior: Any) -> str:
    """:attr:`~outcast_core.runtime.pipeline.auto_sun.SunFit.note` in the command line's words.

    The note is written for the app: "the warm area of the map" is its dial's heat map, which
    the command line does not show, so it is left out, and a sun set "by eye" on the dial is
    one given with ``--from`` here. For a tilted camera the printed sun is
    in the camera's frame and the EXIF sun the note names is against the horizon (a user trial
    read "120.2 41.0" and "azimuth 122°, elevation 39°" as two answers): the note says so, with
    the EXIF sun in the camera's frame beside it.
    """
    from outcast_core.runtime.pipeline.auto_sun import describe_tilt, is_tilted

    note = fit.note.replace(_MAP_WORDS, ")").replace(*_BY_EYE)
    if prior is None or not prior.description or not is_tilted(fit.pitch, fit.roll):
        return note
    tilt = describe_tilt(fit.pitch, fit.roll, fit.pose_source or "assumed")
    seen_as = _exif_sun_in_camera_frame(fit, prior)
    if seen_as is None:  # the EXIF gives the true elevation only
        words = (f"{prior.description}, against the horizon (the sun above is in the frame of "
                 f"the {tilt})")
    else:
        words = (f"{prior.description}, against the horizon; in the frame of the {tilt}, "
                 f"the frame of the sun above: azimuth {seen_as[0]:.0f}°, elevation "
                 f"{seen_as[1]:.0f}°")
    return note.replace(prior.description, words, 1)


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``outcast sun`` to the ``outcast`` command line."""
    from outcast_core.runtime.cli.main import add_input_options
    from outcast_core.runtime.cli.timelapse_cli import _number

    p = sub.add_parser("sun", help="find the photo's sun from its shadows (and its EXIF GPS, "
                                   "time and heading)",
                       epilog=f"Exit status: 0 with a sun, {NO_SUN_STATUS} when the photo's "
                              "shadows do not tell it (said on stderr), 2 on an error.")
    p.add_argument("image")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--no-exif", action="store_true",
                   help="ignore the photo's GPS, time, heading and camera pitch/roll (shadows "
                        "only)")
    p.add_argument("--heading", type=_number(-360.0, 360.0, "a heading"),
                   help="the camera's compass heading, deg from true north: it replaces the "
                        "photo's EXIF one (phone compasses are often tens of degrees off) or "
                        "gives the missing one")
    p.add_argument("--mode", choices=["auto", "direct", "learned"], default="auto",
                   help="predicted shadows: learned S network (default when installed) or Direct")
    add_input_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print only the result")
    p.set_defaults(func=cmd_sun)


__all__ = ["cmd_sun", "note_for_the_cli", "register"]
