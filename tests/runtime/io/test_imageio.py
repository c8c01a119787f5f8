"""Image, shadow and depth file I/O: formats, precision, orientation, errors, atomic writes."""

from __future__ import annotations

import io
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
import pytest
from PIL import Image, ImageFile, ImageOps

from outcast_core.runtime.io import imageio
from outcast_core.runtime.io.imageio import (
    ImageReadError,
    ImageReadReason,
    atomic_output,
    read_depth,
    read_image,
    read_image_size,
    read_shadow_png,
    write_depth,
    write_image,
    write_shadow_png,
)

REPO = Path(__file__).resolve().parents[3]


def _smooth_image(h: int = 48, w: int = 64) -> np.ndarray:
    """A smooth float32 test image (lossy codecs keep it well)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.stack(
        [x / (w - 1), y / (h - 1), 0.5 + 0.4 * np.sin(x / 7.0) * np.cos(y / 5.0)], axis=2
    ).astype(np.float32)


def _noise_image(h: int = 37, w: int = 53, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).random((h, w, 3), dtype=np.float32)


def _listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ------------------------------------------------------------------------------------------
# Round trips


@pytest.mark.parametrize(
    ("name", "bit_depth", "tolerance"),
    [
        ("a.png", 8, 0.5 / 255 + 1e-6),
        ("a.png", 16, 0.5 / 65535 + 1e-7),
        ("a.tif", 8, 0.5 / 255 + 1e-6),
        ("a.tiff", 16, 0.5 / 65535 + 1e-7),
        ("a.webp", 8, None),  # quality 100 = lossless: checked exactly below
    ],
)
def test_lossless_round_trip(tmp_path: Path, name: str, bit_depth: int, tolerance) -> None:
    image = _noise_image()
    path = write_image(tmp_path / name, image, bit_depth=bit_depth, quality=100)
    loaded = read_image(path)
    assert loaded.image_srgb.dtype == np.float32 and loaded.image_srgb.shape == image.shape
    assert loaded.original_size == (image.shape[1], image.shape[0])
    assert loaded.bit_depth == bit_depth
    top = 65535 if bit_depth == 16 else 255
    codes = np.rint(image * top)
    assert np.array_equal(np.rint(loaded.image_srgb * top), codes)
    if tolerance is not None:
        assert np.abs(loaded.image_srgb - image).max() <= tolerance


def test_sixteen_bits_keep_codes_8_bits_cannot(tmp_path: Path) -> None:
    codes = np.arange(0, 3 * 40 * 50, dtype=np.uint16).reshape(40, 50, 3) * 7  # all distinct
    image = codes.astype(np.float32) / 65535
    for name in ("p.png", "t.tif"):
        loaded = read_image(write_image(tmp_path / name, image, bit_depth=16)).image_srgb
        assert np.array_equal(np.rint(loaded * 65535).astype(np.uint16), codes)
        assert len(np.unique(loaded)) == codes.size
    eight = read_image(write_image(tmp_path / "e.png", image, bit_depth=8)).image_srgb
    assert len(np.unique(eight)) < 256


# WebP lossy always subsamples chroma 4:2:0 (measured max error 0.049 on this image).
@pytest.mark.parametrize(("name", "max_error"), [("a.jpg", 0.03), ("a.jpeg", 0.03),
                                                 ("a.webp", 0.06)])
def test_lossy_round_trip(tmp_path: Path, name: str, max_error: float) -> None:
    image = _smooth_image()
    loaded = read_image(write_image(tmp_path / name, image, quality=95))
    assert loaded.image_srgb.shape == image.shape
    assert np.abs(loaded.image_srgb - image).mean() < 0.01
    assert np.abs(loaded.image_srgb - image).max() < max_error


def test_jpeg_quality_changes_file(tmp_path: Path) -> None:
    image = _noise_image(64, 64)
    low = write_image(tmp_path / "low.jpg", image, quality=20).stat().st_size
    high = write_image(tmp_path / "high.jpg", image, quality=95).stat().st_size
    assert low < high


def test_grey_array_is_written_and_read_as_three_channels(tmp_path: Path) -> None:
    grey = _noise_image()[:, :, 0]
    loaded = read_image(write_image(tmp_path / "g.png", grey, bit_depth=16)).image_srgb
    assert loaded.shape == (*grey.shape, 3)
    assert np.array_equal(loaded[:, :, 0], loaded[:, :, 2])
    assert np.abs(loaded[:, :, 1] - grey).max() <= 0.5 / 65535 + 1e-7


def test_heic_is_read(tmp_path: Path) -> None:
    rgb = (_smooth_image(64, 96) * 255).astype(np.uint8)
    path = tmp_path / "photo.heic"
    Image.fromarray(rgb).save(path, quality=95)
    loaded = read_image(path)
    assert loaded.format == "HEIF"
    assert loaded.image_srgb.shape == (64, 96, 3)
    assert np.abs(loaded.image_srgb - rgb / 255.0).mean() < 0.02
    exif = Image.Exif()
    exif[0x0112] = 6  # pillow-heif turns this into a HEIF rotation; reading undoes it once
    Image.fromarray(rgb).save(tmp_path / "rot.heic", quality=95, exif=exif.tobytes())
    rotated = read_image(tmp_path / "rot.heic").image_srgb
    assert rotated.shape == (96, 64, 3)
    assert np.abs(rotated - np.rot90(rgb / 255.0, k=-1)).mean() < 0.02


def test_exif_bytes_are_copied_upright(tmp_path: Path) -> None:
    source = read_image(REPO / "samples" / "exif_003_th_pool.jpg", max_pixels=80 * 60)
    assert source.exif_bytes is not None
    out = write_image(tmp_path / "relit.jpg", source.image_srgb, exif=source.exif_bytes)
    copied = read_image(out).exif
    assert copied.latitude == source.exif.latitude
    assert copied.capture_time == source.exif.capture_time
    assert copied.orientation == 1


@pytest.mark.parametrize("name", ["x.png", "x.tif", "x.tiff"])
@pytest.mark.parametrize("sample", ["exif_003_th_pool.jpg", "exif_001_cz_fieldpath.jpg"])
def test_16_bit_files_keep_the_exif(tmp_path: Path, name: str, sample: str) -> None:
    """GPS, time, heading and camera survive a 16-bit export (they were dropped: OpenCV writes
    16-bit files without metadata; found by a user trial), and the pixels stay exact. The
    field path's EXIF has an interoperability pointer and a maker note, whose offsets would
    point nowhere in the new file: left out, so reading it back warns of nothing (warnings are
    errors here)."""
    source = read_image(REPO / "samples" / sample, max_pixels=80 * 60)
    out = write_image(tmp_path / name, source.image_srgb, bit_depth=16, exif=source.exif_bytes)
    back = read_image(out)
    assert back.bit_depth == 16
    assert np.abs(back.image_srgb - source.image_srgb).max() < 1e-4
    meta = back.exif
    for field in ("latitude", "longitude", "capture_time", "heading_deg", "make", "model",
                  "focal_35mm"):
        assert getattr(meta, field) == getattr(source.exif, field), field
    assert meta.orientation == 1
    with Image.open(out) as im:  # a valid file for other readers too
        assert im.size == (source.image_srgb.shape[1], source.image_srgb.shape[0])
        exif_ifd = im.getexif().get_ifd(0x8769)
        assert exif_ifd.get(0x9000) == source_exif_version(sample)
        if name != "x.png":  # a PNG keeps the whole EXIF block, whose offsets are its own
            assert 0xA005 not in exif_ifd and 0x927C not in exif_ifd


def source_exif_version(sample: str) -> bytes | None:
    with Image.open(REPO / "samples" / sample) as im:
        return im.getexif().get_ifd(0x8769).get(0x9000)


# ------------------------------------------------------------------------------------------
# Orientation and pixel formats


def test_jpeg_orientation_6_is_rotated_clockwise(tmp_path: Path) -> None:
    stored = np.zeros((40, 60, 3), np.uint8)
    stored[:10, :, 0] = 255  # red band along the stored top edge
    exif = Image.Exif()
    exif[0x0112] = 6
    path = tmp_path / "rot.jpg"
    Image.fromarray(stored).save(path, exif=exif.tobytes(), quality=95)
    loaded = read_image(path)
    assert loaded.image_srgb.shape == (60, 40, 3)  # portrait once upright
    assert loaded.original_size == (40, 60) and read_image_size(path) == (40, 60)
    assert loaded.exif.orientation == 6
    red = loaded.image_srgb[:, :, 0]
    assert red[:, -8:].mean() > 0.9 and red[:, :28].mean() < 0.05  # top band -> right side
    small = read_image(path, max_pixels=600)
    assert small.image_srgb.shape[0] > small.image_srgb.shape[1]
    assert small.original_size == (40, 60)


@pytest.mark.parametrize("orientation", range(1, 9))
@pytest.mark.parametrize("kind", ["png", "tiff", "tiff-L", "tiff-I;16", "tiff-RGBA",
                                  "tiff-CMYK", "tiff16"])
def test_all_orientations_match_pillow(tmp_path: Path, orientation: int, kind: str) -> None:
    """Turned upright once, whatever the format, mode and decoder (Pillow 13 turns TIFFs
    upright as it loads them; a second turn put them on their side. By name it maps an
    uncompressed grey, 16-bit, RGBA or CMYK TIFF into memory and does not turn it)."""
    stored = (_noise_image(9, 14, seed=orientation) * 255).astype(np.uint8)
    if kind in ("tiff-L", "tiff-I;16"):
        stored = np.repeat(stored[:, :, :1], 3, axis=2)  # grey: the same in every channel
    exif = Image.Exif()
    exif[0x0112] = orientation
    ref = tmp_path / "o.png"
    Image.fromarray(stored).save(ref, exif=exif.tobytes())
    with Image.open(ref) as im:  # PNGs are never turned on load: the reference
        expected = np.asarray(ImageOps.exif_transpose(im)).astype(np.float32) / 255
    path = ref
    if kind == "tiff":
        path = tmp_path / "o.tif"
        Image.fromarray(stored).save(path, exif=exif)
    elif kind.startswith("tiff-"):
        mode = kind[5:]
        path = tmp_path / "o.tif"
        if mode == "L":
            im = Image.fromarray(stored[:, :, 0])
        elif mode == "I;16":
            im = Image.fromarray(stored[:, :, 0].astype(np.uint16) * 257)
        elif mode == "RGBA":
            im = Image.fromarray(np.dstack([stored, np.full(stored.shape[:2], 255, np.uint8)]))
        else:  # CMYK: converted back to RGB by Pillow; compare with its own conversion
            im = Image.fromarray(stored).convert("CMYK")
            expected_im = Image.fromarray(
                np.asarray(im.convert("RGB"))).transpose(_TRANSPOSE[orientation]) \
                if orientation > 1 else im.convert("RGB")
            expected = np.asarray(expected_im).astype(np.float32) / 255
        im.save(path, exif=exif)  # uncompressed: Pillow would map it into memory by name
    elif kind == "tiff16":  # OpenCV decodes it (16-bit colour)
        path = tmp_path / "o16.tif"
        ok, data = cv2.imencode(".tif", (stored[:, :, ::-1].astype(np.uint16) * 257))
        assert ok
        path.write_bytes(data.tobytes())
        with Image.open(path) as im:  # add the orientation to the 16-bit file's tags
            assert im.size == (stored.shape[1], stored.shape[0])
        _tiff_with_orientation(path, orientation)
    loaded = read_image(path)
    assert np.allclose(loaded.image_srgb, expected, atol=1e-6), kind
    assert loaded.exif.orientation == orientation
    assert loaded.original_size == (expected.shape[1], expected.shape[0])
    assert read_image_size(path) == (expected.shape[1], expected.shape[0])
    small = read_image(path, max_pixels=40)  # decoded smaller: still upright
    assert (small.image_srgb.shape[0] > small.image_srgb.shape[1]) == (
        expected.shape[0] > expected.shape[1])


#: EXIF orientation -> the transpose that makes it upright (as ``ImageOps.exif_transpose``).
_TRANSPOSE = {2: Image.Transpose.FLIP_LEFT_RIGHT, 3: Image.Transpose.ROTATE_180,
              4: Image.Transpose.FLIP_TOP_BOTTOM, 5: Image.Transpose.TRANSPOSE,
              6: Image.Transpose.ROTATE_270, 7: Image.Transpose.TRANSVERSE,
              8: Image.Transpose.ROTATE_90}


def _tiff_with_orientation(path: Path, orientation: int) -> None:
    """Set the Orientation tag (274) of a little-endian baseline TIFF's first IFD in place."""
    data = bytearray(path.read_bytes())
    assert data[:4] == b"II*\x00"
    ifd = struct.unpack_from("<I", data, 4)[0]
    n = struct.unpack_from("<H", data, ifd)[0]
    entries = [struct.unpack_from("<HHII", data, ifd + 2 + 12 * i) for i in range(n)]
    tags = [e[0] for e in entries]
    assert 0x0112 not in tags
    entries.append((0x0112, 3, 1, orientation))  # SHORT, count 1, value in place
    entries.sort()
    block = struct.pack("<H", n + 1) + b"".join(struct.pack("<HHII", *e) for e in entries)
    block += struct.pack("<I", 0)  # no next IFD
    new_ifd = len(data) + (len(data) % 2)
    data += b"\x00" * (new_ifd - len(data)) + block
    struct.pack_into("<I", data, 4, new_ifd)
    path.write_bytes(bytes(data))


def test_grey_8_and_16_bit_inputs(tmp_path: Path) -> None:
    grey8 = (np.arange(30 * 20) % 256).astype(np.uint8).reshape(20, 30)
    Image.fromarray(grey8).save(tmp_path / "g8.png")
    loaded = read_image(tmp_path / "g8.png").image_srgb
    assert loaded.shape == (20, 30, 3)
    assert np.array_equal(loaded[:, :, 1], grey8 / np.float32(255))

    grey16 = (np.arange(30 * 20) * 97 % 65536).astype(np.uint16).reshape(20, 30)
    cv2.imwrite(str(tmp_path / "g16.png"), grey16)
    loaded = read_image(tmp_path / "g16.png")
    assert loaded.bit_depth == 16
    assert np.array_equal(np.rint(loaded.image_srgb[:, :, 2] * 65535).astype(np.uint16), grey16)

    Image.fromarray(grey8 > 100).save(tmp_path / "bw.png")  # 1-bit
    bw = read_image(tmp_path / "bw.png").image_srgb
    assert set(np.unique(bw).tolist()) == {0.0, 1.0}


def test_alpha_is_composited_on_white(tmp_path: Path) -> None:
    rgba = np.zeros((10, 12, 4), np.uint8)
    rgba[..., 0] = 200
    rgba[..., 3] = np.linspace(0, 255, 12).astype(np.uint8)[None, :]
    Image.fromarray(rgba).save(tmp_path / "a8.png")
    loaded = read_image(tmp_path / "a8.png").image_srgb
    alpha = rgba[..., 3:] / 255.0
    expected = (rgba[..., :3] / 255.0) * alpha + (1 - alpha)
    assert np.abs(loaded - expected).max() <= 1.5 / 255
    assert np.allclose(loaded[:, 0], 1.0)  # fully transparent -> white

    Image.fromarray(rgba[..., [0, 3]], mode="LA").save(tmp_path / "la.png")
    la = read_image(tmp_path / "la.png").image_srgb
    assert np.allclose(la[:, 0], 1.0) and la[:, -1, 0] == pytest.approx(200 / 255, abs=1e-6)

    rgba16 = np.zeros((10, 12, 4), np.uint16)  # OpenCV order: B, G, R, A
    rgba16[..., 1] = 30000
    rgba16[..., 3] = np.linspace(0, 65535, 12).astype(np.uint16)[None, :]
    cv2.imwrite(str(tmp_path / "a16.png"), rgba16)
    loaded16 = read_image(tmp_path / "a16.png").image_srgb
    a16 = rgba16[..., 3] / 65535.0
    assert np.abs(loaded16[..., 1] - (30000 / 65535 * a16 + 1 - a16)).max() < 1e-6
    assert np.abs(loaded16[..., 0] - (1 - a16)).max() < 1e-6


def test_palette_and_cmyk_inputs(tmp_path: Path) -> None:
    rgb = (_smooth_image(20, 24) * 255).astype(np.uint8)
    pal = Image.fromarray(rgb).quantize(16)
    pal.save(tmp_path / "p.png")
    loaded = read_image(tmp_path / "p.png").image_srgb
    assert np.array_equal(loaded, np.asarray(pal.convert("RGB")) / np.float32(255))

    cmyk = Image.fromarray(rgb).convert("CMYK")
    cmyk.save(tmp_path / "c.jpg", quality=95)
    loaded = read_image(tmp_path / "c.jpg").image_srgb
    assert loaded.shape == (20, 24, 3)
    assert np.abs(loaded - rgb / 255.0).mean() < 0.02


# ------------------------------------------------------------------------------------------
# Errors


def _truncated(tmp_path: Path, name: str, **kwargs) -> Path:
    path = write_image(tmp_path / name, _noise_image(64, 80), **kwargs)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def _check_error(path: Path, fragment: str, reason: ImageReadReason) -> ImageReadError:
    """``read_image(path)`` raises a one-line ImageReadError with ``fragment`` in its text,
    the file named in its message for a person, and ``reason``."""
    with pytest.raises(ImageReadError) as info:
        read_image(path)
    message = str(info.value)
    assert "\n" not in message and fragment in message and path.name in info.value.message
    assert isinstance(info.value, ValueError)
    assert info.value.reason == reason
    return info.value


def test_read_errors_are_one_line_image_read_errors(tmp_path: Path) -> None:
    _check_error(tmp_path / "missing.jpg", "not found", ImageReadReason.MISSING)
    (tmp_path / "empty.png").write_bytes(b"")
    _check_error(tmp_path / "empty.png", "empty", ImageReadReason.DAMAGED)
    (tmp_path / "notes.jpg").write_text("this is text, not a photo\n")
    err = _check_error(tmp_path / "notes.jpg", "not an image", ImageReadReason.NOT_AN_IMAGE)
    assert err.__cause__ is not None  # Pillow's error is chained, not printed
    Image.new("RGB", (8, 8)).save(tmp_path / "anim.gif")
    _check_error(tmp_path / "anim.gif", "unsupported format GIF",
                 ImageReadReason.UNSUPPORTED_FORMAT)
    (tmp_path / "shot.cr2").write_bytes(b"II*\x00 raw data")
    _check_error(tmp_path / "shot.cr2", "RAW", ImageReadReason.CAMERA_RAW)
    (tmp_path / "folder.png").mkdir()
    _check_error(tmp_path / "folder.png", "folder", ImageReadReason.NOT_AN_IMAGE)
    (tmp_path / "depth.exr").write_bytes(b"v/1\x01 not a photo")
    _check_error(tmp_path / "depth.exr", "not a supported photo format",
                 ImageReadReason.UNSUPPORTED_FORMAT)


def test_an_image_read_error_keeps_the_decoders_words_apart(tmp_path: Path) -> None:
    """The message for a person has no decoder words and is the error's ``str`` (what every
    front end prints); the decoder's words are kept apart; a pickled copy (from a batch worker
    process) is the same."""
    import pickle

    cut = _truncated(tmp_path, "cut.jpg")
    err = _check_error(cut, "truncated or corrupt", ImageReadReason.DAMAGED)
    assert err.message == f"cannot read image '{cut}': the file is truncated or corrupt"
    assert err.detail.startswith("OSError: image file is truncated")
    assert str(err) == err.message
    copy = pickle.loads(pickle.dumps(err))
    assert (str(copy), copy.message, copy.reason, copy.detail) == (
        str(err), err.message, err.reason, err.detail)
    plain = ImageReadError("cannot read 'x.png': file not found", "missing")
    assert str(plain) == plain.message and plain.reason is ImageReadReason.MISSING
    with pytest.raises(ValueError, match="not-a-reason"):
        ImageReadError("cannot read 'x.png'", "not-a-reason")


def test_a_tiff_cut_before_its_directory_is_damaged_not_not_an_image(tmp_path: Path) -> None:
    """Pillow cannot identify a TIFF whose directory (written after the pixels) was cut off;
    it starts as a TIFF, so it is damaged, not "not an image" with advice to choose a TIFF.
    (Outside pytest, where Pillow's "Corrupt EXIF data" warning is no error, this is what a
    user gets.)"""
    import warnings

    for name, bit_depth in (("cut.tif", 8), ("cut16.tif", 16)):
        path = _truncated(tmp_path, name, bit_depth=bit_depth)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            _check_error(path, "truncated or corrupt", ImageReadReason.DAMAGED)
            with pytest.raises(ImageReadError) as info:
                imageio.read_metadata(path)
            assert info.value.reason is ImageReadReason.DAMAGED
    with pytest.raises(ValueError, match="max_pixels"):
        read_image(tmp_path / "notes.jpg", max_pixels=0)


def test_a_video_is_not_an_image_not_a_damaged_photo(tmp_path: Path) -> None:
    """MP4 and MOV files start with an ``ftyp`` box as HEIC does: only HEIF brands count as
    a photo cut short (a dropped video got the interrupted-download advice)."""
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypisom\x00\x00\x02\x00isomiso2" + bytes(64))
    _check_error(video, "not an image", ImageReadReason.NOT_AN_IMAGE)
    heic = tmp_path / "cut.heic"
    heic.write_bytes(b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic" + bytes(8))
    _check_error(heic, "truncated or corrupt", ImageReadReason.DAMAGED)


@pytest.mark.parametrize(("name", "bit_depth"), [("t.jpg", 8), ("t.png", 8), ("t16.png", 16),
                                                 ("t.webp", 8), ("t16.tif", 16)])
def test_truncated_files(tmp_path: Path, name: str, bit_depth: int) -> None:
    path = _truncated(tmp_path, name, bit_depth=bit_depth)
    _check_error(path, "truncated or corrupt", ImageReadReason.DAMAGED)


def test_a_png_chunk_longer_than_the_file_is_refused_before_decoding(tmp_path: Path) -> None:
    """A chunk whose length runs past the end of the file (a corrupt or cut PNG) is refused,
    by reading and by the app's quick check, without reading what the length says (Pillow
    read 84 MB for a 60-byte file: a fuzz test); a PNG lacking only its end chunk is read."""
    import tracemalloc

    from outcast_core.runtime.io.imageio import check_photo_file

    whole = tmp_path / "whole.png"
    Image.fromarray((_noise_image(30, 40) * 255).round().astype(np.uint8)).save(whole)
    data = whole.read_bytes()
    assert data.endswith(b"IEND\xaeB`\x82")
    no_end = tmp_path / "no_end.png"
    no_end.write_bytes(data[:-12])
    np.testing.assert_array_equal(read_image(no_end).image_srgb, read_image(whole).image_srgb)
    check_photo_file(no_end)
    idat = data.index(b"IDAT") - 4
    claims = tmp_path / "claims.png"  # the image-data chunk says 2 GB
    claims.write_bytes(data[:idat] + (2**31 - 1).to_bytes(4, "big") + data[idat + 4:])
    # An EXIF chunk after the image data that says 1.5 GB, the file ending in it (a review:
    # the EXIF lookup, which runs first, read what it said before the file was found short).
    exif = tmp_path / "exif_claims.png"
    exif.write_bytes(data[:-12] + (1_500_000_000).to_bytes(4, "big") + b"eXIfII*\x00")
    for path in (claims, tmp_path / "cut.png", exif):
        if path.name == "cut.png":
            path.write_bytes(data[: idat + 20])
        tracemalloc.start()
        try:
            _check_error(path, "truncated or corrupt", ImageReadReason.DAMAGED)
        finally:
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        assert peak < 8 * 2**20
        with pytest.raises(ImageReadError, match="truncated or corrupt") as info:
            check_photo_file(path)
        assert ("eXIf" if path == exif else "IDAT") + " chunk runs" in info.value.detail


@pytest.mark.parametrize("subsampling", [0, 2])  # 4:4:4 (8 x 8 blocks), 4:2:0 (16 x 16)
def test_a_jpeg_lacking_only_its_end_marker_is_read(tmp_path: Path, subsampling: int) -> None:
    """Every block is there, only the end-of-image marker is missing (some writers leave it
    off; viewers show such files): read as the whole file is. Cut short by a few hundred
    bytes, it is still refused (its last blocks are missing)."""
    image = _noise_image(61, 83)  # sizes that end in partial blocks
    whole = tmp_path / "whole.jpg"
    Image.fromarray((image * 255).round().astype(np.uint8)).save(
        whole, quality=90, subsampling=subsampling)
    data = whole.read_bytes()
    assert data.endswith(b"\xff\xd9")
    no_end = tmp_path / "no_end.jpg"
    no_end.write_bytes(data[:-2])
    ref = read_image(whole).image_srgb
    assert np.array_equal(read_image(no_end).image_srgb, ref)
    small = read_image(whole, max_pixels=30 * 20).image_srgb
    assert np.array_equal(read_image(no_end, max_pixels=30 * 20).image_srgb, small)
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(data[:-400])
    _check_error(cut, "truncated or corrupt", ImageReadReason.DAMAGED)


@pytest.mark.parametrize("kind", ["baseline", "progressive"])
def test_the_quick_check_refuses_a_cut_jpeg_as_reading_does(tmp_path: Path, kind: str) -> None:
    """:func:`check_photo_file` (what the app calls before it asks to save the open photo)
    refuses a JPEG cut short, as :func:`read_image` does, and passes the whole file and one
    lacking only its end marker where reading does (a user trial: a cut JPEG passed)."""
    from outcast_core.runtime.io.imageio import check_photo_file

    im = Image.fromarray((_noise_image(61, 83) * 255).round().astype(np.uint8))
    whole = tmp_path / "whole.jpg"
    im.save(whole, quality=90, progressive=kind == "progressive")
    data = whole.read_bytes()
    check_photo_file(whole)
    no_end = tmp_path / "no_end.jpg"
    no_end.write_bytes(data[:-2])
    if kind == "baseline":
        check_photo_file(no_end)
        read_image(no_end)
    for keep in (len(data) * 2 // 3, len(data) - 400):
        cut = tmp_path / f"cut{keep}.jpg"
        cut.write_bytes(data[:keep])
        with pytest.raises(ImageReadError, match="truncated or corrupt") as info:
            check_photo_file(cut)
        assert info.value.reason is ImageReadReason.DAMAGED
        _check_error(cut, "truncated or corrupt", ImageReadReason.DAMAGED)


@pytest.mark.parametrize("kind", ["progressive", "cmyk"])
def test_a_cut_progressive_or_cmyk_jpeg_stays_refused(tmp_path: Path, kind: str) -> None:
    """Their last block does not turn mid-grey when cut short (a progressive JPEG's first
    scan holds every block's mean): the end-marker test cannot tell them, so they are refused
    as before, whole or cut (found by a review: a progressive file cut at half was read)."""
    im = Image.fromarray((_noise_image(64, 96) * 255).round().astype(np.uint8))
    whole = tmp_path / "whole.jpg"
    if kind == "progressive":
        im.save(whole, quality=90, progressive=True)
    else:
        im.convert("CMYK").save(whole, quality=90)
    data = whole.read_bytes()
    read_image(whole)  # the whole file reads
    for keep in (len(data) // 2, len(data) - 2):
        cut = tmp_path / f"cut{keep}.jpg"
        cut.write_bytes(data[:keep])
        _check_error(cut, "truncated or corrupt", ImageReadReason.DAMAGED)


def test_read_image_size_errors(tmp_path: Path) -> None:
    with pytest.raises(ImageReadError, match="not found"):
        read_image_size(tmp_path / "nope.png")
    (tmp_path / "t.png").write_text("text")
    with pytest.raises(ImageReadError, match="not an image"):
        read_image_size(tmp_path / "t.png")


# ------------------------------------------------------------------------------------------
# Large images


def _png_header_only(path: Path, width: int, height: int) -> None:
    """A PNG whose header declares width x height; the pixel data is missing."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                     + chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b""))


def test_pillow_bomb_guard_is_replaced_by_our_limit(tmp_path: Path) -> None:
    limit_before = Image.MAX_IMAGE_PIXELS
    big = tmp_path / "pano.png"
    _png_header_only(big, 12000, 10000)  # 120 MP: Pillow alone warns (DecompressionBombWarning)
    with pytest.warns(Image.DecompressionBombWarning):
        Image.open(big).close()
    assert read_image_size(big) == (12000, 10000)
    # the pixels are missing, not a bomb error
    _check_error(big, "truncated or corrupt", ImageReadReason.DAMAGED)
    huge = tmp_path / "huge.png"
    _png_header_only(huge, 40000, 30000)
    _check_error(huge, "MP limit", ImageReadReason.TOO_LARGE)
    assert limit_before == Image.MAX_IMAGE_PIXELS


def _png_with_late_exif(path: Path, width: int, height: int, orientation: int,
                        pixels: bool = True) -> None:
    """A PNG whose eXIf chunk comes after the pixel data (Pillow decodes to find it)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    exif = Image.Exif()
    exif[0x0112] = orientation
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    if pixels:
        rows = b"".join(b"\x00" + bytes(range(3 * width)) for _ in range(height))
        idat = zlib.compress(rows)
    else:
        idat = zlib.compress(b"\x00" * 64)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat)
                     + chunk(b"eXIf", exif.tobytes()) + chunk(b"IEND", b""))


@pytest.fixture
def no_decoding(monkeypatch) -> list[str]:
    """Records (and fails) every attempt to decode pixels with Pillow or OpenCV."""
    calls: list[str] = []

    def pil_load(self, *args, **kwargs):
        calls.append("PIL load")
        raise RuntimeError("pixels decoded")

    def cv2_imdecode(*args, **kwargs):
        calls.append("cv2.imdecode")
        raise RuntimeError("pixels decoded")

    monkeypatch.setattr(ImageFile.ImageFile, "load", pil_load)
    monkeypatch.setattr(imageio.cv2, "imdecode", cv2_imdecode)
    return calls


@pytest.mark.parametrize("late_exif", [False, True])
def test_bomb_is_refused_from_the_header_without_decoding(
    tmp_path: Path, no_decoding: list[str], late_exif: bool
) -> None:
    bomb = tmp_path / "bomb.png"
    if late_exif:
        _png_with_late_exif(bomb, 50000, 50000, 1, pixels=False)
    else:
        _png_header_only(bomb, 50000, 50000)
    _check_error(bomb, "MP limit", ImageReadReason.TOO_LARGE)
    with pytest.raises(ImageReadError, match="MP limit"):
        read_image(bomb, max_pixels=1000)
    with pytest.raises(ImageReadError, match="MP limit"):
        read_image_size(bomb)
    assert no_decoding == []


def test_read_image_size_reads_a_late_png_exif_without_decoding(
    tmp_path: Path, no_decoding: list[str]
) -> None:
    path = tmp_path / "rotated.png"
    _png_with_late_exif(path, 3000, 2000, orientation=6, pixels=False)
    assert read_image_size(path) == (2000, 3000)
    assert no_decoding == []


def test_late_png_exif_is_applied_when_reading(tmp_path: Path) -> None:
    path = tmp_path / "rotated.png"
    _png_with_late_exif(path, 6, 4, orientation=6)
    loaded = read_image(path)
    assert loaded.image_srgb.shape == (6, 4, 3) and loaded.original_size == (4, 6)
    assert loaded.exif.orientation == 6


_BOMB_CHILD = """
import resource, sys, time
from outcast_core.runtime.io.imageio import ImageReadError, read_image
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
try:
    read_image(sys.argv[1])
except ImageReadError as exc:
    assert "MP limit" in str(exc), exc
else:
    raise SystemExit("not refused")
seconds = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(seconds, (peak - base) / 1024)
"""


@pytest.mark.parametrize(("width", "height"), [(50000, 50000), (20000, 20000)])
def test_bomb_refusal_is_fast_and_small(tmp_path: Path, width: int, height: int) -> None:
    bomb = tmp_path / "bomb.png"
    _png_with_late_exif(bomb, width, height, 1, pixels=False)
    result = subprocess.run(
        [sys.executable, "-c", _BOMB_CHILD, str(bomb)],
        capture_output=True, text=True, check=True, cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    seconds, extra_mb = (float(v) for v in result.stdout.split())
    assert seconds < 1.0 and extra_mb < 20.0


def test_max_pixels_on_a_photo_above_pillows_warning_size(tmp_path: Path) -> None:
    # 10000 x 9000 = 90 MP is above Pillow's 89.5 MP DecompressionBombWarning (an error here).
    h, w = 9000, 10000
    grey = np.add.outer(np.arange(h, dtype=np.uint16) // 40, np.arange(w, dtype=np.uint16) // 40)
    grey = grey.astype(np.uint8)
    path = tmp_path / "big.jpg"
    ok, data = cv2.imencode(".jpg", grey, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    data.tofile(path)
    del grey
    loaded = read_image(path, max_pixels=500_000)
    lh, lw = loaded.image_srgb.shape[:2]
    assert lw * lh <= 500_000 and lw * lh > 0.99 * 500_000
    assert abs(lw / lh - w / h) < 0.01
    assert loaded.original_size == (w, h) and loaded.scale == pytest.approx(lw / w)


_CHILD = """
import resource, sys
from outcast_core.runtime.io.imageio import read_image
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
image = read_image(sys.argv[1], max_pixels=int(sys.argv[2])).image_srgb
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(image.shape[0], image.shape[1], (peak - base) / 1024)
"""


def test_max_pixels_bounds_peak_memory(tmp_path: Path) -> None:
    h, w = 6000, 8000  # 48 MP: full-size float32 RGB would be 576 MB
    y = np.linspace(0, 255, h, dtype=np.float32)[:, None]
    x = np.linspace(0, 255, w, dtype=np.float32)[None, :]
    rgb = np.empty((h, w, 3), np.uint8)
    rgb[..., 0] = (0.5 * x + 0.5 * y).astype(np.uint8)
    rgb[..., 1] = y.astype(np.uint8)
    rgb[..., 2] = x.astype(np.uint8)
    path = tmp_path / "big.jpg"
    ok, data = cv2.imencode(".jpg", rgb)
    assert ok
    data.tofile(path)
    del rgb, data
    result = subprocess.run(
        [sys.executable, "-c", _CHILD, str(path), "1000000"],
        capture_output=True, text=True, check=True, cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    rows, cols, peak_mb = result.stdout.split()
    assert int(rows) * int(cols) <= 1_000_000
    assert (int(cols), int(rows)) == (1154, 866)
    assert float(peak_mb) < 150.0  # measured about 35 MB (libjpeg decodes at 1/4 scale)


def test_max_pixels_on_16_bit_png(tmp_path: Path) -> None:
    image = _smooth_image(300, 400)
    path = write_image(tmp_path / "s.png", image, bit_depth=16)
    loaded = read_image(path, max_pixels=100 * 75)
    assert loaded.image_srgb.shape == (75, 100, 3)
    expected = cv2.resize(image, (100, 75), interpolation=cv2.INTER_AREA)
    assert np.abs(loaded.image_srgb - expected).max() < 1e-4


# ------------------------------------------------------------------------------------------
# Writing: overwrite protection, atomicity, argument checks


def test_no_overwrite_without_force(tmp_path: Path) -> None:
    path = tmp_path / "out.png"
    write_image(path, np.zeros((4, 5, 3), np.float32))
    with pytest.raises(FileExistsError, match="--force"):
        write_image(path, np.ones((4, 5, 3), np.float32))
    assert read_image(path).image_srgb.max() == 0.0
    write_image(path, np.ones((4, 5, 3), np.float32), force=True)
    assert read_image(path).image_srgb.min() == 1.0
    assert _listing(tmp_path) == ["out.png"]
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_failed_write_leaves_nothing_and_keeps_old_file(tmp_path: Path, monkeypatch) -> None:
    def broken(path: Path, array: np.ndarray, ext: str, exif: bytes | None = None) -> None:
        path.write_bytes(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(imageio, "_write_cv2", broken)
    with pytest.raises(OSError, match="disk full"):
        write_image(tmp_path / "new.png", np.zeros((4, 4, 3), np.float32), bit_depth=16)
    assert _listing(tmp_path) == []
    old = write_image(tmp_path / "old.png", np.zeros((4, 4, 3), np.float32))
    before = old.read_bytes()
    with pytest.raises(OSError, match="disk full"):
        write_image(old, np.ones((4, 4, 3), np.float32), bit_depth=16, force=True)
    assert old.read_bytes() == before and _listing(tmp_path) == ["old.png"]


def test_atomic_output_context_manager(tmp_path: Path) -> None:
    target = tmp_path / "clip.mp4"
    with atomic_output(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".mp4" and tmp != target
        tmp.write_bytes(b"video")
        assert not target.exists()
    assert target.read_bytes() == b"video" and _listing(tmp_path) == ["clip.mp4"]
    with pytest.raises(RuntimeError, match="encoder"), atomic_output(target, force=True) as tmp:
        tmp.write_bytes(b"partial")
        raise RuntimeError("encoder crashed")
    assert target.read_bytes() == b"video" and _listing(tmp_path) == ["clip.mp4"]
    with pytest.raises(FileNotFoundError, match="does not exist"):
        write_image(tmp_path / "sub" / "a.png", np.zeros((2, 2, 3), np.float32))
    made = write_image(tmp_path / "sub" / "a.png", np.zeros((2, 2, 3), np.float32),
                       make_parents=True)
    assert made.is_file()


@pytest.mark.parametrize(
    ("name", "array", "kwargs", "match"),
    [
        ("a.bmp", np.zeros((2, 2, 3), np.float32), {}, "extension"),
        ("a.jpg", np.zeros((2, 2, 3), np.float32), {"bit_depth": 16}, "bit_depth 8"),
        ("a.png", np.zeros((2, 2, 3), np.float32), {"bit_depth": 12}, "bit_depth"),
        ("a.png", np.zeros((2, 2, 3), np.int32), {}, "float"),  # uint8 is written as it is
        ("a.png", np.zeros((2, 2, 4), np.float32), {}, "shape"),
        ("a.png", np.full((2, 2, 3), np.nan, np.float32), {}, "NaN"),
        ("a.jpg", np.zeros((2, 2, 3), np.float32), {"quality": 0}, "quality"),
    ],
)
def test_write_image_rejects_bad_input(tmp_path: Path, name, array, kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        write_image(tmp_path / name, array, **kwargs)
    assert _listing(tmp_path) == []


def test_values_outside_range_are_clipped(tmp_path: Path) -> None:
    image = np.array([[[-0.5, 0.5, 1.5]]], np.float32)
    loaded = read_image(write_image(tmp_path / "c.png", image, bit_depth=16)).image_srgb
    assert loaded[0, 0].tolist() == [0.0, pytest.approx(0.5, abs=1e-5), 1.0]


def test_shadow_png(tmp_path: Path) -> None:
    shadow = np.random.default_rng(3).random((21, 34)).astype(np.float32)
    shadow[0, :3] = [0.0, 1.0, 1.2]
    path = write_shadow_png(tmp_path / "s.png", shadow)
    stored = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert stored.dtype == np.uint16 and stored.shape == shadow.shape
    assert np.array_equal(stored, np.rint(np.clip(shadow, 0, 1) * 65535).astype(np.uint16))
    back = read_shadow_png(path)
    assert back.shape == shadow.shape
    assert np.abs(back - np.clip(shadow, 0, 1)).max() <= 0.5 / 65535 + 1e-7
    with pytest.raises(FileExistsError):
        write_shadow_png(path, shadow)
    with pytest.raises(ValueError, match="H x W"):
        write_shadow_png(tmp_path / "t.png", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match=".png"):
        write_shadow_png(tmp_path / "t.jpg", shadow)


# ------------------------------------------------------------------------------------------
# Depth


def _depth(h: int = 24, w: int = 31) -> np.ndarray:
    depth = np.random.default_rng(5).uniform(0.5, 40.0, (h, w)).astype(np.float32)
    depth[:4] = np.inf  # sky
    return depth


@pytest.mark.parametrize("ext", [".npy", ".exr"])
def test_depth_exact_round_trip(tmp_path: Path, ext: str) -> None:
    depth = _depth()
    back = read_depth(write_depth(tmp_path / f"d{ext}", depth))
    assert back.dtype == np.float32 and back.shape == depth.shape
    assert np.array_equal(back, depth)  # inf included
    assert np.isposinf(back[:4]).all()


def test_depth_png_round_trip_and_invalid_pixels(tmp_path: Path) -> None:
    depth = _depth()
    depth[5, :3] = [np.nan, 0.0, -2.0]
    depth[6, 0] = 1e-6  # tiny but valid: stored as code 1, not as "invalid"
    path = write_depth(tmp_path / "d.png", depth)
    with Image.open(path) as im:
        assert im.mode == "I;16"
        assert float(im.info[imageio.DEPTH_SCALE_KEY]) == pytest.approx(float(
            np.nanmax(np.where(np.isfinite(depth), depth, np.nan))))
    back = read_depth(path)
    invalid = ~(np.isfinite(depth) & (depth > 0))
    assert np.array_equal(np.isposinf(back), invalid)
    max_depth = float(depth[~invalid].max())
    normal = ~invalid
    normal[6, 0] = False
    assert np.abs(back[normal] - depth[normal]).max() <= 0.5 / 65535 * max_depth * 1.001
    assert back[6, 0] == pytest.approx(max_depth / 65535)  # clamped up to the smallest code


def test_depth_png_from_another_tool_reads_as_relative(tmp_path: Path) -> None:
    codes = np.array([[0, 1000], [65535, 32768]], np.uint16)
    cv2.imwrite(str(tmp_path / "z.png"), codes)
    back = read_depth(tmp_path / "z.png")
    assert np.isposinf(back[0, 0])
    assert back[1, 0] == pytest.approx(1.0) and back[0, 1] == pytest.approx(1000 / 65535)


def test_a_colour_png_given_as_depth_is_named_in_words(tmp_path: Path) -> None:
    """A 16-bit colour PNG reads as Pillow's 8-bit "RGB": the error says "colour", not "mode
    RGB" (a user trial found that odd for a 16-bit file)."""
    cv2.imwrite(str(tmp_path / "c.png"), np.full((4, 4, 3), 1000, np.uint16))
    with pytest.raises(ValueError, match="got a PNG image in colour$"):
        read_depth(tmp_path / "c.png")


def test_depth_exr_channel_choice(tmp_path: Path) -> None:
    r = np.full((3, 4), 2.0, np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"R": r, "G": r * 2, "B": r * 3}).write(str(tmp_path / "rgb.exr"))
    assert np.array_equal(read_depth(tmp_path / "rgb.exr"), r)
    OpenEXR.File(header, {"A": r, "B": r}).write(str(tmp_path / "ab.exr"))
    with pytest.raises(ValueError, match="'Z'"):
        read_depth(tmp_path / "ab.exr")


def test_depth_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="H x W"):
        write_depth(tmp_path / "d.npy", np.zeros((4, 4, 1), np.float32))
    with pytest.raises(ValueError, match="float"):
        write_depth(tmp_path / "d.npy", np.zeros((4, 4), np.int32))
    with pytest.raises(ValueError, match="extension"):
        write_depth(tmp_path / "d.tif", np.zeros((4, 4), np.float32))
    assert _listing(tmp_path) == []
    np.save(tmp_path / "rgb.npy", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="H x W"):
        read_depth(tmp_path / "rgb.npy")
    np.save(tmp_path / "int.npy", np.zeros((4, 4), np.int64))
    with pytest.raises(ValueError, match="float"):
        read_depth(tmp_path / "int.npy")
    write_image(tmp_path / "photo.png", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="16-bit grey"):
        read_depth(tmp_path / "photo.png")
    with pytest.raises(ImageReadError, match="not found") as info:
        read_depth(tmp_path / "none.exr")
    assert info.value.reason is ImageReadReason.MISSING
    (tmp_path / "empty.npy").write_bytes(b"")
    with pytest.raises(ImageReadError, match="empty") as info:
        read_depth(tmp_path / "empty.npy")
    assert info.value.reason is ImageReadReason.DAMAGED
    for name, reason in (("bad.npy", ImageReadReason.NOT_AN_IMAGE),
                         ("bad.exr", ImageReadReason.DAMAGED),
                         ("bad.png", ImageReadReason.NOT_AN_IMAGE)):
        (tmp_path / name).write_text("not a depth map")
        with pytest.raises(ImageReadError, match="bad") as info:
            read_depth(tmp_path / name)
        assert info.value.reason is reason, name
    good = write_depth(tmp_path / "good.exr", _depth())
    data = good.read_bytes()
    good.write_bytes(data[: len(data) // 2])
    with pytest.raises(ImageReadError):
        read_depth(good)
    write_depth(tmp_path / "keep.npy", _depth())
    with pytest.raises(FileExistsError, match="--force"):
        write_depth(tmp_path / "keep.npy", _depth())


# ------------------------------------------------------------------------------------------
# Colour profiles


def _s15(x: float) -> bytes:
    return struct.pack(">i", round(x * 65536))


def _matrix_profile(primaries: list[tuple[float, float, float]], name: str) -> bytes:
    """A minimal ICC v2 RGB matrix/TRC display profile (gamma 2.2)."""
    def xyz(v: tuple[float, float, float]) -> bytes:
        return b"XYZ \0\0\0\0" + b"".join(_s15(c) for c in v)

    text = name.encode("ascii") + b"\0"
    desc = (b"desc\0\0\0\0" + struct.pack(">I", len(text)) + text + b"\0" * 8
            + b"\0" * 3 + b"\0" * 67)
    curve = b"curv\0\0\0\0" + struct.pack(">IH", 1, round(2.2 * 256)) + b"\0\0"
    tags = [(b"desc", desc), (b"wtpt", xyz((0.9642, 1.0, 0.8249))),
            (b"rXYZ", xyz(primaries[0])), (b"gXYZ", xyz(primaries[1])),
            (b"bXYZ", xyz(primaries[2])), (b"rTRC", curve), (b"gTRC", curve), (b"bTRC", curve)]
    offset = 128 + 4 + 12 * len(tags)
    table, data = b"", b""
    for sig, body in tags:
        table += sig + struct.pack(">II", offset + len(data), len(body))
        data += body + b"\0" * (-len(body) % 4)
    size = offset + len(data)
    header = (struct.pack(">I", size) + b"none" + bytes([2, 0x10, 0, 0]) + b"mntrRGB XYZ "
              + b"\0" * 12 + b"acsp" + b"\0" * 24 + b"\0" * 4
              + _s15(0.9642) + _s15(1.0) + _s15(0.8249) + b"\0" * 48)
    assert len(header) == 128
    return header + struct.pack(">I", len(tags)) + table + data


def test_non_srgb_icc_profile_is_converted(tmp_path: Path) -> None:
    red, green, blue = (0.4361, 0.2225, 0.0139), (0.3851, 0.7169, 0.0971), (0.1431, 0.0606, 0.7141)
    swapped = _matrix_profile([green, red, blue], "Swapped RG test")  # stored R means sRGB G
    pixels = np.zeros((4, 6, 3), np.uint8)
    pixels[..., 0] = 200
    Image.fromarray(pixels).save(tmp_path / "icc.png", icc_profile=swapped)
    loaded = read_image(tmp_path / "icc.png").image_srgb
    assert loaded[..., 1].mean() > 0.7 and loaded[..., 0].mean() < 0.1  # red became green
    Image.fromarray(pixels).save(tmp_path / "plain.png")
    assert read_image(tmp_path / "plain.png").image_srgb[..., 0].mean() == pytest.approx(200 / 255)


def _png16_with_profile(path: Path, pixels16: np.ndarray, icc: bytes) -> None:
    """A 16-bit RGB PNG (OpenCV) with an iCCP chunk (Pillow cannot write 16-bit colour)."""
    ok, data = cv2.imencode(".png", np.ascontiguousarray(pixels16[:, :, ::-1]))
    assert ok
    png = data.tobytes()
    body = b"iCCP" + b"test\0\0" + zlib.compress(icc)
    chunk = struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body))
    path.write_bytes(png[:33] + chunk + png[33:])  # right after IHDR


def test_16_bit_colour_file_with_a_profile_is_converted_like_an_8_bit_one(tmp_path: Path) -> None:
    """16-bit colour files are decoded by OpenCV, which ignores profiles: an Adobe RGB 16-bit
    export was read as sRGB (16 % duller, found by a user trial). Now its conversion matches
    LittleCMS's on the 8-bit file within 2/255, and keeps the 16-bit steps."""
    adobe = _matrix_profile([(0.6097, 0.3111, 0.0195), (0.2052, 0.6257, 0.0609),
                             (0.1492, 0.0632, 0.7448)], "Adobe-like test")
    rng = np.random.default_rng(4)
    pixels = rng.integers(0, 256, (16, 24, 3)).astype(np.uint8)
    Image.fromarray(pixels).save(tmp_path / "a8.png", icc_profile=adobe)
    _png16_with_profile(tmp_path / "a16.png", pixels.astype(np.uint16) * 257, adobe)
    eight, sixteen = read_image(tmp_path / "a8.png"), read_image(tmp_path / "a16.png")
    assert sixteen.bit_depth == 16
    diff = np.abs(eight.image_srgb - sixteen.image_srgb) * 255
    assert diff.max() <= 1.0  # a matrix/TRC profile is converted exactly (8-bit rounding)
    assert np.abs(sixteen.image_srgb - pixels / np.float32(255)).mean() * 255 > 3  # converted
    ramp = np.repeat(np.arange(0, 65536, 64, dtype=np.uint16)[None, :, None], 3, 2)  # 1024 steps
    _png16_with_profile(tmp_path / "ramp.png", np.repeat(ramp, 2, 0), adobe)
    grey = read_image(tmp_path / "ramp.png").image_srgb[0, :, 1]
    assert np.all(np.diff(grey) >= 0) and np.unique(grey).size > 900  # smooth, not 8-bit steps


def test_16_bit_conversion_through_littlecms_samples_for_other_profiles(monkeypatch) -> None:
    """A profile without matrix/TRC tags (LUT-based) is converted through samples of
    LittleCMS's conversion: within 2/255 of it away from sRGB's gamut edge."""
    import outcast_core.runtime.io.imageio as imageio_mod

    adobe = _matrix_profile([(0.6097, 0.3111, 0.0195), (0.2052, 0.6257, 0.0609),
                             (0.1492, 0.0632, 0.7448)], "Adobe-like test")
    monkeypatch.setattr(imageio_mod, "_matrix_shaper", lambda icc: None)  # as a LUT profile
    pixels = np.random.default_rng(5).integers(0, 256, (16, 24, 3)).astype(np.uint8)
    with Image.open(io.BytesIO(_png_bytes(pixels, adobe))) as im:
        lcms = np.asarray(imageio_mod._convert_icc_to_srgb(im), np.float32) / 255
    ours = imageio_mod._convert_icc_float(pixels.astype(np.float32) / 255, adobe)
    diff = np.abs(ours - lcms) * 255
    inside = ((lcms > 16 / 255) & (lcms < 239 / 255)).all(axis=2)  # clips bend it at the edge
    assert inside.mean() > 0.3 and diff[inside].max() <= 2.5 and diff.mean() < 1.0
    assert np.abs(ours - pixels / 255).mean() * 255 > 3  # it did convert


def _png_bytes(pixels: np.ndarray, icc: bytes) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, "PNG", icc_profile=icc)
    return buf.getvalue()


def test_atomic_output_never_replaces_a_device(tmp_path: Path) -> None:
    link = tmp_path / "null.png"
    link.symlink_to("/dev/null")
    with pytest.raises(ValueError, match="not a regular file"):
        write_image(link, np.zeros((2, 2, 3), np.float32), force=True)
    assert link.is_symlink() and Path("/dev/null").is_char_device()


def test_read_metadata_reads_exif_without_the_pixels(tmp_path: Path) -> None:
    """GPS, time and heading from a JPEG, and from a PNG's eXIf chunk (Pillow's own reader
    decodes the whole PNG to find it); a file that is no image is an ImageReadError."""
    from outcast_core.runtime.io.imageio import ImageReadError, read_metadata

    sample = Path(__file__).resolve().parents[3] / "samples" / "exif_003_th_pool.jpg"
    meta = read_metadata(sample)
    assert meta.latitude is not None and meta.capture_time is not None
    assert meta.heading_deg is not None
    loaded = read_image(sample, max_pixels=64 * 48)
    png = tmp_path / "with_exif.png"
    write_image(png, loaded.image_srgb, exif=loaded.exif_bytes)
    again = read_metadata(png)
    assert (again.latitude, again.capture_time) == (meta.latitude, meta.capture_time)
    text = tmp_path / "notes.jpg"
    text.write_text("not an image")
    with pytest.raises(ImageReadError):
        read_metadata(text)


def test_same_file_sees_through_other_names(tmp_path: Path) -> None:
    from outcast_core.runtime.io.imageio import same_file

    a, b = tmp_path / "a.jpg", tmp_path / "b.jpg"
    a.write_bytes(b"x")
    b.write_bytes(b"x")
    link = tmp_path / "link.jpg"
    os.link(a, link)
    assert same_file(a, link) and same_file(a, tmp_path / "." / "a.jpg")
    assert not same_file(a, b) and not same_file(a, None) and not same_file(a, tmp_path / "no")


def test_parametric_tone_curve_of_a_v4_profile() -> None:
    """ICC ``para`` type 3 with sRGB's parameters is sRGB's curve (v4 profiles use it)."""
    from outcast_core.runtime.geometry.colour import srgb_to_linear
    from outcast_core.runtime.io.imageio import _icc_curve

    params = [2.4, 1 / 1.055, 0.055 / 1.055, 1 / 12.92, 0.04045]
    data = b"para\0\0\0\0" + struct.pack(">HH", 3, 0) + b"".join(
        struct.pack(">i", round(v * 65536)) for v in params)
    curve = _icc_curve(data, 0)
    x = np.linspace(0.0, 1.0, curve.size, dtype=np.float32)
    assert np.abs(curve - srgb_to_linear(x)).max() < 1e-4
    assert _icc_curve(b"mAB " + b"\0" * 12, 0) is None  # other types: not a tone curve


def test_jpeg_whose_header_declares_far_more_than_its_data_is_refused(tmp_path: Path) -> None:
    """A 64 x 64 JPEG whose frame header says 9000 x 9000 decoded as a flat grey photo (libjpeg
    fills missing data without an error; found by a user trial)."""
    buf = io.BytesIO()
    Image.fromarray((_noise_image(64, 64, seed=2) * 255).astype(np.uint8)).save(buf, "JPEG")
    data = bytearray(buf.getvalue())
    sof = data.index(b"\xff\xc0")
    struct.pack_into(">HH", data, sof + 5, 9000, 9000)  # height, width
    (tmp_path / "big.jpg").write_bytes(bytes(data))
    err = _check_error(tmp_path / "big.jpg", "cannot hold the 9000 x 9000 JPEG",
                       ImageReadReason.DAMAGED)
    size = len(data)
    assert err.message.endswith(f"its {size:,} bytes cannot hold the 9000 x 9000 JPEG its "
                                "header declares") and err.detail == ""
    flat = tmp_path / "flat.jpg"  # a real flat frame compresses far less than that
    Image.new("L", (2000, 1500), 0).save(flat, "JPEG", quality=1, optimize=True)
    assert read_image(flat, max_pixels=300 * 200).original_size == (2000, 1500)


def test_a_cut_short_16_bit_png_is_refused_without_libpng_noise(tmp_path: Path,
                                                                 capfd: pytest.CaptureFixture
                                                                 ) -> None:
    """OpenCV's libpng printed its own error line on stderr before OutCast's message (found by
    a user trial); bytes after the IEND chunk are still fine."""
    ok, data = cv2.imencode(".png", (_noise_image(40, 50, seed=3) * 65535).astype(np.uint16))
    assert ok
    whole = data.tobytes()
    (tmp_path / "cut.png").write_bytes(whole[: len(whole) // 2])
    err = _check_error(tmp_path / "cut.png", "truncated or corrupt", ImageReadReason.DAMAGED)
    assert err.message.endswith(f"its {len(whole) // 2:,} bytes stop before the end of the PNG")
    assert "IDAT" not in err.message and "IDAT chunk runs" in err.detail  # (walked)
    # Cut between two chunks: every chunk whole, the end chunk missing (told at decoding).
    iend = whole.index(b"IEND") - 4
    (tmp_path / "cut.png").write_bytes(whole[:iend])
    err = _check_error(tmp_path / "cut.png", "truncated or corrupt", ImageReadReason.DAMAGED)
    assert err.message.endswith(f"its {iend:,} bytes stop before the end of the PNG")
    assert "IEND" not in err.message and "IEND" in err.detail
    assert "libpng" not in capfd.readouterr().err
    (tmp_path / "tail.png").write_bytes(whole + b"\0" * 5000)
    assert read_image(tmp_path / "tail.png").bit_depth == 16
