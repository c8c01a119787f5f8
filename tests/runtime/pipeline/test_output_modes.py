"""Every output follows the umask, like a plain ``open`` (issue 19, defect 9: MP4s were 0600)."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from outcast_core.runtime.io.imageio import write_image
from outcast_core.runtime.pipeline.timelapse import export_frames


@pytest.fixture
def umask_027():
    old = os.umask(0o027)
    try:
        yield 0o640, 0o750  # files, folders
    finally:
        os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("name", ["clip.mp4", "clip.gif", "clip.webp", "frames"])
def test_timelapse_outputs_follow_the_umask(tmp_path, umask_027, name):
    file_mode, folder_mode = umask_027
    frame = np.full((16, 24, 3), 0.5, np.float32)
    out = export_frames(lambda i: frame, 3, tmp_path / name, fmt=None if "." in name else "png")
    if out.is_dir():
        assert _mode(out) == folder_mode
        assert {_mode(p) for p in out.iterdir()} == {file_mode}
    else:
        assert _mode(out) == file_mode


def test_stills_and_timelapses_have_the_same_mode(tmp_path, umask_027):
    frame = np.full((16, 24, 3), 0.5, np.float32)
    still = write_image(tmp_path / "still.png", frame)
    clip = export_frames(lambda i: frame, 2, tmp_path / "clip.mp4")
    assert _mode(still) == _mode(clip) == umask_027[0]
