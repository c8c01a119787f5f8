"""Sun paths and frame writers of outcast_core.runtime.pipeline.timelapse (no Qt, no torch)."""

from __future__ import annotations

import argparse
import datetime as dt
import threading

import av
import numpy as np
import pytest
from PIL import Image

from outcast_core.runtime.cli.timelapse_cli import _samples_from_args, register
from outcast_core.runtime.geometry.camera import sun_angles, sun_vector
from outcast_core.runtime.pipeline import timelapse as tl


def _frame(i: int, h: int = 33, w: int = 47) -> np.ndarray:
    """A frame whose mean brightness encodes its index (decodable after lossy coding)."""
    img = np.zeros((h, w, 3), np.float32)
    img[..., 0] = np.linspace(0, 1, w)[None, :]
    img[..., 1] = (i * 40 % 256) / 255.0
    img[..., 2] = 0.5
    return img


# ------------------------------------------------------------------ paths


@pytest.mark.parametrize("easing", tl.EASINGS)
def test_ease_endpoints_and_monotonic(easing):
    t = np.linspace(0, 1, 51)
    e = tl.ease(t, easing)
    assert e[0] == pytest.approx(0.0) and e[-1] == pytest.approx(1.0)
    assert np.all(np.diff(e) >= -1e-12)


def test_ease_rejects_unknown():
    with pytest.raises(ValueError, match="expected an easing"):
        tl.ease(0.5, "bounce")


def test_sweep_endpoints_count_and_wrap():
    path = tl.sweep_path((300.0, 10.0), (420.0, 50.0), 7, "ease-in-out")
    assert len(path) == 7
    assert path[0].azimuth == pytest.approx(300.0) and path[0].elevation == pytest.approx(10.0)
    assert path[-1].azimuth == pytest.approx(60.0) and path[-1].elevation == pytest.approx(50.0)
    assert path[3].azimuth == pytest.approx(0.0)  # midpoint of 300 -> 420 with symmetric easing
    assert all(0.0 <= s.azimuth < 360.0 for s in path)


def test_sweep_easing_slows_ends():
    lin = [s.elevation for s in tl.sweep_path((0, 0), (0, 60), 11, "linear")]
    eio = [s.elevation for s in tl.sweep_path((0, 0), (0, 60), 11, "ease-in-out")]
    assert eio[1] - eio[0] < lin[1] - lin[0]
    assert eio[6] - eio[5] > lin[6] - lin[5]


@pytest.mark.parametrize(
    "args", [((0, 0), (10, 10), 0), ((0, 95), (10, 10), 3), ((0, float("nan")), (1, 1), 3)]
)
def test_sweep_rejects_bad_input(args):
    with pytest.raises(ValueError, match="expected"):
        tl.sweep_path(*args)


def _unit(az, el):
    a, e = np.radians(az), np.radians(el)
    return np.array([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)])


@pytest.mark.parametrize(
    "when, lat, lon, ref",
    [  # samples/README.md (NREL SPA, no refraction)
        (dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC), 7.831431, 98.296653, (76.6, 66.6)),
        (dt.datetime(2018, 7, 25, 14, 34, 23, tzinfo=dt.UTC), 50.299603, 14.820294, (252.6, 39.3)),
        (dt.datetime(2022, 2, 3, 14, 44, 9, tzinfo=dt.UTC), 40.788685, -4.005141, (215.7, 24.6)),
    ],
)
def test_true_sun_matches_sample_readme(when, lat, lon, ref):
    az, el = tl.true_sun_position(when, lat, lon)
    # astral differs from SPA by about 0.28 deg here (measured); alignment by eye is coarser.
    sep = np.degrees(np.arccos(np.clip(_unit(az, el) @ _unit(*ref), -1.0, 1.0)))
    assert sep < 0.5


def test_naive_time_is_local():
    when = dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC)
    az, el = tl.true_sun_position(when, 7.831431, 98.296653)
    # A naive time is local at the given offset.
    az2, el2 = tl.true_sun_position(dt.datetime(2019, 8, 21, 10, 57, 22), 7.831431, 98.296653, 7)
    assert (az2, el2) == pytest.approx((az, el))


def test_heading_round_trip_and_solve():
    for true_az, heading in [(76.6, 163.7), (10.0, 350.0), (200.0, 20.0)]:
        rel = tl.relative_azimuth(true_az, heading)
        assert tl.heading_from_sun(true_az, rel) == pytest.approx(heading % 360.0)
    when = dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC)
    true_az, _ = tl.true_sun_position(when, 7.831431, 98.296653)
    rel = tl.relative_azimuth(true_az, 163.7)  # what a user aligning the pool photo should find
    assert tl.solve_heading(when, 7.831431, 98.296653, rel) == pytest.approx(163.7, abs=1e-6)


def test_a_tilted_camera_sees_the_true_sun_in_its_own_frame():
    """The EXIF sun, the solved heading and the real path's vectors take the camera's pitch and
    roll: a camera pitched 20 deg down sees a sun 40 deg up behind it at 20 deg, ahead at 60."""
    from outcast_core.runtime.geometry.camera import sun_vector

    class Exif:
        capture_time = dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC)
        latitude, longitude, heading_deg = 7.831431, 98.296653, None

    behind = tl.sun_vectors([tl.SunSample(180.0, 40.0, tilt=(-20.0, 0.0))])[0]
    ahead = tl.sun_vectors([tl.SunSample(0.0, 40.0, tilt=(-20.0, 0.0))])[0]
    assert sun_angles(behind) == pytest.approx((180.0, 20.0))
    assert sun_angles(ahead) == pytest.approx((0.0, 60.0))
    # A sun under the horizon is lifted in the horizon's frame, then turned into the camera's.
    low = tl.sun_vectors([tl.SunSample(90.0, -5.0, tilt=(10.0, 5.0))])[0]
    assert low == pytest.approx(sun_vector(90.0, tl.MIN_RENDER_ELEVATION, 10.0, 5.0))

    level = tl.exif_sun(Exif(), heading=163.7)
    assert level == pytest.approx((273.5, 66.8), abs=0.1)
    for tilt in [(-25.0, 0.0), (-10.0, 6.0), (15.0, -3.0)]:
        cam = tl.exif_sun(Exif(), heading=163.7, tilt=tilt)
        assert cam == pytest.approx(sun_angles(sun_vector(*level, *tilt)), abs=1e-9)
        assert abs(cam[1] - level[1]) > 2.0
        # The heading solved from the sun aligned in the camera's frame is the compass's again.
        solved = tl.solve_heading(Exif.capture_time, Exif.latitude, Exif.longitude, cam[0],
                                  original_elevation=cam[1], tilt=tilt)
        assert solved == pytest.approx(163.7, abs=1e-6)
        # So is the heading a sun seen in the frame implies (exif_sun gives that sun back).
        seen = tl.exif_heading_from_sun(Exif(), *cam, tilt=tilt)
        assert seen == pytest.approx(163.7, abs=1e-6)
    wrong_compass = tl.exif_sun(Exif(), heading=40.0)
    assert tl.exif_heading_from_sun(Exif(), *wrong_compass) == pytest.approx(40.0, abs=1e-6)
    assert tl.exif_heading_from_sun(object(), *level) is None  # no GPS and time
    with pytest.raises(ValueError, match="elevation"):
        tl.solve_heading(Exif.capture_time, 7.8, 98.3, 10.0, tilt=(-5.0, 0.0))
    # A camera pitched 80 deg up has the sun ahead of it, 66.8 deg up, 13.2 deg under its own
    # horizon: the vector is kept as it is (the app's dial clamps it).
    true_az, el = tl.true_sun_position(Exif.capture_time, Exif.latitude, Exif.longitude)
    ahead_up = tl.exif_sun(Exif(), heading=true_az, tilt=(80.0, 0.0))
    assert ahead_up == pytest.approx((0.0, el - 80.0), abs=1e-9)
    path = tl.real_sun_path(dt.date(2019, 8, 21), 7.83, 98.3, 163.7, 3, tilt=(-20.0, 1.0))
    assert all(p.tilt == (-20.0, 1.0) for p in path)
    want = [sun_vector(p.azimuth, max(p.elevation, tl.MIN_RENDER_ELEVATION), -20.0, 1.0)
            for p in path]
    assert np.allclose(tl.sun_vectors(path), want)


def test_real_sun_path_day():
    day = dt.date(2019, 8, 21)
    path = tl.real_sun_path(day, 7.831431, 98.296653, heading=163.7, frames=9, utc_offset_hours=7)
    assert len(path) == 9
    assert path[0].time.hour in (5, 6) and path[-1].time.hour in (18, 19)
    els = [s.elevation for s in path]
    assert abs(els[0]) < 1.5 and abs(els[-1]) < 1.5  # sunrise / sunset
    assert max(els) > 60.0 and int(np.argmax(els)) in (3, 4, 5)
    for s in path:  # relative = true - heading
        assert s.azimuth == pytest.approx((s.true_azimuth - 163.7) % 360.0)


def test_real_sun_path_times_and_errors():
    day = dt.date(2019, 8, 21)
    path = tl.real_sun_path(
        day, 7.83, 98.3, 0.0, 3, start=dt.time(9, 0), end=dt.time(15, 0), utc_offset_hours=7
    )
    assert [s.time.hour for s in path] == [9, 12, 15]
    with pytest.raises(ValueError, match="end time after"):
        tl.real_sun_path(day, 7.83, 98.3, 0.0, 3, start=dt.time(15, 0), end=dt.time(9, 0))
    # Polar night: no times to give (a user trial was told to give a start and end time, then
    # that the sun was down all the time); polar day: a start and end time are the way.
    with pytest.raises(ValueError, match=r"polar night.*choose another date"):
        tl.real_sun_path(dt.date(2020, 12, 21), 80.0, 15.0, 0.0, 3)
    with pytest.raises(ValueError, match=r"polar day.*give a start and end time"):
        tl.real_sun_path(dt.date(2020, 6, 21), 80.0, 15.0, 0.0, 3)
    with pytest.raises(ValueError, match=r"polar night"):  # the south's winter
        tl.real_sun_path(dt.date(2020, 6, 21), -80.0, -60.0, 0.0, 3)
    assert len(tl.real_sun_path(dt.date(2020, 6, 21), 80.0, 15.0, 0.0, 3, start=dt.time(1),
                                end=dt.time(23))) == 3
    # An ordinary day whose local morning is the UTC day before: astral's sunrise failed
    # there and it was taken for a polar day (a review); as astral's elsewhere, to a minute.
    import astral.sun

    rise, sset = tl.daylight_range(dt.date(2021, 4, 17), 40.0, 80.0)
    assert (rise.hour, sset.hour) == (4, 18)
    for lat, lon, when in ((7.83, 98.3, dt.date(2019, 3, 1)), (50.0, 14.0, dt.date(2023, 6, 1)),
                           (-33.0, 151.0, dt.date(2023, 1, 5)), (69.0, 18.0, dt.date(2023, 5, 9))):
        tz = dt.timezone(dt.timedelta(hours=round(lon / 15)))
        ours = tl.daylight_range(when, lat, lon, round(lon / 15))
        obs = tl._observer(lat, lon)
        theirs = (astral.sun.sunrise(obs, when, tzinfo=tz), astral.sun.sunset(obs, when, tzinfo=tz))
        for a, b in zip(ours, theirs, strict=True):
            assert abs((a - b).total_seconds()) < 90, (lat, a, b)
    with pytest.raises(ValueError, match="latitude"):
        tl.real_sun_path(day, 95.0, 0.0, 0.0, 3)


def test_sun_vectors_lift_low_sun():
    vs = tl.sun_vectors([tl.SunSample(90.0, -10.0), tl.SunSample(45.0, 30.0)])
    az0, el0 = sun_angles(vs[0])
    az1, el1 = sun_angles(vs[1])
    assert el0 == pytest.approx(tl.MIN_RENDER_ELEVATION) and az0 == pytest.approx(90.0)
    assert (az1, el1) == pytest.approx((45.0, 30.0))


# ------------------------------------------------------------------ writers


def test_mp4_decodes_back_with_even_size(tmp_path):
    out = tmp_path / "clip.mp4"
    seen = []
    tl.export_frames(_frame, 5, out, fps=10, progress=lambda s, f: seen.append(f))
    assert seen == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    with av.open(str(out)) as c:
        stream = c.streams.video[0]
        assert stream.codec_context.name == "h264"
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(stream)]
        assert c.streams.video[0].codec_context.pix_fmt == "yuv420p"
    assert len(frames) == 5
    assert frames[0].shape == (34, 48, 3)
    greens = [f[:33, :47, 1].mean() for f in frames]
    assert np.all(np.diff(greens) > 20)  # the frames come back in order
    assert list(tmp_path.iterdir()) == [out]  # no temp file left


@pytest.mark.parametrize("ext", ["gif", "webp"])
def test_animated_images(tmp_path, ext):
    out = tmp_path / f"clip.{ext}"
    tl.export_frames(lambda i: _frame(i, 20, 30), 4, out, fps=8)
    with Image.open(out) as im:
        assert im.n_frames == 4 and im.size == (30, 20)
        assert im.info.get("loop") == 0
    assert list(tmp_path.iterdir()) == [out]


def test_png_sequence(tmp_path):
    out = tmp_path / "frames"
    tl.export_frames(lambda i: (_frame(i) * 255).astype(np.uint8), 3, out)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["frame_0001.png", "frame_0002.png", "frame_0003.png"]
    with Image.open(out / names[0]) as im:
        assert im.size == (47, 33)
    assert list(tmp_path.iterdir()) == [out]


def test_png_sequence_replaces_only_its_own_frames(tmp_path, monkeypatch):
    out = tmp_path / "frames"
    tl.export_frames(lambda i: _frame(i), 3, out)
    with pytest.raises(FileExistsError):  # an earlier sequence needs force
        tl.export_frames(lambda i: _frame(i), 2, out)
    tl.export_frames(lambda i: _frame(i), 2, out, force=True)
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.png", "frame_0002.png"]
    # A folder the user keeps other files in is refused, even with force, and left as it was.
    (out / "notes.txt").write_text("keep")
    with pytest.raises(FileExistsError, match="notes.txt"):
        tl.export_frames(lambda i: _frame(i), 2, out, force=True)
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.png", "frame_0002.png",
                                                      "notes.txt"]
    # "-o . --force" in a folder with the user's files: refused before any frame is drawn.
    work = tmp_path / "work"
    work.mkdir()
    (work / "precious.txt").write_text("keep")
    monkeypatch.chdir(work)
    drawn = []
    with pytest.raises(FileExistsError, match="precious.txt"):
        tl.export_frames(lambda i: drawn.append(i) or _frame(i), 2, ".", force=True)
    assert drawn == [] and sorted(p.name for p in work.iterdir()) == ["precious.txt"]


def test_png_sequence_keeps_the_old_frames_when_a_file_appears_meanwhile(tmp_path):
    out = tmp_path / "frames"
    tl.export_frames(lambda i: _frame(i), 3, out)
    (out / ".DS_Store").write_text("a file manager's")  # ignored, and left

    def render(i):
        if i == 1:  # the user saves a file into the folder while the frames render
            (out / "notes.txt").write_text("keep")
        return _frame(i)

    with pytest.raises(FileExistsError, match="notes.txt"):
        tl.export_frames(render, 2, out, force=True)
    names = sorted(p.name for p in out.iterdir())
    assert names == [".DS_Store", "frame_0001.png", "frame_0002.png", "frame_0003.png",
                     "notes.txt"]  # no temp folder, nothing lost


def test_png_sequence_clears_what_a_killed_export_left(tmp_path):
    out = tmp_path / "frames"
    tl.export_frames(lambda i: _frame(i), 2, out)
    dead = out / f"{tl.PART_PREFIX}999999999-abc"  # no such process
    dead.mkdir()
    (dead / "frame_0001.png").write_bytes(b"half")
    alive = out / f"{tl.PART_PREFIX}1-xyz"  # init: always there
    alive.mkdir()
    tl.export_frames(lambda i: _frame(i), 2, out, force=True)
    assert not dead.exists() and alive.is_dir()
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "frame_0001.png", "frame_0002.png"]


def test_png_sequence_into_an_empty_folder(tmp_path, monkeypatch):
    out = tmp_path / "empty"
    out.mkdir()
    tl.export_frames(lambda i: _frame(i), 2, out)  # nothing to overwrite: no force needed
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.png", "frame_0002.png"]
    monkeypatch.chdir(out)
    tl.export_frames(lambda i: _frame(i), 1, ".", force=True)  # "." works as a folder
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty"]  # no temp folder left


@pytest.mark.parametrize("name", ["a.mp4", "a.gif", "a.webp", "seq"])
def test_cancel_midway_leaves_nothing(tmp_path, name):
    stop = threading.Event()

    def render(i):
        if i == 2:
            stop.set()
        return _frame(i)

    with pytest.raises(tl.ExportCancelledError):
        tl.export_frames(render, 6, tmp_path / name, cancel=stop)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["a.mp4", "a.webp", "seq"])
def test_failed_render_leaves_nothing(tmp_path, name):
    def render(i):
        if i == 3:
            raise RuntimeError("boom")
        return _frame(i)

    with pytest.raises(RuntimeError, match="boom"):
        tl.export_frames(render, 6, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["a.mp4", "a.gif", "seq"])
def test_never_overwrites_unless_forced(tmp_path, name):
    out = tmp_path / name
    tl.export_frames(_frame, 2, out)
    stamp = out.stat().st_mtime_ns
    with pytest.raises(FileExistsError):
        tl.export_frames(_frame, 2, out)
    assert out.stat().st_mtime_ns == stamp
    tl.export_frames(_frame, 3, out, force=True)
    assert len(list(tmp_path.iterdir())) == 1


def test_file_appearing_during_export_is_not_clobbered(tmp_path):
    out = tmp_path / "race.gif"

    def render(i):
        if i == 1:
            out.write_bytes(b"user's file")
        return _frame(i)

    with pytest.raises(FileExistsError):
        tl.export_frames(render, 3, out)
    assert out.read_bytes() == b"user's file"
    assert list(tmp_path.iterdir()) == [out]


def test_mismatched_frame_sizes_fail_cleanly(tmp_path):
    with pytest.raises(ValueError, match="expected every frame"):
        tl.export_frames(lambda i: _frame(0, 20 + i, 30), 3, tmp_path / "x.mp4")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ CLI parsing


def _parse(argv):
    parser = argparse.ArgumentParser(prog="outcast")
    register(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


class _Exif:
    latitude = 7.831431
    longitude = 98.296653
    capture_time = dt.datetime(2019, 8, 21, 3, 57, 22, tzinfo=dt.UTC)


def test_cli_sweep_arguments():
    args = _parse(
        [
            "timelapse",
            "x.jpg",
            "--from",
            "40,60",
            "--sweep",
            "90,10:270,10",
            "--frames",
            "5",
            "-o",
            "o.mp4",
        ]
    )
    assert args.func.__name__ == "run_timelapse_command"
    samples = _samples_from_args(args, None)
    assert len(samples) == 5 and samples[0].azimuth == pytest.approx(90.0)
    assert samples[-1].azimuth == pytest.approx(270.0)


def test_cli_date_solves_heading_from_exif():
    when = _Exif.capture_time
    true_az, _ = tl.true_sun_position(when, _Exif.latitude, _Exif.longitude)
    rel = tl.relative_azimuth(true_az, 163.7)
    args = _parse(
        [
            "timelapse",
            "x.jpg",
            "--from",
            f"{rel},66",
            "--date",
            "2019-08-21",
            "--start",
            "08:00",
            "--end",
            "16:00",
            "--frames",
            "3",
            "-o",
            "o.mp4",
        ]
    )
    samples = _samples_from_args(args, _Exif())
    assert len(samples) == 3
    for s in samples:
        assert s.azimuth == pytest.approx((s.true_azimuth - 163.7) % 360.0, abs=1e-6)
    # With the camera's tilt (the photo's pose, else its ground plane) the --from sun is in the
    # camera's frame: the heading is solved in the horizon's, and the path carries the tilt.
    tilt = (-15.0, 3.0)
    cam_az, cam_el = sun_angles(sun_vector(rel, 66.0, *tilt))
    args.from_sun = (cam_az, cam_el)
    samples = _samples_from_args(args, _Exif(), lambda: (*tilt, "ground plane"))
    assert [s.tilt for s in samples] == [tilt] * 3
    for s in samples:
        assert s.azimuth == pytest.approx((s.true_azimuth - 163.7) % 360.0, abs=1e-6)


def test_cli_refuses_a_window_with_no_sun():
    """Every frame below the horizon (a night window): refused, not 48 identical frames at
    the horizon (a user trial)."""
    args = _parse(["timelapse", "x.jpg", "--from", "0,30", "--date", "2019-08-21", "--lat",
                   "7.83", "--lon", "98.3", "--heading", "160", "--utc-offset", "7",
                   "--start", "20:00", "--end", "22:00", "-o", "o.mp4"])
    with pytest.raises(ValueError, match="below the horizon for the whole time-lapse from 20:00"):
        _samples_from_args(args, None)
    args.start, args.end = dt.time(17, 0), dt.time(20, 0)  # the sun sets in it: fine
    assert len(_samples_from_args(args, None)) == 48


def test_cli_errors():
    with pytest.raises(ValueError, match="exactly one"):
        _samples_from_args(_parse(["timelapse", "x", "--from", "0,30", "-o", "o.mp4"]), None)
    with pytest.raises(ValueError, match="--frames"):
        args = _parse(["timelapse", "x", "--from", "0,30", "--sweep", "0,1:2,3", "-o", "o.mp4"])
        _samples_from_args(args, None)
    with pytest.raises(ValueError, match="--lat"):
        args = _parse(["timelapse", "x", "--from", "0,30", "--date", "2020-01-01", "-o", "o.mp4"])
        _samples_from_args(args, None)
    with pytest.raises(SystemExit):
        _parse(["timelapse", "x", "--from", "0;30", "--date", "2020-01-01", "-o", "o.mp4"])


def test_cli_refuses_an_end_before_the_start_before_any_work(tmp_path, capsys):
    """``--start 18:00 --end 06:00`` is refused before the photo's depth is estimated and the
    heading solved (it was said after both: a user trial), whatever the photo."""
    from outcast_core.runtime.cli.main import main
    from outcast_core.runtime.io.imageio import write_image

    photo = tmp_path / "p.png"
    write_image(photo, np.full((32, 48, 3), 0.5, np.float32))
    rc = main(["timelapse", str(photo), "--from", "0,30", "--date", "2019-06-21", "--lat", "50",
               "--lon", "14", "--heading", "0", "--start", "18:00", "--end", "06:00",
               "-o", str(tmp_path / "t.gif")])
    err = capsys.readouterr().err
    assert rc == 2 and "expected the end time after the start time, got 18:00 -> 06:00" in err
    assert "depth" not in err.lower() and "heading" not in err.lower()
    assert not (tmp_path / "t.gif").exists()
    # A time typed with an offset is compared as the clock time it is (no traceback).
    args = _parse(["timelapse", "x.jpg", "--from", "0,30", "--date", "2019-06-21", "--lat",
                   "50", "--lon", "14", "--heading", "0", "--start", "06:00+02:00", "--end",
                   "18:00", "-o", "o.mp4"])
    assert len(_samples_from_args(args, None)) == 48
    args.start, args.end = dt.time(18, 0, tzinfo=dt.UTC), dt.time(6, 0)
    with pytest.raises(ValueError, match="end time after the start time"):
        _samples_from_args(args, None)


def test_cli_end_to_end_writes_and_refuses_overwrite(tmp_path):
    from outcast_core.runtime.cli.main import main

    photo = tmp_path / "p.png"
    rng = np.random.default_rng(1)
    Image.fromarray((rng.random((48, 64, 3)) * 255).astype(np.uint8)).save(photo)
    out = tmp_path / "clip.mp4"
    argv = ["timelapse", str(photo), "--from", "120,40", "--sweep", "90,20:270,20",
            "--frames", "4", "-o", str(out), "--preset", "fast"]  # fmt: skip
    assert main(argv) == 0
    with av.open(str(out)) as c:
        frames = list(c.decode(video=0))
    assert len(frames) == 4 and (frames[0].width, frames[0].height) == (64, 48)
    stamp = out.stat().st_mtime_ns
    assert main(argv) == 2  # exists: refused without --force
    assert out.stat().st_mtime_ns == stamp
    assert main([*argv, "--force"]) == 0


def test_the_calendars_ends_are_refused_in_one_line() -> None:
    """``--date 0001-01-01`` or ``9999-12-31`` ended in an OverflowError's traceback inside
    the sunrise search (a user trial): the first and last days are refused as a value, the
    ones inside them work."""
    from outcast_core.runtime.pipeline.timelapse import FIRST_DAY, LAST_DAY, real_sun_path

    for day in (dt.date.min, dt.date.max):
        with pytest.raises(ValueError, match="expected a date from 0001-01-02 to 9999-12-30"):
            real_sun_path(day, 7.8, 98.3, 164.0, 3, utc_offset_hours=7.0)
    for day in (FIRST_DAY, LAST_DAY):
        assert len(real_sun_path(day, 7.8, 98.3, 164.0, 3, utc_offset_hours=7.0)) == 3
        # The zones furthest from UTC: the scan stops at the calendar's ends (it overflowed,
        # then called an ordinary day at 40 N a polar day: a review).
        for lon, offset in ((0.0, 14.0), (0.0, -12.0), (170.0, 0.0), (-170.0, 0.0)):
            rise, sset = tl.daylight_range(day, 40.0, lon, offset)
            assert dt.timedelta(hours=8) < sset - rise < dt.timedelta(hours=11)
    with pytest.raises(ValueError, match="expected a date from 0001-01-02 to 9999-12-30"):
        tl.daylight_range(dt.date.min, 40.0, 0.0)


def test_a_night_time_exif_clock_solves_no_heading(capsys) -> None:
    """A copy of the pool sample with its capture time moved to 02:00 solved a heading of
    135.7 degrees from a sun 60 degrees below the horizon, in silence (a user trial; its
    compass says 163.7): no heading is solved from a sun below the horizon; the command line
    takes the EXIF compass heading then, saying so, or asks for ``--heading``."""
    night = dt.datetime(2019, 8, 21, 19, 0, tzinfo=dt.UTC)  # 02:00 local
    with pytest.raises(tl.SunBelowHorizonError, match=r"the sun was 60\.\d° below the horizon"):
        tl.solve_heading(night, _Exif.latitude, _Exif.longitude, 273.0)
    # Its own error: another (a tilt without the sun's elevation) is no reason for the compass.
    with pytest.raises(ValueError, match="elevation with a camera tilt") as info:
        tl.solve_heading(_Exif.capture_time, _Exif.latitude, _Exif.longitude, 273.0,
                         tilt=(-10.0, 0.0))
    assert not isinstance(info.value, tl.SunBelowHorizonError)
    args = _parse(["timelapse", "x.jpg", "--from", "273,67", "--date", "2019-08-21",
                   "--frames", "3", "-o", "o.mp4"])

    class Night(_Exif):
        capture_time = night
        heading_deg = 163.7

    samples = _samples_from_args(args, Night())
    assert all(s.azimuth == pytest.approx((s.true_azimuth - 163.7) % 360.0) for s in samples)
    assert "the EXIF compass heading is taken: 163.7 deg" in capsys.readouterr().err
    Night.heading_deg = None
    with pytest.raises(ValueError, match="cannot be solved from the aligned sun: give "
                                         "--heading DEG"):
        _samples_from_args(args, Night())


class _SummerExif:
    """The field-path sample's place with a summer zone (UTC+2) its EXIF gives; the longitude's
    guess is UTC+1."""

    latitude = 49.1
    longitude = 15.2
    capture_time = dt.datetime(2018, 7, 25, 11, 0, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    tz_offset = dt.timedelta(hours=2)
    heading_deg = None


def _evening(extra: list[str]) -> argparse.Namespace:
    return _parse(["timelapse", "x.jpg", "--from", "33,39", "--date", "2018-07-25", "--start",
                   "20:00", "--end", "20:50", "--frames", "3", "-o", "o.gif", *extra])


def test_start_and_end_are_read_at_the_photos_own_time_zone(capsys) -> None:
    """``--start``/``--end`` were read at the longitude's zone, not the photo's EXIF one the app
    takes: a summer evening 20:00-20:50 (UTC+2) at the field-path sample was refused as after
    sunset (a user trial). The zone is the photo's, ``--utc-offset``'s, or with ``--lon`` the
    longitude's, and the command says which."""
    samples = _samples_from_args(_evening([]), _SummerExif())
    assert samples[0].time.utcoffset() == dt.timedelta(hours=2)
    assert samples[0].elevation > 3.0  # (the sun sets at about 20:45 there)
    err = capsys.readouterr().err
    assert "from 20:00 to 20:50 local time (UTC+02:00, from the photo's EXIF)" in err
    # The longitude's zone reads the same clock an hour later: after sunset, refused.
    with pytest.raises(ValueError, match=r"below the horizon .* \(UTC\+01:00, from "
                                         r"--utc-offset\)"):
        _samples_from_args(_evening(["--utc-offset", "1"]), _SummerExif())
    samples = _samples_from_args(_evening(["--utc-offset", "3"]), _SummerExif())
    assert samples[0].time.utcoffset() == dt.timedelta(hours=3)
    assert "UTC+03:00, from --utc-offset" in capsys.readouterr().err


def test_the_zone_of_start_and_end_is_chosen_as_said() -> None:
    """Which zone ``--start``/``--end`` are read at (:func:`local_zone`): a zone typed with
    the times; the photo's own when the place is the photo's, or the photo has no GPS and
    ``--lat/--lon`` are typed (a camera that writes its zone but no position: a review), or
    ``--lon`` is within 7.5 degrees of the photo's; else the longitude's."""
    from outcast_core.runtime.cli.timelapse_cli import local_zone

    class NoGps:
        latitude = longitude = None
        tz_offset = dt.timedelta(hours=2)

    def zone(extra: list[str], exif: object, lon: float) -> tuple[float, str]:
        return local_zone(_evening(extra), exif, lon)

    assert zone([], _SummerExif(), 15.2) == (2.0, "the photo's EXIF")
    assert zone(["--lat", "49", "--lon", "15.2"], NoGps(), 15.2) == (2.0, "the photo's EXIF")
    assert zone(["--lat", "49", "--lon", "20"], _SummerExif(), 20.0)[0] == 2.0
    assert zone(["--lat", "40", "--lon", "-74"], _SummerExif(), -74.0) == (
        -5.0, "the longitude of --lon")
    assert zone([], object(), 98.3) == (7.0, "its longitude (the photo gives none)")
    args = _parse(["timelapse", "x.jpg", "--from", "33,39", "--date", "2018-07-25", "--start",
                   "20:00+05:30", "--end", "20:50", "-o", "o.gif"])
    assert local_zone(args, _SummerExif(), 15.2) == (5.5, "the zone typed with the times")
    samples = _samples_from_args(args, _SummerExif())
    assert samples[0].time.utcoffset() == dt.timedelta(hours=5, minutes=30)
    args.end = dt.time(20, 50, tzinfo=dt.UTC)
    with pytest.raises(ValueError, match="--start and --end in one time zone"):
        local_zone(args, _SummerExif(), 15.2)
    args.end, args.utc_offset = dt.time(20, 50), 2.0
    with pytest.raises(ValueError, match=r"--utc-offset to agree .* \(UTC\+05:30\), got 2"):
        local_zone(args, _SummerExif(), 15.2)


def test_a_capture_time_without_a_zone_is_read_at_the_longitudes_zone(capsys) -> None:
    """A camera's bare clock was read as UTC when the command solved the heading (the app reads
    it at its longitude's zone): a photo at longitude 98.3 solved a heading hours of sun
    off."""

    class Bare(_Exif):
        capture_time = dt.datetime(2019, 8, 21, 10, 57, 22)  # _Exif's 03:57 UTC, at UTC+7

    true_az, _ = tl.true_sun_position(_Exif.capture_time, _Exif.latitude, _Exif.longitude)
    rel = tl.relative_azimuth(true_az, 163.7)
    args = _parse(["timelapse", "x.jpg", "--from", f"{rel},66", "--date", "2019-08-21",
                   "--frames", "3", "-o", "o.mp4"])
    samples = _samples_from_args(args, Bare())
    for s in samples:
        assert s.azimuth == pytest.approx((s.true_azimuth - 163.7) % 360.0, abs=1e-6)
    assert "its time read at UTC+07:00, from its longitude" in capsys.readouterr().err


def test_a_compass_far_from_the_solved_heading_is_said(capsys) -> None:
    """The pool sample solved 237.2 degrees from a ``--from`` sun while its EXIF compass says
    163.7, in silence (a user trial): a compass more than 30 degrees off is said, with the
    option that takes it; one that agrees is not."""

    class Compass(_Exif):
        heading_deg = 163.7

    true_az, _ = tl.true_sun_position(_Exif.capture_time, _Exif.latitude, _Exif.longitude)
    for heading, said in ((237.2, True), (170.0, False)):
        rel = tl.relative_azimuth(true_az, heading)
        args = _parse(["timelapse", "x.jpg", "--from", f"{rel},66", "--date", "2019-08-21",
                       "--frames", "2", "-o", "o.mp4"])
        _samples_from_args(args, Compass())
        err = capsys.readouterr().err
        assert ("EXIF compass heading is 163.7 deg, 74 deg from it" in err) is said
        assert ("--heading 163.7 takes the compass's" in err) is said
    # A magnetic compass is not offered as a true heading.
    Compass.heading_ref = "M"
    rel = tl.relative_azimuth(true_az, 237.2)
    args = _parse(["timelapse", "x.jpg", "--from", f"{rel},66", "--date", "2019-08-21",
                   "--frames", "2", "-o", "o.mp4"])
    _samples_from_args(args, Compass())
    err = capsys.readouterr().err
    assert "163.7 deg from magnetic north, 74 deg from it" in err
    assert "--heading 163.7" not in err


def test_the_seen_suns_heading_reads_a_bare_capture_time_at_its_longitudes_zone() -> None:
    """:func:`exif_heading_from_sun` read a capture time without a zone as UTC, where
    :func:`exif_sun` reads it at its longitude's: the heading it gave did not give the seen
    sun back (a review)."""

    class Bare(_Exif):
        capture_time = dt.datetime(2019, 8, 21, 10, 57, 22)  # 03:57 UTC at UTC+7
        heading_deg = None

    heading = tl.exif_heading_from_sun(Bare(), 20.0, 60.0)
    assert heading == pytest.approx(tl.exif_heading_from_sun(_Exif(), 20.0, 60.0), abs=1e-6)
    assert tl.exif_sun(Bare(), heading=heading)[0] == pytest.approx(20.0, abs=1e-6)


def test_a_date_the_month_does_not_have_is_named() -> None:
    """2018-02-30 was told "expected YYYY-MM-DD", the form it has (a user trial)."""
    from outcast_core.runtime.cli.timelapse_cli import _date

    with pytest.raises(argparse.ArgumentTypeError, match="no such day: '2018-02-30'"):
        _date("2018-02-30")
    with pytest.raises(argparse.ArgumentTypeError, match="expected YYYY-MM-DD, got '18-2-3'"):
        _date("18-2-3")
    with pytest.raises(argparse.ArgumentTypeError, match="no such day: '2018-02-30'"):
        _date(" 2018-02-30 ")
    assert _date("2024-02-29") == dt.date(2024, 2, 29)


def test_a_gifs_frames_keep_the_frame_rate(tmp_path) -> None:
    """GIF delays are centiseconds: 12 fps was written 80 ms a frame, 12.5 fps (a user trial).
    The delays alternate so that the frames keep time, and a GIF faster than browsers play
    (under 2 cs a frame) gets 20 ms frames; WebP's are milliseconds."""
    from PIL import Image

    from outcast_core.runtime.pipeline.timelapse import GifWriter, WebpWriter, frame_durations

    assert sum(frame_durations(120, 12.0, 10)) == 10000
    assert set(frame_durations(120, 12.0, 10)) == {80, 90}
    assert frame_durations(3, 60.0, 10, 20) == [20, 20, 20]
    for cls, name, ticks in ((GifWriter, "a.gif", {80, 90}), (WebpWriter, "a.webp", {83, 84})):
        w = cls(tmp_path / name, fps=12.0)
        for i in range(12):
            w.write(np.full((8, 8, 3), 20 * i, np.uint8))
        w.commit()
        with Image.open(tmp_path / name) as im:
            got = []
            for k in range(im.n_frames):
                im.seek(k)
                im.load()  # (WebP gives a frame's duration once it is read)
                got.append(im.info["duration"])
        assert set(got) == ticks and abs(sum(got) - 1000) <= 10, got
