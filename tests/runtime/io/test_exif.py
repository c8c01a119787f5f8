"""EXIF metadata: the real samples (values from samples/README.md) and synthetic tag sets."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from PIL import Image, TiffImagePlugin

from outcast_core.runtime.io.exif import PhotoMetadata, metadata_from_exif
from outcast_core.runtime.io.imageio import read_image

SAMPLES = Path(__file__).resolve().parents[3] / "samples"
R = TiffImagePlugin.IFDRational

# (file, latitude, longitude, UTC capture time) as listed in samples/README.md.
SAMPLE_FACTS = [
    ("exif_001_cz_fieldpath.jpg", 50.299603, 14.820294, datetime(2018, 7, 25, 14, 34, 23)),
    ("exif_003_th_pool.jpg", 7.831431, 98.296653, datetime(2019, 8, 21, 3, 57, 22)),
    ("exif_005_es_skislope.jpg", 40.788685, -4.005141, datetime(2022, 2, 3, 14, 44, 9)),
]


@pytest.mark.parametrize(("name", "lat", "lon", "utc"), SAMPLE_FACTS)
def test_samples_gps_and_time(name: str, lat: float, lon: float, utc: datetime) -> None:
    meta = read_image(SAMPLES / name, max_pixels=64 * 48).exif
    assert meta.has_gps
    assert meta.latitude == pytest.approx(lat, abs=1e-4)
    assert meta.longitude == pytest.approx(lon, abs=1e-4)
    assert meta.capture_time is not None and meta.capture_time.tzinfo is not None
    error = meta.capture_time_utc - utc.replace(tzinfo=UTC)
    assert abs(error.total_seconds()) <= 1.0


def test_sample_details() -> None:
    with Image.open(SAMPLES / "exif_003_th_pool.jpg") as im:
        pool = metadata_from_exif(im.getexif())
    assert (pool.make, pool.model) == ("Apple", "iPhone XS Max")
    assert pool.focal_35mm == 26.0 and pool.focal_mm == pytest.approx(4.25)
    assert pool.heading_deg == pytest.approx(163.7, abs=0.05) and pool.heading_ref == "T"
    # Wall clock 10:57:23 vs GPS 03:57:22.64 UTC: Thailand, UTC+7.
    assert pool.tz_offset == timedelta(hours=7) and pool.tz_offset_source == "gps"
    assert pool.local_time == datetime(2019, 8, 21, 10, 57, 23, 345000)
    assert pool.capture_time_source == "gps"

    with Image.open(SAMPLES / "exif_001_cz_fieldpath.jpg") as im:
        field = metadata_from_exif(im.getexif())
    assert field.tz_offset == timedelta(hours=2)  # CEST
    assert field.heading_deg is None and field.heading_ref is None
    assert field.altitude_m == pytest.approx(252.0)

    with Image.open(SAMPLES / "exif_005_es_skislope.jpg") as im:
        ski = metadata_from_exif(im.getexif())
    assert ski.heading_deg == pytest.approx(93.0) and ski.heading_ref == "M"
    assert ski.focal_35mm is None and ski.make is None


def _jpeg_with_exif(tmp_path: Path, base: dict, exif_ifd: dict | None, gps: dict | None) -> Path:
    exif = Image.Exif()
    for tag, value in base.items():
        exif[tag] = value
    if exif_ifd is not None:
        exif[0x8769] = exif_ifd
    if gps is not None:
        exif[0x8825] = gps
    path = tmp_path / "tagged.jpg"
    Image.new("RGB", (16, 8), (90, 120, 200)).save(path, exif=exif.tobytes())
    return path


def _meta(path: Path) -> PhotoMetadata:
    with Image.open(path) as im:
        return metadata_from_exif(im.getexif())


def test_explicit_offset_southern_western_hemisphere(tmp_path: Path) -> None:
    path = _jpeg_with_exif(
        tmp_path,
        {0x010F: "Canon\x00", 0x0110: "  EOS  R5 ", 0x0112: 6},
        {0x9003: "2021:06:21 12:00:00", 0x9011: "+05:30", 0x9291: "25",
         0x920A: R(50, 1), 0xA405: 75},
        {1: "S", 2: (R(33, 1), R(51, 1), R(3571, 100)), 3: "W", 4: (R(70, 1), R(0, 1), R(0, 1)),
         5: b"\x01", 6: R(10, 1), 7: (R(6, 1), R(31, 1), R(0, 1)), 0x1D: "2021:06:21",
         0x10: "M", 0x11: R(2705, 10)},
    )
    meta = _meta(path)
    assert (meta.make, meta.model) == ("Canon", "EOS R5")
    assert meta.latitude == pytest.approx(-(33 + 51 / 60 + 35.71 / 3600), abs=1e-9)
    assert meta.longitude == pytest.approx(-70.0)
    assert meta.altitude_m == pytest.approx(-10.0)
    assert meta.focal_mm == 50.0 and meta.focal_35mm == 75.0
    assert meta.heading_deg == pytest.approx(270.5) and meta.heading_ref == "M"
    assert meta.orientation == 6
    # The explicit offset wins over the GPS stamp (which is 1 minute off here).
    assert meta.capture_time_source == "exif_offset" and meta.tz_offset_source == "exif"
    assert meta.capture_time.isoformat() == "2021-06-21T12:00:00.250000+05:30"
    assert meta.capture_time_utc == datetime(2021, 6, 21, 6, 30, 0, 250000, tzinfo=UTC)


def test_offset_derived_across_midnight_and_rejected_when_inconsistent(tmp_path: Path) -> None:
    gps = {0x1D: "2019:12:31", 7: (R(19, 1), R(0, 1), R(5, 1)), 2: (R(12, 1), R(0, 1), R(0, 1)),
           4: (R(77, 1), R(0, 1), R(0, 1)), 1: "N", 3: "E"}
    meta = _meta(_jpeg_with_exif(tmp_path, {}, {0x9003: "2020:01:01 00:30:00"}, gps))
    assert meta.tz_offset == timedelta(hours=5, minutes=30)
    assert meta.capture_time_utc == datetime(2019, 12, 31, 19, 0, 5, tzinfo=UTC)

    meta = _meta(_jpeg_with_exif(tmp_path, {}, {0x9003: "2019:12:31 22:07:30"}, gps))
    assert meta.tz_offset is None  # 3 h 7 min 25 s is no time zone
    assert meta.capture_time_source == "gps"
    assert meta.capture_time == datetime(2019, 12, 31, 19, 0, 5, tzinfo=UTC)


def test_naive_local_time_without_zone(tmp_path: Path) -> None:
    meta = _meta(_jpeg_with_exif(tmp_path, {0x0132: "2020:03:04 05:06:07"}, None, None))
    assert meta.capture_time == datetime(2020, 3, 4, 5, 6, 7)
    assert meta.capture_time.tzinfo is None and meta.capture_time_utc is None
    assert meta.capture_time_source == "local" and meta.tz_offset is None
    assert not meta.has_gps


def test_malformed_tags_are_none(tmp_path: Path) -> None:
    meta = _meta(_jpeg_with_exif(
        tmp_path,
        {0x0112: 12},
        {0x9003: "    :  :     :  :  ", 0x9011: "garbage", 0xA405: 0, 0x920A: R(0, 0)},
        {1: "N", 2: (R(1, 0), R(2, 1), R(3, 1)), 3: "E", 4: (R(1, 1), R(2, 1), R(3, 1)),
         0x1D: "2020:13:45", 7: (R(1, 1), R(2, 1), R(3, 1)), 0x11: R(400, 1), 0x10: "T"},
    ))
    assert meta.orientation == 1
    assert meta.capture_time is None and meta.local_time is None
    assert meta.focal_35mm is None and meta.focal_mm is None
    assert meta.latitude is None and meta.longitude is None
    assert meta.heading_deg is None and meta.heading_ref is None


def test_void_or_zero_gps_fix_is_none(tmp_path: Path) -> None:
    position = {1: "N", 2: (R(10, 1), R(0, 1), R(0, 1)), 3: "E", 4: (R(20, 1), R(0, 1), R(0, 1))}
    assert _meta(_jpeg_with_exif(tmp_path, {}, None, position)).latitude == pytest.approx(10.0)
    void = {**position, 9: "V"}
    assert _meta(_jpeg_with_exif(tmp_path, {}, None, void)).latitude is None
    zero = {1: "N", 2: (R(0, 1), R(0, 1), R(0, 1)), 3: "E", 4: (R(0, 1), R(0, 1), R(0, 1))}
    assert not _meta(_jpeg_with_exif(tmp_path, {}, None, zero)).has_gps


def test_no_exif_at_all(tmp_path: Path) -> None:
    assert metadata_from_exif(None) == PhotoMetadata()
    path = tmp_path / "plain.png"
    Image.new("RGB", (4, 4)).save(path)
    meta = read_image(path).exif
    assert meta == PhotoMetadata()
    assert meta.capture_time is None and meta.orientation == 1
