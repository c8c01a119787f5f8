"""Time-lapse speed paths: the session's two-stage stream, write-behind encoding, frames made at
their own size (never via full resolution)."""

from __future__ import annotations

import math
import threading
from pathlib import Path

import av
import numpy as np
import pytest

from outcast_core.runtime.pipeline import timelapse as tl
from outcast_core.runtime.pipeline.session import RelightSession
from tests.runtime.scenes import box_scene_depth

W_O = (0.3, -0.8, -0.5)


def _session(mode: str, photo_u8: bool = False) -> RelightSession:
    h, w = 120, 160
    depth = box_scene_depth(h, w, w / (2 * math.tan(math.radians(15))), 60.0,
                            [(-4.0, 0.0, -3.0, 1.0, 4.0), (2.0, 5.0, 1.0, 4.0, 2.0)])
    rng = np.random.default_rng(2)
    image = np.clip(0.5 + 0.1 * rng.standard_normal((h, w, 3)), 0, 1)
    if photo_u8:
        image = np.rint(image * 255).astype(np.uint8)
    s = RelightSession(preset="fast", mode=mode)
    s.set_image(image, depth=depth)
    s.set_original_sun(W_O)
    return s


@pytest.mark.parametrize("mode", ["learned", "classic"])
def test_stream_equals_one_relight_per_sun(mode: str) -> None:
    s = _session(mode)
    suns = tl.sun_vectors(tl.sweep_path((60.0, 20.0), (300.0, 50.0), 5))
    streamed = list(s.relight_stream(suns))
    fresh = _session(mode)
    for frame, w in zip(streamed, suns, strict=True):
        np.testing.assert_array_equal(frame, fresh.relight(w))
    # Suns already cached come from the cache (the same arrays).
    again = list(s.relight_stream(suns[:2]))
    assert len(again) == 2
    assert list(s.relight_stream([])) == []


def test_stream_runs_the_next_shadow_beside_this_relighting(monkeypatch) -> None:
    """While L runs for sun i, S for sun i + 1 is already running in another thread."""
    s = _session("learned")
    active: dict[str, int] = {"shadow": 0, "relight": 0}
    overlaps = []
    lock = threading.Lock()
    real_load = s.registry.load

    def load(name, **kwargs):
        model = real_load(name, **kwargs)

        class Watched:
            def __getattr__(self, attr):
                return getattr(model, attr)

            def run(self, feeds):
                with lock:
                    active[name] += 1
                    overlaps.append(dict(active))
                try:
                    if name == "relight":
                        threading.Event().wait(0.05)  # give the shadow thread time to start
                    return model.run(feeds)
                finally:
                    with lock:
                        active[name] -= 1

        return Watched()

    monkeypatch.setattr(s.registry, "load", load)
    suns = tl.sun_vectors(tl.sweep_path((60.0, 20.0), (300.0, 50.0), 4))
    list(s.relight_stream(suns))
    assert any(o["shadow"] and o["relight"] for o in overlaps)


def test_frames_above_working_size_never_pass_through_full_resolution(monkeypatch,
                                                                      tmp_path: Path) -> None:
    s = _session("classic", photo_u8=True)
    # A "photo" of 1200 x 1600 behind a 120 x 160 working size: 720p frames are 720 x 960.
    s.full_image_srgb = np.repeat(np.repeat(s.full_image_srgb, 10, axis=0), 10, axis=1)
    monkeypatch.setattr(s, "relight_full", lambda *a, **k: pytest.fail("full resolution used"))
    sizes = []
    import outcast_core.runtime.pipeline.relight as relight_module

    real = relight_module.transfer_to_full_resolution

    def spy(photo, before, after, **kwargs):
        sizes.append(photo.shape[:2])
        return real(photo, before, after, **kwargs)

    monkeypatch.setattr(relight_module, "transfer_to_full_resolution", spy)
    out = tl.render_timelapse(s, tl.sweep_path((60.0, 20.0), (120.0, 40.0), 3),
                              tmp_path / "a.mp4", size="720p")
    assert sizes == [(720, 960)] * 3
    with av.open(str(out)) as c:
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == 3 and frames[0].shape == (720, 960, 3)


def test_write_behind_reports_an_encoder_error_and_leaves_nothing(tmp_path: Path) -> None:
    calls = []

    def render(i: int) -> np.ndarray:
        calls.append(i)
        size = 16 if i < 2 else 18  # the third frame has another size: the writer refuses it
        return np.zeros((size, size, 3), np.uint8)

    with pytest.raises(ValueError, match="every frame"):
        tl.export_frames(render, 8, tmp_path / "b.mp4")
    assert list(tmp_path.iterdir()) == []
    assert len(calls) < 8  # stopped soon after the error, not after all frames


def test_write_behind_writes_every_frame_in_order(tmp_path: Path) -> None:
    def render(i: int) -> np.ndarray:
        return np.full((16, 16, 3), 20 * i, np.uint8)

    out = tl.export_frames(render, 6, tmp_path / "seq")
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 6
    from outcast_core.runtime.io.imageio import read_image

    levels = [int(read_image(out / n, keep_uint8=True).image_srgb[0, 0, 0]) for n in names]
    assert levels == [0, 20, 40, 60, 80, 100]
