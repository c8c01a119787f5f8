"""Depth maps stored inside photos: GDepth JPEGs built to Google's field definitions, HEIF depth
images through pillow-heif's objects (pillow-heif cannot write one)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from outcast_core.runtime.geometry.camera import Camera
from outcast_core.runtime.io import phone_depth
from outcast_core.runtime.io.phone_depth import (
    PhoneDepthError,
    gdepth_properties,
    gdepth_to_depth,
    heif_depth_from_image,
    heif_depth_to_depth,
    orient_to_photo,
    phone_depth_at,
    ray_to_axis,
    read_phone_depth,
)
from tests.runtime.depth_fixtures import (
    dynamic_depth_jpeg,
    finite_corr,
    gdepth_jpeg,
    png_bytes,
    range_inverse,
    range_linear,
)


def _scene(h: int = 24, w: int = 32) -> np.ndarray:
    """A depth map with near and far parts, 1.5 to 40 m."""
    yy, xx = np.mgrid[0:h, 0:w]
    depth = 40.0 / (1.0 + 25.0 * yy / h) + 0.05 * xx
    depth[4:12, 10:18] = 3.0  # something close
    return depth.astype(np.float32)


def _photo(h: int = 48, w: int = 64) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform(0.2, 0.8, (h, w, 3)).astype(np.float32)


@pytest.mark.parametrize("fmt, encode, bits", [
    ("RangeInverse", range_inverse, 16), ("RangeLinear", range_linear, 16),
    ("RangeInverse", range_inverse, 8), ("RangeLinear", range_linear, 8),
])
def test_gdepth_jpeg_gives_back_its_depth(tmp_path: Path, fmt, encode, bits) -> None:
    depth = _scene()
    near, far = float(depth.min()), float(depth.max())
    top = 65535 if bits == 16 else 255
    q = np.round(encode(depth, near, far) * top).astype(np.uint16 if bits == 16 else np.uint8)
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt=fmt, near=near, far=far)
    found = read_phone_depth(path)
    assert found is not None and found.container == f"GDepth {fmt}" and found.metric
    assert found.depth.shape == depth.shape  # the map's own size: the photo is 64 x 48
    assert finite_corr(found.depth, depth, np.ones(depth.shape, bool)) >= 0.99
    tol = 1e-3 if bits == 16 else 0.12  # 8 bits: RangeInverse's far steps are coarse
    assert np.median(np.abs(found.depth / depth - 1)) < tol


def test_gdepth_data_in_the_standard_xmp_and_units(tmp_path: Path) -> None:
    depth = _scene()
    q = np.round(range_linear(depth, 1.0, 50.0) * 65535).astype(np.uint16)
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt="RangeLinear",
                       near=1000.0, far=50000.0, extra='GDepth:Units="mm"',
                       data_in_extended=False)
    found = read_phone_depth(path)
    assert found is not None
    np.testing.assert_allclose(found.depth, depth, rtol=1e-3)  # millimetres -> metres


def test_gdepth_jpeg_depth_is_turned_upright_with_the_photo(tmp_path: Path) -> None:
    depth = _scene()  # stored like the pixels: landscape
    q = np.round(range_linear(depth, 1.0, 50.0) * 65535).astype(np.uint16)
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt="RangeLinear",
                       near=1.0, far=50.0, orientation=6)
    found = read_phone_depth(path)
    assert found is not None and found.depth.shape == (32, 24)
    np.testing.assert_allclose(found.depth, np.rot90(depth, k=-1), rtol=1e-3)


@pytest.mark.parametrize("padding", [0, 16])
def test_dynamic_depth_jpeg_gives_back_its_depth(tmp_path: Path, padding: int) -> None:
    depth = _scene()
    q = np.round(range_inverse(depth, 1.0, 50.0) * 65535).astype(np.uint16)
    path = dynamic_depth_jpeg(tmp_path / "dd.jpg", _photo(), png_bytes(q), fmt="RangeInverse",
                              near=1.0, far=50.0, padding=padding)
    found = read_phone_depth(path)
    assert found is not None and found.container == "Dynamic Depth RangeInverse" and found.metric
    assert finite_corr(found.depth, depth, np.ones(depth.shape, bool)) >= 0.99
    np.testing.assert_allclose(found.depth, depth, rtol=1e-3)


def test_dynamic_depth_item_out_of_place_is_refused(tmp_path: Path) -> None:
    q = np.zeros((24, 32), np.uint8)
    path = dynamic_depth_jpeg(tmp_path / "dd.jpg", _photo(), png_bytes(q), fmt="RangeLinear",
                              near=1.0, far=5.0)
    path.write_bytes(path.read_bytes()[:-10])  # truncated: the PNG is not all there
    with pytest.raises(PhoneDepthError, match="Dynamic Depth item"):
        read_phone_depth(path)


@pytest.mark.parametrize("kind", ["gdepth", "dynamic"])
def test_each_xmp_packet_is_read_once(tmp_path: Path, monkeypatch, kind: str) -> None:
    q = np.round(range_linear(_scene(), 1.0, 50.0) * 255).astype(np.uint8)
    make = gdepth_jpeg if kind == "gdepth" else dynamic_depth_jpeg
    path = make(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt="RangeLinear", near=1.0,
                far=50.0)
    calls = {"scan": 0, "parse": []}
    scan, parse = phone_depth.jpeg_xmp_packets, phone_depth.parse_xmp

    def counted_scan(data: bytes):
        calls["scan"] += 1
        return scan(data)

    def counted_parse(packet: bytes):
        calls["parse"].append(packet)
        return parse(packet)

    monkeypatch.setattr(phone_depth, "jpeg_xmp_packets", counted_scan)
    monkeypatch.setattr(phone_depth, "parse_xmp", counted_parse)
    found = read_phone_depth(path)
    assert found is not None and found.container.endswith("RangeLinear")
    standard, extended = scan(path.read_bytes())
    assert calls["scan"] == 1
    assert sorted(calls["parse"]) == sorted([standard, *extended.values()])  # once each


def test_plain_photos_have_no_phone_depth(tmp_path: Path) -> None:
    for ext in (".jpg", ".png"):
        p = tmp_path / f"plain{ext}"
        Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(p)
        assert read_phone_depth(p) is None


@pytest.mark.parametrize("change, message", [
    ({"fmt": "RangeCubic"}, "Format"),
    ({"near": 5.0, "far": 2.0}, "Near < Far"),
    ({"mime": "image/gif"}, "Mime"),
    ({"depth_png": b"not an image"}, "not a readable image"),
])
def test_malformed_gdepth_gives_a_clear_error(tmp_path: Path, change, message) -> None:
    q = np.round(range_linear(_scene(), 1.0, 50.0) * 255).astype(np.uint8)
    kw = {"fmt": "RangeLinear", "near": 1.0, "far": 50.0, "depth_png": png_bytes(q)} | change
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), **kw)
    with pytest.raises(PhoneDepthError, match=message):
        read_phone_depth(path)


def test_mismatched_gdepth_map_is_refused(tmp_path: Path) -> None:
    q = np.zeros((40, 10), np.uint8)  # portrait map on a landscape photo
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt="RangeLinear",
                       near=1.0, far=5.0)
    with pytest.raises(PhoneDepthError, match="does not match the photo"):
        read_phone_depth(path)


def test_broken_base64_and_missing_fields() -> None:
    with pytest.raises(PhoneDepthError, match="base64"):
        phone_depth.decode_gdepth({"Near": "1", "Far": "2", "Data": "@@@@"})
    with pytest.raises(PhoneDepthError, match="lacks Data"):
        phone_depth.decode_gdepth({"Near": "1", "Far": "2"})
    with pytest.raises(PhoneDepthError, match="numbers"):
        phone_depth.decode_gdepth({"Near": "one", "Far": "2", "Data": "AAAA"})


def test_truncated_extended_xmp_is_refused(tmp_path: Path) -> None:
    q = np.zeros((24, 32), np.uint8)
    path = gdepth_jpeg(tmp_path / "p.jpg", _photo(), png_bytes(q), fmt="RangeLinear",
                       near=1.0, far=5.0, chunk=100_000)
    data = bytearray(path.read_bytes())
    i = data.index(b"http://ns.adobe.com/xmp/extension/\x00") + 35 + 32
    data[i:i + 4] = (10).to_bytes(4, "big")  # full length smaller than the chunk
    with pytest.raises(PhoneDepthError, match="extended XMP"):
        gdepth_properties(bytes(data))


def test_gdepth_formulas_end_points() -> None:
    dn = np.array([[0.0, 1.0]])
    np.testing.assert_allclose(gdepth_to_depth(dn, "RangeInverse", 2.0, 10.0), [[2.0, 10.0]])
    np.testing.assert_allclose(gdepth_to_depth(dn, "RangeLinear", 2.0, 10.0), [[2.0, 10.0]])
    # RangeInverse spends its steps on the near range: half-way is 2 far near / (far + near)
    half = gdepth_to_depth(np.array([[0.5]]), "RangeInverse", 2.0, 10.0)[0, 0]
    assert half == pytest.approx(2 * 10 * 2 / 12)


# ------------------------------------------------------------------------------------- HEIF


class FakeDepthImage:
    """What pillow-heif's ``HeifDepthImage`` offers: ``info["metadata"]`` and ``to_pillow``."""

    def __init__(self, values: np.ndarray, metadata: dict) -> None:
        self.values = values
        self.info = {"metadata": metadata}

    def to_pillow(self) -> Image.Image:
        return Image.fromarray(self.values)


def _pug_metadata(d_min: float = 1.498046875, d_max: float = 4.3828125) -> dict:
    # The keys and values pillow-heif gives for an iPhone portrait photo (its test file pug.heic).
    return {"d_min": d_min, "d_max": d_max, "representation_type": 1,
            "disparity_reference_view": 0, "nonlinear_representation_model_size": 0}


def test_heif_disparity_becomes_depth_in_metres() -> None:
    depth = np.linspace(0.25, 0.6, 24 * 32).reshape(24, 32)
    meta = _pug_metadata()
    v = np.round((1 / depth - meta["d_min"]) / (meta["d_max"] - meta["d_min"]) * 255)
    found = heif_depth_from_image(FakeDepthImage(v.astype(np.uint8), meta))
    assert found.container == "HEIF disparity" and found.metric
    assert finite_corr(found.depth, depth, np.ones(depth.shape, bool)) >= 0.99
    np.testing.assert_allclose(found.depth, depth, rtol=0.02)


@pytest.mark.parametrize("rep", [0, 2])
def test_heif_z_and_inverse_z(rep: int) -> None:
    depth = np.linspace(1.0, 9.0, 64).reshape(8, 8)
    near, far = 1.0, 9.0
    linear = (depth - near) / (far - near)
    inverse = (1 / depth - 1 / far) / (1 / near - 1 / far)
    v = linear if rep == 2 else inverse
    out, metric, kind = heif_depth_to_depth(np.round(v * 65535), 16,
                                            {"representation_type": rep, "z_near": near,
                                             "z_far": far})
    assert metric and kind in ("Z", "inverse Z")
    np.testing.assert_allclose(out, depth, rtol=1e-3)


def test_heif_depth_without_range_is_relative_and_bad_metadata_is_refused() -> None:
    out, metric, _ = heif_depth_to_depth(np.full((4, 4), 128), 8, {"representation_type": 1})
    assert not metric and np.isfinite(out).all()
    with pytest.raises(PhoneDepthError, match="z_near and z_far"):
        heif_depth_to_depth(np.zeros((4, 4)), 8, {"representation_type": 2})
    with pytest.raises(PhoneDepthError, match="d_min < d_max"):
        heif_depth_to_depth(np.zeros((4, 4)), 8, _pug_metadata(3.0, 1.0))
    with pytest.raises(PhoneDepthError, match="type 0-3"):
        heif_depth_to_depth(np.zeros((4, 4)), 8, {"representation_type": 7})


def test_heic_photo_with_a_depth_image(tmp_path: Path, monkeypatch) -> None:
    import pillow_heif

    path = tmp_path / "p.heic"
    pillow_heif.from_pillow(Image.fromarray(np.full((48, 64, 3), 128, np.uint8))).save(
        path, quality=90)
    assert read_phone_depth(path) is None  # a HEIC without a depth image
    depth = np.linspace(0.3, 3.0, 24 * 32).reshape(24, 32)
    meta = _pug_metadata(1 / 3.0, 1 / 0.3)
    v = np.round((1 / depth - meta["d_min"]) / (meta["d_max"] - meta["d_min"]) * 255)
    sideways = FakeDepthImage(np.ascontiguousarray(v.astype(np.uint8).T[::-1]), meta)
    monkeypatch.setattr(phone_depth, "heif_depth_images", lambda p: ([sideways], 6))
    found = read_phone_depth(path)
    assert found is not None and found.depth.shape == (24, 32)  # turned like the photo
    assert finite_corr(found.depth, depth, np.ones(depth.shape, bool)) >= 0.99
    monkeypatch.setattr(phone_depth, "heif_depth_images", lambda p: ([sideways], 1))
    with pytest.raises(PhoneDepthError, match="does not match"):
        read_phone_depth(path)


def test_orientation_and_ray_helpers() -> None:
    d = np.arange(12, dtype=np.float32).reshape(3, 4)
    assert orient_to_photo(d, (6, 8)).shape == (3, 4)
    assert orient_to_photo(d, (8, 6), 8).shape == (4, 3)
    cam = Camera(3, 4, 2.0)
    z = ray_to_axis(np.ones((3, 4), np.float32), cam)
    assert z.max() < 1.0 and z.min() > 0.5
    phone = phone_depth.PhoneDepth(np.full((6, 8), 2.0, np.float32), "GDepth RangeLinear", True)
    np.testing.assert_allclose(phone_depth_at(phone, cam), 2.0, rtol=1e-5)
    ray = phone_depth.PhoneDepth(np.full((6, 8), 2.0, np.float32), "x", True, "ray")
    assert phone_depth_at(ray, cam).max() < 2.0


# ------------------------------------------------------------------------------------- fuzz

_FUZZ = settings(max_examples=60, deadline=10_000,
                 suppress_health_check=[HealthCheck.too_slow,
                                        HealthCheck.function_scoped_fixture])


def _valid_phone_jpegs(tmp_path: Path) -> list[bytes]:
    q = np.round(range_linear(_scene(), 1.0, 50.0) * 255).astype(np.uint8)
    a = gdepth_jpeg(tmp_path / "a.jpg", _photo(24, 32), png_bytes(q), fmt="RangeLinear",
                    near=1.0, far=50.0, chunk=300)
    b = dynamic_depth_jpeg(tmp_path / "b.jpg", _photo(24, 32), png_bytes(q),
                           fmt="RangeInverse", near=1.0, far=50.0)
    return [a.read_bytes(), b.read_bytes()]


@_FUZZ
@given(which=st.integers(0, 1), edits=st.lists(
    st.tuples(st.floats(0, 1), st.integers(0, 255)), min_size=1, max_size=8),
    cut=st.floats(0.05, 1.0))
def test_damaged_phone_jpegs_give_a_result_or_a_clear_error(tmp_path: Path, which, edits,
                                                            cut) -> None:
    data = bytearray(_valid_phone_jpegs(tmp_path)[which])
    for where, value in edits:
        data[min(len(data) - 1, int(where * len(data)))] = value
    data = data[:max(4, int(cut * len(data)))]
    path = tmp_path / "fuzz.jpg"
    path.write_bytes(bytes(data))
    try:
        found = read_phone_depth(path, (24, 32))
    except PhoneDepthError as exc:
        assert "\n" not in str(exc)
        return
    if found is not None:
        assert found.depth.ndim == 2 and np.isfinite(found.depth).all()


def test_heic_orientation_is_read_from_its_exif(tmp_path: Path) -> None:
    import pillow_heif

    exif = Image.Exif()
    exif[0x0112] = 6
    path = tmp_path / "o.heic"
    pillow_heif.from_pillow(Image.fromarray(np.zeros((48, 64, 3), np.uint8))).save(
        path, exif=exif.tobytes(), quality=80)
    assert phone_depth.heif_depth_images(path) == ([], 6)
