"""Dialog texts for exceptions (``app.errors``, Qt-free)."""

from __future__ import annotations

from app.errors import UserMessage, message_for


def test_os_errors_read_as_plain_words_and_never_name_a_temporary_file() -> None:
    temp = PermissionError(13, "Permission denied", "/photos/.day.qza7hje1.part.gif")
    msg = message_for(temp, "export")
    assert msg.title == "Export failed"
    assert msg.what == "Permission denied: cannot write in the folder '/photos'"
    assert "Errno" not in msg.text() and ".part" not in msg.text()
    assert "folder you can write to" in msg.todo
    frames = OSError(28, "No space left on device", "/photos/.day.part-x1/frame_0007.png")
    assert message_for(frames, "export").what == ("No space left on device: cannot write in "
                                                  "the folder '/photos'")
    plain = message_for(FileNotFoundError(2, "No such file or directory", "/x/p.jpg"), "open")
    assert plain.what == "No such file or directory: '/x/p.jpg'"
    assert message_for(ValueError("expected a photo\nmore"), "open").what == "expected a photo"


def test_a_frames_folder_with_other_files_never_offers_to_replace() -> None:
    """A PNG-sequence folder holding the user's files is refused even when confirmed: the
    message says so instead of offering to replace."""
    folder = message_for(IsADirectoryError("'/p/day' holds files other than frames"), "export")
    assert "new or empty folder" in folder.todo and "confirm" not in folder.todo
    exists = message_for(FileExistsError("'/p/a.mp4' already exists"), "export")
    assert "confirm replacing" in exists.todo


def test_a_damaged_photo_and_a_wrong_export_name_get_advice_that_fits(tmp_path) -> None:
    """A truncated JPEG was told to "choose a JPEG, PNG ..."; an export named .xyz got a Python
    list and advice about free disk space (found by a user trial)."""
    import numpy as np
    from PIL import Image

    from outcast_core.runtime.io.imageio import read_image, write_image

    cut = tmp_path / "cut.jpg"
    Image.new("RGB", (64, 48), (90, 120, 30)).save(cut, "JPEG")
    cut.write_bytes(cut.read_bytes()[:300])
    try:
        read_image(cut)
    except ValueError as exc:
        damaged = message_for(exc, "open")
    assert "damaged or cut short" in damaged.todo and "Choose a JPEG" not in damaged.todo
    assert damaged.what.endswith("the file is truncated or corrupt")  # not the decoder's words
    assert "OSError" not in damaged.what and "cut.jpg" in damaged.what
    assert "Choose a JPEG" in message_for(ValueError("not an image file"), "open").todo
    try:
        write_image(tmp_path / "out.xyz", np.zeros((4, 4, 3), np.float32))
    except ValueError as exc:
        wrong = message_for(exc, "export")
    assert "[" not in wrong.what and ".jpg, .png, .tif, .tiff or .webp" in wrong.what
    assert "extensions above" in wrong.todo and "disk" not in wrong.todo


def test_an_export_over_the_open_photo_is_not_a_disk_problem() -> None:
    from app.errors import OwnFileError

    msg = message_for(OwnFileError("'pool.jpg' is the photo you opened; choose another name"),
                      "export")
    assert "never replaces the photo" in msg.todo and "disk" not in msg.todo


def _open_message(path) -> UserMessage:
    from outcast_core.runtime.io.imageio import ImageReadError, read_image

    try:
        read_image(path)
    except ImageReadError as exc:
        return message_for(exc, "open")
    raise AssertionError(f"{path} was read")


def test_open_advice_follows_the_reason_not_the_words(tmp_path) -> None:
    """The advice is chosen by the error's reason: a message that merely contains "truncated
    or corrupt" (another error's words) is not taken for a damaged photo, and a damaged
    photo's message need not contain them."""
    from outcast_core.runtime.io.imageio import ImageReadError, ImageReadReason

    words = ValueError("cannot read 'a.jpg': the file is truncated or corrupt (x)")
    assert "damaged" not in message_for(words, "open").todo
    assert message_for(words, "open").what == str(words)
    odd = ImageReadError("cannot read image 'a.tif': it cannot be decoded",
                         ImageReadReason.UNSUPPORTED_LAYOUT, "cv2.imdecode returned None")
    msg = message_for(odd, "open")
    assert "16-bit PNG or TIFF" in msg.todo and msg.what == odd.message
    damaged = ImageReadError("cannot read image 'a.jpg': it stops half-way",
                             ImageReadReason.DAMAGED, "OSError: (7 bytes not processed)")
    msg = message_for(damaged, "open")
    assert "damaged or cut short" in msg.todo and "not processed" not in msg.text()
    assert msg.what == "cannot read image 'a.jpg': it stops half-way"


def test_a_too_short_jpeg_keeps_its_byte_counts(tmp_path) -> None:
    """Cutting the message at " (" lost what tells the user the file is cut short: its size
    against the size its header declares."""
    import io
    import struct

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (64, 64), (10, 200, 30)).save(buf, "JPEG")
    data = bytearray(buf.getvalue())
    struct.pack_into(">HH", data, data.index(b"\xff\xc0") + 5, 9000, 9000)
    (tmp_path / "big.jpg").write_bytes(bytes(data))
    msg = _open_message(tmp_path / "big.jpg")
    assert msg.what.endswith(f"its {len(data):,} bytes cannot hold the 9000 x 9000 JPEG its "
                             "header declares")
    assert "damaged or cut short" in msg.todo


def test_each_kind_of_unopenable_file_gets_its_own_advice(tmp_path) -> None:
    from PIL import Image

    (tmp_path / "shot.nef").write_bytes(b"MM\x00* raw")
    assert "RAW editor" in _open_message(tmp_path / "shot.nef").todo
    missing = _open_message(tmp_path / "gone.jpg")
    assert "moved, renamed or deleted" in missing.todo and "gone.jpg" in missing.what
    (tmp_path / "notes.jpg").write_text("text")
    assert _open_message(tmp_path / "notes.jpg").todo.startswith("Choose a JPEG")
    Image.new("RGB", (4, 4)).save(tmp_path / "a.gif")
    assert _open_message(tmp_path / "a.gif").todo.startswith("Choose a JPEG")
    (tmp_path / "empty.png").write_bytes(b"")
    assert "damaged or cut short" in _open_message(tmp_path / "empty.png").todo


def test_a_folder_picked_as_a_depth_map_is_called_a_folder(tmp_path) -> None:
    """A folder named like a photo was "a .jpg file, not a depth map" (a user trial)."""
    from app.errors import depth_file_problem

    (tmp_path / "adir.jpg").mkdir()
    (tmp_path / "d.npy").mkdir()
    assert depth_file_problem(tmp_path / "adir.jpg") == "'adir.jpg' is a folder, not a depth map"
    assert depth_file_problem(tmp_path / "d.npy") == "'d.npy' is a folder, not a depth map"
    assert depth_file_problem(tmp_path / "p.jpg") == "'p.jpg' is a .jpg file, not a depth map"
