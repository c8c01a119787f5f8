"""The `outcast` command line: the contract users and other tools rely on."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.cli.main import azel_angles, main, parse_vector
from outcast_core.runtime.io.imageio import read_image, read_shadow_png, write_depth
from tests.runtime.scenes import box_scene_depth


@pytest.fixture
def depth_file(tmp_path: Path) -> Path:
    depth = box_scene_depth(60, 80, 80 / (2 * math.tan(math.radians(15))), 60.0,
                            [(-4.0, 0.0, -3.0, 1.0, 4.0)])
    path = tmp_path / "depth.npy"
    write_depth(path, depth)
    return path


def test_parse_angles() -> None:
    assert azel_angles("90,0") == (90.0, 0.0) and azel_angles("400,30") == (400.0, 30.0)
    np.testing.assert_allclose(parse_vector("0,0,-2"), [0, 0, -1])
    for bad in ("90", "a,b", "10,95", "nan,10"):
        with pytest.raises(ValueError, match="AZ,EL"):
            azel_angles(bad)
    with pytest.raises(ValueError, match=r"from 0 \(the horizon\) to 90"):  # not "[-90, 90]"
        azel_angles("10,95")
    with pytest.raises(ValueError):
        parse_vector("0,0,0")
    # A sun below the horizon is refused as --sun's is (a user trial's 0,1,0 cast shadows
    # from under the ground); on the horizon and huge components are suns.
    with pytest.raises(ValueError, match="at or above the horizon"):
        parse_vector("0,1,0")
    with pytest.raises(ValueError, match="at or above the horizon"):
        parse_vector("1,0.01,0")
    np.testing.assert_allclose(parse_vector("1,0,0"), [1, 0, 0])
    np.testing.assert_allclose(parse_vector("1e308,-1e308,0"), [0.5**0.5, -(0.5**0.5), 0])


def test_shadow_writes_16bit_png(photo: Path, depth_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "shadow.png"
    rc = main(["shadow", str(photo), "--sun-dir=-0.5,-0.3,-0.8", "--depth", str(depth_file),
               "--fov", "30", "--mode", "direct", "-o", str(out), "-q"])
    assert rc == 0
    s = read_shadow_png(out)
    assert s.shape == (60, 80)
    assert (s == 0).mean() > 0.02 and s.max() > 0.7  # a cast shadow and lit ground
    # Thin occluders cast shorter shadows.
    out2 = tmp_path / "thin.png"
    assert main(["shadow", str(photo), "--sun-dir=-0.5,-0.3,-0.8", "--depth", str(depth_file),
                 "--fov", "30", "--thickness", "0.001", "-o", str(out2), "-q"]) == 0
    assert (read_shadow_png(out2) == 0).sum() < (s == 0).sum()


def test_relight_full_resolution_and_no_overwrite(photo: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "relit.tif"
    args = ["relight", str(photo), "--from", "120,40", "--to", "250,30", "-o", str(out), "-q"]
    assert main(args) == 0
    img = read_image(out)
    assert img.image_srgb.shape == (60, 80, 3) and img.bit_depth == 16
    before = out.read_bytes()
    assert main(args) == 2
    assert "--force" in capsys.readouterr().err
    assert out.read_bytes() == before
    assert main(args + ["--force"]) == 0


@pytest.mark.parametrize("command", ["relight", "deshadow"])
def test_without_from_the_photos_exif_sun_is_the_original(
    command: str, photo: Path, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--from`` may be left out, as ``outcast batch`` and the app take the photo's own sun (a
    user trial): a photo whose EXIF gives no sun says so with what to do; one whose EXIF gives
    a full sun is relit from it, said on stderr, exactly as with ``--from`` that sun."""
    from outcast_core.runtime.pipeline import timelapse

    to = ["--to", "250,30"] if command == "relight" else []
    given, derived = tmp_path / "given.png", tmp_path / "exif.png"
    assert main([command, str(photo), *to, "-o", str(derived)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"outcast {command}: error: no --from and no sun from the photo (")
    assert "give --from AZ,EL" in err and "outcast sun" in err and not derived.exists()
    monkeypatch.setattr(timelapse, "exif_sun", lambda exif, heading=None, tilt=(0, 0): (120.0,
                                                                                         40.0))
    assert main([command, str(photo), *to, "-o", str(derived)]) == 0
    assert "original sun: azimuth 120.0, elevation 40.0, from the photo's EXIF" in (
        capsys.readouterr().err)
    assert main([command, str(photo), "--from", "120,40", *to, "-o", str(given), "-q"]) == 0
    np.testing.assert_array_equal(read_image(derived).image_srgb, read_image(given).image_srgb)


def test_without_from_a_sun_in_the_photo_is_the_original(tmp_path: Path, capsys) -> None:
    """The ski-slope sample shows its sun (its compass is 129 degrees off): ``deshadow``
    without ``--from`` takes the sun in the photo, as ``outcast sun`` finds it."""
    sample = Path(__file__).resolve().parents[3] / "samples" / "exif_005_es_skislope.jpg"
    out = tmp_path / "d.jpg"
    assert main(["deshadow", str(sample), "--preset", "fast", "-o", str(out)]) == 0
    said = capsys.readouterr().err
    assert "original sun: azimuth 354." in said and "the sun in the photo" in said
    assert "EXIF" not in said.split("original sun:")[1].splitlines()[0] and out.exists()


def test_argument_errors_are_one_line(capsys) -> None:
    """argparse printed its usage block before the error (11-14 lines; a user trial)."""
    for argv in (["relight", "x.jpg", "--from", "1,2", "--to", "3,4", "--exposure", "bogus",
                  "-o", "y.jpg"], ["timelapse", "x.jpg", "--from", "1,2", "--frames", "1",
                                   "-o", "y.gif"], []):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "error:" in err and "--help)" in err, err


def test_relight_metered_exposure(photo: Path, depth_file: Path, tmp_path: Path,
                                  exposures_relit) -> None:
    """``--exposure metered`` reaches the session; other values are refused."""
    seen = exposures_relit
    common = ["relight", str(photo), "--from", "120,40", "--to", "250,30", "--depth",
              str(depth_file), "--fov", "30", "-q"]
    assert main([*common, "-o", str(tmp_path / "a.png")]) == 0
    assert main([*common, "--exposure", "metered", "-o", str(tmp_path / "b.png")]) == 0
    assert seen == ["photo", "metered"]
    with pytest.raises(SystemExit):
        main([*common, "--exposure", "auto", "-o", str(tmp_path / "c.png")])
    from outcast_core.runtime.cli.main import EXPOSURE_CHOICES
    from outcast_core.runtime.pipeline.relight import EXPOSURES

    assert EXPOSURE_CHOICES == EXPOSURES


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["shadow", "{missing}", "--sun", "10,20", "-o", "{out}"], "file not found"),
        (["shadow", "{text}", "--sun", "10,20", "-o", "{out}"], "not an image"),
        (["shadow", "{photo}", "--sun", "10,100", "-o", "{out}"], "elevation"),
        (["shadow", "{photo}", "--sun-dir", "0,0,0", "-o", "{out}"], "non-zero"),
        (["relight", "{photo}", "--from", "1,2", "--to", "3,4", "--depth", "{text}",
          "-o", "{out}"], "depth"),
        (["depth", "{photo}", "-o", "{out}"], "depth.json"),
    ],
)
def test_errors_are_one_line(argv, message, photo: Path, tmp_path: Path, capsys,
                             monkeypatch) -> None:
    monkeypatch.setenv("OUTCAST_MODEL_DIR", str(tmp_path / "no-models"))
    text = tmp_path / "notes.txt"
    text.write_text("not an image\n")
    subs = {"missing": str(tmp_path / "nope.jpg"), "text": str(text), "photo": str(photo),
            "out": str(tmp_path / "o.png")}
    try:
        status = main([a.format(**subs) for a in argv])
    except SystemExit as exc:  # refused by the parser (a bad --sun), naming the option
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert message in err
    assert not (tmp_path / "o.png").exists()


def test_console_script_runs_in_a_fresh_process(photo: Path, tmp_path: Path) -> None:
    out = tmp_path / "s.png"
    r = subprocess.run([sys.executable, "-m", "outcast_core.runtime.cli.main", "shadow", str(photo),
                        "--sun", "135,40", "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert out.is_file()
    r = subprocess.run([sys.executable, "-m", "outcast_core.runtime.cli.main", "--help"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "relight" in r.stdout
    json.dumps(r.stdout)  # plain text


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["shadow", "p.jpg", "--sun", "1,2", "--steps", "0", "-o", "o.png"],
         "step count in [1, "),
        (["shadow", "p.jpg", "--sun", "1,2", "--steps", "many", "-o", "o.png"],
         "step count in [1, "),
        (["eval-real", "d", "--preset", "fast,quick"],
         "presets from fast, balanced, accurate separated by commas"),
        (["eval-real", "d", "--preset", ","], "presets from"),
        (["batch", "d", "--to", "1,2", "--sources", "exif,moon"], "sources from"),
    ],
)
def test_option_lists_and_ranges_say_what_they_take(argv, message, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_sun_takes_the_same_input_options_as_the_other_commands(capsys) -> None:
    from outcast_core.runtime.cli.main import DEFAULT_CLI_PRESET, build_parser

    p = build_parser()
    args = p.parse_args(["sun", "p.jpg", "--depth-model", "m.onnx", "--fov", "50"])
    assert (args.depth_model, args.fov, args.preset) == ("m.onnx", 50.0, DEFAULT_CLI_PRESET)
    assert p.parse_args(["eval-real", "d", "--preset", "fast, accurate"]).preset == (
        "fast", "accurate")


@pytest.mark.parametrize("command", [["batch", "d", "--to", "1,2"], ["timelapse", "p.jpg",
                                                                     "-o", "o.mp4"]])
def test_fps_has_one_range_for_every_video_command(command, capsys) -> None:
    from outcast_core.runtime.pipeline.timelapse import MAX_FPS, MIN_FPS

    for bad in ("0.5", "0", "61", "nan"):
        with pytest.raises(SystemExit):
            main([*command, "--fps", bad])
        assert f"frames per second in [{MIN_FPS:g}, {MAX_FPS:g}]" in capsys.readouterr().err


def test_negative_azimuths_are_values_not_options() -> None:
    """``--to -90,30`` (a sun west of the camera) used to be refused with "expected one
    argument"; it is read as ``--to=-90,30``."""
    from outcast_core.runtime.cli.main import build_parser, join_negative_values

    argv = join_negative_values(["timelapse", "p.jpg", "--from", "-90,30", "--sweep",
                                 "-90,30:90,30", "-o", "o.mp4", "--frames", "-3"])
    assert argv == ["timelapse", "p.jpg", "--from=-90,30", "--sweep=-90,30:90,30", "-o", "o.mp4",
                    "--frames=-3"]
    args = build_parser().parse_args(join_negative_values(
        ["relight", "p.jpg", "--from", "-90,30", "--to", "-45.5,10", "-o", "o.jpg"]))
    assert (args.from_sun, args.to_sun) == ((-90.0, 30.0), (-45.5, 10.0))
    assert join_negative_values(["relight", "--", "-1"]) == ["relight", "--", "-1"]


def test_timelapse_says_an_odd_frame_size_is_padded_for_h264(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 61 x 41 photo at full size: the MP4 is 62 x 42 (H.264 needs even sides), and the
    command says so instead of announcing the photo's size."""
    import av

    from outcast_core.runtime.io.imageio import write_image

    photo = tmp_path / "odd.png"
    rng = np.random.default_rng(0)
    write_image(photo, rng.uniform(0.2, 0.8, (41, 61, 3)).astype(np.float32))
    out = tmp_path / "odd.mp4"
    assert main(["timelapse", str(photo), "--from", "120,40", "--sweep", "90,30:270,30",
                 "--frames", "2", "--size", "full", "--preset", "fast",
                 "-o", str(out)]) == 0
    assert "61x41 (full), written as 62x42 (H.264 needs even sides" in capsys.readouterr().err
    with av.open(str(out)) as c:
        ctx = c.streams.video[0].codec_context
        assert (ctx.width, ctx.height) == (62, 42)
    # The input options of the other commands (depth from a file or a model, the field of
    # view), and -q says nothing on success.
    depth = tmp_path / "d.npy"
    np.save(depth, np.full((41, 61), 5.0, np.float32))
    assert main(["timelapse", str(photo), "--from", "120,40", "--sweep", "90,30:270,30",
                 "--frames", "2", "--preset", "fast", "--depth", str(depth), "--fov", "50",
                 "-o", str(out), "--force", "-q"]) == 0
    assert capsys.readouterr().err == ""
    # A GIF faster than browsers play is said (its frames go 20 ms apart); 50 fps is not.
    gif = tmp_path / "fast.gif"
    for fps, said in (("60", True), ("50", False)):
        assert main(["timelapse", str(photo), "--from", "120,40", "--sweep", "90,30:270,30",
                     "--frames", "2", "--preset", "fast", "--depth", str(depth), "--fps", fps,
                     "-o", str(gif), "--force"]) == 0
        err = capsys.readouterr().err
        assert ("a GIF plays at most 50 fps: its frames are written 20 ms apart" in err) is said
        assert "the sweep turns" not in err  # 180 degrees as typed: no other way is shorter
    # A sweep the long way round (as typed) is said, with the other way (a user trial's
    # 320,15:30,15 went round behind the camera).
    assert main(["timelapse", str(photo), "--from", "120,40", "--sweep", "320,15:30,15",
                 "--frames", "2", "--preset", "fast", "--depth", str(depth),
                 "-o", str(gif), "--force"]) == 0
    assert ("note: the sweep turns 290° of azimuth as typed, through 175° (behind the camera); "
            "--sweep=320,15:390,15 turns the other way, 70°") in capsys.readouterr().err
    # The other way, as the note writes it, is taken by the parser and says nothing more.
    assert main(["timelapse", str(photo), "--from", "120,40", "--sweep=30,15:-40,15",
                 "--frames", "2", "--preset", "fast", "--depth", str(depth),
                 "-o", str(gif), "--force"]) == 0
    assert "the sweep turns" not in capsys.readouterr().err


def test_timelapse_takes_the_photos_own_sun_without_from(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    """Without ``--from`` the time-lapse takes the photo's sun as relight does (a user trial:
    it asked for ``--from`` where relight found the sun itself): the ski slope's sun in the
    frame; the field path, with no compass and no sun in the frame, is refused saying why."""
    samples = Path(__file__).resolve().parents[3] / "samples"
    out = tmp_path / "ski.gif"
    assert main(["timelapse", str(samples / "exif_005_es_skislope.jpg"), "--sweep",
                 "90,30:270,30", "--frames", "2", "--size", "working", "--preset", "fast",
                 "-o", str(out)]) == 0
    assert "original sun: azimuth 354." in capsys.readouterr().err and out.is_file()
    assert main(["timelapse", str(samples / "exif_001_cz_fieldpath.jpg"), "--sweep",
                 "90,30:270,30", "--frames", "2", "--size", "working", "--preset", "fast",
                 "-o", str(tmp_path / "field.gif")]) == 2
    assert "no --from and no sun from the photo" in capsys.readouterr().err
    assert not (tmp_path / "field.gif").exists()


def test_timelapse_of_a_day_says_nothing_with_q(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The field path has GPS and time but no compass: without -q the heading solved from the
    aligned sun is said, with -q nothing is."""
    photo = Path(__file__).resolve().parents[3] / "samples" / "exif_001_cz_fieldpath.jpg"
    args = ["timelapse", str(photo), "--from", "120,39", "--date", "2023-06-01", "--frames",
            "2", "--size", "working", "--preset", "fast", "-o", str(tmp_path / "day.gif")]
    assert main(args) == 0
    assert "camera heading solved" in capsys.readouterr().err
    assert main([*args, "--force", "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_timelapse_says_a_missing_sun_path_before_an_existing_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "a.gif"
    out.write_bytes(b"GIF89a")
    assert main(["timelapse", "p.jpg", "--from", "90,30", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exactly one of --sweep or --date" in err and "already exists" not in err


def test_progress_is_rewritten_on_a_terminal_and_separate_lines_in_a_log() -> None:
    """Progress went to stderr with ``\\r`` into logs too, where it ran into one line (a user
    trial): only a terminal gets ``\\r``; a log gets a line a tenth of a stage apart."""
    import io

    from outcast_core.runtime.cli.main import ProgressLine

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    tty, log = Terminal(), io.StringIO()
    for stream in (tty, log):
        progress = ProgressLine(stream)
        for stage, n in (("depth", 3), ("timelapse", 48)):
            for i in range(1, n + 1):
                progress(stage, i / n)
        progress.end_line()
    assert tty.getvalue().count("\r") == 51 and tty.getvalue().endswith("100.0 %\n")
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and lines[0] == "depth:  33 %"
    assert [x for x in lines if x.startswith("timelapse")][-1] == "timelapse: 100 %"
    assert len([x for x in lines if x.startswith("timelapse")]) == 11
    quiet = io.StringIO()
    ProgressLine(quiet, quiet=True)("depth", 0.5)
    assert quiet.getvalue() == ""


def test_progress_says_the_time_left_at_the_stages_own_pace() -> None:
    """After ETA_AFTER_S seconds of a stage, the time left from its pace since it began (a
    formula from the session's last stages was 4x off for time-lapses); a new stage starts
    its own clock; none at the end."""
    import io

    from outcast_core.runtime.cli.main import ProgressLine

    now = [0.0]
    log = io.StringIO()
    progress = ProgressLine(log, clock=lambda: now[0])
    for i in range(0, 11):  # 10 % every 2 s after a start at 0
        now[0] = 2.0 * i
        progress("timelapse", i / 10)
    now[0] = 100.0
    progress("writing", 0.5)  # a new stage: no pace yet
    lines = log.getvalue().splitlines()
    assert lines[0] == "timelapse:   0 %" and lines[1] == "timelapse:  10 %"  # 2 s: too soon
    assert lines[2] == "timelapse:  20 %, about 16 s left"  # 4 s for 20 %: 16 s for 80 %
    assert lines[9] == "timelapse:  90 %, about 2 s left"
    assert lines[10] == "timelapse: 100 %" and lines[11] == "writing:  50 %"
    now[0] = 110.0
    progress("writing", 0.1)  # the stage started over: its clock too
    now[0] = 114.0
    progress("writing", 0.5)
    assert log.getvalue().splitlines()[-1] == "writing:  50 %, about 5 s left"  # 0.4 in 4 s


def test_timelapse_progress_in_a_log_is_lines(photo: Path, tmp_path: Path, capsys) -> None:
    assert main(["timelapse", str(photo), "--from", "120,40", "--sweep", "1,20:90,20",
                 "--frames", "20", "--size", "working", "--preset", "fast", "-o",
                 str(tmp_path / "t.gif")]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and "\n\n" not in err
    frames = [line for line in err.splitlines() if line.startswith("timelapse:")]
    assert 2 <= len(frames) <= 11 and frames[-1] == "timelapse: 100 %"
    assert err.splitlines()[-1].startswith("wrote 20 frames to ")


def test_timelapse_refuses_the_other_path_s_options(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A sweep took --heading, --lat and --start, and a day --easing, without a word (a user
    trial): each is refused by name before any work, and nothing is written."""
    photo = Path(__file__).resolve().parents[3] / "samples" / "exif_001_cz_fieldpath.jpg"
    out = tmp_path / "t.gif"
    sweep = ["timelapse", str(photo), "--from", "120,39", "--sweep", "90,30:270,30", "--frames",
             "2", "--preset", "fast", "-o", str(out)]
    assert main([*sweep, "--heading", "30", "--lat", "10", "--start", "07:00"]) == 2
    err = capsys.readouterr().err
    assert "--lat, --heading, --start apply to --date (a real day's sun path) only" in err
    assert main([*sweep, "--utc-offset", "2"]) == 2
    assert "--utc-offset applies to --date" in capsys.readouterr().err
    day = ["timelapse", str(photo), "--from", "120,39", "--date", "2023-06-01", "--frames", "2",
           "--preset", "fast", "-o", str(out), "--easing", "linear"]
    assert main(day) == 2
    assert "--easing applies to --sweep only" in capsys.readouterr().err
    assert not out.exists()


def test_a_black_and_white_file_is_written_back_in_one_channel(tmp_path: Path) -> None:
    """A greyscale JPEG was relit and de-shadowed into three equal channels (a user trial):
    what is made of a one-channel file has one channel, at the same size."""
    from PIL import Image

    rng = np.random.default_rng(0)
    grey = rng.integers(90, 200, (96, 128), dtype=np.uint8)
    grey[60:80, 20:100] //= 3  # a shadow-like band
    photo = tmp_path / "bw.jpg"
    Image.fromarray(grey, "L").save(photo, quality=95)
    colour = tmp_path / "colour.jpg"
    Image.fromarray(np.repeat(grey[..., None], 3, 2)).save(colour, quality=95)
    for cmd, src, name in (("relight", photo, "r.jpg"), ("deshadow", photo, "d.png"),
                           ("relight", colour, "c.jpg")):
        out = tmp_path / name
        extra = ["--to", "90,30"] if cmd == "relight" else []
        assert main([cmd, str(src), "--from", "200,40", *extra, "--preset", "fast",
                     "-o", str(out)]) == 0
        with Image.open(out) as im:
            assert im.size == (128, 96)
            assert im.mode == ("RGB" if src == colour else "L"), (name, im.mode)
