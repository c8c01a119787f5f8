"""Undo and redo: a Qt-free snapshot of what the user edits, and a thin ``QUndoCommand``.

What is undoable: moving either sun (a drag counts once, on release; a key nudge or a typed
value once each), confirming the original sun and going back to re-align it (the step), the
quality preset, the depth map, the camera heading typed in step 1, step 2's exposure, light
("Keep the photo's light") and relighting (learned or physics) and the user's corrections of the
photo's found shadows (step 2's "Not a shadow" / "Mark shadow": a click, or a brush stroke, one
step however many dabs it lays). View settings (overlay opacity, split, buffer view, zoom) are
not; the time-lapse dialog's settings are not either, but they count as unsaved work
(``MainWindow.has_unsaved_changes``).

Each user action records ``EditState`` before and after; undo applies "before", redo "after".
The window applies a state through one narrow method, :meth:`EditTarget.apply_edit_state`, so
the command knows nothing of widgets.

Steps of one field in a burst (the camera heading box's arrow keys, its arrow buttons, the mouse
wheel) make one undo step, as editors merge them (``QUndoCommand.mergeWith``): a step merges
into the last command when that is a step of the same field, nothing else changed in between,
and it came within :data:`STEP_BURST_S` of the previous step. A typed value (Enter) is always
its own step. Qt never merges across the saved (clean) state.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from time import monotonic
from typing import TYPE_CHECKING, Protocol

from PySide6.QtGui import QUndoCommand

from app.state import RELIGHTINGS
from app.sun_dial_math import same_sun

if TYPE_CHECKING:
    from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit

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
        daylight: whether relit photos take the new sun's daylight (step 2's "Keep the
            photo's light" clear; ``RelightSession.daylight``).
        relighting: ``"learned"`` or ``"physics"`` (step 2's "Relighting";
            ``RelightSession.relight_mode``).
        shadow_edits: the user's corrections of the photo's found shadows, in order
            (:class:`~outcast_core.runtime.pipeline.photo_shadows.ShadowEdit`); ``()``: none.
    """

    step: str
    align_sun: SunPair
    original_sun: SunPair | None
    target_sun: SunPair
    preset: str
    depth_path: str = ""
    heading: float | None = None
    exposure: str = "photo"
    daylight: bool = True
    relighting: str = "learned"
    shadow_edits: tuple[ShadowEdit, ...] = ()

    def __post_init__(self) -> None:
        if self.step not in ("align", "relight"):
            raise ValueError(f"expected step 'align' or 'relight', got {self.step!r}")
        if self.relighting not in RELIGHTINGS:
            raise ValueError(f"expected relighting {' or '.join(RELIGHTINGS)}, got "
                             f"{self.relighting!r}")
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
    if before.daylight != after.daylight:
        return "Take the new sun's daylight" if after.daylight else "Keep the photo's light"
    if before.relighting != after.relighting:
        return f"Relighting: {after.relighting.capitalize()}"
    if before.shadow_edits != after.shadow_edits:
        return shadow_edit_text(after.shadow_edits)
    if before.target_sun != after.target_sun:
        return "Move new sun"
    return "Change"


def same_edit_state(a: EditState, b: EditState, tol: float = 1e-6) -> bool:
    """Whether ``a`` and ``b`` are the same edit: equal, their suns within ``tol`` degrees
    (a found sun came back 1e-14 off the EXIF sun the dial stood at, through a vector round
    trip, and was recorded as a move that marked the photo unsaved: a user trial).

    Example:
        >>> a = EditState("align", (10.0, 30.0), None, (90.0, 30.0), "fast")
        >>> same_edit_state(a, replace(a, align_sun=(10.0, 30.0 + 1e-12)))
        True
        >>> same_edit_state(a, replace(a, align_sun=(10.1, 30.0)))
        False
    """
    def near(x: SunPair | None, y: SunPair | None) -> bool:
        return x == y or (x is not None and y is not None and same_sun(x, y, tol))

    suns = ("align_sun", "original_sun", "target_sun")
    return (all(near(getattr(a, n), getattr(b, n)) for n in suns)
            and replace(a, **{n: getattr(b, n) for n in suns}) == b)


#: How the save question names the parts of :class:`EditState` (``step``, ``align_sun`` and
#: ``original_sun`` are all the original sun's: one part).
_PART_WORDS = (
    ("step", "the original sun"), ("align_sun", "the original sun"),
    ("original_sun", "the original sun"), ("target_sun", "the new sun"),
    ("preset", "the quality"), ("depth_path", "the depth map"),
    ("heading", "the camera heading"), ("exposure", "the exposure"), ("daylight", "the light"),
    ("relighting", "the relighting"),
    ("shadow_edits", "the corrections of the found shadows"),
)


def changed_parts(before: EditState, after: EditState) -> list[str]:
    """The parts of the session that differ between ``before`` and ``after``, in words, once
    each, the suns first (the save question says what it would drop).

    Example:
        >>> a = EditState("relight", (10.0, 30.0), (10.0, 30.0), (90.0, 30.0), "fast")
        >>> changed_parts(a, replace(a, target_sun=(95.0, 30.0), preset="accurate"))
        ['the new sun', 'the quality']
    """
    words: list[str] = []
    for name, word in _PART_WORDS:
        if getattr(before, name) != getattr(after, name) and word not in words:
            words.append(word)
    return words


def shadow_edit_text(edits: tuple[ShadowEdit, ...]) -> str:
    """The Edit-menu label of a change of the shadow corrections to ``edits`` (a click or a
    brush stroke added to the end, or all cleared): "Mark shadow", "Not a shadow" (a click),
    "Paint shadow", "Paint not a shadow" (a stroke) or "Clear shadow corrections".

    Example:
        >>> from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit
        >>> shadow_edit_text((ShadowEdit(0.5, 0.5, False), ShadowEdit(0.5, 0.5, False, 0.02)))
        'Paint not a shadow'
    """
    if not edits:
        return "Clear shadow corrections"
    last = edits[-1]
    if last.radius > 0:
        return "Paint shadow" if last.shadow else "Paint not a shadow"
    return "Mark shadow" if last.shadow else "Not a shadow"


def edit_done_note(edits: tuple[ShadowEdit, ...]) -> str:
    """What the status bar says once a correction's result is shown (``edits``: the
    corrections it left; short, to be whole at 1024 px).

    Example:
        >>> from outcast_core.runtime.pipeline.photo_shadows import ShadowEdit
        >>> edit_done_note((ShadowEdit(0.5, 0.5, False),))
        'applied "Not a shadow" · Ctrl+Z takes it back'
        >>> edit_done_note(())
        'cleared the shadow corrections · Ctrl+Z brings them back'
    """
    if not edits:
        return "cleared the shadow corrections · Ctrl+Z brings them back"
    return f'applied "{shadow_edit_text(edits)}" · Ctrl+Z takes it back'


STEP_BURST_S = 1.0
"""Steps of one field at most this far apart (seconds) make one undo step (a held arrow key
repeats about 30 times a second; clicks on a spin box's arrows come a few tenths apart)."""

_MERGE_IDS = {f.name: i for i, f in enumerate(fields(EditState), start=1)}
"""``QUndoCommand.id`` of the steps of each field (``-1``, Qt's "never merge", for others)."""


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
        step_of: the :class:`EditState` field this edit steps (an arrow key in its box), or
            ``""`` (a typed value, a drag...: never merged). Consecutive steps of one field
            merge into one command (:meth:`mergeWith`).

    Raises:
        ValueError: ``step_of`` is not a field of :class:`EditState`.
    """

    def __init__(
        self, target: EditTarget, before: EditState, after: EditState, text: str = "",
        *, step_of: str = "",
    ) -> None:
        super().__init__(text or describe_change(before, after))
        if step_of and step_of not in _MERGE_IDS:
            raise ValueError(f"expected step_of to be a field of EditState, got {step_of!r}")
        self.target = target
        self.before = before
        self.after = after
        self.step_of = step_of
        self.last_step_at = monotonic()
        self._done = True

    def id(self) -> int:
        """Qt's merge key: the stepped field's, or -1 (never merged)."""
        return _MERGE_IDS.get(self.step_of, -1)

    def mergeWith(self, other: QUndoCommand) -> bool:  # noqa: N802 - Qt's name
        """Take in ``other``, the command pushed right after this one, when it is a step of
        the same field that follows on from this one's ``after`` (nothing else changed in
        between) within :data:`STEP_BURST_S` of this one's last step.

        A burst that ends where it began leaves nothing to undo: the command is obsolete and
        Qt drops it.

        Returns:
            Whether ``other`` was merged (Qt then discards it).
        """
        if not (isinstance(other, EditCommand) and self.step_of
                and other.step_of == self.step_of):
            return False
        if other.last_step_at - self.last_step_at > STEP_BURST_S or other.before != self.after:
            return False
        field = self.step_of
        if replace(other.after, **{field: getattr(self.after, field)}) != self.after:
            return False  # the step changed another field too
        self.after = other.after
        self.last_step_at = other.last_step_at
        self.setObsolete(self.after == self.before)
        return True

    def redo(self) -> None:
        if self._done:  # pushed after the fact
            self._done = False
            return
        self.target.apply_edit_state(self.after)

    def undo(self) -> None:
        self.target.apply_edit_state(self.before)
