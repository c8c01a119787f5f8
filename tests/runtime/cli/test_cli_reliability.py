"""Issue 20: bad arguments and outputs fail fast with one line; nothing is left behind."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.cli import main as cli
from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io.imageio import ImageReadError, read_depth, write_depth, write_image
from outcast_core.runtime.pipeline.session import RelightSession
from tests.sigterm import terminate_when_ready


@pytest.fixture
def no_work(monkeypatch) -> None:
    """Fail the test if a command gets as far as building a session (the slow part)."""

    def boom(*args, **kwargs):
        raise AssertionError("the command started its work before checking its arguments")

    monkeypatch.setattr(cli, "_make_session", boom)
    monkeypatch.setattr("outcast_core.runtime.pipeline.session.RelightSession.__init__", boom)


def _one_line_error(capsys, fragment: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    last = err.splitlines()[-1]
    assert fragment in last, err
    return last


# ------------------------------------------------------------------------------------------
# 3: --steps


@pytest.mark.parametrize("steps", ["1000000000", "2049", "0", "-3", "ten"])
def test_steps_out_of_range_is_refused_before_the_work(photo, tmp_path, capsys, no_work,
                                                       steps) -> None:
    with pytest.raises(SystemExit) as info:
        main(["shadow", str(photo), "--sun", "90,30", "--mode", "direct", "--steps", steps,
              "-o", str(tmp_path / "s.png")])
    assert info.value.code == 2
    _one_line_error(capsys, "--steps")


def test_steps_in_learned_mode_is_said_not_to_apply(photo, tmp_path, capsys) -> None:
    if RelightSession(shadow_mode="auto").shadow_mode != "learned":
        pytest.skip("the learned shadow model is not installed")
    assert main(["shadow", str(photo), "--sun", "90,30", "--mode", "learned", "--steps", "64",
                 "--preset", "fast", "-o", str(tmp_path / "s.png")]) == 0
    assert "--steps applies to Direct shadows only" in capsys.readouterr().err


def test_steps_at_the_limit_runs(photo, tmp_path) -> None:
    assert main(["shadow", str(photo), "--sun", "90,30", "--mode", "direct", "--steps",
                 str(cli.MAX_DIRECT_STEPS), "-o", str(tmp_path / "s.png"), "-q"]) == 0


# ------------------------------------------------------------------------------------------
# 5: depth with no valid pixel


@pytest.mark.parametrize("fill", [0.0, -1.0, math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("ext", [".npy", ".exr"])
def test_depth_without_a_valid_pixel_is_refused(tmp_path, fill, ext) -> None:
    path = tmp_path / f"d{ext}"
    write_depth(path, np.full((6, 8), fill, np.float32))
    with pytest.raises(ImageReadError, match="no valid pixel") as info:
        read_depth(path)
    assert info.value.reason == "no-valid-depth"


def test_depth_png_with_a_scale_float32_cannot_hold_is_refused(tmp_path) -> None:
    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add_text("outcast:depth_scale", "1e308")
    path = tmp_path / "d.png"
    Image.fromarray(np.full((6, 8), 1000, np.uint16)).save(path, pnginfo=info)
    with pytest.raises(ValueError, match="depth_scale"):
        read_depth(path)


def test_session_refuses_depth_without_a_valid_pixel() -> None:
    image = np.full((12, 16, 3), 0.5, np.float32)
    session = RelightSession(shadow_mode="direct", relight_mode="physics")
    for fill in (0.0, -2.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="valid pixel"):
            session.set_image(image, depth=np.full((12, 16), fill, np.float32))


def test_cli_refuses_an_all_zero_depth_map(photo, tmp_path, capsys) -> None:
    depth = tmp_path / "zeros.npy"
    np.save(depth, np.zeros((60, 80), np.float32))
    out = tmp_path / "r.png"
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40", "--depth",
                 str(depth), "-o", str(out)]) == 2
    _one_line_error(capsys, "no valid pixel")
    assert not out.exists()


def test_text_file_as_npy_is_not_numpys_pickle_advice(tmp_path) -> None:
    path = tmp_path / "d.npy"
    path.write_text("1 2 3\n4 5 6\n")
    with pytest.raises(ImageReadError) as info:
        read_depth(path)
    assert "pickle" not in str(info.value) and "not a NumPy .npy file" in str(info.value)


def test_npy_bomb_is_refused_from_its_header(tmp_path) -> None:
    path = tmp_path / "d.npy"
    header = {"descr": "<f4", "fortran_order": False, "shape": (100000, 100000)}
    with open(path, "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\0" * 64)
    with pytest.raises(ImageReadError, match="MP limit"):
        read_depth(path)
    header["shape"] = (60, 80)
    with open(path, "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\0" * 64)
    with pytest.raises(ImageReadError, match="truncated") as info:
        read_depth(path)
    whole = path.stat().st_size - 64 + 60 * 80 * 4
    assert info.value.message.endswith(f"it ends after {path.stat().st_size:,} of {whole:,} "
                                       "bytes")
    assert info.value.reason == "damaged"


# ------------------------------------------------------------------------------------------
# 6: --fov 0


@pytest.mark.parametrize("fov", ["0", "-0", "-10", "180", "500", "nan", "inf", "wide"])
def test_bad_fov_is_refused(photo, tmp_path, capsys, no_work, fov) -> None:
    with pytest.raises(SystemExit) as info:
        main(["shadow", str(photo), "--sun", "90,30", f"--fov={fov}",
              "-o", str(tmp_path / "s.png")])
    assert info.value.code == 2
    _one_line_error(capsys, "field of view")


def test_session_fov_zero_is_not_the_default() -> None:
    session = RelightSession(shadow_mode="direct", relight_mode="physics")
    with pytest.raises(ValueError, match="field of view"):
        session.set_image(np.full((12, 16, 3), 0.5, np.float32), fov_deg=0.0)


# ------------------------------------------------------------------------------------------
# 9 and 11: outputs checked before the work


@pytest.mark.parametrize(
    ("command", "name", "fragment"),
    [
        (["relight", "--from", "90,30", "--to", "200,40"], "out.avi", "extension"),
        (["relight", "--from", "90,30", "--to", "200,40"], "out", "extension"),
        (["shadow", "--sun", "90,30"], "s.jpg", "extension"),
        (["depth"], "d.jpg", "extension"),
        (["relight", "--from", "90,30", "--to", "200,40"], "exists.png", "already exists"),
        (["depth"], "exists.npy", "already exists"),
        (["shadow", "--sun", "90,30"], "afile/s.png", "is a file, not a folder"),
        (["shadow", "--sun", "90,30"], "afile/deeper/s.png", "is a file, not a folder"),
        (["relight", "--from", "90,30", "--to", "200,40"], "folder.png", "it is a folder"),
        # (a user trial's "-o out/" was told of a missing extension)
        (["relight", "--from", "90,30", "--to", "200,40"], "folder.png/", "it is a folder; "
         "give a file name in it"),
        (["deshadow", "--from", "90,30"], "afolder", "it is a folder; give a file name in it"),
        (["shadow", "--sun", "90,30"], "nosuch/", "it names a folder; give a file name in it"),
    ],
)
def test_bad_outputs_are_refused_before_the_work(photo, tmp_path, capsys, no_work, monkeypatch,
                                                 command, name, fragment) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "exists.png").write_bytes(b"old")
    (tmp_path / "exists.npy").write_bytes(b"old")
    (tmp_path / "afile").write_text("a file")
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "afolder").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main([command[0], str(photo), *command[1:], "-o", name]) == 2
    _one_line_error(capsys, fragment)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "exists.png").read_bytes() == b"old"


def test_output_equal_to_input_is_refused_even_with_force(photo, tmp_path, capsys,
                                                          no_work) -> None:
    before = photo.read_bytes()
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40", "-o", str(photo),
                 "--force"]) == 2
    _one_line_error(capsys, "input file")
    assert photo.read_bytes() == before


def test_a_device_is_never_replaced(photo, tmp_path, capsys, no_work) -> None:
    link = tmp_path / "null.png"
    link.symlink_to("/dev/null")
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40", "-o", str(link),
                 "--force"]) == 2
    _one_line_error(capsys, "not a regular file")
    assert main(["timelapse", str(photo), "--from", "90,30", "--sweep", "1,2:3,4", "--frames",
                 "2", "-o", "/dev/null", "--force"]) == 2
    _one_line_error(capsys, "not a regular file")
    assert Path("/dev/null").is_char_device() and link.is_symlink()


def test_png_frames_never_empty_a_folder_of_other_files(photo, tmp_path, capsys,
                                                        no_work) -> None:
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "note.txt").write_text("keep")
    assert main(["timelapse", str(photo), "--from", "90,30", "--sweep", "1,2:3,4", "--frames",
                 "2", "-o", str(folder), "--force"]) == 2
    _one_line_error(capsys, "note.txt")
    assert [p.name for p in folder.iterdir()] == ["note.txt"]


MISSING_FOLDER_COMMANDS = {
    "relight": ["relight", "{photo}", "--from", "90,30", "--to", "200,40", "-o",
                "{missing}/r.jpg"],
    "shadow": ["shadow", "{photo}", "--sun", "90,30", "-o", "{missing}/s.png"],
    "deshadow": ["deshadow", "{photo}", "--from", "90,30", "-o", "{missing}/d.jpg"],
    "deshadow-mask": ["deshadow", "{photo}", "--from", "90,30", "-o", "{tmp}/d.jpg", "--mask",
                      "{missing}/m.png"],
    "depth": ["depth", "{photo}", "-o", "{missing}/d.npy"],
    "timelapse-video": ["timelapse", "{photo}", "--from", "90,30", "--sweep", "1,20:3,20",
                        "--frames", "2", "-o", "{missing}/t.mp4"],
    # a PNG folder is made, but not in a missing folder
    "timelapse-frames": ["timelapse", "{photo}", "--from", "90,30", "--sweep", "1,20:3,20",
                         "--frames", "2", "-o", "{missing}/frames"],
    "batch-out": ["batch", "{photos}", "-o", "{missing}/out", "--to", "1,2"],
    "batch-report": ["batch", "{photos}", "-o", "{tmp}/out", "--to", "1,2", "--report",
                     "{missing}/r.json"],
    "eval-json": ["eval", "real", "{data}", "--json", "{missing}/r.json"],
    "eval-sheet": ["eval", "real", "{data}", "--sheet", "{missing}/s.png"],
    "eval-report": ["eval", "real", "{data}", "--report", "{missing}/EVAL.md"],
}


@pytest.mark.parametrize("argv", MISSING_FOLDER_COMMANDS.values(),
                         ids=MISSING_FOLDER_COMMANDS.keys())
def test_a_missing_output_folder_is_refused_not_made(argv, photo, tmp_path, capsys,
                                                     no_work) -> None:
    """``-o typo/sub/x.mp4`` made the whole tree (a user trial), where the app refuses a
    missing folder: every file a command writes is refused before the work, naming the
    folder, and nothing is made."""
    photos, data = tmp_path / "in", tmp_path / "data"
    photos.mkdir()
    data.mkdir()
    (photos / "p.png").write_bytes(photo.read_bytes())
    (data / "a_image.png").write_bytes(photo.read_bytes())
    write_image(data / "a_mask.png", np.zeros((60, 80, 3), np.float32))
    missing = tmp_path / "typo" / "sub"
    subs = {"photo": str(photo), "photos": str(photos), "data": str(data), "tmp": str(tmp_path),
            "missing": str(missing)}
    assert main([a.format(**subs) for a in argv]) == 2
    _one_line_error(capsys, f"folder '{missing}' does not exist")
    assert not (tmp_path / "typo").exists() and not (tmp_path / "out").exists()


def test_a_command_whose_output_is_a_folder_makes_it(photo, tmp_path) -> None:
    """A time-lapse's PNG folder is made when missing (in a folder that exists)."""
    frames = tmp_path / "frames"
    assert main(["timelapse", str(photo), "--from", "90,30", "--sweep", "1,20:3,20", "--frames",
                 "2", "--size", "working", "-o", str(frames), "--preset", "fast", "-q"]) == 0
    assert sorted(p.name for p in frames.iterdir()) == ["frame_0001.png", "frame_0002.png"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused_before_the_work(photo, tmp_path, capsys, no_work) -> None:
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40",
                     "-o", str(folder / "r.jpg")]) == 2
        line = _one_line_error(capsys, "not writable")
        assert ".tmp" not in line
    finally:
        folder.chmod(0o755)


def test_unwritable_folder_is_refused_before_the_work(photo, tmp_path, capsys, no_work,
                                                      monkeypatch) -> None:
    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / "tmpabc"))

    monkeypatch.setattr(cli.tempfile, "TemporaryFile", denied)  # as root, chmod is no test
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40",
                 "-o", str(tmp_path / "r.jpg")]) == 2
    line = _one_line_error(capsys, "not writable")
    assert "tmp" not in line.split("not writable")[1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


def test_write_errors_name_the_destination_not_the_temp_file(tmp_path, capsys,
                                                             monkeypatch) -> None:
    import errno

    from outcast_core.runtime.io import imageio

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(imageio.Image.Image, "save", full_disk)
    out = tmp_path / "r.png"
    with pytest.raises(OSError) as info:
        write_image(out, np.zeros((4, 4, 3), np.float32))
    assert info.value.filename == str(out) and info.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []

    def denied(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / ".r.abc.tmp.png"))

    monkeypatch.setattr(imageio.tempfile, "mkstemp", denied)
    with pytest.raises(PermissionError) as info:
        write_image(out, np.zeros((4, 4, 3), np.float32))
    assert info.value.filename == str(out)


def test_cli_names_the_output_when_the_disk_is_full(photo, tmp_path, capsys,
                                                    monkeypatch) -> None:
    import errno

    from outcast_core.runtime.io import imageio

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(imageio.Image.Image, "save", full_disk)
    out = tmp_path / "r.jpg"
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40", "--mode",
                 "physics", "--shadows", "direct", "-o", str(out)]) == 2
    line = _one_line_error(capsys, "No space left on device")
    assert "()" not in line and "r.jpg" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


# ------------------------------------------------------------------------------------------
# 4: SIGTERM cleans up like SIGINT

_SLOW_WRITER = """
import sys, time
from outcast_core.runtime.io import imageio
from outcast_core.runtime.cli.main import main
save = imageio.Image.Image.save
def slow_save(self, fp, *args, **kwargs):
    save(self, fp, *args, **kwargs)
    print("writing", flush=True)
    time.sleep(60)
imageio.Image.Image.save = slow_save
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_removes_the_temporary_file(photo, tmp_path) -> None:
    out = tmp_path / "r.jpg"

    def temp_file_exists() -> None:
        assert any(p.name.startswith(".r.") for p in tmp_path.iterdir())

    ended = terminate_when_ready(
        ["-c", _SLOW_WRITER, "relight", str(photo), "--from", "90,30", "--to", "200,40",
         "--mode", "physics", "--shadows", "direct", "-o", str(out)],
        "writing", before=temp_file_exists)
    assert ended.seconds < 10
    assert ended.returncode == 143, ended.stderr
    assert "terminated" in ended.stderr and "Traceback" not in ended.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


# ------------------------------------------------------------------------------------------
# 11: smaller ones


def test_huge_sun_dir_is_not_a_zero_vector(photo, tmp_path) -> None:
    from outcast_core.runtime.geometry.camera import normalize_sun

    np.testing.assert_allclose(normalize_sun([1e308, 1e308, 0]), [2**-0.5, 2**-0.5, 0])
    assert main(["shadow", str(photo), "--sun-dir", "1e308,-1e308,1e308", "--mode", "direct",
                 "-o", str(tmp_path / "s.png"), "-q"]) == 0


def test_relight_keeps_the_photos_exif(tmp_path) -> None:
    from PIL import Image

    exif = Image.Exif()
    exif[0x0132] = "2024:06:21 12:00:00"  # DateTime
    gps = {1: "N", 2: (48.0, 51.0, 24.0), 3: "E", 4: (2.0, 21.0, 3.0)}
    exif[0x8825] = gps
    path = tmp_path / "p.jpg"
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((30, 40, 3)) * 255).astype(np.uint8)).save(path, exif=exif)
    out = tmp_path / "r.jpg"
    assert main(["relight", str(path), "--from", "90,30", "--to", "200,40", "--mode", "physics",
                 "--shadows", "direct", "-o", str(out), "-q"]) == 0
    with Image.open(out) as im:
        got = im.getexif()
        assert got[0x0132] == "2024:06:21 12:00:00"
        assert got.get_ifd(0x8825)[1] == "N"


def test_sixteen_bit_png_stays_sixteen_bit_and_transparency_is_said(tmp_path, capsys) -> None:
    import cv2

    rng = np.random.default_rng(5)
    deep = (rng.random((60, 80, 3)) * 65535).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "deep.png"), deep)
    for cmd in (["relight", "--to", "200,40"], ["deshadow"]):
        out = tmp_path / f"{cmd[0]}.png"
        assert main([cmd[0], str(tmp_path / "deep.png"), "--from", "90,30", *cmd[1:], "-o",
                     str(out), "--preset", "fast", "-q"]) == 0
        assert cv2.imread(str(out), cv2.IMREAD_UNCHANGED).dtype == np.uint16, cmd[0]
    rgba = np.dstack([deep[..., :3] // 257, np.full((60, 80), 255)]).astype(np.uint8)
    rgba[:20, :20, 3] = 0
    cv2.imwrite(str(tmp_path / "alpha.png"), rgba)
    capsys.readouterr()
    assert main(["relight", str(tmp_path / "alpha.png"), "--from", "90,30", "--to", "200,40",
                 "-o", str(tmp_path / "a.png"), "--preset", "fast", "-q"]) == 0
    assert "has transparency; it is filled with white" in capsys.readouterr().err
    rgba[..., 3] = 255  # an opaque RGBA export: nothing to say
    cv2.imwrite(str(tmp_path / "opaque.png"), rgba)
    assert main(["relight", str(tmp_path / "opaque.png"), "--from", "90,30", "--to", "200,40",
                 "-o", str(tmp_path / "o.png"), "--preset", "fast", "-q"]) == 0
    assert "transparency" not in capsys.readouterr().err


@pytest.mark.parametrize(("size", "warned"), [((8, 8), True), ((23, 400), True),
                                             ((24, 24), False), ((80, 60), False)])
def test_a_photo_too_small_to_relight_is_warned_of(tmp_path, capsys, size, warned) -> None:
    """An 8 x 8 photo was relit and reported as written with no word (a user trial): said
    even with -q, and the output still written."""
    rng = np.random.default_rng(6)
    small = tmp_path / "small.png"
    write_image(small, rng.random((size[1], size[0], 3)).astype(np.float32))
    out = tmp_path / "o.png"
    assert main(["relight", str(small), "--from", "90,30", "--to", "200,40", "-o", str(out),
                 "--preset", "fast", "-q"]) == 0
    assert out.is_file()
    err = capsys.readouterr().err
    w, h = size
    assert (f"outcast: warning: the photo is only {w} x {h} pixels: too small to relight "
            "meaningfully" in err) is warned, err
    # `outcast sun` says it in the sun's terms, not the relighting's (a user trial).
    assert main(["sun", str(small), "--preset", "fast"]) in (0, 3)
    err = capsys.readouterr().err
    assert "relight" not in err
    # (find_sun reads shadows from 64 pixels on the shorter side up: 24 x 24 is small for it)
    assert "too small or too narrow for its shadows to tell the sun" in err or not warned, err


def test_a_truncated_photo_is_said_in_plain_words(tmp_path, capsys) -> None:
    """A cut-short JPEG's error ended in Python's words ("(OSError: image file is truncated
    (5 bytes not processed))"; a user trial): the command line says it in plain words, as the
    app does; a batch keeps the decoder's words in its report only."""
    import json

    sample = Path(__file__).resolve().parents[3] / "samples" / "exif_003_th_pool.jpg"
    photos = tmp_path / "in"
    photos.mkdir()
    cut = photos / "cut.jpg"
    cut.write_bytes(sample.read_bytes()[:20000])
    assert main(["relight", str(cut), "--from", "90,30", "--to", "200,40", "-o",
                 str(tmp_path / "r.jpg")]) == 2
    err = capsys.readouterr().err
    assert err == (f"outcast relight: error: cannot read image '{cut}': the file is truncated "
                   "or corrupt\n")
    report = tmp_path / "r.json"
    assert main(["batch", str(photos), "-o", str(tmp_path / "out"), "--from", "90,30", "--to",
                 "200,40", "-q", "--report", str(report)]) == 2
    err = capsys.readouterr().err
    assert "cut.jpg: failed: cannot read image" in err
    assert "Error" not in err and "not processed" not in err
    result = json.loads(report.read_text())["results"][0]
    assert result["message"].endswith("the file is truncated or corrupt")
    assert result["details"]["decoder"].startswith("OSError: image file is truncated")


def test_png_frames_go_into_a_folder_holding_only_a_file_managers_files(photo, tmp_path) -> None:
    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / ".DS_Store").write_text("")
    assert main(["timelapse", str(photo), "--from", "90,30", "--sweep", "1,20:3,20", "--frames",
                 "2", "--size", "working", "-o", str(folder), "--preset", "fast"]) == 0
    assert sorted(p.name for p in folder.iterdir()) == [".DS_Store", "frame_0001.png",
                                                        "frame_0002.png"]


def test_a_folder_that_takes_no_file_is_not_called_unwritable(tmp_path, monkeypatch) -> None:
    """``-o /proc/x.jpg`` said "folder '/proc' is not writable (No such file or directory)"
    (a user trial): a permission is "not writable"; any other refusal says no file can be made
    there, with the system's reason."""
    import errno
    import tempfile

    from outcast_core.runtime.cli.main import CliError, check_folder_writable

    def refuse(exc: OSError):
        def temporary_file(*args, **kwargs):
            raise exc
        return temporary_file

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse(FileNotFoundError(
        errno.ENOENT, "No such file or directory")))
    with pytest.raises(CliError, match=r"no file can be made in folder '.*' \(No such file"):
        check_folder_writable(tmp_path, "cannot write 'x.jpg'")
    monkeypatch.setattr(tempfile, "TemporaryFile", refuse(PermissionError(
        errno.EACCES, "Permission denied")))
    with pytest.raises(CliError, match=r"is not writable \(Permission denied\)"):
        check_folder_writable(tmp_path, "cannot write 'x.jpg'")
