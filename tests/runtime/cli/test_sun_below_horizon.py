"""A sun below the horizon (issue 19, defect 10).

Decision: OutCast renders sunlight and the shadows it casts, not twilight. A still's sun
(``shadow --sun``, ``relight --from/--to``, ``timelapse --from``, ``batch --from/--to``) below
the horizon is refused with one line and exit status 2; a time-lapse path that dips below the
horizon (a real day's sunrise and sunset, a sweep: ``timelapse --sweep`` and ``batch --sweep``
alike) renders those frames with the sun at the horizon.

A photo whose EXIF time and place put the sun below the horizon (a night photo, or a wrong
camera clock or time zone) gives no EXIF sun: ``outcast sun`` and ``outcast batch`` say so in
one line, how far below and at what time as read, and what to do.
"""

from __future__ import annotations

import numpy as np
import pytest

from outcast_core.runtime.cli.main import azel_angles, build_parser, main
from outcast_core.runtime.pipeline.timelapse import MIN_RENDER_ELEVATION, sun_vectors, sweep_path


def test_azel_angles_refuses_a_sun_below_the_horizon():
    assert azel_angles("90,0") == (90.0, 0.0)  # the horizon is fine
    with pytest.raises(ValueError, match="at or above the horizon.*not twilight"):
        azel_angles("90,-10")


def _exit_code(args: list[str]) -> int:
    try:
        return main(args)
    except SystemExit as exc:  # argparse refuses an option's value
        return int(exc.code)


@pytest.mark.parametrize(
    "argv",
    [
        ["relight", "{photo}", "--from", "273,67", "--to", "90,-10", "-o", "{out}.jpg"],
        ["relight", "{photo}", "--from", "273,-5", "--to", "90,30", "-o", "{out}.jpg"],
        ["shadow", "{photo}", "--sun", "90,-0.5", "-o", "{out}.png"],
        ["timelapse", "{photo}", "--from", "90,-10", "--sweep", "0,20:90,20", "--frames", "2",
         "-o", "{out}.gif"],
    ],
)  # fmt: skip
def test_cli_refuses_a_sun_below_the_horizon(photo, tmp_path, capsys, argv):
    out = tmp_path / "out"
    assert _exit_code([a.format(photo=photo, out=out) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "above the horizon" in err and "Traceback" not in err
    assert "above the horizon" in err.strip().splitlines()[-1]  # the last line says why
    assert not list(tmp_path.glob("out*"))


def test_timelapse_paths_below_the_horizon_render_at_the_horizon():
    samples = sweep_path((90.0, 10.0), (270.0, -10.0), 5)
    assert min(s.elevation for s in samples) < 0  # the path may dip below
    lowest = min(sun_vectors(samples), key=lambda w: -w[1])
    el = np.degrees(np.arcsin(-lowest[1]))
    assert el == pytest.approx(MIN_RENDER_ELEVATION)


#: The start of each command line whose --sweep / --from / --to are checked (parsing only).
_SWEEP_COMMANDS = {
    "timelapse": ["timelapse", "photo.jpg", "--from", "90,30", "-o", "out.mp4"],
    "batch": ["batch", "photos", "-o", "out"],
}


@pytest.mark.parametrize("command", sorted(_SWEEP_COMMANDS))
def test_a_sweep_end_may_be_below_the_horizon(command):
    """One rule for both commands (one parser): a sweep is a sun path, so an end may dip below
    the horizon (down to -90); a malformed end or one past -90 is refused by both."""
    parser = build_parser()
    argv = _SWEEP_COMMANDS[command]
    args = parser.parse_args([*argv, "--sweep", "90,10:270,-10"])
    assert args.sweep == ((90.0, 10.0), (270.0, -10.0))
    args = parser.parse_args([*argv, "--sweep", "0,-90:45,0"])
    assert args.sweep == ((0.0, -90.0), (45.0, 0.0))
    for bad in ("90,10:270,-91", "90,10", "90,10:east,5", "90,nan:0,5"):
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([*argv, "--sweep", bad])
        assert exc.value.code == 2


@pytest.mark.parametrize("option", ["--from", "--to"])
def test_batch_refuses_a_still_sun_below_the_horizon(option, capsys):
    parser = build_parser()
    assert parser.parse_args(["batch", "photos", "-o", "out", option, "90,0"]) is not None
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(["batch", "photos", "-o", "out", option, "90,-10"])
    assert exc.value.code == 2
    assert "above the horizon" in capsys.readouterr().err


#: Each command's still sun flags (parsing only).
_STILL_SUNS = [
    (["relight", "p.jpg", "--to", "90,30", "-o", "o.jpg"], "--from"),
    (["relight", "p.jpg", "--from", "90,30", "-o", "o.jpg"], "--to"),
    (["deshadow", "p.jpg", "-o", "o.jpg"], "--from"),
    (["shadow", "p.jpg", "-o", "o.png"], "--sun"),
    (["batch", "photos", "-o", "out"], "--to"),
    (["batch", "photos", "-o", "out"], "--from"),
    (["timelapse", "p.jpg", "--sweep", "0,10:90,20", "--frames", "2", "-o", "o.gif"],
     "--from"),
]


@pytest.mark.parametrize(("argv", "option"), _STILL_SUNS)
@pytest.mark.parametrize("bad", ["120,95", "abc", "90;30"])
def test_every_still_sun_is_refused_one_way_naming_its_flag(argv, option, bad, capsys):
    """A user trial: relight's bad --from said only "expected AZ,EL ..." (which flag?), while
    batch named its flag and said "[-90, 90]" for an elevation of 95 whose -5 it then refused
    too. Now every command refuses a still's sun by one rule, naming the flag."""
    parser = build_parser()
    with pytest.raises(SystemExit) as exc:
        parser.parse_args([*argv, option, bad])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"argument {option}: expected AZ,EL" in err and repr(bad) in err
    if bad == "120,95":
        assert "from 0 (the horizon) to 90 (overhead)" in err


def test_batch_refuses_a_new_sun_where_it_makes_no_relighting(tmp_path, capsys):
    """A user trial: ``--to`` beside ``--deshadow`` or ``--sweep`` was ignored without a word."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for what in (["--deshadow"], ["--sweep", "0,10:90,40", "--frames", "2"], ["--day"]):
        assert _exit_code(["batch", str(photos), "-o", str(tmp_path / "out"), *what,
                           "--to", "90,30"]) == 2
        err = capsys.readouterr().err
        assert f"--to is the new sun of a relighting; {what[0]} takes none" in err
        assert not (tmp_path / "out").exists()
    # --easing is a sweep's: beside --day or a relighting it was ignored (a user trial).
    for what, said in ((["--day"], "--day follows the real sun's clock"),
                       (["--to", "90,30"], "leave it out, or add --sweep")):
        assert _exit_code(["batch", str(photos), "-o", str(tmp_path / "out"), *what,
                           "--easing", "linear"]) == 2
        assert f"--easing is the pace of a --sweep; {said}" in capsys.readouterr().err
        assert not (tmp_path / "out").exists()
    _exit_code(["batch", str(photos), "-o", str(tmp_path / "out"), "--sweep", "0,10:90,40",
                "--frames", "2", "--easing", "linear"])  # (no photos: refused for that)
    assert "--easing" not in capsys.readouterr().err


# ------------------------------------------------------------------ a photo taken at night
def _photo_at(path, when: str, offset: str | None = "+07:00"):
    """A small photo whose EXIF places it at Phuket (the pool sample's GPS) at ``when``
    (``YYYY:MM:DD HH:MM:SS``, local at ``offset``; no offset: a time without a zone)."""
    from PIL import Image

    exif = Image.Exif()
    ifd = exif.get_ifd(0x8769)
    ifd[0x9003] = when  # DateTimeOriginal
    if offset is not None:
        ifd[0x9011] = offset  # OffsetTimeOriginal
    exif.get_ifd(0x8825).update({1: "N", 2: (7.0, 49.0, 53.15), 3: "E", 4: (98.0, 17.0, 47.95)})
    rng = np.random.default_rng(5)
    img = np.full((60, 80, 3), (150, 160, 170), np.uint8)
    img[30:] = (140, 120, 100)
    img[45:55, 20:40] //= 3
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    Image.fromarray(img).save(path, exif=exif.tobytes())
    return path


def test_the_words_for_a_sun_below_the_horizon_at_the_photos_time(tmp_path):
    """What happened, with the numbers that tell why: how far below, and the time as read (a
    time without a zone is read at its longitude's zone, and says so; until 2026-12-03 it was
    read as UTC, which put a Phuket photo at 18:00 local time seven hours later, at night)."""
    from outcast_core.runtime.io.imageio import read_metadata
    from outcast_core.runtime.pipeline.timelapse import (
        exif_sun_problem,
        sun_below_horizon_at_capture,
        true_sun_position,
    )

    night = read_metadata(_photo_at(tmp_path / "n.jpg", "2019:08:21 23:00:00"))
    el = true_sun_position(night.capture_time, night.latitude, night.longitude)[1]
    assert el < -10.0
    text = sun_below_horizon_at_capture(night)
    assert text == (f"the sun was {-el:.1f}° below the horizon at the photo's time and place "
                    "(2019-08-21 23:00 +07:00)")
    assert exif_sun_problem(night) == text  # before the missing compass heading
    evening = read_metadata(_photo_at(tmp_path / "u.jpg", "2019:08:21 18:00:00", offset=None))
    assert evening.capture_time.tzinfo is None
    assert sun_below_horizon_at_capture(evening) is None  # 18:00 at +07:00: the sun still up
    naive = read_metadata(_photo_at(tmp_path / "v.jpg", "2019:08:21 23:00:00", offset=None))
    assert sun_below_horizon_at_capture(naive) == (
        f"the sun was {-el:.1f}° below the horizon at the photo's time and place "
        "(2019-08-21 23:00 +07:00, the time zone of its longitude: the EXIF gives none)")
    day = read_metadata(_photo_at(tmp_path / "d.jpg", "2019:08:21 11:00:00"))
    assert sun_below_horizon_at_capture(day) is None
    assert exif_sun_problem(day) == "no EXIF compass heading"
    assert exif_sun_problem(day, heading=120.0) is None
    from outcast_core.runtime.io.exif import PhotoMetadata

    assert exif_sun_problem(PhotoMetadata()) == (
        "no EXIF GPS position, capture time or compass heading")
    half = PhotoMetadata(latitude=50.0, capture_time=day.capture_time)  # no longitude
    assert exif_sun_problem(half) == "no EXIF GPS position or compass heading"


def test_batch_says_a_night_photos_sun_was_below_the_horizon_and_what_to_do(tmp_path, capsys):
    """It said "no EXIF GPS, time and heading (or the sun was down)" of a photo that has them
    all but was taken at night."""
    photos = tmp_path / "in"
    photos.mkdir()
    _photo_at(photos / "night.jpg", "2019:08:21 23:00:00")
    assert main(["batch", str(photos), "-o", str(tmp_path / "out"), "--to", "90,30",
                 "--sources", "project,exif,given", "--preset", "fast", "-q"]) == 2
    line = next(x for x in capsys.readouterr().err.splitlines() if "night.jpg: failed" in x)
    assert line.endswith(
        "failed: no original sun: no night.outcast.json with a confirmed sun; the sun was "
        f"{line.split('the sun was ')[1].split('°')[0]}° below the horizon at the photo's time "
        "and place (2019-08-21 23:00 +07:00): give --from AZ,EL")


def test_outcast_sun_says_why_a_night_photos_exif_gives_no_sun(tmp_path, capsys):
    photo = _photo_at(tmp_path / "night.jpg", "2019:08:21 23:00:00")
    args = ["sun", str(photo), "--mode", "direct", "--preset", "fast"]
    assert main(args) in (0, 3)
    notes = [x for x in capsys.readouterr().err.splitlines() if "below the horizon" in x]
    assert len(notes) == 1 and notes[0].startswith("outcast sun: note: the sun was ")
    assert "(2019-08-21 23:00 +07:00), so the EXIF gives no sun" in notes[0]
    assert "clock or time zone" in notes[0]
    assert main([*args, "--no-exif"]) in (0, 3)  # the EXIF not asked for: nothing to say
    assert "below the horizon" not in capsys.readouterr().err
