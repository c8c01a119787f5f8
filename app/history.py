"""Undo and redo: a Qt-free snapshot of what the user edits, and a thin ``QUndoCommand``.

What is undoable: moving either sun (a drag counts once, on release; a key nudge or a typed value
once each), confirming the original sun and going back to re-align it (the step), the quality
preset, the depth map, the camera heading typed in step 1 and step 2's exposure. View settings
(overlay opacity, split, buffer view, zoom) are not; the time-lapse dialog's settings are not
either, but they count as unsaved work (``MainWindow.has_unsaved_changes``).

Each user action records ``EditState`` before and after; undo applies "before", redo "after".
The window applies a state through one narrow method, :meth:`EditTarget.apply_edit_state`, so
the command knows nothing of widgets.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from PySide6.QtGui import QUndoCommand

SunPair = tuple[float, float]


@dataclass(frozen=True)
class EditState:
    """The undoable part of a photo's session.

    Attributes:
        step: ``"align"`` (step 1) or ``"relight"`` (step 2).
        align_sun: where the original-sun dial stands (azimuth, elevation in degrees).
        original_sun: the confirmed original sun, or ``None`` before the first confirm. While
            re-aligning it is the previous confirmed sun.
        target_sun: where the new-sun dial stands.
        preset: quality preset name.
        depth_path: a depth map from elsewhere, or ``""`` for the app's own depth.
        heading: the camera's compass heading typed in step 1 (degrees from true north), or
            ``None`` (unknown, or the one the photo's EXIF records).
        exposure: ``"photo"`` (the photo's exposure kept) or ``"metered"`` (step 2).
    """

    step: str
    align_sun: SunPair
    original_sun: SunPair | None
    target_sun: SunPair
    preset: str
    depth_path: str = ""
    heading: float | None = None
    exposure: str = "photo"

    def __post_init__(self) -> None:
        if self.step not in ("align", "relight"):
            raise ValueError(f"expected step 'align' or 'relight', got {self.step!r}")
        if self.step == "relight" and self.original_sun is None:
            raise ValueError("expected an original sun in step 'relight', got None")


def describe_change(before: EditState, after: EditState) -> str:
    """What changed from ``before`` to ``after``, as an Edit-menu label ("Move new sun").

    Example:
        >>> a = EditState("align", (10.0, 30.0), None, (90.0, 30.0), "fast")
        >>> describe_change(a, EditState("align", (20.0, 30.0), None, (90.0, 30.0), "fast"))
        'Move original sun'
    """
    if before.depth_path != after.depth_path:
        return "Load depth map" if after.depth_path else "Use the app's depth"
    if before.step != after.step:
        return "Confirm original sun" if after.step == "relight" else "Re-align original sun"
    if before.preset != after.preset:
        return f"Quality: {after.preset.capitalize()}"
    if before.align_sun != after.align_sun or before.original_sun != after.original_sun:
        return "Move original sun"
    if before.heading != after.heading:
        return "Camera heading"
    if before.exposure != after.exposure:
        return "Meter the new light" if after.exposure == "metered" else "Keep the photo's exposure"
    if before.target_sun != after.target_sun:
        return "Move new sun"
    return "Change"


class EditTarget(Protocol):
    """What an :class:`EditCommand` needs from the window."""

    def apply_edit_state(self, state: EditState) -> None:
        """Make the session and the widgets show ``state`` (without recording a new edit)."""


class EditCommand(QUndoCommand):
    """One undoable edit between two snapshots.

    The edit has already happened when the command is pushed, so the first ``redo()`` (which
    ``QUndoStack.push`` calls) does nothing.

    Args:
        target: applies snapshots.
        before: the state before the edit.
        after: the state after it.
        text: the Edit-menu label; default: :func:`describe_change`.
    """

    def __init__(
        self, target: EditTarget, before: EditState, after: EditState, text: str = ""
    ) -> None:
        super().__init__(text or describe_change(before, after))
        self.target = target
        self.before = before
        self.after = after
        self._done = True

    def redo(self) -> None:
        if self._done:  # pushed after the fact
            self._done = False
            return
        self.target.apply_edit_state(self.after)

    def undo(self) -> None:
        self.target.apply_edit_state(self.before)
