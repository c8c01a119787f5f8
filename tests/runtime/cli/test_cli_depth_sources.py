"""``outcast`` with depth from elsewhere: ``--depth-model`` and the photo's own depth map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io.imageio import read_depth, write_image
from tests.runtime.depth_fixtures import (
    encode_inverse_image,
    finite_corr,
    gdepth_jpeg,
    outdoor_scene,
    png_bytes,
    range_inverse,
    tiny_depth_model,
)

pytest.importorskip("onnx")


@pytest.fixture
def scene(tmp_path: Path) -> tuple[np.ndarray, Path]:
    truth, _ = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    path = tmp_path / "photo.png"
    write_image(path, image)
    return truth, path


@pytest.fixture
def model(tmp_path: Path) -> Path:
    return tiny_depth_model(tmp_path / "da.onnx", input_name="pixel_values",
                            output_name="predicted_depth", size=None, block=14, gain=7.0,
                            offset=0.3)


def test_depth_with_a_depth_model(scene, model: Path, tmp_path: Path, capsys) -> None:
    truth, photo = scene
    out = tmp_path / "d.npy"
    assert main(["depth", str(photo), "--depth-model", str(model), "--fov", "60",
                 "-o", str(out)]) == 0
    assert "depth: model da.onnx (" in capsys.readouterr().err
    depth = read_depth(out)
    surface = np.isfinite(truth) & np.isfinite(depth) & (truth < 30)
    assert finite_corr(depth, truth, surface) >= 0.99
    assert (np.isfinite(depth) == np.isfinite(truth)).mean() > 0.97  # sky = inf


def test_shadow_with_a_depth_model(scene, model: Path, tmp_path: Path, capsys) -> None:
    _, photo = scene
    out = tmp_path / "s.png"
    assert main(["shadow", str(photo), "--sun", "90,30", "--mode", "direct", "--depth-model",
                 str(model), "-o", str(out)]) == 0
    assert "depth: model da.onnx" in capsys.readouterr().err


def test_depth_and_depth_model_exclude_each_other(scene, model: Path, tmp_path: Path) -> None:
    _, photo = scene
    with pytest.raises(SystemExit):
        main(["shadow", str(photo), "--sun", "90,30", "--depth", "x.npy", "--depth-model",
              str(model), "-o", str(tmp_path / "s.png")])


def test_a_broken_model_is_one_line(scene, tmp_path: Path, capsys) -> None:
    _, photo = scene
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"nope")
    assert main(["depth", str(photo), "--depth-model", str(bad), "-o",
                 str(tmp_path / "d.npy")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "not a readable ONNX model" in err


def _phone_photo(tmp_path: Path, *, far: float = 200.0, broken: bool = False) -> Path:
    truth, _ = outdoor_scene()
    image, _ = encode_inverse_image(truth)
    stored = np.where(np.isfinite(truth), np.minimum(truth, far), far)
    q = np.round(range_inverse(stored, 1.0, far) * 65535).astype(np.uint16)
    data = b"garbage" if broken else png_bytes(q)
    return gdepth_jpeg(tmp_path / "phone.jpg", image, data, fmt="RangeInverse", near=1.0,
                       far=far)


def test_phone_depth_is_used_and_said(tmp_path: Path, capsys) -> None:
    truth, _ = outdoor_scene()
    photo = _phone_photo(tmp_path)
    out = tmp_path / "d.npy"
    assert main(["depth", str(photo), "--fov", "60", "-o", str(out)]) == 0
    assert "depth: phone" in capsys.readouterr().err
    depth = read_depth(out)
    surface = np.isfinite(truth) & np.isfinite(depth) & (truth < 30)
    assert finite_corr(depth, truth, surface) >= 0.99
    np.testing.assert_allclose(depth[surface], truth[surface], rtol=0.02)  # metres, as stored
    assert main(["depth", str(photo), "--no-phone-depth", "-o", str(out), "--force"]) == 0
    err = capsys.readouterr().err
    assert "depth: model," in err and "depth: phone" not in err


def test_broken_phone_depth_falls_back_to_the_model(tmp_path: Path, capsys) -> None:
    photo = _phone_photo(tmp_path, broken=True)
    assert main(["depth", str(photo), "-o", str(tmp_path / "d.npy")]) == 0
    err = capsys.readouterr().err
    assert "note: the photo's own depth map is not used" in err
    assert "not a readable image" in err and "depth: model" in err
