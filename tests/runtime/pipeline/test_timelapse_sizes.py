"""Time-lapse frame sizes (working, 720p, 1080p, 4k, full) and the time estimate (issue 19, 3)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import av
import numpy as np
import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io.imageio import write_image
from outcast_core.runtime.pipeline.timelapse import (
    FRAME_SIZES,
    describe_seconds,
    frame_shape,
    render_timelapse,
    sweep_path,
)


@pytest.mark.parametrize(
    "size, photo, expected",
    [
        ("720p", (3000, 4000), (720, 960)),
        ("1080p", (3000, 4000), (1080, 1440)),
        ("4k", (3000, 4000), (2160, 2880)),
        ("1080p", (4000, 3000), (1440, 1080)),  # portrait: the shorter side is the width
        ("1080p", (1080, 1920), (1080, 1920)),
        ("4k", (960, 1280), (960, 1280)),  # never larger than the photo
        ("720p", (1001, 1333), (720, 958)),  # even, for H.264
        ("full", (1001, 1333), (1001, 1333)),
        ("working", (3000, 4000), (288, 384)),
    ],
)
def test_frame_shape(size, photo, expected):
    assert frame_shape(size, photo, (288, 384)) == expected


def test_frame_shape_refuses_unknown_sizes():
    with pytest.raises(ValueError, match="frame size"):
        frame_shape("8k", (100, 100), (50, 50))
    assert FRAME_SIZES == ("working", "720p", "1080p", "4k", "full")


def test_describe_seconds():
    assert describe_seconds(42.4) == "about 42 s"
    assert describe_seconds(185) == "about 3 min"
    assert describe_seconds(3900) == "about 1 h 5 min"


class _FakeSession:
    """What render_timelapse uses of RelightSession: a 600 x 800 photo, working size 150 x 200,
    ``relight`` / ``relight_full`` and ``relight_stream`` (``relight`` for each sun in order,
    at working size, as the real one gives), and ``without_old_sun_full`` for the frames above
    the working size."""

    def __init__(self):
        rng = np.random.default_rng(0)
        self.full_image_srgb = rng.random((600, 800, 3), dtype=np.float32)
        self.image_srgb = self.full_image_srgb[::4, ::4].copy()
        self.sky = np.zeros(self.image_srgb.shape[:2], bool)  # (no skyline to guard)
        self.original_sun = np.array([0.0, -1.0, 0.0])
        self.calls = SimpleNamespace(relight=0, full=0, stream=0, glare=0)

    def relight(self, w, preview=False):
        self.calls.relight += 1
        return self.image_srgb * 0.8

    def relight_full(self, w):
        self.calls.full += 1
        return self.full_image_srgb * 0.8

    def relight_fills(self):  # no marked shadow: nothing filled
        return None

    def without_old_sun_full(self, out, relit, w):  # this photo shows no sun
        self.calls.glare += 1
        return out

    def relight_stream(self, suns, exposure=None):
        if self.original_sun is None:
            raise RuntimeError("set_original_sun() must be called before relight_stream()")
        self.calls.stream += 1
        for w in suns:
            yield self.relight(w)


@pytest.mark.parametrize("size, shape", [("working", (150, 200)), ("720p", (600, 800)),
                                         ("full", (600, 800))])  # fmt: skip
def test_render_timelapse_sizes(tmp_path, size, shape):
    session = _FakeSession()
    out = render_timelapse(session, sweep_path((0, 20), (90, 20), 3), tmp_path / "a.mp4",
                           size=size)  # fmt: skip
    with av.open(str(out)) as c:
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == 3 and frames[0].shape[:2] == shape
    # One stream, no full-resolution relighting; above the working size each frame is offered
    # to the old sun's full-size removal.
    glare = 0 if size == "working" else 3
    assert session.calls == SimpleNamespace(relight=3, full=0, stream=1, glare=glare)


def test_render_timelapse_between_working_and_full(tmp_path, monkeypatch):
    import outcast_core.runtime.pipeline.timelapse as tl

    monkeypatch.setitem(tl.SHORT_SIDES, "720p", 300)  # a 300 px "720p" of the 600 x 800 photo
    session = _FakeSession()
    out = render_timelapse(session, sweep_path((0, 20), (90, 20), 2), tmp_path / "b.gif",
                           size="720p")  # fmt: skip
    from PIL import Image

    with Image.open(out) as im:
        assert im.size == (400, 300)
    assert session.calls.full == 0 and session.calls.relight == 2  # the photo's detail, not full


def test_cli_timelapse_size_option(tmp_path: Path, capsys, monkeypatch):
    rng = np.random.default_rng(1)
    photo = tmp_path / "p.png"
    write_image(photo, np.clip(0.5 + 0.1 * rng.standard_normal((120, 160, 3)), 0, 1))
    out = tmp_path / "clip.mp4"
    rc = main(["timelapse", str(photo), "--from", "90,40", "--sweep", "0,20:90,30", "--frames",
               "2", "--size", "working", "--preset", "fast", "-o", str(out)])  # fmt: skip
    assert rc == 0
    err = capsys.readouterr().err
    assert "rendering 2 frames of 160x120 (working)\n" in err  # no guess up front
    assert f"wrote 2 frames to {out}\n" in err  # the output as given
    # A video size beyond the photo: the photo's own size, and said so (not "(4k)").
    rc = main(["timelapse", str(photo), "--from", "90,40", "--sweep", "0,20:90,30", "--frames",
               "2", "--size", "4k", "--preset", "fast", "-o", str(tmp_path / "big.gif")])
    assert rc == 0
    err = capsys.readouterr().err
    assert "rendering 2 frames of 160x120 (the photo's own size: 4k is larger)\n" in err
    # A frames folder given relative is named as given (it came back absolute: a user trial).
    monkeypatch.chdir(tmp_path)
    rc = main(["timelapse", "p.png", "--from", "90,40", "--sweep", "0,20:90,30", "--frames",
               "2", "--size", "working", "--preset", "fast", "-o", "frames"])
    assert rc == 0 and "wrote 2 frames to frames\n" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["timelapse", str(photo), "--from", "90,40", "--sweep", "0,20:90,30", "--frames",
              "2", "--size", "8k", "-o", str(tmp_path / "x.mp4")])  # fmt: skip
