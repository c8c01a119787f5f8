"""Issue 20, defect 7: ``outcast timelapse`` options checked before any work, one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.pipeline import timelapse as tl
from tests.sigterm import terminate_when_ready


@pytest.fixture
def photo(tmp_path: Path) -> Path:
    path = tmp_path / "p.png"
    rng = np.random.default_rng(1)
    Image.fromarray((rng.random((48, 64, 3)) * 255).astype(np.uint8)).save(path)
    return path


@pytest.fixture
def no_work(monkeypatch) -> None:
    def boom(*args, **kwargs):
        raise AssertionError("the time-lapse started its work before checking its options")

    monkeypatch.setattr("outcast_core.runtime.io.imageio.read_image", boom)
    monkeypatch.setattr("outcast_core.runtime.pipeline.session.RelightSession.__init__", boom)


def _sweep(photo: Path, out: str, *extra: str) -> list[str]:
    return ["timelapse", str(photo), "--from", "120,40", "--sweep", "90,20:270,20",
            "--frames", "3", "-o", out, "--preset", "fast", *extra]


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--fps", "1e-9"], "frames per second"),
        (["--fps", "0"], "frames per second"),
        (["--fps", "1000"], "frames per second"),
        (["--fps", "nan"], "frames per second"),
        (["--frames", "1000000000000"], "frame count"),
        (["--frames", "0"], "frame count"),
        (["--from", "273,95"], "elevation from 0 (the horizon) to 90 (overhead)"),
        (["--from", "nan,30"], "finite azimuth"),
        (["--sweep", "90,20:270,100"], "elevation in [-90, 90]"),
        (["--lat", "91"], "latitude"),
        (["--lon", "inf"], "longitude"),
        (["--utc-offset", "30"], "UTC offset"),
        (["--heading", "nan"], "heading"),
    ],
)
def test_bad_options_are_refused_by_the_parser(photo, tmp_path, capsys, no_work, extra,
                                               fragment) -> None:
    with pytest.raises(SystemExit) as info:
        main(_sweep(photo, str(tmp_path / "o.mp4"), *extra))
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and fragment in err.strip().splitlines()[-1]


@pytest.mark.parametrize(
    ("name", "fragment"),
    [("out.avi", "expected a time-lapse output"), ("out.mov", "expected a time-lapse output"),
     ("p.png", "expected a time-lapse output"), ("afile/o.mp4", "is a file, not a folder"),
     ("exists.mp4", "already exists")],
)
def test_bad_outputs_are_refused_before_the_work(photo, tmp_path, capsys, no_work, monkeypatch,
                                                 name, fragment) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "exists.mp4").write_bytes(b"old")
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(_sweep(photo, name)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and fragment in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_output_equal_to_the_photo_is_refused(tmp_path, capsys, no_work) -> None:
    clip = tmp_path / "clip.gif"
    Image.new("RGB", (8, 8)).save(clip)
    before = clip.read_bytes()
    assert main(["timelapse", str(clip), "--from", "1,2", "--sweep", "1,2:3,4", "--frames", "2",
                 "-o", str(clip), "--force"]) == 2
    assert "input file" in capsys.readouterr().err
    assert clip.read_bytes() == before


def test_writer_refuses_a_frame_rate_it_cannot_encode(tmp_path) -> None:
    for fps in (1e-9, 0.5, 61.0):
        with pytest.raises(ValueError, match="fps"):
            tl.Mp4Writer(tmp_path / "a.mp4", fps=fps)
    with pytest.raises(ValueError, match="time-lapse output"):
        tl.format_from_path("out.avi")
    assert tl.format_from_path("frames") == "png"


def test_png_folder_output_still_works(photo, tmp_path) -> None:
    out = tmp_path / "frames"
    assert main(_sweep(photo, str(out))) == 0
    assert len(list(out.glob("*.png"))) == 3


_SLOW_RENDER = """
import pathlib, sys, time
from outcast_core.runtime.pipeline import session
from outcast_core.runtime.cli.main import main
relight = session.RelightSession._relight_from  # one call per frame
calls = []
def slow(self, *args, **kwargs):
    calls.append(1)
    if len(calls) == 2:
        # frame 0 is encoded in another thread: wait until its partial output exists
        folder = pathlib.Path(sys.argv[sys.argv.index("-o") + 1]).parent
        for _ in range(200):
            if any(p.name.startswith(".") for p in folder.iterdir()):
                break
            time.sleep(0.05)
        print("rendering", flush=True)
        time.sleep(60)
    return relight(self, *args, **kwargs)
session.RelightSession._relight_from = slow
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("name", ["tl.mp4", "frames"])
def test_sigterm_leaves_no_partial_files(photo, tmp_path, name) -> None:
    def partial_output_exists() -> None:
        assert any(p.name.startswith(".") for p in tmp_path.iterdir())

    ended = terminate_when_ready(["-c", _SLOW_RENDER, *_sweep(photo, str(tmp_path / name))],
                                 "rendering", before=partial_output_exists)
    assert ended.seconds < 10
    assert ended.returncode == 143, ended.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.png"]


def test_a_dark_dusk_is_said_with_what_to_do() -> None:
    """A day's first and last frames came out near black with the photo's exposure kept, and
    nothing said why (a user trial): the lowest sun's frame is metered before rendering and,
    as dark as the app's status line hints at, the note says so and names ``--exposure
    metered``."""
    from types import SimpleNamespace

    from outcast_core.runtime.cli.timelapse_cli import dark_frames_note
    from outcast_core.runtime.geometry.colour import linear_to_srgb
    from outcast_core.runtime.pipeline.relight import EXPOSURE_HINT_FACTOR
    from outcast_core.runtime.pipeline.timelapse import SunSample

    photo = np.full((8, 8, 3), linear_to_srgb(np.float32(0.2)), np.float32)
    asked: list[np.ndarray] = []

    def session(level: float, exposure: str = "photo") -> SimpleNamespace:
        """A session whose relit frames are ``level`` times the photo's linear light."""
        def relight(w: np.ndarray) -> np.ndarray:
            asked.append(w)
            return np.full_like(photo, linear_to_srgb(np.float32(0.2 * level)))
        return SimpleNamespace(exposure=exposure, image_srgb=photo, relight=relight)

    day = [SunSample(90.0, 2.0), SunSample(180.0, 60.0), SunSample(270.0, -0.5)]
    note = dark_frames_note(session(0.1), day)
    assert "come out 10.0x darker than the photo" in note and "--exposure metered" in note
    assert "(at the horizon)" in note  # the lowest sun, rendered at the horizon
    assert asked[-1][1] == pytest.approx(0.0, abs=0.05)  # (y down: the horizon's sun)
    assert "(at elevation 12 deg)" in dark_frames_note(session(0.1), [SunSample(0.0, 12.0)])
    assert dark_frames_note(session(1.05 / EXPOSURE_HINT_FACTOR), day) == ""
    n = len(asked)
    assert dark_frames_note(session(0.1, "metered"), day) == "" and len(asked) == n
    assert dark_frames_note(session(0.1), []) == ""
