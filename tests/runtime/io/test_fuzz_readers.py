"""Issue 20: a bounded fuzz harness over the readers and the CLI's argument parsing.

Every input either works or raises the project's own error type (a ``ValueError``: an
``ImageReadError``, or a ``ModelError`` for manifests) with a one-line message; nothing hangs
(hypothesis' deadline) and nothing allocates past a budget (``tracemalloc`` for Python-side
allocations; declared sizes past :data:`~outcast_core.runtime.io.imageio.MAX_DECODE_PIXELS` are
refused from the header). About 10 s in all.
"""

from __future__ import annotations

import io
import json
import struct
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from PIL import Image

from outcast_core.runtime.cli.main import build_parser
from outcast_core.runtime.io.imageio import read_depth, read_image, read_image_size
from outcast_core.runtime.io.models import ModelError, ModelRegistry

FUZZ = settings(max_examples=60, deadline=10_000,  # generous: the machine is shared
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
BUDGET_BYTES = 64 * 2**20  # Python-side allocations per input


def _chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


@st.composite
def png_files(draw) -> bytes:
    """PNGs with arbitrary header fields, chunks and (often truncated) pixel data."""
    width = draw(st.integers(0, 2**31 - 1) | st.integers(1, 64))
    height = draw(st.integers(0, 2**31 - 1) | st.integers(1, 64))
    depth = draw(st.sampled_from([1, 2, 4, 8, 16, 3, 0]))
    colour = draw(st.sampled_from([0, 2, 3, 4, 6, 1, 7]))
    interlace = draw(st.sampled_from([0, 1]))
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, interlace)
    chunks = [_chunk(b"IHDR", ihdr)]
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(st.sampled_from([b"tEXt", b"eXIf", b"iCCP", b"PLTE", b"zTXt", b"abcd"]))
        chunks.append(_chunk(kind, draw(st.binary(max_size=64))))
    chunks.append(_chunk(b"IDAT", zlib.compress(draw(st.binary(max_size=256)))))
    if draw(st.booleans()):
        chunks.append(_chunk(b"eXIf", draw(st.binary(max_size=64))))
    chunks.append(_chunk(b"IEND", b""))
    data = b"\x89PNG\r\n\x1a\n" + b"".join(chunks)
    cut = draw(st.integers(8, len(data)))
    return data[:cut]


def _smallest_valid(fmt: str) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (5, 4), (10, 200, 30)).save(buf, format=fmt)
    return buf.getvalue()


@st.composite
def mutated_images(draw) -> tuple[str, bytes]:
    """A valid small JPEG/PNG/TIFF/WebP/BMP with bytes flipped, cut or appended."""
    fmt, ext = draw(st.sampled_from([("JPEG", ".jpg"), ("PNG", ".png"), ("TIFF", ".tif"),
                                     ("WEBP", ".webp"), ("BMP", ".bmp")]))
    data = bytearray(_smallest_valid(fmt))
    for _ in range(draw(st.integers(0, 6))):
        i = draw(st.integers(0, len(data) - 1))
        data[i] = draw(st.integers(0, 255))
    data = data[: draw(st.integers(1, len(data)))] + draw(st.binary(max_size=32))
    return ext, bytes(data)


def _read_within_budget(reader, path: Path) -> None:
    tracemalloc.start()
    try:
        try:
            reader(path)
        except ValueError as exc:
            message = str(exc)
            assert message and "\n" not in message, message
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    assert peak < BUDGET_BYTES


@FUZZ
@given(data=png_files())
def test_png_headers(tmp_path_factory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("fuzz") / "f.png"
    path.write_bytes(data)
    _read_within_budget(read_image_size, path)
    _read_within_budget(lambda p: read_image(p, max_pixels=10_000), path)


@FUZZ
@given(sample=mutated_images())
# A PNG whose image-data chunk says it is 84 MB long: Pillow read that much (found here).
@example(sample=(".png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x05\x00\x00\x00"
                 b"\x04\x08\x02\x00\x00\x00\xc9Qb\x17\x05\x00\x00\x14IDATx\x9cc\xe4:!\xc7"
                 b"\x80\x04\x98\x18P\x01!>\x00"))
def test_mutated_images(tmp_path_factory, sample: tuple[str, bytes]) -> None:
    ext, data = sample
    path = tmp_path_factory.mktemp("fuzz") / f"f{ext}"
    path.write_bytes(data)
    _read_within_budget(read_image, path)


@st.composite
def npy_files(draw) -> bytes:
    shape = tuple(draw(st.lists(st.integers(0, 2**40), min_size=0, max_size=3)))
    descr = draw(st.sampled_from(["<f4", "<f8", "<i4", "|O", "<f2", "garbage"]))
    header = {"descr": descr, "fortran_order": draw(st.booleans()), "shape": shape}
    text = repr(header).encode("latin1")
    pad = 64 - (10 + len(text) + 1) % 64
    head = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text) + pad + 1) + text + b" " * pad
    return head + b"\n" + draw(st.binary(max_size=256))


@FUZZ
@given(data=npy_files() | st.binary(max_size=256))
def test_npy_depth(tmp_path_factory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("fuzz") / "d.npy"
    path.write_bytes(data)
    _read_within_budget(read_depth, path)


@FUZZ
@given(data=png_files())
def test_png_depth(tmp_path_factory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("fuzz") / "d.png"
    path.write_bytes(data)
    _read_within_budget(read_depth, path)


JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=3),
    max_leaves=8,
)
MANIFEST_KEYS = ["file", "sha256", "pad_multiple", "input_side", "inputs", "outputs", "name"]


@FUZZ
@given(fields=st.dictionaries(st.sampled_from(MANIFEST_KEYS), JSON, max_size=7))
def test_manifests(tmp_path_factory, fields: dict) -> None:
    folder = tmp_path_factory.mktemp("models")
    (folder / "shadow.json").write_text(json.dumps(fields))
    try:
        ModelRegistry(folder).load("shadow")
    except ModelError as exc:
        assert "\n" not in str(exc)


ARG_TOKENS = st.sampled_from([
    "shadow", "relight", "depth", "timelapse", "--sun", "--sun-dir", "--from", "--to", "--fov",
    "--steps", "--depth", "--mode", "--preset", "--thickness", "-o", "--force", "--sweep",
    "--frames", "--fps", "--date", "--lat", "--lon", "--heading", "--start", "--end",
    "--utc-offset", "0", "-0", "1e308", "nan", "inf", "-inf", "90,30", "273,95", "0,0,0",
    "1e308,1e308,0", "1000000000", "x.png", "out.avi", "", "a,b", "24:61", "2024-13-40",
])


@settings(max_examples=300, deadline=10_000)
@given(argv=st.lists(ARG_TOKENS | st.text(max_size=6), max_size=8))
def test_cli_argument_parsing(argv: list[str]) -> None:
    """Parsing never raises anything but a clean argparse exit (status 2, or 0 for help)."""
    parser = build_parser()
    parser.exit = _exit  # type: ignore[method-assign]
    parser.error = lambda message: _exit(2, message)  # type: ignore[method-assign]
    for action in parser._subparsers._group_actions[0].choices.values():  # noqa: SLF001
        action.exit = _exit
        action.error = lambda message: _exit(2, message)
    try:
        args = parser.parse_args(argv)
    except _ExitError as exc:
        assert exc.status in (0, 2)
        return
    assert callable(args.func)


class _ExitError(Exception):
    def __init__(self, status: int) -> None:
        self.status = status


def _exit(status: int = 0, message: str | None = None) -> None:
    assert message is None or "Traceback" not in message
    raise _ExitError(status)


def test_fuzz_fixture_sanity(tmp_path) -> None:
    """The generators make files the readers accept, too (not only garbage)."""
    path = tmp_path / "ok.png"
    path.write_bytes(_smallest_valid("PNG"))
    assert read_image(path).image_srgb.shape == (4, 5, 3)
    np.save(tmp_path / "d.npy", np.ones((3, 4), np.float32))
    assert read_depth(tmp_path / "d.npy").shape == (3, 4)


@pytest.fixture(autouse=True)
def _quiet_help(capsys):
    yield
    capsys.readouterr()
