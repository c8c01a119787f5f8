"""Turn exceptions into what a photographer needs: what happened and what to do (Qt-free)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from outcast_core.runtime.io.imageio import (
    DEPTH_EXTENSIONS,
    MAX_DECODE_PIXELS,
    ImageReadError,
    ImageReadReason,
)
from outcast_core.runtime.io.models import ModelError

DEPTH_KINDS = "a .npy array (float32, H × W), a 16-bit grayscale PNG or an OpenEXR (.exr) file"


class DepthMapError(ValueError):
    """The depth map a project names could not be read or does not fit its photo (told as a
    depth-map problem, not as a photo that cannot be opened)."""


class OwnFileError(ValueError):
    """An export named the open photo, its depth map or a project file of it, which an export
    never replaces (:meth:`~app.main_window.MainWindow.refuse_own_file`)."""


@dataclass(frozen=True)
class UserMessage:
    """A dialog's content."""

    title: str
    what: str
    todo: str
    #: Nothing failed: the app refused, to protect a file (shown as a warning, not an error).
    refusal: bool = False

    def text(self) -> str:
        return f"{self.what}\n\n{self.todo}"


def _one_line(exc: BaseException) -> str:
    """The exception in one line for a dialog: an operating-system error as its plain reason
    and the file (not ``[Errno 13] ...``), and an output's temporary file (``.NAME.part...``,
    :func:`~outcast_core.runtime.io.imageio.atomic_output`) as the folder it was written in.
    A file that could not be read (:class:`ImageReadError`) is its message for a person (its
    ``str``), without the decoder's own words.

    Example:
        >>> _one_line(PermissionError(13, "Permission denied", "/photos/.t.x1.part.gif"))
        "Permission denied: cannot write in the folder '/photos'"
    """
    if isinstance(exc, OSError) and exc.strerror:
        if not exc.filename:
            return exc.strerror
        path = Path(os.fsdecode(exc.filename))
        temp = next((i for i, part in enumerate(path.parts)
                     if part.startswith(".") and ".part" in part), None)
        if temp is not None:  # a temporary file, or a file in a temporary folder
            return f"{exc.strerror}: cannot write in the folder '{Path(*path.parts[:temp])}'"
        return f"{exc.strerror}: '{path}'"
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


_CHOOSE_A_PHOTO = "Choose a JPEG, PNG, TIFF, WebP, HEIC or BMP photo."  # (as the reader)

_OPEN_ADVICE: dict[ImageReadReason | None, str] = {
    ImageReadReason.DAMAGED: "The file looks damaged or cut short (an interrupted copy or "
                             "download?): open another copy of it.",
    ImageReadReason.UNSUPPORTED_LAYOUT: "If the file opens elsewhere, export it again as a "
                                        "16-bit PNG or TIFF, or open another copy of it.",
    ImageReadReason.CAMERA_RAW: "Export the photo from your RAW editor as a JPEG, PNG or "
                                "16-bit TIFF, then open that.",
    ImageReadReason.TOO_LARGE: f"Open a copy of it reduced to at most "
                               f"{MAX_DECODE_PIXELS / 1e6:.0f} megapixels.",
    ImageReadReason.OUT_OF_MEMORY: "Close other programs, or open a copy of the photo with "
                                   "fewer pixels.",
    ImageReadReason.MISSING: "It may have been moved, renamed or deleted: open it from where "
                             "it is now.",
    ImageReadReason.NO_ACCESS: "Check that the disk is connected and that you may read the "
                               "file, then try again.",
}
"""What to do when a photo could not be opened, by :attr:`ImageReadError.reason` (anything
else: choose a photo)."""


def message_for(exc: BaseException, action: str) -> UserMessage:
    """Dialog content for an exception raised while doing ``action``.

    Args:
        exc: the exception.
        action: one of ``"open"``, ``"depth"``, ``"depth-model"``, ``"export"``, ``"project"``
            (opening one), ``"save-project"``, or anything else.

    Returns:
        A :class:`UserMessage`.
    """
    detail = _one_line(exc)
    if action == "depth-model":
        return UserMessage(
            "Could not use the depth model",
            detail,
            "A depth model is an ONNX file with one image input (N x 3 x H x W) and one output, "
            "such as Depth Anything or MiDaS (README: Depth from phones and other estimators). "
            "The photo's depth is unchanged.",
        )
    if isinstance(exc, ModelError):
        return UserMessage(
            "A model file is missing or damaged",
            detail,
            "OutCast carries on with its built-in Direct shadows and physics relighting. "
            "To get the learned models back, reinstall OutCast or restore the models folder.",
        )
    if isinstance(exc, MemoryError):
        return UserMessage(
            "Not enough memory",
            "The computer ran out of memory for this photo.",
            "Choose the Fast quality preset or a smaller photo, then try again.",
        )
    if action == "open":
        reason = exc.reason if isinstance(exc, ImageReadError) else None
        todo = _OPEN_ADVICE.get(reason, _CHOOSE_A_PHOTO) + " Your current work is unchanged."
        return UserMessage("Could not open the photo", detail, todo)
    if action == "depth" and isinstance(exc, DepthMapError):
        return UserMessage(
            "Could not open the project's depth map",
            detail,
            "Put the depth map back where the project expects it, or open the photo on its own "
            f"(File \u25b8 Open) and load another depth map: {DEPTH_KINDS}, the size of the "
            "photo or with its aspect ratio. Your current work is unchanged.",
        )
    if action == "depth":
        return UserMessage(
            "Could not load the depth map",
            detail,
            f"A depth map is {DEPTH_KINDS}, the size of the photo or with its aspect ratio. "
            "The photo, its depth and your suns are unchanged.",
        )
    if action == "export":
        # A refusal that protects a file is no failure (a user trial read "Export failed" for
        # an existing name that was kept as it should be).
        refused = isinstance(exc, (IsADirectoryError, FileExistsError, OwnFileError))
        title = "Not exported" if refused else "Export failed"
        if isinstance(exc, IsADirectoryError):  # a frames folder that holds other files
            todo = ("Nothing in that folder was changed. Choose a new or empty folder for the "
                    "frames.")
        elif isinstance(exc, FileExistsError):
            todo = "Nothing was overwritten. Choose another name, or confirm replacing the file."
        elif isinstance(exc, PermissionError):
            todo = "Nothing was written. Choose a folder you can write to."
        elif isinstance(exc, ValueError) and "output extension" in detail:
            todo = "Nothing was written. Choose a name with one of the extensions above."
        elif isinstance(exc, OwnFileError):
            todo = ("Nothing was written: an export never replaces the photo, its depth map or "
                    "its project.")
        else:
            todo = (
                "Nothing was written. Check that the folder exists, that you can write to it and "
                "that the disk has free space, then try again."
            )
        return UserMessage(title, detail, todo, refusal=refused)
    if action == "project":  # opening one
        return UserMessage(
            "Could not open the project",
            detail,
            "Project files are the .outcast.json files OutCast writes next to the photo. "
            "Your current work is unchanged.",
        )
    if action == "save-project":
        return UserMessage(
            "Could not save the project",
            detail,
            "Nothing on disk was changed; your edits are still here, unsaved. Check that the "
            "folder exists, that you can write to it and that the disk has free space, then "
            "save again (or choose File \u25b8 Save project as).",
        )
    return UserMessage(
        "Something went wrong",
        detail,
        "Your photo and settings are unchanged; try again, or choose the Fast preset.",
    )


def depth_file_problem(path: str | os.PathLike[str]) -> str | None:
    """What is wrong with ``path`` as a depth map, from its name and size alone (no reading).

    Cheap enough for the GUI thread, so a wrong pick is reported at once rather than after the
    worker's queue; the content is checked when the worker reads it.

    Returns:
        One line for the user, or ``None`` when the file may be a depth map.

    Example:
        >>> depth_file_problem("photo.jpg")
        "'photo.jpg' is a .jpg file, not a depth map"
    """
    p = Path(path)
    ext = p.suffix.lower()
    if p.is_dir():  # (a folder named like a photo was "a .jpg file": a user trial)
        return f"'{p.name}' is a folder, not a depth map"
    if ext not in DEPTH_EXTENSIONS:
        kind = f"a {ext} file" if ext else "a file without an extension"
        return f"'{p.name}' is {kind}, not a depth map"
    if not p.is_file():
        return f"'{p.name}' does not exist (in {p.parent})"
    if p.stat().st_size == 0:
        return f"'{p.name}' is empty"
    return None
