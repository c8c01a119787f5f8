"""What to ask before the work on screen goes away: quitting, or opening another photo, or a
file about to be replaced (Qt-free).

Two things can be lost: an export that is still running (the worker is killed on quit, and a new
photo would wait behind it), and edits not saved in the project file. :func:`leave_questions`
lists the questions in the order to ask them; the window shows each one and acts on the answer.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

#: Answers that go ahead (the export is stopped / the project saved / the edits dropped).
STOP, SAVE, DISCARD = "stop", "save", "discard"
#: Answers that keep everything as it is and abandon the quit or open.
KEEP, CANCEL = "keep", "cancel"
#: The answer that replaces a project file this window did not open or save, or an export's
#: file whose name the app completed.
REPLACE = "replace"
#: The one answer to a notice.
OK = "ok"
#: A project's photo is missing: find it (a file dialog follows).
LOCATE = "locate"
#: A project's photo is not the one it was saved with: use the project's work with it anyway.
CONTINUE = "continue"


@dataclass(frozen=True)
class Choice:
    """One button: the answer it gives, its label, and its role (``accept``, ``reject``,
    ``destructive``)."""

    key: str
    label: str
    role: str


@dataclass(frozen=True)
class Question:
    """A question with buttons; ``default`` is the button Enter presses, ``escape`` Esc's."""

    title: str
    text: str
    detail: str
    choices: tuple[Choice, ...]
    default: str
    escape: str

    def goes_ahead(self, answer: str) -> bool:
        """Whether ``answer`` lets the quit or open go on."""
        return answer not in (KEEP, CANCEL)


@dataclass(frozen=True)
class RunningExport:
    """An export in the worker: its file name and how far it got (0-1, or ``None``)."""

    name: str
    fraction: float | None = None


def leave_questions(
    action: str, exports: list[RunningExport], unsaved: bool, project_name: str,
    changes: Sequence[str] = (),
) -> list[Question]:
    """The questions to ask before ``action``.

    Args:
        action: ``"quit"`` or ``"open"`` (another photo or project).
        exports: exports running or waiting in the worker.
        unsaved: whether there are edits not saved in the project file.
        project_name: the project file's name, for the save question.
        changes: what is not saved, in words ("the new sun", ...), for the save question; ``()``
            when not known (it then says "the changes you made"; a user trial's question
            named every kind of setting, the depth map and heading it never touched too).

    Returns:
        Zero, one or two questions: the running export first, then unsaved changes.

    Example:
        >>> [q.title for q in leave_questions("quit", [RunningExport("a.mp4", 0.4)], True, "a")]
        ['An export is still running', 'Save the changes to this photo?']
        >>> leave_questions("open", [], True, "a", ["the new sun", "the quality"])[0].text
        'Your changes to the new sun and the quality are not saved.'
        >>> leave_questions("quit", [RunningExport("a.mp4", 0.4)], True, "a", ["the new sun"]
        ...                 )[1].text  # (the export's name once replaced the changes)
        'Your changes to the new sun are not saved.'
    """
    if action not in ("quit", "open"):
        raise ValueError(f"expected action 'quit' or 'open', got {action!r}")
    verb = "Quit" if action == "quit" else "Open"
    questions = []
    if exports:
        names = ", ".join(
            e.name + (f" ({100 * e.fraction:.0f} % done)" if e.fraction is not None else "")
            for e in exports)
        then = "quit" if action == "quit" else "open the other photo"
        questions.append(
            Question(
                title="An export is still running",
                text=f"OutCast is still exporting {names}.",
                detail=(
                    f"If you stop it now, nothing is written and the file is not created. "
                    f"Or keep exporting; you can {then} once it has finished."
                ),
                choices=(
                    Choice(KEEP, "Keep exporting", "reject"),
                    Choice(STOP, f"Stop export and {verb.lower()}", "destructive"),
                ),
                default=KEEP,
                escape=KEEP,
            )
        )
    if unsaved:
        questions.append(
            Question(
                title="Save the changes to this photo?",
                text=(f"Your changes to {_joined(changes)} are not saved." if changes
                      else "The changes you made to this photo are not saved."),
                detail=f"Save them in {project_name} to continue later, or drop them.",
                choices=(
                    Choice(SAVE, "Save project", "accept"),
                    Choice(DISCARD, "Don't save", "destructive"),
                    Choice(CANCEL, "Cancel", "reject"),
                ),
                default=SAVE,
                escape=CANCEL,
            )
        )
    return questions


def _joined(words: Sequence[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def finished_before_stop_notice(paths: list[str]) -> Question:
    """Told when the user chose to stop an export that finished while the question was open:
    the file exists, although the question said stopping writes nothing (a user trial).

    Example:
        >>> finished_before_stop_notice(["/tmp/clip.mp4"]).text
        'clip.mp4 finished before it could be stopped, and was saved.'
    """
    names = ", ".join(os.path.basename(p) for p in paths)
    were = "were" if len(paths) > 1 else "was"
    return Question(
        title="The export had finished",
        text=f"{names} finished before it could be stopped, and {were} saved.",
        detail="\n".join(paths),
        choices=(Choice(OK, "OK", "accept"),),
        default=OK,
        escape=OK,
    )


def replace_file_question(path: str) -> Question:
    """Asked when an export's name, typed without its extension, was completed by the app and
    the completed name exists: the save dialog asked only about the name as typed (a user
    trial's "tl" replaced tl.mp4 without a word).

    Example:
        >>> q = replace_file_question("/photos/tl.mp4")
        >>> q.text, [c.key for c in q.choices], q.default
        ('tl.mp4 already exists. Replace it?', ['replace', 'cancel'], 'cancel')
    """
    return _replace_question("Replace the file?",
                             f"{os.path.basename(path)} already exists. Replace it?",
                             f"{path}\nChoose Cancel to keep it, then export under another name.")


def _replace_question(title: str, text: str, detail: str) -> Question:
    """"Replace it" or Cancel (the default: nothing is replaced on Enter or Esc)."""
    return Question(
        title=title,
        text=text,
        detail=detail,
        choices=(
            Choice(REPLACE, "Replace it", "destructive"),
            Choice(CANCEL, "Cancel", "reject"),
        ),
        default=CANCEL,
        escape=CANCEL,
    )


def replace_project_question(project_name: str, saved: str,
                             other_photo: str | None = None) -> Question:
    """Asked before saving over a project file this window neither opened nor saved (the
    photo was opened on its own while a project of it exists): saving would replace the
    suns kept there, which ``outcast batch`` reads too. With ``other_photo``, the file is the
    project of another photo, whose work saving would replace (asked even after the file
    dialog's own question, which does not say so; found by a user trial).

    Args:
        project_name: the project file's name.
        saved: when it was last saved, in words.
        other_photo: the name of the photo the file is the project of, when not this one.

    Example:
        >>> q = replace_project_question("a.outcast.json", "2026-12-01 08:00")
        >>> [c.key for c in q.choices], q.default
        (['replace', 'cancel'], 'cancel')
    """
    if other_photo:
        title = "Replace another photo's project?"
        text = f"{project_name} is the project of another photo, {other_photo} (saved {saved})."
        detail = (f"Saving here replaces the suns and settings kept for {other_photo} with this "
                  "photo's. Choose another name to keep both.")
    else:
        title = "Replace the saved project?"
        text = f"{project_name} already holds a project of this photo (saved {saved})."
        detail = ("You opened the photo on its own, so saving replaces the suns and settings "
                  "kept there. Open the project file instead to continue that work.")
    return _replace_question(title, text, detail)


def locate_photo_question(project_name: str, photo_path: str) -> Question:
    """Asked when a project's photo is not where the project says (moved, renamed or
    deleted): "Locate photo…" picks it where it is now and opens the project with it, its suns
    and shadow corrections kept (a user trial's only way on was opening the photo on its own,
    a fresh session).

    Example:
        >>> q = locate_photo_question("pool.outcast.json", "/photos/pool.jpg")
        >>> [c.label for c in q.choices], q.default
        (['Locate photo…', 'Cancel'], 'locate')
    """
    name, folder = os.path.basename(photo_path), os.path.dirname(photo_path)
    return Question(
        title="The project's photo is missing",
        text=(f"{project_name} holds the work on {name}, which is no longer in "
              f"{folder or 'its folder'}."),
        detail=("If it was moved or renamed, locate it to continue the project's work with it "
                "(suns, shadow corrections and settings); saving the project then records "
                "where it is now."),
        choices=(
            Choice(LOCATE, "Locate photo\u2026", "accept"),
            Choice(CANCEL, "Cancel", "reject"),
        ),
        default=LOCATE,
        escape=CANCEL,
    )


def other_photo_question(project_name: str, photo_name: str, why: str) -> Question:
    """Asked when the photo a project opens does not match the one it was saved with
    (:meth:`~app.state.PhotoIdentity.mismatch`: another pixel size or content, say a file
    replaced under the same name): its suns and shadow corrections would be laid over another
    picture (a user trial's ski-slope corrections over the pool).

    Example:
        >>> q = other_photo_question("a.outcast.json", "a.jpg", "it is 10 × 10 pixels")
        >>> [c.key for c in q.choices], q.default
        (['continue', 'cancel'], 'cancel')
    """
    return Question(
        title="Another photo than the project's?",
        text=(f"{photo_name} does not look like the photo {project_name} was saved with: "
              f"{why}."),
        detail=("The project's suns and shadow corrections were made on that photo and may not "
                "fit this one. Continue to use them with this photo anyway (saving the project "
                "then records it), or cancel to leave your current work as it is."),
        choices=(
            Choice(CONTINUE, "Continue with this photo", "destructive"),
            Choice(CANCEL, "Cancel", "reject"),
        ),
        default=CANCEL,
        escape=CANCEL,
    )
