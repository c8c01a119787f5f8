"""Camera pitch and roll from the photo's metadata (XMP GPano / DJI, Exif CameraElevationAngle),
and Find sun applying the EXIF elevation prior in that frame; photos made here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image, PngImagePlugin

from outcast_core.runtime.geometry.camera import sun_angles
from outcast_core.runtime.io.camera_pose import (
    CameraPose,
    pose_from_exif,
    pose_from_xmp,
    read_camera_pose,
)
from outcast_core.runtime.pipeline.auto_sun import SunPrior, find_sun

XMP_DJI = (
    '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
    'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description rdf:about="" '
    'xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" drone-dji:GimbalRollDegree="+1.20" '
    'drone-dji:GimbalPitchDegree="-30.50" drone-dji:FlightPitchDegree="+4.00"/></rdf:RDF>'
    "</x:xmpmeta>"
)
XMP_GPANO = (
    '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
    'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description rdf:about="" '
    'xmlns:GPano="http://ns.google.com/photos/1.0/panorama/">'
    "<GPano:PosePitchDegrees>12.5</GPano:PosePitchDegrees>"
    "<GPano:PoseRollDegrees>-3</GPano:PoseRollDegrees></rdf:Description></rdf:RDF></x:xmpmeta>"
)


def _photo() -> Image.Image:
    return Image.new("RGB", (48, 32), (120, 110, 100))


def test_dji_gimbal_in_a_jpeg(tmp_path: Path) -> None:
    path = tmp_path / "drone.jpg"
    _photo().save(path, xmp=XMP_DJI.encode())
    pose = read_camera_pose(path)
    assert pose == CameraPose(-30.5, 1.2, "XMP DJI gimbal")
    assert pose.pitch_roll() == (-30.5, 1.2)


def test_a_photo_above_pillows_bomb_limit_is_read_without_its_warning(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Pillow warns from 89 MP (and fails from twice that); OutCast relights up to 160 MP and
    checks its own limit where it reads the pixels. A 108 MP photo printed Pillow's warning
    when its pose was read (a user trial). Pillow's limit is lowered here so that a small
    photo stands in for the large one: the pose is still read, and nothing is warned."""
    import warnings

    from outcast_core.runtime.io.phone_depth import _jpeg_orientation

    path = tmp_path / "drone.jpg"
    _photo().save(path, xmp=XMP_DJI.encode())
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 48 * 32 * 2 // 3)  # within 2x: a warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert read_camera_pose(path) == CameraPose(-30.5, 1.2, "XMP DJI gimbal")
        assert _jpeg_orientation(path) == 1
    assert not [w for w in caught if issubclass(w.category, Image.DecompressionBombWarning)]
    assert Image.MAX_IMAGE_PIXELS == 48 * 32 * 2 // 3  # Pillow's own limit is put back


def test_gpano_elements_in_a_png(tmp_path: Path) -> None:
    path = tmp_path / "phone.png"
    info = PngImagePlugin.PngInfo()
    info.add_itxt("XML:com.adobe.xmp", XMP_GPANO)
    _photo().save(path, pnginfo=info)
    assert read_camera_pose(path) == CameraPose(12.5, -3.0, "XMP GPano")


def test_exif_camera_elevation_angle(tmp_path: Path) -> None:
    path = tmp_path / "exif.jpg"
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0x9405] = 7.25
    _photo().save(path, exif=exif)
    pose = read_camera_pose(path)
    assert pose == CameraPose(7.25, None, "Exif CameraElevationAngle")
    assert pose.pitch_roll() == (7.25, 0.0)


def test_no_pose_and_bad_values(tmp_path: Path) -> None:
    plain = tmp_path / "plain.jpg"
    _photo().save(plain)
    assert read_camera_pose(plain) is None
    assert read_camera_pose(tmp_path / "missing.jpg") is None
    (tmp_path / "junk.jpg").write_bytes(b"not an image")
    assert read_camera_pose(tmp_path / "junk.jpg") is None
    assert pose_from_xmp(None) is None and pose_from_xmp("") is None
    assert pose_from_xmp('GPano:PosePitchDegrees="nan"') is None
    assert pose_from_xmp('GPano:PosePitchDegrees="95"') is None  # out of range
    assert pose_from_xmp('GPano:PosePitchDegrees="abc"') is None
    roll_only = pose_from_xmp('GPano:PoseRollDegrees="10"')
    assert roll_only == CameraPose(None, 10.0, "XMP GPano") and roll_only.pitch_roll() is None
    assert pose_from_xmp('GPano:PosePitchDegrees=""') is None


def test_xmp_without_namespace_declarations_is_still_read() -> None:
    """The pose is found by its prefix, so a packet that is not well-formed XML (undeclared
    prefixes, as in the app's Find sun test) still gives it."""
    loose = b'<x:xmpmeta><rdf:Description GPano:PosePitchDegrees=" -8.5 " /></x:xmpmeta>'
    assert pose_from_xmp(loose) == CameraPose(-8.5, None, "XMP GPano")


def test_malformed_exif_pitch_gives_none() -> None:
    assert pose_from_exif({0x8769: {0x9405: (-25, 2)}}) == CameraPose(
        -12.5, None, "Exif CameraElevationAngle")  # a plain mapping, a rational as a pair
    assert pose_from_exif({0x8769: {0x9405: (1, 0)}}) is None  # zero denominator
    assert pose_from_exif({0x8769: {0x9405: 91}}) is None  # out of range
    assert pose_from_exif({0x8769: {0x9405: "abc"}}) is None
    assert pose_from_exif({0x8769: "junk"}) is None and pose_from_exif({}) is None
    assert pose_from_exif(None) is None


def test_the_sample_photos_record_no_pose() -> None:
    root = Path(__file__).resolve().parents[3] / "samples"
    for photo in sorted(root.glob("*.jpg")):
        assert read_camera_pose(photo) is None, photo.name


def _find_with(pose: object) -> tuple[float, float, float, str]:
    from outcast_core.runtime.pipeline.session import RelightSession
    from tests.runtime.pipeline.test_auto_sun import DEPTH, H, W

    s = RelightSession(mode="classic", preset="fast")
    rng = np.random.default_rng(1)
    s.set_image((0.4 + 0.1 * rng.random((H, W, 3))).astype(np.float32), fov_deg=60.0,
                depth=DEPTH)
    fit = find_sun(s, prior=SunPrior(40.0), pitch_roll=pose)
    return fit.pitch, fit.roll, sun_angles(fit.w, fit.pitch, fit.roll)[1], fit.pose_source


def test_find_sun_applies_the_prior_in_the_metadata_pose() -> None:
    pitch, roll, el, source = _find_with(CameraPose(-20.0, 5.0, "XMP GPano"))
    assert (pitch, roll, source) == (-20.0, 5.0, "XMP GPano")
    assert el == pytest.approx(40.0, abs=2.0 + 1e-6)  # the EXIF elevation in the ground's frame
    pitch, roll, _, source = _find_with(CameraPose(None, 5.0, "XMP GPano"))
    assert source in ("ground plane", "level (no ground plane)")  # no pitch: the plane's
    pitch, roll, _, source = _find_with((3.0, -1.0))
    assert (pitch, roll, source) == (3.0, -1.0, "given")
    with pytest.raises(ValueError, match="pitch and roll"):
        _find_with((float("nan"), 0.0))
