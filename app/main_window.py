"""The main window: open a photo, align its sun (step 1), relight it (step 2), export.

Every call into the session runs in the worker thread (:class:`app.workers.TaskRunner`); job
functions capture plain values and never touch widgets. Results come back as signals to slots of
this window, in the GUI thread. Channels (one pending job each, latest wins):

``load``, ``preset``, ``shadow`` (step-1 overlay), ``find_sun`` (step 1's automatic sun),
``confirm``, ``relight`` (step-2 view),
``export_still``, ``export_shadows_removed``, ``tl_preview``, ``tl_export``, ``tl_estimate``
(a short time-lapse export, timed for the dialog's estimate).

The step-2 views "Shadows removed" and "Shadows found" do not depend on the new sun: their
images are computed once per photo, original sun, preset and shadow corrections (on the
``relight`` channel, so the latest view choice wins) and kept, so dragging the new sun there
costs nothing.

The user's corrections of the found shadows (:attr:`MainWindow.shadow_edits`, step 2's "Not a
shadow" / "Mark shadow" tools: a click on a region, or a brush stroke, its dabs sent to the worker
once, on release) are app state like the suns: undoable (a stroke as one step), saved in the
project.
Every job whose result depends on the found shadows captures the tuple and hands it to
``session.set_shadow_edits`` before its work (cheap when unchanged), so a job never runs with
older or newer corrections than the ones it was asked for, whichever jobs the latest-wins
channels dropped.
"""

from __future__ import annotations

import functools
import html
import math
import os
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import (
    QEvent,
    QEventLoop,
    QObject,
    QPoint,
    QSettings,
    QSize,
    Qt,
    QTimer,
    Slot,
)
from PySide6.QtGui import (
    QAction,
    QCloseEvent,
    QColor,
    QDragEnterEvent,
    QDropEvent,
    QFont,
    QIcon,
    QImage,
    QKeyEvent,
    QKeySequence,
    QPainter,
    QUndoStack,
)
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QApplication,
    QComboBox,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMenu,
    QMessageBox,
    QProgressBar,
    QScrollArea,
    QSizePolicy,
    QSplitter,
    QStackedWidget,
    QStyle,
    QToolButton,
    QToolTip,
    QVBoxLayout,
    QWidget,
)

from app import display
from app import sun_dial_math as dm
from app.canvas import ImageCanvas, qimage_from_array
from app.errors import DepthMapError, OwnFileError, depth_file_problem, message_for
from app.history import (
    EditCommand,
    EditState,
    changed_parts,
    edit_done_note,
    same_edit_state,
    shadow_edit_text,
)
from app.leave_prompts import (
    CONTINUE,
    LOCATE,
    REPLACE,
    SAVE,
    STOP,
    Question,
    RunningExport,
    finished_before_stop_notice,
    leave_questions,
    locate_photo_question,
    other_photo_question,
    replace_file_question,
    replace_project_question,
)
from app.panels import (
    BRUSH_DEFAULT,
    BRUSH_RANGE,
    SHADOW_TOOLS,
    VIEW_CHOICES,
    AlignPanel,
    PanelStack,
    RelightPanel,
)
from app.state import (
    IMAGE_SUFFIXES,
    PRESET_NAMES,
    PhotoIdentity,
    ProjectState,
    RecentFiles,
    StageTimings,
    Step,
    Sun,
    TimelapseSettings,
    is_project_file,
    load_project,
    project_path_for,
    save_project,
    with_filter_extension,
)
from app.workers import JobContext, TaskRunner
from outcast_core.runtime.geometry.camera import cosine_term, sun_angles, sun_vector
from outcast_core.runtime.io.imageio import check_photo_file, same_file
from outcast_core.runtime.io.models import ModelError
from outcast_core.runtime.pipeline.auto_sun import SOURCE_EXIF, SOURCE_SUN_IN_FRAME
from outcast_core.runtime.pipeline.batch import small_photo_note
from outcast_core.runtime.pipeline.photo_shadows import (
    STROKE_FEATHER,
    ShadowEdit,
    shadow_edit_limit,
    shadow_edit_strokes,
)
from outcast_core.runtime.pipeline.relight import EXPOSURE_HINT_FACTOR
from outcast_core.runtime.pipeline.session import elongation_note

APP_NAME = "OutCast"
STAGE_WORDS = {
    "load": "Opening photo",
    "preset": "Changing quality",
    "shadow": "Predicting shadows",
    "find_sun": "Finding the sun",
    "confirm": "Refining the original shadows",
    "relight": "Relighting",
    "export_still": "Exporting still",
    "export_shadows_removed": "Exporting shadows removed",
    "tl_preview": "Rendering time-lapse frame",
    "tl_export": "Exporting time-lapse",
    "tl_estimate": "Timing a short time-lapse export",
}
#: Exports of one image at full resolution (same progress, cancel and safe writing).
IMAGE_EXPORT_CHANNELS = ("export_still", "export_shadows_removed")
EXPORT_CHANNELS = (*IMAGE_EXPORT_CHANNELS, "tl_export")
#: Step-2 views of the photo's own shadows (independent of the new sun), and those with a split.
DESHADOW_VIEWS = ("shadows_removed", "shadows_found")
SPLIT_VIEWS = ("output", "shadows_removed")
#: How far left of a correction (fraction of the photo's width) the before | after line moves
#: when the correction was made on the original's side of it.
SPLIT_MARGIN = 0.03
#: ... and no closer to the photo's left edge than this (the original stays in view).
SPLIT_LEAST = 0.05
DEFAULT_SUN = (135.0, 45.0)  # behind-right of the camera, half-way up: where a new photo starts
LEVEL_TILT = (0.0, 0.0, "level")  # the camera's (pitch, roll, source) before a photo is loaded
ICON_PATH = Path(__file__).resolve().parent / "resources" / "outcast.svg"
STILL_FILTERS = "PNG image (*.png);;JPEG image (*.jpg *.jpeg);;16-bit TIFF (*.tif *.tiff)"
#: The deshadow views' images kept for other corrections (undo and redo show them at once): at
#: most this many bytes of images besides the shown ones (a 24-megapixel photo's take 72 MB).
DESHADOW_KEEP_BYTES = 256 * 1024 * 1024
#: A "Mark shadow" click that marks more than this share of the photo is said in the status
#: bar, with how to take it back: a click on a shadow's soft edge can fill a whole
#: surface of that brightness (a user trial: a blue court darker than the green round it, 12 %
#: of the photo, 0.5 % of it in the human-marked shadow). Of the 55 clicks of a simulated user
#: on the 47 dev photos (fast; the darkest point of the two largest shadows the app missed), 40
#: marked something, 8 of them more than 5 % of the frame, 5 of those mostly shadow: the note
#: says what happened, it refuses nothing.
LARGE_MARK_SHARE = 0.05
#: The status-bar hint while a shadow-correction tool is on.
SHADOW_TOOL_HINTS = {key: f"{hint} ([ ] brush size, Esc ends the tool)"
                     for key, _, _, hint in SHADOW_TOOLS}
#: A brush stroke's colour while it is painted, per tool: the found shadows' magenta for "Mark
#: shadow", a pale cyan (what stays of the photo) for "Not a shadow".
BRUSH_COLOURS = {"shadow": QColor(255, 60, 200), "not_shadow": QColor(150, 235, 255)}
#: The share of the brush's radius, inward from its circle, over which a tool fades in (the
#: canvas draws a dashed circle where it works at full strength): "Mark shadow" is a soft
#: brush (:data:`~outcast_core.runtime.pipeline.photo_shadows.STROKE_FEATHER`, full strength
#: halfway through the fade), "Not a shadow" a hard one (a faint tint was left under it).
BRUSH_SOFTNESS = {"shadow": 0.5 * STROKE_FEATHER, "not_shadow": 0.0}


#: The least opacity of step 2's "Shadows found" tint, whatever step 1's overlay slider says.
FOUND_LEAST_OPACITY = 0.4
#: Degrees off the EXIF elevation's ring at which Find sun's "turn the sun around the ring"
#: notice goes (a hand on the dial does not stay on the ring exactly).
RING_NOTICE_TOL = 2.0


def _timings(session: Any) -> dict[str, float]:
    return dict(getattr(session, "timings", {}) or {})


#: What an opening and a quality switch do after the session's preparation (its depth,
#: normals...): the camera's tilt, and for a quality switch with a confirmed sun first its
#: shadows at the new size.
TILT_STAGE = "camera tilt"
#: Jobs whose result a dialog shows (the time-lapse preview's frames): the status bar keeps
#: saying the user's own jobs.
DIALOG_CHANNELS = ("tl_preview",)
REDO_STAGE = "original shadows"


def session_progress(ctx: JobContext, then: str, share: float) -> Callable[[str, float], None]:
    """The session's progress reports as the first ``share`` of a job's; its last, "ready" at
    100 %, says what the job does next, ``then`` (the status bar said "Changing quality: ready
    100 %" while the original shadows were redone, a user trial)."""

    def report(stage: str, fraction: float) -> None:
        ctx.progress(stage if fraction < 1.0 else then, share * min(fraction, 1.0))

    return report


class WindowShortcutsWin(QObject):
    """Event filter for text fields: the window's shortcuts win over the field's own key bindings.

    A focused spin box's line edit claims Ctrl+E (end of line), Ctrl+Z (its own undo) and more;
    without this filter Export still, Undo, ... do nothing while the azimuth box has focus.

    Args:
        sequences: returns the key sequences that must reach the window's actions.
        parent: owner of the filter.
    """

    def __init__(self, sequences: Callable[[], Iterable[QKeySequence]], parent: QObject):
        super().__init__(parent)
        self._sequences = sequences

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.ShortcutOverride and isinstance(event, QKeyEvent):
            pressed = QKeySequence(event.keyCombination())
            exact = QKeySequence.SequenceMatch.ExactMatch
            for seq in self._sequences():
                if not seq.isEmpty() and pressed.matches(seq) == exact:
                    box = watched if isinstance(watched, QAbstractSpinBox) else watched.parent()
                    if isinstance(box, QAbstractSpinBox):
                        box.interpretText()  # a typed number counts before the action runs
                    event.ignore()  # not claimed by the field: the shortcut map fires the action
                    return True
        return False


class StatusText(QLabel):
    """The status bar's message, whole in its tooltip too: a long one (a found sun with its
    EXIF prior, a shadow tool's hint) does not fit at 1366 x 768. It is shown cut with an
    ellipsis at the width the status bar gives it; drawn whole, it ran under the timings
    beside it (a screenshot at 1400 px). :meth:`text` is the whole message.

    Its size hint is the whole message's width and it can shrink to nothing: in the status bar
    it takes the room it needs before the timings (:class:`TimingsText`, which take only what
    is left), and is cut only where the bar has no more (a user trial at 1024 x 700 saw the
    timings keep their room and the message, a shadow tool's hint, cut to nothing)."""

    def __init__(self, text: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._full = ""
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Preferred)
        self.setText(text)

    def setText(self, text: str) -> None:  # noqa: N802 (Qt's name)
        self._full = text
        self.setToolTip(text)
        self._elide()
        self.updateGeometry()  # the whole message's width is its size hint

    def text(self) -> str:
        return self._full

    def sizeHint(self) -> QSize:  # noqa: N802 (Qt's name)
        m = self.contentsMargins()
        width = self.fontMetrics().horizontalAdvance(self._full) + m.left() + m.right()
        return QSize(width + 2 * self.margin() + 1, super().sizeHint().height())

    def minimumSizeHint(self) -> QSize:  # noqa: N802 (Qt's name)
        return QSize(0, super().minimumSizeHint().height())

    def resizeEvent(self, event: Any) -> None:  # noqa: N802 (Qt's name)
        super().resizeEvent(event)
        self._elide()

    def shown(self) -> str:
        """The message as drawn: cut to the label's width."""
        return super().text()

    def _elide(self) -> None:
        super().setText(self._cut(self._full, max(0, self.contentsRect().width())))

    def _cut(self, text: str, width: int) -> str:
        return self.fontMetrics().elidedText(text, Qt.TextElideMode.ElideRight, width)


class TimingsText(StatusText):
    """The status bar's stage timings ("shadow 0.21 s · relight 1 ms · ..."), for developers:
    they take only the room the message (:class:`StatusText`) leaves, and are shown as many
    whole entries as fit, then "…" (none where there is no room); all of them in the window's
    tooltip for them. :meth:`text` is the whole line."""

    SEPARATOR = " · "

    def __init__(self, text: str, parent: QWidget | None = None) -> None:
        super().__init__(text, parent)
        # Its size hint is ignored: it gets what the bar has left, never more.
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)

    def _cut(self, text: str, width: int) -> str:
        fm = self.fontMetrics()
        if fm.horizontalAdvance(text) <= width:
            return text
        entries = text.split(self.SEPARATOR)
        while entries:
            entries.pop()
            shown = self.SEPARATOR.join([*entries, "…"])
            if fm.horizontalAdvance(shown) <= width:
                return shown
        return ""


def _typed_numbers_first(method: Callable[..., Any]) -> Callable[..., Any]:
    """A user action that first takes in a number still being typed in a spin box (no Enter
    yet; a toolbar button takes no focus, so the box has not committed it): as Enter would
    (:meth:`MainWindow._commit_typed_fields`; user trials exported and saved old values)."""

    @functools.wraps(method)
    def wrapper(self: MainWindow, *args: Any, **kwargs: Any) -> Any:
        self._commit_typed_fields()
        return method(self, *args, **kwargs)

    return wrapper


class MainWindow(QMainWindow):
    """OutCast's main window.

    Args:
        settings: where recent files live (default: the user's OutCast settings).
        preset: initial quality preset.
        session_mode: passed to ``RelightSession(mode=...)``.
    """

    def __init__(
        self,
        settings: QSettings | None = None,
        preset: str = "balanced",
        session_mode: str = "auto",
    ):
        super().__init__()
        self.settings = settings if settings is not None else QSettings(APP_NAME, APP_NAME)
        self.session: Any = None
        self.loaded: Any = None  # LoadedImage of the current photo
        self.image_path = ""
        #: The open photo's pixel size and fingerprint, recorded in its project (None: no photo).
        self.photo_identity: PhotoIdentity | None = None
        #: Where the open project said its photo was, when it was located elsewhere ("" : not
        #: moved): saving over that project is saving this photo's project.
        self._photo_moved_from = ""
        self.session_mode = session_mode
        #: Step 2's "Relighting" as the user chose it (``"learned"`` or ``"physics"``): what
        #: the undo history and the project keep; the panel shows (and jobs take) physics
        #: instead while the learned relighting cannot run (:meth:`_show_relighting`).
        self.relighting_choice = "learned"
        self.depth_mode = "auto"
        self.depth_path = ""
        #: An ONNX depth model the user chose (remembered in the settings); "" = the shipped Z.
        self.depth_model = str(self.settings.value("depth_model", "") or "")
        #: Whether a phone photo's own depth map is used (remembered in the settings).
        self.use_phone_depth = str(self.settings.value("phone_depth", "true")).lower() != "false"
        self.preset = preset if preset in PRESET_NAMES else "balanced"
        self.step = Step.EMPTY
        self.original_sun: Sun | None = None
        self.timelapse_settings = TimelapseSettings()
        #: The time-lapse settings as the dialog first showed them since the photo was opened
        #: or the project saved (None: not shown since); changes from them are unsaved work.
        self._timelapse_baseline: TimelapseSettings | None = None
        #: The camera heading the time-lapse dialog filled in (solved from the aligned sun, or
        #: the EXIF's), not typed: solved again when the dialog reopens, so a re-aligned sun or
        #: a new step-1 heading reaches the real sun path (a user trial).
        self.timelapse_auto_heading: float | None = None
        #: The time-lapse's UTC offset as the dialog guessed it from the longitude (the EXIF
        #: gave none), or None: not kept by a project, so guessed again when it reopens.
        self.timelapse_auto_offset: float | None = None
        #: The sweep the time-lapse dialog filled in from the two suns (:meth:`sweep_suns`),
        #: as its widgets show it, or None: not kept by a project, so filled in again from the
        #: suns of the day when the dialog reopens.
        self.timelapse_auto_sweep: tuple[Sun, Sun] | None = None
        #: A compass heading typed in step 1 (None: unknown, or the EXIF's when it records one,
        #: which a typed heading replaces).
        self.user_heading: float | None = None
        #: The project files this window opened or saved for the photo on screen: saving over
        #: another one asks first (:meth:`save_project`).
        self._project_files: set[str] = set()
        self._opening_project_file = ""
        #: The project file Save writes: the one opened or last saved for the photo on screen
        #: ("" : the photo's own, ``photo.outcast.json``; a user trial's Ctrl+S after opening
        #: "my project.outcast.json" asked to replace the photo's own instead).
        self._project_file = ""
        #: The heading the sun in the frame implies (None: no sun in the frame, or no GPS and
        #: time); said under the EXIF button while the heading box holds it.
        self.seen_heading: float | None = None
        #: The loaded photo's camera ``(pitch, roll, source)`` (auto_sun.camera_tilt).
        self.camera_tilt: tuple[float, float, str] = LEVEL_TILT
        #: The last automatic sun (``auto_sun.SunFit``) of this photo, or None.
        self.sun_fit: Any = None
        # Shown instead of "Ready · ..." once the pending overlay is drawn (a found sun's, or
        # the photo just opened: what was found in it must not flash by).
        self._held_message = ""
        self._load_notice = ""  # the warning above the photo after loading (file, depth)
        #: Sun searches started: a result whose number is not the last is not applied (the
        #: sun was confirmed meanwhile: a user trial's confirm was followed by the search's
        #: sun moving the dial and recording a step-1 move after it).
        self._searches = 0
        #: The dial's sun the search notice speaks of (it goes when the dial leaves it: undo,
        #: redo, a drag; azimuth None: any azimuth at that elevation), or None when the notice
        #: is advice that holds anywhere.
        self._notice_sun: tuple[float | None, float] | None = None
        #: What the command line says of the photo's file (photo_file_notes), kept for the
        #: status bar's "Photo notes" in every step.
        self._file_notes: list[str] = []
        self.timings = StageTimings()
        self.recent = RecentFiles([str(p) for p in (self.settings.value("recent", []) or [])])
        self.last_error: str = ""
        self.last_export: str = ""
        self._pending_project: ProjectState | None = None
        self._shown: dict[str, int] = {}
        self._photo_qimage: QImage | None = None
        self._timelapse_dialog: Any = None
        self._last_load: tuple[Any, ...] | None = None
        self._after_label = "Relit"
        #: The user's corrections of the photo's found shadows, in order (step 2's tools).
        self.shadow_edits: tuple[ShadowEdit, ...] = ()
        #: How many edits (a click: 1; a stroke: its dabs) were just added: the next
        #: found-shadows job says if they changed nothing.
        self._edit_just_added = 0
        self._edit_note = ""  # said after "Ready" when the last correction changed nothing
        #: The corrections as the user's last click, stroke or "Clear corrections" left them
        #: (None once an undo, a redo or another photo changed them), until the step-2 view
        #: that shows them is asked for: the job carries them, and its result says what the
        #: correction did (:func:`~app.history.edit_done_note`, in :attr:`_edit_done`).
        self._edit_made: tuple[ShadowEdit, ...] | None = None
        self._edit_done = ""
        #: What an undo or redo said, the jobs it started (or that were running: then not its
        #: own, and their result is not said), for the last of them to report it before its
        #: own result (:meth:`_undo_step`); dropped by the user's next change.
        self._undo_note: tuple[str, set[int], bool] | None = None
        #: The redo steps a correction replaced (:meth:`_restore_redo`), and whether they are
        #: being put back (their undo shows nothing).
        self._redo_before_edit: list[tuple[EditState, EditState, str]] = []
        self._applying_redo_back = False
        #: The correction just made in "Shadows removed", to bring into view once it is shown
        #: and changed something (:meth:`_show_correction_side`).
        self._edit_to_show: tuple[ShadowEdit, ...] = ()
        # The deshadow views' images: (load, original sun, preset, shadow corrections) ->
        # (de-shadowed photo or None, found-shadows overlay); the shown ones and a few more.
        self._loads = 0  # counts loaded sessions
        self._deshadow_key: tuple[Any, ...] | None = None
        self._deshadow_images: tuple[QImage | None, QImage] | None = None
        self._deshadow_kept: OrderedDict[tuple[Any, ...], tuple[QImage | None, QImage]] = (
            OrderedDict())
        #: (key, with the de-shadowed photo, id) of the deshadow job being computed.
        self._deshadow_job: tuple[tuple[Any, ...], bool, int] | None = None
        # Undo/redo (app/history.py): the last recorded state, and a reload's state to restore.
        self.undo_stack = QUndoStack(self)
        self._edit_state: EditState | None = None
        self._applying_edit = False
        self._pending_restore: EditState | None = None
        self._pending_record_from: EditState | None = None
        self._job_fraction: dict[int, float] = {}  # last progress of each running job
        self._saved_exports: dict[int, str] = {}  # the file each finished export job wrote
        self._exposure_hint = ""  # said after "Ready" when the new light changes the level a lot
        self._close_without_asking = False

        # Timing a short time-lapse export gives way to anything the user asks for.
        self.runner = TaskRunner(self, background=frozenset({"tl_estimate"}))
        self.runner.started.connect(self._on_job_started)
        self.runner.progress.connect(self._on_job_progress)
        self.runner.finished.connect(self._on_job_finished)
        self.runner.failed.connect(self._on_job_failed)
        self.runner.cancelled.connect(self._on_job_cancelled)
        self.runner.idle.connect(self._on_idle)

        self._build_ui()
        self._set_step(Step.EMPTY)
        self.setAcceptDrops(True)
        self.resize(1280, 800)
        self._update_title()

    # ================================================================== UI
    def _show_footer(self, index: int) -> None:
        """The step's footer, the stack as tall as it: a stack's layout asks for its tallest
        page's height but leaves out a page whose vertical size policy is Ignored, so step 2's
        two rows (Re-align above the exports) no longer take 20 px of step 1's dial at
        1024 x 700 (a review)."""
        stack = self.footers
        for k in range(stack.count()):
            page = stack.widget(k)
            page.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Preferred
                               if k == index else QSizePolicy.Policy.Ignored)
        stack.setCurrentIndex(index)
        stack.updateGeometry()

    def _build_ui(self) -> None:
        if ICON_PATH.is_file():
            self.setWindowIcon(QIcon(str(ICON_PATH)))
        self.canvas = ImageCanvas(self)
        self.align_panel = AlignPanel(self)
        self.relight_panel = RelightPanel(self)
        self.steps = PanelStack(self)
        self.steps.addWidget(self.align_panel)
        self.steps.addWidget(self.relight_panel)
        scroll = self.side_scroll = QScrollArea(self)
        scroll.setWidget(self.steps)
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QScrollArea.Shape.NoFrame)
        # Not a Tab stop of its own: it showed no focus (a keyboard trial); its controls are,
        # and focusing one scrolls it into view.
        scroll.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        # Each step's main buttons (Confirm sun; Export, Time-lapse) stay below the scrolling
        # panel, in view on a 768-pixel-high screen too.
        self.footers = QStackedWidget(self)
        self.footers.addWidget(self.align_panel.footer)
        self.footers.addWidget(self.relight_panel.footer)
        self.footers.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)
        self.steps.currentChanged.connect(self._show_footer)
        self._show_footer(self.steps.currentIndex())
        # Each step's title stays above it (scrolled down to the corrections, the panel cut
        # "Step 2 · Relight" in half: a user trial).
        self.headers = QStackedWidget(self)
        self.headers.addWidget(self.align_panel.header)
        self.headers.addWidget(self.relight_panel.header)
        self.headers.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)
        self.steps.currentChanged.connect(self.headers.setCurrentIndex)
        side = QWidget(self)
        side.setMinimumWidth(290)
        side_layout = QVBoxLayout(side)
        side_layout.setContentsMargins(0, 0, 0, 0)
        side_layout.setSpacing(0)
        side_layout.addWidget(self.headers)
        side_layout.addWidget(scroll, 1)
        side_layout.addWidget(self.footers)
        # Step 1's notice sits above the photo, as wide as the canvas (the panel is narrow).
        view = QWidget(self)
        view_layout = QVBoxLayout(view)
        view_layout.setContentsMargins(0, 0, 0, 0)
        view_layout.setSpacing(0)
        view_layout.addWidget(self.align_panel.notice)
        view_layout.addWidget(self.canvas, 1)
        splitter = QSplitter(Qt.Orientation.Horizontal, self)
        splitter.addWidget(view)
        splitter.addWidget(side)
        splitter.setStretchFactor(0, 1)
        splitter.setStretchFactor(1, 0)
        splitter.setSizes([960, 320])
        self.setCentralWidget(splitter)

        # Actions
        self.act_open = QAction("&Open…", self, shortcut=QKeySequence.StandardKey.Open)
        self.act_open.setToolTip("Open a photo or an OutCast project (Ctrl+O)")
        self.act_open.triggered.connect(self.open_dialog)
        self.act_save = QAction("&Save project", self, shortcut=QKeySequence.StandardKey.Save)
        self.act_save.setToolTip("Save suns and settings next to the photo (Ctrl+S)")
        self.act_save.triggered.connect(lambda: self.save_project())
        self.act_save_as = QAction("Save project &as…", self)
        self.act_save_as.triggered.connect(self.save_project_dialog)
        self.act_export = QAction("&Export still…", self, shortcut=QKeySequence("Ctrl+E"))
        self.act_export.triggered.connect(self.export_still_dialog)
        self.act_export_deshadow = QAction(
            "Export shadows &removed…", self, shortcut=QKeySequence("Ctrl+Shift+E")
        )
        self.act_export_deshadow.setToolTip(
            "Save the photo with its own shadows removed, at full resolution (Ctrl+Shift+E)"
        )
        self.act_export_deshadow.triggered.connect(self.export_shadows_removed_dialog)
        self.act_depth = QAction("Load &depth map…", self)
        self.act_depth.setToolTip(
            "Use a depth map from elsewhere (a phone's depth, another estimator): .npy, 16-bit "
            "PNG or .exr"
        )
        self.act_depth.triggered.connect(self.load_depth_dialog)
        self.act_depth_model = QAction("Use depth &model…", self)
        self.act_depth_model.setToolTip(
            "Estimate depth with an ONNX depth model of your own (Depth Anything, MiDaS, ...) "
            "instead of OutCast's; remembered for the next photos"
        )
        self.act_depth_model.triggered.connect(self.choose_depth_model_dialog)
        self.act_builtin_depth = QAction("Use OutCast's depth model", self)
        self.act_builtin_depth.setToolTip("Forget the chosen ONNX depth model")
        self.act_builtin_depth.triggered.connect(lambda: self.set_depth_model(""))
        self.act_builtin_depth.setEnabled(bool(self.depth_model))
        self.act_phone_depth = QAction("Use the photo's own depth map", self, checkable=True)
        self.act_phone_depth.setToolTip(
            "Phone portrait photos carry a depth map (GDepth or Dynamic Depth JPEG, HEIC depth "
            "image): use it when there is one"
        )
        self.act_phone_depth.setChecked(self.use_phone_depth)
        self.act_phone_depth.toggled.connect(self.set_use_phone_depth)
        self.act_timelapse = QAction("&Time-lapse…", self, shortcut=QKeySequence("Ctrl+T"))
        self.act_timelapse.triggered.connect(self.open_timelapse)
        self.act_quit = QAction("&Quit", self)
        # The platform's key where it has one (Cmd+Q, Ctrl+Q), else Ctrl+Q: Qt's generic
        # theme and Windows have none (a user trial: Ctrl+Q did nothing under plain X11).
        self.act_quit.setShortcuts(QKeySequence.keyBindings(QKeySequence.StandardKey.Quit)
                                   or [QKeySequence("Ctrl+Q")])
        self.act_quit.triggered.connect(self.close)
        self.act_fit = QAction("&Fit to window", self, shortcut=QKeySequence("Ctrl+0"))
        self.act_fit.triggered.connect(self.canvas.fit)
        self.act_actual = QAction("&Actual pixels", self, shortcut=QKeySequence("Ctrl+1"))
        self.act_actual.triggered.connect(lambda: self.canvas.set_zoom(1.0))
        self.act_zoom_in = QAction("Zoom &in", self, shortcut=QKeySequence.StandardKey.ZoomIn)
        self.act_zoom_in.triggered.connect(lambda: self.canvas.set_zoom(self.canvas.zoom() * 1.25))
        self.act_zoom_out = QAction("Zoom &out", self, shortcut=QKeySequence.StandardKey.ZoomOut)
        self.act_zoom_out.triggered.connect(lambda: self.canvas.set_zoom(self.canvas.zoom() / 1.25))
        self.act_confirm = QAction(
            "&Confirm original sun", self, shortcut=QKeySequence("Ctrl+Return")
        )
        self.act_confirm.triggered.connect(self._confirm_clicked)
        self.act_find_sun = QAction("&Find sun from shadows", self, shortcut=QKeySequence("Ctrl+F"))
        self.act_find_sun.setToolTip(
            "Search the sky for the sun whose shadows match the photo's (Ctrl+F; again to cancel)"
        )
        self.act_find_sun.triggered.connect(self.toggle_find_sun)
        self.act_undo = self.undo_stack.createUndoAction(self, "&Undo")
        self.act_undo.setShortcut(QKeySequence.StandardKey.Undo)
        self.act_redo = self.undo_stack.createRedoAction(self, "&Redo")
        # The platform's redo key first, then the two others, each once: on X11 the platform's
        # is Ctrl+Shift+Z, and the same key twice made Qt call it ambiguous and redo nothing
        # (a user trial; offscreen, Ctrl+Y was the doubled one).
        redo_keys: list[QKeySequence] = []
        for key in (*QKeySequence.keyBindings(QKeySequence.StandardKey.Redo),
                    QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")):
            if not key.isEmpty() and key not in redo_keys:
                redo_keys.append(key)
        self.act_redo.setShortcuts(redo_keys)
        # While a brush stroke is painted, undo and redo cancel it and do nothing else (they
        # undid the step before and the stroke was still added on release, its redo lost).
        for act, step in ((self.act_undo, self.undo_stack.undo),
                          (self.act_redo, self.undo_stack.redo)):
            act.triggered.disconnect()  # (the stack's own step)
            act.triggered.connect(lambda _c=False, step=step, redo=act is self.act_redo:
                                  self._undo_step(step, redo))
        self.undo_stack.cleanChanged.connect(self._on_clean_changed)
        self.act_about = QAction("&About OutCast", self)
        self.act_about.triggered.connect(self._about)
        self.act_keys = QAction("&Keyboard shortcuts", self, shortcut=QKeySequence("F1"))
        self.act_keys.triggered.connect(self._shortcuts)
        # Esc ends a shadow-correction tool (enabled only while one is on, so Esc is left alone
        # otherwise); no menu entry: the window holds it.
        self.act_end_shadow_tool = QAction("End the shadow tool", self,
                                           shortcut=QKeySequence(Qt.Key.Key_Escape))
        self.act_end_shadow_tool.setEnabled(False)
        self.act_end_shadow_tool.triggered.connect(
            lambda: self.relight_panel.set_shadow_tool(""))
        self.addAction(self.act_end_shadow_tool)
        # [ and ] shrink and grow the brush, as in photo editors (with the tools shown).
        self.act_brush_smaller = QAction("Smaller brush", self,
                                         shortcut=QKeySequence(Qt.Key.Key_BracketLeft))
        self.act_brush_larger = QAction("Larger brush", self,
                                        shortcut=QKeySequence(Qt.Key.Key_BracketRight))
        for act, steps in ((self.act_brush_smaller, -1), (self.act_brush_larger, 1)):
            act.setEnabled(False)
            act.triggered.connect(lambda _c=False, n=steps: self._step_brush(n))
            self.addAction(act)

        file_menu = self.menuBar().addMenu("&File")
        file_menu.addAction(self.act_open)
        self.recent_menu = QMenu("Open &recent", self)
        file_menu.addMenu(self.recent_menu)
        file_menu.addAction(self.act_depth)
        file_menu.addAction(self.act_depth_model)
        file_menu.addAction(self.act_builtin_depth)
        file_menu.addAction(self.act_phone_depth)
        file_menu.addSeparator()
        file_menu.addAction(self.act_save)
        file_menu.addAction(self.act_save_as)
        file_menu.addSeparator()
        file_menu.addAction(self.act_export)
        file_menu.addAction(self.act_export_deshadow)
        file_menu.addAction(self.act_timelapse)
        file_menu.addSeparator()
        file_menu.addAction(self.act_quit)
        self.edit_menu = self.menuBar().addMenu("&Edit")
        self.edit_menu.addAction(self.act_undo)
        self.edit_menu.addAction(self.act_redo)
        view_menu = self.menuBar().addMenu("&View")
        for a in (self.act_fit, self.act_actual, self.act_zoom_in, self.act_zoom_out):
            view_menu.addAction(a)
        sun_menu = self.menuBar().addMenu("&Sun")
        sun_menu.addAction(self.act_find_sun)
        sun_menu.addAction(self.act_confirm)
        help_menu = self.menuBar().addMenu("&Help")
        help_menu.addAction(self.act_keys)
        help_menu.addAction(self.act_about)
        self._rebuild_recent_menu()

        tb = self.addToolBar("Main")
        tb.setObjectName("main-toolbar")
        tb.setMovable(False)
        tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        tb.addAction(self.act_open)
        tb.addAction(self.act_save)
        tb.addSeparator()
        tb.addWidget(QLabel(" Quality ", self))
        self.preset_combo = QComboBox(self)
        for name in PRESET_NAMES:
            self.preset_combo.addItem(name.capitalize(), name)
        self.preset_combo.setCurrentIndex(PRESET_NAMES.index(self.preset))
        self.preset_combo.setToolTip(
            "Fast: quick previews at low resolution. Accurate: finer shadows, slower."
        )
        self.preset_combo.currentIndexChanged.connect(
            lambda _i: self.set_preset(str(self.preset_combo.currentData()))
        )
        tb.addWidget(self.preset_combo)
        tb.addSeparator()
        tb.addAction(self.act_fit)
        tb.addAction(self.act_actual)
        tb.addSeparator()
        tb.addAction(self.act_export)
        tb.addAction(self.act_timelapse)

        # Status bar: the message and the running job's progress on the left, the stage timings
        # in the room they leave (cut first), the photo's notes, modes and zoom on the right.
        self.stage_label = StatusText("Ready", self)
        self.progress_bar = QProgressBar(self)
        self.progress_bar.setMaximumWidth(180)
        self.progress_bar.setRange(0, 100)
        # The percentage in the bar, never cut with the message beside it (a user trial at
        # 1280 px read "Exporting shadows removed: removing …" and no percentage).
        self.progress_bar.setFormat("%p %")
        self.progress_bar.setTextVisible(True)
        self.progress_bar.setMinimumWidth(
            self.progress_bar.fontMetrics().horizontalAdvance("100 %") + 40)
        self.progress_bar.hide()
        self.timings_label = TimingsText("", self)
        self.timings_label.setToolTip("How long each stage took, last run")
        self.mode_label = QLabel("", self)
        self.zoom_label = QLabel("", self)
        self.zoom_label.setToolTip("Zoom (Ctrl+0 fits, Ctrl+1 shows actual pixels)")
        # What the photo's file and EXIF say (transparency filled, a strip's shape, what the
        # EXIF gives of the sun): step 1's notice says it above the photo, but a project opens
        # straight into step 2, where it was in the status bar for a moment only. Kept here,
        # small, in every step; hovering or clicking shows the notes.
        self.photo_notes_button = QToolButton(self)
        self.photo_notes_button.setText("Photo notes")
        self.photo_notes_button.setIcon(
            self.style().standardIcon(QStyle.StandardPixmap.SP_MessageBoxInformation))
        self.photo_notes_button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.photo_notes_button.setAutoRaise(True)
        self.photo_notes_button.setAccessibleName("Photo notes")
        self.photo_notes_button.clicked.connect(self.show_photo_notes)
        self.photo_notes_button.hide()
        # "Zoom 44 %", not "44 %" alone: after the mode label it read as the depth model's
        # share ("... depth: model 44 %", a user trial).
        self.canvas.zoom_changed.connect(
            lambda z: self.zoom_label.setText(f"Zoom {self._photo_zoom(z) * 100:.0f} %"))
        sb = self.statusBar()
        sb.addWidget(self.stage_label)  # as wide as its message, while the bar has room
        sb.addWidget(self.progress_bar)
        sb.addWidget(self.timings_label, 1)  # the rest, if any
        sb.addPermanentWidget(self.photo_notes_button)
        sb.addPermanentWidget(self.mode_label)
        sb.addPermanentWidget(self.zoom_label)

        # Wiring
        ap, rp = self.align_panel, self.relight_panel
        ap.sun_panel.sun_changed.connect(self._on_original_sun_changed)
        ap.sun_panel.sun_committed.connect(self._on_original_sun_committed)
        ap.opacity_slider.valueChanged.connect(lambda v: self.canvas.set_overlay_opacity(v / 100.0))
        ap.confirm_clicked.connect(self._confirm_clicked)
        ap.exif_clicked.connect(self.use_exif_sun)
        ap.find_sun_clicked.connect(self.toggle_find_sun)
        ap.heading_changed.connect(self._on_heading_typed)
        rp.sun_panel.sun_changed.connect(self._on_target_sun_changed)
        rp.sun_panel.sun_committed.connect(self._on_target_sun_committed)
        rp.split_slider.valueChanged.connect(self._on_split_changed)
        rp.exposure_changed.connect(self._on_exposure_changed)
        rp.daylight_changed.connect(self._on_daylight_changed)
        rp.relighting_changed.connect(self._on_relighting_changed)
        self.canvas.split_dragged.connect(lambda f: rp.split_slider.setValue(round(f * 100)))
        rp.view_combo.currentIndexChanged.connect(self._on_view_changed)
        rp.export_still_clicked.connect(self.export_still_dialog)
        rp.timelapse_clicked.connect(self.open_timelapse)
        rp.realign_clicked.connect(self.back_to_align)
        rp.shadow_tool_changed.connect(self._on_shadow_tool_changed)
        rp.clear_shadow_edits_clicked.connect(self.clear_shadow_edits)
        self.canvas.image_clicked.connect(self._on_canvas_clicked)
        self.canvas.split_clicked.connect(lambda: self.stage_label.setText(
            "That click fell on the before | after line (drag it to move it): click beside "
            "it to correct the shadows there"))
        self.canvas.stroke_painted.connect(self._on_canvas_stroke)
        try:  # the brush's size, as the user left it
            brush = float(self.settings.value("brush_size", BRUSH_DEFAULT))
        except (TypeError, ValueError):
            brush = BRUSH_DEFAULT
        if not BRUSH_RANGE[0] <= brush <= BRUSH_RANGE[1]:  # (also NaN)
            brush = BRUSH_DEFAULT
        rp.set_brush(brush / 100.0)
        self.canvas.set_brush(rp.brush())
        rp.brush_changed.connect(self._on_brush_changed)
        self.canvas.set_overlay_opacity(ap.opacity_slider.value() / 100.0)
        shortcuts_win = WindowShortcutsWin(self._window_shortcuts, self)
        for box in self.findChildren(QAbstractSpinBox):
            box.installEventFilter(shortcuts_win)
            for child in box.findChildren(QObject):
                child.installEventFilter(shortcuts_win)

    def _window_shortcuts(self) -> list[QKeySequence]:
        """Shortcuts that reach the window even while a number field has focus."""
        acts = (
            self.act_export, self.act_export_deshadow, self.act_timelapse, self.act_confirm,
            self.act_find_sun, self.act_save, self.act_open, self.act_quit, self.act_undo,
            self.act_redo, self.act_keys, self.act_brush_smaller, self.act_brush_larger,
        )  # fmt: skip
        return [seq for act in acts for seq in act.shortcuts()]

    def _rebuild_recent_menu(self) -> None:
        self.recent_menu.clear()
        paths = self.recent.paths()
        for p in paths:
            act = self.recent_menu.addAction(os.path.basename(p))
            act.setToolTip(p)
            act.setData(p)
            act.triggered.connect(lambda _c=False, path=p: self.open_path(path))
        self.recent_menu.setEnabled(bool(paths))

    def _set_step(self, step: Step) -> None:
        if step is not self.step:  # a new step's panel starts at its top
            self.side_scroll.verticalScrollBar().setValue(0)
        dialog = self._timelapse_dialog
        if (step is not Step.RELIGHT and dialog is not None and dialog.isVisible()
                and not dialog.exporting()):
            # Its path and heading come from the confirmed sun: it opens again (Ctrl+T) once
            # the sun is confirmed (a user trial exported from it while re-aligning, with the
            # old sun; a review, after undoing the confirm). An export running from it keeps
            # it open, for its progress and Cancel (and it refuses another until then).
            dialog.close()
        self.step = step
        has_photo = step is not Step.EMPTY
        self.steps.setCurrentWidget(
            self.relight_panel if step is Step.RELIGHT else self.align_panel
        )
        self.align_panel.setEnabled(has_photo)
        self.align_panel.footer.setEnabled(has_photo)  # below the panel, not inside it
        for act in (self.act_save, self.act_save_as, self.act_depth, self.act_fit,
                    self.act_actual, self.act_zoom_in, self.act_zoom_out):
            act.setEnabled(has_photo)
        tips = {self.act_export: "Save the relit photo at full resolution (Ctrl+E)",
                self.act_export_deshadow: "Save the photo with its own shadows removed, at "
                                          "full resolution (Ctrl+Shift+E)",
                self.act_timelapse: "Render the photo along a path of suns as a video, an "
                                    "animation or PNG frames (Ctrl+T)"}
        for act, tip in tips.items():
            act.setEnabled(step is Step.RELIGHT)
            # Say why a greyed-out button is grey (Qt shows tooltips of disabled buttons).
            act.setToolTip(tip if step is Step.RELIGHT else
                           f"{tip}. First confirm the photo's sun (step 1)"
                           if has_photo else f"{tip}. First open a photo")
        self.act_confirm.setEnabled(step is Step.ALIGN)
        self.act_find_sun.setEnabled(step is Step.ALIGN)
        self._update_shadow_tools()
        self._update_photo_notes()
        if step is Step.RELIGHT:
            self.canvas.set_overlay(None)
            self._on_split_changed(self.relight_panel.split_slider.value())
        else:
            self._photo_as_base()
            self.canvas.set_after(None)
            self.canvas.set_split(None)

    def _update_title(self) -> None:
        name = os.path.basename(self.image_path) if self.image_path else ""
        self.setWindowTitle(f"{name}[*] — {APP_NAME}" if name else APP_NAME)
        self.setWindowModified(bool(name) and self.has_unsaved_changes())

    @Slot(bool)
    def _on_clean_changed(self, _clean: bool) -> None:
        self._update_title()

    @property
    def loads(self) -> int:
        """How many photos (sessions) were loaded: a job's result for an earlier one is stale."""
        return self._loads

    def has_unsaved_changes(self) -> bool:
        """Whether undoable edits, or changes to the time-lapse settings, were made since the
        photo was opened or the project saved."""
        return not self.undo_stack.isClean() or self._timelapse_changed()

    def _timelapse_changed(self) -> bool:
        """Whether the time-lapse settings differ from their baseline, as a project keeps
        them (:meth:`_timelapse_to_save`): what the dialog filled in (a sweep from the suns of
        the moment, a solved heading, a guessed offset) is not the user's change. Compared as
        shown, a sweep filled in again from a moved sun stayed unsaved work after the move was
        undone (a user trial)."""
        return (self._timelapse_baseline is not None
                and self._timelapse_to_save() != self._timelapse_baseline)

    def unsaved_parts(self) -> list[str]:
        """What :meth:`has_unsaved_changes` sees, in words (the save question's): the parts of
        the edit state that differ from the saved (clean) one, and the time-lapse settings.
        Without an edit-state part when the saved state cannot be reached by undo or redo (Qt
        dropped it) or the edits cancel out (a move there and back); ``[]``: the question's
        general words."""
        stack, state = self.undo_stack, self.edit_state()
        clean, now = stack.cleanIndex(), stack.index()
        parts: list[str] = []
        if state is not None and clean >= 0 and now != clean:
            command = stack.command(clean if now > clean else clean - 1)
            if isinstance(command, EditCommand):
                parts = changed_parts(command.before if now > clean else command.after, state)
        if self._timelapse_changed():
            parts.append("the time-lapse settings")
        return parts

    def set_timelapse_settings(self, settings: TimelapseSettings, shown: bool = False) -> None:
        """The time-lapse dialog's settings, as they change; ``shown``: as it first shows them
        (with the place, date and heading filled from the photo), the baseline of unsaved work
        until the next save or photo."""
        self.timelapse_settings = settings
        if shown and self._timelapse_baseline is None:
            self._timelapse_baseline = self._timelapse_to_save()
        self._update_title()

    # ================================================================== undo / redo
    def edit_state(self) -> EditState | None:
        """The undoable part of the current session (``None`` without a photo)."""
        if self.session is None or self.step is Step.EMPTY:
            return None
        return EditState(
            step="relight" if self.step is Step.RELIGHT else "align",
            align_sun=self.align_panel.sun_panel.sun(),
            original_sun=self.original_sun.as_tuple() if self.original_sun else None,
            target_sun=self.relight_panel.sun_panel.sun(),
            preset=self.preset,
            depth_path=self.depth_path,
            heading=self.user_heading,
            exposure=self.relight_panel.exposure(),
            daylight=self.relight_panel.daylight(),
            relighting=self.relighting_choice,
            shadow_edits=self.shadow_edits,
        )

    def _record(self, after: EditState | None = None, text: str = "", step_of: str = "") -> None:
        """Push the change from the last recorded state to ``after`` (default: the current one).

        ``step_of``: the field an arrow-key step changed (a burst of them is one undo step,
        :meth:`EditCommand.mergeWith`), or ``""``.
        """
        if self._applying_edit:
            return
        after = after if after is not None else self.edit_state()
        before, self._edit_state = self._edit_state, after
        if before is None or after is None or same_edit_state(before, after):
            return
        self._undo_note = None  # the user's own change: what an undo did is past
        self.undo_stack.push(EditCommand(self, before, after, text, step_of=step_of))

    def _reset_history(self, state: EditState | None) -> None:
        self._timelapse_baseline = None
        self.timelapse_auto_heading = None
        self.timelapse_auto_offset = None
        self.timelapse_auto_sweep = None
        self.undo_stack.clear()
        self._edit_state = state
        self.undo_stack.setClean()
        self._update_title()

    def apply_edit_state(self, state: EditState) -> None:
        """Show ``state``: preset, depth, both suns and the step (undo/redo; records nothing)."""
        if self.session is None or self._applying_redo_back:  # (states never shown)
            return
        self._edit_state = state
        if state.depth_path != self.depth_path:  # re-run the light-independent stages
            self._reload(state)
            return
        self._applying_edit = True
        try:
            if state.shadow_edits != self.shadow_edits:  # shown below (the relit view, ...)
                self._show_shadow_edits(state.shadow_edits)
                self._refresh_timelapse_preview()
            if state.heading != self.user_heading:
                self.set_user_heading(state.heading)
            # The exposure, the light and the relighting: relit below, once; an open
            # time-lapse's frame too (an undone exposure left it drawn at the other one: a
            # review).
            exposure = state.exposure != self.relight_panel.exposure()
            daylight = state.daylight != self.relight_panel.daylight()
            relighting = state.relighting != self.relighting_choice
            if exposure:
                self.set_exposure(state.exposure, refresh=False)
            if daylight:
                self.set_daylight(state.daylight, refresh=False)
            if relighting:
                self.set_relighting(state.relighting, refresh=False)
            if exposure or daylight or relighting:
                self._refresh_timelapse_preview()
            if state.preset != self.preset:
                self.set_preset(state.preset)
            self.relight_panel.sun_panel.set_sun(*state.target_sun)
            if state.step == "relight" and state.original_sun is not None:
                confirmed = self.original_sun.as_tuple() if self.original_sun else None
                if self.step is Step.RELIGHT and confirmed == state.original_sun:
                    self.align_panel.sun_panel.set_sun(*state.original_sun)
                    self.request_relight(preview=False)
                else:
                    self.align_panel.sun_panel.set_sun(*state.original_sun)
                    self.confirm_original_sun(keep_target=True)
            else:
                self.align_panel.sun_panel.set_sun(*state.align_sun)
                self.original_sun = Sun(*state.original_sun) if state.original_sun else None
                if self.step is not Step.ALIGN:
                    self._set_step(Step.ALIGN)
                self.request_shadow(preview=False)
        finally:
            self._applying_edit = False

    def _reload(self, state: EditState, record_from: EditState | None = None) -> None:
        """Open the photo again with ``state`` (a new depth map); record the change on success."""
        project = self.project_state()
        project.preset = state.preset
        project.depth_path = state.depth_path
        project.heading = state.heading
        project.exposure = state.exposure
        project.daylight = state.daylight
        project.relighting = state.relighting
        project.shadow_edits = state.shadow_edits
        relight = state.step == "relight" and state.original_sun is not None
        project.original_sun = Sun(*state.original_sun) if relight else None
        project.align_sun = Sun(*state.align_sun)
        project.realigning = False  # the restored state says it (_on_loaded)
        project.timelapse = self.timelapse_settings  # as shown (a filled-in heading too)
        project.target_sun = Sun(*state.target_sun)
        self.open_image(self.image_path, project=project, restore=state, record_from=record_from)

    def _about(self) -> None:
        QMessageBox.about(
            self,
            "About OutCast",
            "<b>OutCast</b> relights outdoor photos with correct cast shadows.<br>"
            "Based on Griffiths, Ritschel and Philip, <i>OutCast: Outdoor Single-image "
            "Relighting with Cast Shadows</i>, Eurographics 2022.",
        )

    def _photo_zoom(self, zoom: float) -> float:
        """The canvas's zoom as a share of the photo's own pixels: the buffer views (depth,
        normals, shadows) show a working-size image, whose zoom read 367 % where the photo's
        read 47 % at the same size on screen (a user trial)."""
        shown = self.canvas.image_size().width()
        size = getattr(self.loaded, "original_size", None)
        return zoom * shown / size[0] if shown > 0 and size and size[0] > 0 else zoom

    def _shortcuts(self) -> None:
        quit_key = self.act_quit.shortcut().toString(QKeySequence.SequenceFormat.NativeText)
        QMessageBox.information(
            self,
            "Keyboard shortcuts",
            "Sun dial (click it first): arrow keys move the sun 1°, Shift 10°, Ctrl 0.1°.\n"
            "Ctrl+O open · Ctrl+S save project · Ctrl+F find the sun (again to cancel) · "
            "Ctrl+Return confirm the sun · Ctrl+E export still · Ctrl+Shift+E export shadows "
            "removed · Ctrl+T time-lapse · Ctrl+Z undo · Ctrl+Shift+Z or Ctrl+Y redo"
            f" · {quit_key} quit\n"
            "Canvas: mouse wheel or Ctrl++ / Ctrl+- zooms, drag pans, double-click or Ctrl+0 "
            "fits, Ctrl+1 actual pixels.\n"
            "Step 2, Shadows found / removed: \"Not a shadow\" or \"Mark shadow\", then click a "
            "region of the photo or drag to paint (the middle button pans); [ and ] shrink and "
            "grow the brush; Esc ends the tool.",
        )

    def show_error(self, exc: BaseException, action: str) -> None:
        """Tell the user what happened and what to do; the app carries on."""
        msg = message_for(exc, action)
        self.last_error = f"{msg.title}: {msg.what}"
        self.stage_label.setText(msg.title)
        # A refusal that kept a file is a warning; a failure is an error.
        box = QMessageBox.warning if msg.refusal else QMessageBox.critical
        box(self, msg.title, f"{msg.title}.\n\n{msg.text()}")

    # ================================================================== opening
    def open_dialog(self) -> None:
        patterns = " ".join(f"*{s}" for s in IMAGE_SUFFIXES)
        path, _ = QFileDialog.getOpenFileName(
            self,
            "Open a photo or project",
            os.path.dirname(self.image_path) if self.image_path else "",
            f"Photos and projects ({patterns} *.outcast.json);;Photos ({patterns});;"
            "OutCast projects (*.outcast.json)",
        )
        if path:
            self.open_path(path)

    def open_path(self, path: str) -> None:
        """Open a photo or a project file (the load runs in the worker).

        With a running export or unsaved edits the user is asked first (and may say no).
        """
        # A file that cannot be opened is said before anything is asked: the save question
        # came first, and only then "not an image file" (a user trial).
        project = is_project_file(path)
        try:
            if project:
                load_project(path)
            else:
                check_photo_file(path)  # the first bytes and header: what cannot be a photo
        except (OSError, ValueError) as exc:  # (ImageReadError is a ValueError)
            self._drop_if_gone(path)
            self.show_error(exc, "project" if project else "open")
            return
        if self.image_path and not self.confirm_leave("open"):
            return
        if project:
            try:  # read again: "Save" may have just written this very project
                state = load_project(path)
            except (OSError, ValueError) as exc:
                self.show_error(exc, "project")
                return
            self.recent.add(path)
            self._save_recent()
            photo = state.image_path
            if photo and not os.path.exists(photo):  # moved, renamed or deleted
                photo = self.locate_photo(path, state)
                if not photo:
                    return
            self._opening_project_file = os.path.abspath(path)
            self.open_image(photo, project=state)
        else:
            self._opening_project_file = ""
            self.open_image(path)

    def _drop_if_gone(self, path: str) -> None:
        """A recent file that has gone away leaves the recent list."""
        if path and not os.path.exists(path):
            self.recent.remove(path)
            self._save_recent()

    def locate_photo(self, project_path: str, project: ProjectState) -> str:
        """Ask where a project's missing photo is now ("Locate photo…", then a file dialog in
        the project's folder); the photo chosen, or "" when the user cancels."""
        name = os.path.basename(project_path)
        answer = self.ask(locate_photo_question(name, project.image_path))
        path = ""
        if answer == LOCATE:
            patterns = " ".join(f"*{s}" for s in IMAGE_SUFFIXES)
            path, _ = QFileDialog.getOpenFileName(
                self, f"Locate {os.path.basename(project.image_path)}",
                os.path.dirname(os.path.abspath(project_path)), f"Photos ({patterns})")
        if not path:
            self.stage_label.setText(f"Not opened: the photo of {name} is missing")
        return path

    def open_image(
        self,
        path: str,
        project: ProjectState | None = None,
        restore: EditState | None = None,
        record_from: EditState | None = None,
    ) -> None:
        """Load ``path`` in the worker, with a project's settings when given.

        Args:
            path: the photo.
            project: settings to apply once it is loaded (suns, preset, depth map, views).
            restore: reopening the same photo (a new depth map, undo, a model fallback): the
                undo history is kept and this state shown. ``None``: a new photo, a fresh history.
            record_from: with ``restore``, record the change from this state once loaded.
        """
        preset = project.preset if project is not None else self.preset
        mode = self.session_mode
        depth_mode = self.depth_mode
        depth_path = project.depth_path if project is not None else ""
        # A project opened now (not a depth map the user just chose, nor an undo across one):
        # its depth map's failure is said as the project's.
        opening_project = project is not None and restore is None
        depth_model = self.depth_model
        use_phone = self.use_phone_depth

        def job(ctx: JobContext) -> dict[str, Any]:
            from outcast_core.runtime.io.depth_models import pick_depth_source
            from outcast_core.runtime.io.imageio import read_depth, read_image
            from outcast_core.runtime.pipeline.session import RelightSession, check_given_depth

            ctx.progress("reading", 0.02)
            # 8-bit photos stay 8-bit: the session keeps this array (no float copy) and the
            # full-resolution passes read it in bands.
            loaded = read_image(path, keep_uint8=True)
            depth = None
            if depth_path:
                try:
                    depth = check_given_depth(read_depth(depth_path),
                                              loaded.image_srgb.shape[:2])
                except ValueError as exc:
                    if not opening_project:  # the map the user chose: "depth" (below)
                        raise
                    raise DepthMapError(getattr(exc, "message", str(exc))) from exc
            session = RelightSession(preset=preset, mode=mode, depth_mode=depth_mode)
            note = ""
            if depth is None:  # a chosen model, else the photo's own depth map, else Z
                width, height = loaded.original_size
                session.depth_provider, note = pick_depth_source(
                    path, (height, width), model_path=depth_model or None, use_phone=use_phone,
                    strict=False, photo_srgb=loaded.image_srgb,
                )
            focal = loaded.exif.focal_35mm if loaded.exif else None
            session.set_image(loaded.image_srgb, focal_35mm=focal or None, depth=depth,
                              progress=session_progress(ctx, TILT_STAGE, 0.9), photo_path=path)
            # The camera's pitch and roll (its metadata's, the sun in the frame's, else the
            # ground plane's): the frame in which the EXIF sun and the real sun path are given,
            # and the new sun's daylight's horizon.
            tilt = session.photo_tilt()
            photo = display.to_uint8_rgb(loaded.image_srgb)
            return {"path": path, "loaded": loaded, "session": session, "photo": photo,
                    "depth_path": depth_path, "depth_note": note, "tilt": tilt,
                    "identity": PhotoIdentity.of(loaded.image_srgb)}

        self._pending_project = project
        self._pending_restore = restore
        self._pending_record_from = record_from
        self._last_load = (path, project, restore, record_from)
        self.runner.submit("load", job, f"Opening {os.path.basename(path)}")

    def _on_loaded(self, result: dict[str, Any]) -> bool:
        """Show a loaded photo (with its project's work, or the state to restore); False when
        the user declined a project's photo that is not the one it was saved with (nothing
        changed)."""
        project, self._pending_project = self._pending_project, None
        restore, self._pending_restore = self._pending_restore, None
        record_from, self._pending_record_from = self._pending_record_from, None
        identity = result.get("identity")
        # A project opened now: its photo moved (located elsewhere), or not the photo it was
        # saved with (a file replaced under its name): either way it is modified once open.
        moved_from = mismatch = ""
        if project is not None and restore is None:
            if os.path.abspath(project.image_path) != os.path.abspath(result["path"]):
                moved_from = os.path.abspath(project.image_path)
            if project.photo is not None and identity is not None:
                mismatch = project.photo.mismatch(identity)
            if mismatch and self.ask(other_photo_question(
                    os.path.basename(self._opening_project_file) or "The project",
                    os.path.basename(result["path"]), mismatch)) != CONTINUE:
                self.stage_label.setText(
                    f"Not opened: {os.path.basename(result['path'])} is not the project's photo "
                    f"({mismatch})")
                self._opening_project_file = ""  # declined: no project is being opened
                return False
        self.photo_identity = identity
        self.session = result["session"]
        if restore is None:  # another photo: the photo's own exposure (a project's: below)
            self.relight_panel.set_exposure("photo")
            self.relight_panel.set_daylight(True)  # and the new sun's daylight
        self.session.exposure = self.relight_panel.exposure()
        # (a new session, no job holds it yet: its lock is not waited for)
        self.session.daylight = self.relight_panel.daylight()
        if project is None:  # the default for another photo (a project's own: _apply_project)
            self._show_relighting(restore.relighting if restore is not None else "learned")
        self.loaded = result["loaded"]
        self._set_camera_tilt(result.get("tilt", LEVEL_TILT))
        self.depth_path = result.get("depth_path", "")
        self.image_path = os.path.abspath(result["path"])
        if restore is None and project is None:  # (the same photo opened again too: its
            self.timelapse_settings = TimelapseSettings()  # edits were dropped by the user)
        if restore is None and self._timelapse_dialog is not None:
            # Its place, day, heading and size were the last photo's (a user trial changed
            # them and saved them into the new photo's settings): it is opened again for this
            # one once its sun is confirmed.
            self._timelapse_dialog.set_stale()
        if project is None:  # a project opened from the menu is already the recent entry
            self.recent.add(self.image_path)
            self._save_recent()
        self._photo_qimage = qimage_from_array(result["photo"])
        self._deshadow_key = self._deshadow_images = None
        self._deshadow_kept.clear()
        self._exposure_hint = self._edit_note = ""
        self._loads += 1
        self.canvas.set_image(self._photo_qimage)
        self.original_sun = None
        cam = getattr(self.session, "camera", None)
        if cam is not None:
            vfov = math.degrees(2.0 * math.atan(cam.height / (2.0 * cam.focal)))
            self.align_panel.sun_panel.set_fov(cam.fov_deg, vfov)
            self.relight_panel.sun_panel.set_fov(cam.fov_deg, vfov)
        self.mode_label.setText(self._mode_text())
        self._update_title()
        source = str(getattr(self.session, "depth_source", ""))
        if "prior" in source:
            notice = (
                "No depth model is installed, so OutCast assumes flat ground and cannot predict "
                "this photo's cast shadows. Load a depth map (File \u25b8 Load depth map\u2026), "
                "or set the sun by eye or from the photo's EXIF."
            )
        elif source == "model":
            notice = (
                "Depth is from OutCast's small network, trained on synthetic scenes: rough on "
                "real photos, and so are the shadows. For accurate ones: File \u25b8 Load "
                "depth map\u2026 or Use depth model\u2026"
            )
        else:
            notice = ""
        note = str(result.get("depth_note", ""))  # a depth source that could not be used
        if note:
            notice = f"{note[:1].upper()}{note[1:]}. " + notice
        # What the command line says of the file as it reads it (a user trial opened a PNG
        # with transparency and was not told it was filled with white).
        file_notes = self._file_notes = photo_file_notes(result.get("loaded"))
        if file_notes:
            notice = " ".join(file_notes) + " " + notice
        saved = project_path_for(self.image_path)
        if project is None and restore is None and saved.exists():  # the photo on its own
            notice = (f"This photo has a saved project, {saved.name}: open it (File \u25b8 "
                      "Open) to continue that work. ") + notice
        self._load_notice = notice.strip()
        self._show_search_notice("")
        if restore is None:  # another photo: its own heading, no search result yet
            self.user_heading = self.seen_heading = None
            opened = self._opening_project_file if project is not None else ""
            self._project_files = {opened} if opened else set()
            self._project_file = opened
            self._photo_moved_from = moved_from
            self.side_scroll.verticalScrollBar().setValue(0)  # another photo: from the top
            self.align_panel.set_heading(self._exif_heading(), recorded=True)
            self.sun_fit = None
            self.align_panel.sun_panel.dial.set_heat_map(None)
        self._update_exif_controls()
        self._set_step(Step.ALIGN)
        exif_sun = seen_sun = seen_heading = ring_sun = None
        if restore is None:  # another photo: nothing of the previous one stays on screen
            self.timings = StageTimings()
            self.timings_label.setText("")
            self.timings_label.setToolTip("How long each stage took, last run")
            self.relight_panel.sun_panel.dial.set_reference(None)
            seen = getattr(self.session, "sun_seen", None)  # the sun the photo shows
            if seen is not None:  # exact, whatever the compass says
                az, el = sun_angles(seen.w)
                seen_sun = (az, dm.clamp_elevation(el))
                # (a project's heading replaces it below; the note under the EXIF button
                # still says where it came from when they agree)
                seen_heading = self._heading_from_seen_sun(az, el)
            # A project keeps its own sun: the confirmed one, or the step-1 dial's (saved
            # before confirming); older projects without the latter start as a photo does.
            fresh = project is None or (project.original_sun is None
                                        and project.align_sun is None)
            if fresh:
                if seen_sun is None:
                    exif_sun = self.exif_sun()
                if seen_sun is None and exif_sun is None:
                    ring_sun = self._sun_on_exif_ring(*DEFAULT_SUN)
                self.align_panel.sun_panel.set_sun(
                    *(seen_sun or exif_sun or ring_sun or DEFAULT_SUN))
            else:
                seen_sun = None  # not where the dial starts: not said
            if project is None:
                self.relight_panel.sun_panel.set_sun(*DEFAULT_SUN)
        # Another photo starts without corrections; a project (a reload too) brings its own.
        self._show_shadow_edits(project.shadow_edits if project is not None else ())
        self._applying_edit = True
        try:
            if project is not None:
                self._apply_project(project)
            else:
                self.request_shadow(preview=False)
            if restore is not None and restore.step == "align":
                self.align_panel.sun_panel.set_sun(*restore.align_sun)
                self.original_sun = Sun(*restore.original_sun) if restore.original_sun else None
                self.request_shadow(preview=False)
        finally:
            self._applying_edit = False
        opened = f"Opened {os.path.basename(self.image_path)}"
        if moved_from:  # first: a long message is cut at the status bar's end
            opened += (f" for the project, whose photo was {moved_from}: save the project to "
                       "keep where it is now")
        elif mismatch:
            opened += (" for the project, which was saved with another photo: save the project "
                       "to keep it for this one")
        if seen_sun is not None:
            opened += (f" · the sun is in the frame: azimuth {seen_sun[0]:.1f}°, elevation "
                       f"{seen_sun[1]:.1f}°")
        if seen_heading is not None:
            source = "it" if seen_sun is not None else "the sun in the frame"
            opened += f" · camera heading {seen_heading:.1f}° from {source}"
        if exif_sun is not None:
            tilt = self.tilt_note()
            opened += (
                f" · sun from its EXIF: azimuth {exif_sun[0]:.1f}°, elevation {exif_sun[1]:.1f}°"
                f"{f' for a {tilt}' if tilt else ''} (check it against the shadows)"
            )
        elif ring_sun is not None:  # the EXIF's elevation without a compass heading
            tilt = self.tilt_note()
            opened += (f" · sun elevation {ring_sun[1]:.1f}° from its time and place"
                       f"{f' for a {tilt}' if tilt else ''}; no compass heading: turn the sun "
                       "around the ring until the shadows fit")
        if restore is None:  # said once, as the photo is opened (the notice and the status
            # bar's "Photo notes" keep it)
            opened += "".join(f" · {note[:1].lower()}{note[1:].rstrip('.')}"
                              for note in file_notes)
        self.stage_label.setText(opened)
        self._held_message = opened if self._status_pending() else ""
        if restore is not None:  # the same photo again: keep the history
            self._edit_state = record_from
            self._record(restore)
            return True
        baseline = self.edit_state()
        if (baseline is not None and project is not None and project.original_sun is not None
                and not project.realigning):
            baseline = replace(
                baseline, step="relight", original_sun=project.original_sun.as_tuple()
            )
        self._reset_history(baseline)
        if moved_from or mismatch:  # the project file says another photo: unsaved until saved
            self.undo_stack.resetClean()
        return True

    def _mode_text(self) -> str:
        s = self.session
        if s is None:
            return ""
        shadow = "learned shadows" if s.shadow_mode == "learned" else "Direct shadows"
        relight = f"{self.relight_panel.relighting()} relighting"  # (the jobs set it)
        depth = str(getattr(s, "depth_source", "?"))
        self.mode_label.setToolTip(f"{shadow} · {relight} · depth: {depth}")
        short = depth.split(" (")[0]
        return f"{shadow} · {relight} · depth: {short}"

    def exif_sun(self) -> tuple[float, float] | None:
        """The photo's sun relative to the camera from EXIF GPS, time and compass heading (the
        heading typed in step 1 replaces the EXIF's), in the camera's frame (its pitch
        and roll: :attr:`camera_tilt`)."""
        from outcast_core.runtime.pipeline.timelapse import exif_sun

        sun = exif_sun(getattr(self.loaded, "exif", None), heading=self.user_heading,
                       tilt=self.camera_tilt[:2])
        # A camera pitched well up can have the sun under its own horizon: the dial's lowest.
        return None if sun is None else (sun[0], dm.clamp_elevation(sun[1]))

    def _sun_on_exif_ring(self, azimuth: float, elevation: float) -> tuple[float, float] | None:
        """The dial's sun moved onto the elevation ring of the photo's EXIF (GPS and time, no
        compass heading), its azimuth about the true horizon kept; None without that ring."""
        from outcast_core.runtime.pipeline.auto_sun import at_true_elevation

        prior = self.exif_prior()
        if prior is None:
            return None
        az, el = at_true_elevation(azimuth, elevation, prior.elevation, self.camera_tilt[:2])
        return az, dm.clamp_elevation(el)

    def tilt_note(self) -> str:
        """The camera's tilt in words when it is not level ("camera pitched 21.0° down (ground
        plane)"), else ""."""
        from outcast_core.runtime.pipeline.auto_sun import describe_tilt

        return describe_tilt(*self.camera_tilt)

    def _set_camera_tilt(self, tilt: tuple[float, float, str]) -> None:
        """The photo's camera tilt (at load, and again when a preset changes the depth's
        working size, and with it the ground plane): both dials and the EXIF controls."""
        self.camera_tilt = tilt
        for panel in (self.align_panel, self.relight_panel):
            panel.sun_panel.set_tilt(*tilt[:2])
        if self._timelapse_dialog is not None:
            self._timelapse_dialog.refresh_path()

    def exif_prior(self) -> Any:
        """What the photo's EXIF (and a typed heading) says about its sun: an
        :class:`~outcast_core.runtime.pipeline.auto_sun.SunPrior`, or None without GPS and time."""
        from outcast_core.runtime.pipeline.auto_sun import exif_sun_prior

        exif = getattr(self.loaded, "exif", None)
        return exif_sun_prior(exif, heading=self.user_heading) if exif is not None else None

    def exif_note(self, heading_box: str = "below") -> str:
        """Why the EXIF button is greyed out, or what the EXIF gives without a heading;
        ``heading_box``: where the camera heading box is, as the note says it (under the
        button: "below")."""
        from outcast_core.runtime.pipeline import timelapse as tl

        exif = getattr(self.loaded, "exif", None)
        if exif is None or self.session is None:
            return ""
        when = getattr(exif, "capture_time", None)
        lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
        if when is None or lat is None or lon is None:
            missing = " and ".join(n for n, v in (("GPS position", lat), ("capture time", when))
                                   if v is None)
            return f"The photo's EXIF has no {missing}: set the sun by eye or find it."
        night = tl.sun_below_horizon_at_capture(exif)
        if night is not None:  # how far below, at what time as read (a zone-less one: the
            # longitude's zone)
            return (f"{night[0].upper()}{night[1:]}: check the camera's clock and time zone, "
                    "or set the sun by eye or find it.")
        when, guessed = tl.exif_capture_time(exif)
        _, el = tl.true_sun_position(when, lat, lon)
        zone = ""
        if guessed:
            hours = when.utcoffset().total_seconds() / 3600.0
            zone = (f" (its time zone, UTC{hours:+g}, is guessed from the longitude: the EXIF "
                    "gives none)")
        if getattr(exif, "heading_deg", None) is None and self.user_heading is None:
            above = " above the true horizon" if self.tilt_note() else ""
            return (f"No compass heading in the photo's EXIF: Find sun uses the elevation "
                    f"{el:.0f}°{above} from the photo's time and place{zone}. Type the camera "
                    f"heading {heading_box} for the full sun.")
        seen, typed = self.seen_heading, self.user_heading
        if seen is not None and typed is not None and abs(seen - typed) < 0.05:
            recorded = self._exif_heading()
            compass = "" if recorded is None else f" (its EXIF compass says {recorded:.1f}°)"
            return (f"Camera heading {seen:.1f}° from the sun in the frame and the photo's time "
                    f"and place{compass}.")
        return ""

    def _update_exif_controls(self) -> None:
        self.align_panel.exif_button.setEnabled(self.exif_sun() is not None)
        prior = self.exif_prior()
        self.align_panel.sun_panel.dial.set_prior_elevation(
            None if prior is None else prior.elevation)
        self.align_panel.set_exif_note(self.exif_note())
        # A heading only helps with a time and a place. One recorded in the EXIF is shown and
        # may be corrected (phone compasses are often tens of degrees off).
        self.align_panel.heading_box.setEnabled(self._exif_has_place())
        self._update_photo_notes()

    def _exif_has_place(self) -> bool:
        """Whether the photo's EXIF records its GPS position and capture time."""
        exif = getattr(self.loaded, "exif", None)
        return bool(exif is not None and getattr(exif, "has_gps", False)
                    and getattr(exif, "capture_time", None) is not None)

    def photo_notes(self) -> list[str]:
        """What the photo's file and EXIF say, as sentences, for the status bar's "Photo notes"
        (every step; empty without a photo): :func:`photo_file_notes`, then :meth:`exif_note`
        (also under step 1's EXIF button) for an EXIF with a time and place: what it gives
        of the sun (no compass heading, a capture time at night, the heading from the sun in
        the frame). Without them the note only says why step 1's EXIF button is grey, true
        of most photos: "Photo notes" would never go away."""
        if self.step is Step.EMPTY:
            return []
        exif = self.exif_note(heading_box="in step 1") if self._exif_has_place() else ""
        return [*self._file_notes, *([exif] if exif else [])]

    def _update_photo_notes(self) -> None:
        """The status bar's "Photo notes": shown with any, which its tooltip holds; a warning
        sign for what the file's reading changed (transparency, a strip's shape), else an
        information sign."""
        notes = self.photo_notes()
        button = self.photo_notes_button
        button.setToolTip(photo_notes_html(notes))
        sign = (QStyle.StandardPixmap.SP_MessageBoxWarning if self._file_notes
                else QStyle.StandardPixmap.SP_MessageBoxInformation)
        button.setIcon(self.style().standardIcon(sign))
        button.setAccessibleDescription(" ".join(notes))
        button.setVisible(bool(notes))

    def show_photo_notes(self) -> None:
        """Show the photo's notes by the status bar's "Photo notes" (its click: the tooltip,
        without hovering)."""
        button = self.photo_notes_button
        if button.toolTip():
            QToolTip.showText(button.mapToGlobal(QPoint(0, 0)), button.toolTip(), button)

    def _heading_from_seen_sun(self, azimuth: float, elevation: float) -> float | None:
        """The compass heading the sun in the frame implies with the photo's GPS and time, put
        in step 1's heading box (it replaces the EXIF's, often wrong: the ski-slope sample's
        is off by about 126°), so that "Sun from EXIF" and the time-lapse's real sun path
        agree with the sun the photo shows; None without GPS and time."""
        from outcast_core.runtime.pipeline.timelapse import exif_heading_from_sun

        heading = exif_heading_from_sun(getattr(self.loaded, "exif", None), azimuth, elevation,
                                        tilt=self.camera_tilt[:2])
        if heading is None:
            return None
        self.seen_heading = round(heading, 1) % 360.0  # as the box shows it
        self.set_user_heading(self.seen_heading)
        return self.seen_heading

    def _exif_heading(self) -> float | None:
        """The compass heading the photo's EXIF records, or None."""
        heading = getattr(getattr(self.loaded, "exif", None), "heading_deg", None)
        return None if heading is None else float(heading) % 360.0

    @Slot(str)
    def _on_exposure_changed(self, mode: str) -> None:
        """Step 2's "Meter the new light" ticked or cleared: applied, and undoable."""
        self.set_exposure(mode)
        self._record()

    def set_exposure(self, mode: str, refresh: bool = True) -> None:
        """How relit photos are exposed (``"photo"`` or ``"metered"``): the checkbox and the
        session (relit images are cached per exposure, so no lock is waited for); with
        ``refresh``, the relit view and an open time-lapse preview are drawn again. Jobs take
        the exposure shown when they are asked for, not when they run."""
        if self.relight_panel.exposure() != mode:
            self.relight_panel.set_exposure(mode)
        if self.session is not None:
            self.session.exposure = mode
        if refresh:
            self._relight_for_light()

    @Slot(bool)
    def _on_daylight_changed(self, on: bool) -> None:
        """Step 2's "Keep the photo's light" cleared (``on``: the new sun's daylight) or
        ticked: applied, and undoable."""
        self.set_daylight(on)
        self._record()

    def set_daylight(self, on: bool, refresh: bool = True) -> None:
        """Whether relit photos take the new sun's daylight (``RelightSession.daylight``): the
        checkbox; with ``refresh``, the relit view and an open time-lapse preview are drawn
        again. As the exposure, jobs take the light shown when they are asked for; each sets
        it on the session as it starts, in the worker (the setter waits for the session's
        lock, which a relighting under way holds, and forgets the relit images kept)."""
        if self.relight_panel.daylight() != on:
            self.relight_panel.set_daylight(on)
        if refresh:
            self._relight_for_light()

    @Slot(str)
    def _on_relighting_changed(self, mode: str) -> None:
        """Step 2's "Relighting" chosen: applied, and undoable."""
        self.set_relighting(mode)
        self._record()

    def set_relighting(self, mode: str, refresh: bool = True) -> None:
        """How relit photos are made (``RelightSession.relight_mode``: ``"learned"`` or
        ``"physics"``): the user's choice, shown (physics while the learned relighting cannot
        run); with ``refresh``, the relit view and an open time-lapse preview are drawn again.
        As the light, jobs take the relighting shown when they are asked for and set it on the
        session in the worker (:class:`~app.state.RelitLook`)."""
        self.relighting_choice = mode
        shown = mode if self.relight_panel.learned_available() else "physics"
        if self.relight_panel.relighting() != shown:
            self.relight_panel.set_relighting(shown)
        self.mode_label.setText(self._mode_text())
        if refresh:
            self._relight_for_light()

    def _show_relighting(self, mode: str) -> None:
        """Step 2's relighting for a session just loaded (no job holds it): the user's
        choice ``mode``, shown and set on the session, or physics where the learned relighting
        cannot run (the greyed-out choice says why; the choice is kept, for the project and
        for a later session where it can)."""
        session = self.session
        assert session is not None
        why_not = ""
        if self.session_mode == "classic":
            why_not = ("Not available: OutCast runs with Direct shadows and physics relighting "
                       "(--classic, or a model that failed to load)")
        elif not session.registry.available("relight"):
            why_not = "Not available: the relighting model (models/relight.onnx) is not installed"
        self.relight_panel.set_learned_available(why_not)
        self.set_relighting(mode, refresh=False)
        shown = self.relight_panel.relighting()
        if session.relight_mode != shown:
            session.relight_mode = shown

    def _relight_for_light(self) -> None:
        """The exposure or the light changed: the relit view and an open time-lapse preview
        drawn again (in step 2)."""
        if self.step is Step.RELIGHT:
            self.request_relight(preview=False)
            self._refresh_timelapse_preview()

    @Slot(object, bool)
    def _on_heading_typed(self, heading: float | None, stepped: bool = False) -> None:
        """A heading typed (or cleared) in step 1: applied, and undoable; ``stepped`` (arrow
        keys, the box's arrows): a burst of steps is one undo step."""
        self.set_user_heading(heading)
        self._record(text="Camera heading", step_of="heading" if stepped else "")
        # What Find sun said of the heading, or of the ring to turn the sun around without
        # one, no longer holds (a user trial typed a heading and placed the EXIF sun, and the
        # notice still said to turn the sun around the ring).
        self._show_search_notice("")

    def set_user_heading(self, heading: float | None) -> None:
        """The camera heading typed in step 1 (degrees from true north; None: unknown, or the
        EXIF's when it records one). A typed heading replaces the EXIF's."""
        self.user_heading = None if heading is None else float(heading) % 360.0
        recorded = self._exif_heading()
        if (self.user_heading is not None and recorded is not None
                and abs(self.user_heading - recorded) < 0.05):  # the box shows one decimal
            self.user_heading = None  # the recorded one, as it is
        shown = self.user_heading if self.user_heading is not None else self._exif_heading()
        if self.align_panel.heading() != shown:
            self.align_panel.set_heading(shown, recorded=self.user_heading is None)
        else:
            self.align_panel.mark_heading(recorded=self.user_heading is None
                                          and shown is not None)
        self._update_exif_controls()

    # ---- automatic sun
    def toggle_find_sun(self) -> None:
        """Start finding the sun (a number still being typed taken in first), or cancel the
        search that runs. (Taken in before the check, a typed number cancelled the search as
        a move of the sun, and the button then started a new one: a review.)"""
        if self.finding_sun():
            self._cancel_find_sun()
            return
        self._commit_typed_fields()
        self.find_sun()

    def _cancel_find_sun(self) -> None:
        """Cancel the sun search; a result already on its way is not applied (its number is
        no longer the last), and the button says "Find sun" again at once (a search dropped
        before it started sends no "cancelled")."""
        self._searches += 1
        self.runner.cancel("find_sun")
        self.align_panel.set_finding(False)

    def finding_sun(self) -> bool:
        """Whether a sun search is waiting or running."""
        return any(ch == "find_sun" for _, ch, _ in self.runner.active())

    def find_sun(self) -> int | None:
        """Search for the photo's sun in the worker (progress in the status bar, cancellable);
        the result moves the sun (undoable) and shows the agreement on the dial."""
        session = self.session
        if (session is None or self.step is not Step.ALIGN
                or any(ch == "confirm" for _, ch, _ in self.runner.active())):
            return None  # (a confirm on its way: the step is about to change)
        prior = self.exif_prior()
        load = self._loads
        tilt = self.camera_tilt
        self._searches += 1
        search = self._searches
        dial_sun = self.align_panel.sun_panel.sun()  # (moved since: the result is dropped)

        def job(ctx: JobContext) -> dict[str, Any]:
            from outcast_core.runtime.pipeline.auto_sun import find_sun

            fit = find_sun(session, prior=prior, pitch_roll=tilt, progress=ctx.progress)
            return {"fit": fit, "prior": prior, "load": load, "search": search,
                    "dial_sun": dial_sun,
                    "timings": {**_timings(session), "find_sun": fit.seconds}}

        self.align_panel.set_finding(True)
        return self.runner.submit("find_sun", job, "Finding the sun")

    def _on_found_sun(self, result: dict[str, Any]) -> None:
        fit = result["fit"]
        self.align_panel.set_finding(False)
        if result.get("load", self._loads) != self._loads:
            return  # found for a photo that has been replaced since
        if result.get("search", self._searches) != self._searches or self.step is not Step.ALIGN:
            return  # the sun was confirmed while it searched: the confirmed one stands
        if not np.allclose(self.align_panel.sun_panel.sun(), result["dial_sun"], atol=1e-9):
            # Moved while it searched, by a way that does not cancel it (undo, redo): that
            # sun stands (a review; a move by hand or "Sun from EXIF" cancels the search).
            self.stage_label.setText("Find sun: not applied, the sun was moved while it ran")
            return
        self.sun_fit = fit
        m = fit.map
        dial = self.align_panel.sun_panel.dial
        if fit.found:
            dial.set_heat_map(m.azimuths.tolist(), m.elevations.tolist(),
                              m.normalised().tolist())
        else:  # no sun fits (the EXIF's placed or not): a map stretched to its full range
            dial.set_heat_map(None)  # would point at noise
        placed = fit.found or fit.source == SOURCE_EXIF  # the dial goes to the fit's sun
        notice_sun: tuple[float | None, float] | None = None
        if placed:
            self.align_panel.sun_panel.set_sun(fit.azimuth, fit.elevation)
            self.request_shadow(fit.azimuth, fit.elevation, preview=False)
            self._record(text="Find sun")
            # The dial's angles (the camera's frame) only: the EXIF's own are the horizon's.
            text = (f"Sun found: azimuth {fit.azimuth:.1f}°, elevation {fit.elevation:.1f}°, "
                    f"confidence {fit.confidence:.2f}")
            tilt = self.tilt_note()
            if fit.source == SOURCE_EXIF:
                text = (f"Sun from EXIF: azimuth {fit.azimuth:.1f}°, elevation "
                        f"{fit.elevation:.1f}°{f' for a {tilt}' if tilt else ''} (the photo's "
                        "shadows do not tell it; check it against them)")
            elif fit.source == SOURCE_SUN_IN_FRAME:  # exact: no prior had a say
                text = (f"Sun found in the frame: azimuth {fit.azimuth:.1f}°, elevation "
                        f"{fit.elevation:.1f}°")
                if fit.below_level > 0.0:  # (a user trial's sideways photo: 0° said no more)
                    from outcast_core.runtime.pipeline.auto_sun import below_level_words

                    words = below_level_words(fit.below_level)
                    text += f" · {words[0].upper()}{words[1:]}"
            elif fit.compass_decided:  # found in a cold cell of the dial: said first, why,
                # and the warm area ("Sun found" then "the compass chose it" read as a
                # contradiction: a user trial; the command line's note says it so too)
                map_az, map_el = m.best()
                text = (f"Sun placed by {self._heading_words()}: azimuth {fit.azimuth:.1f}°, "
                        f"elevation {fit.elevation:.1f}°, confidence {fit.confidence:.2f} "
                        "(the photo's shadows fit many suns about as well; alone they fit "
                        f"best near {map_az:.0f}°, {map_el:.0f}°: the warm area of the dial)")
                if result.get("prior") is not None:
                    text += f" · using {self._prior_words(result['prior'])}"
            elif result.get("prior") is not None:
                text += f" · using {self._prior_words(result['prior'])}"
        else:
            why = {
                "too-small": "This photo is too small or too narrow for its shadows to tell "
                             "the sun",
                "no-clear-shadows": "No clear shadows in this photo",
                "open-sky": "The suns its shadows fit best would stand in the photo's open "
                            "sky, which shows no sun (rough depth?)",
            }.get(fit.unfound, "No sun makes the predicted shadows fit the photo's (rough depth?)")
            text = (f"{why}: its sun cannot be told from them (confidence "
                    f"{fit.confidence:.2f}). Set it by eye.")
            prior = result.get("prior")
            if prior is not None:  # the EXIF's time and place still give the elevation
                from outcast_core.runtime.pipeline.auto_sun import at_true_elevation

                az, el = at_true_elevation(*self.align_panel.sun_panel.sun(), prior.elevation,
                                           self.camera_tilt[:2])
                el = dm.clamp_elevation(el)
                self.align_panel.sun_panel.set_sun(az, el)
                self.request_shadow(az, el, preview=False)
                self._record(text="Sun elevation from EXIF")
                # "Turn it around the ring": any azimuth at this height above the horizon.
                notice_sun = (None, self._above_horizon(az, el))
                tilt = self.tilt_note()
                where = (f"{el:.1f}° on the dial: {prior.elevation:.1f}° above the true "
                         f"horizon, from the photo's time and place, for a {tilt};" if tilt
                         else f"{el:.1f}°, from the photo's time and place;")
                text += (f" Its elevation is set to {where} turn the sun around the ring until "
                         "the shadows fit.")
        self.stage_label.setText(text)
        self._held_message = text if self._status_pending() else ""
        # Above the photo too where the user has something to check: no sun found, the
        # compass chose among near ties, or the EXIF's sun placed where the shadows tell
        # nothing (a user trial saw that last one only in the status bar, cut short).
        notice = (text if not placed or fit.compass_decided or fit.source == SOURCE_EXIF
                  or fit.below_level > 0.0 else "")
        prior = result.get("prior")
        if not notice and prior is not None and prior.azimuth is not None:
            off = dm.azimuth_gap(fit.azimuth, prior.azimuth)
            if off > 45.0:
                whose = ("the heading you typed" if self.user_heading is not None
                         else "the EXIF compass heading")
                notice = (f"The photo's shadows put the sun {off:.0f}° away from where {whose} "
                          "puts it: the heading may be wrong (\"Sun from photo's EXIF\" puts "
                          "the sun there; correct the Camera heading box).")
        self._show_search_notice(notice, (fit.azimuth, fit.elevation) if placed else notice_sun)

    def _show_search_notice(self, notice: str,
                            sun: tuple[float | None, float] | None = None) -> None:
        """Step 1's notice above the photo: what Find sun said (``""``: nothing, or no longer
        true), over the load's warning (the file, the depth source), which stays. ``sun``: the
        sun the notice speaks of (azimuth None: the elevation it set, the sun to be turned
        round that ring); it goes when the dial leaves it (:meth:`_drop_stale_search_notice`:
        a user trial's undo of Find sun left it); None: advice that holds anywhere."""
        self._notice_sun = sun if notice else None
        self.align_panel.show_notice("\n\n".join(t for t in (notice, self._load_notice) if t))

    def _drop_stale_search_notice(self, az: float, el: float) -> None:
        """Take down the search's notice about a found sun once the dial stands elsewhere (a
        ring's notice: once the sun is :data:`RING_NOTICE_TOL` off the ring, which a tilted
        camera sees at changing dial elevations; turning the sun round it by hand, as the
        notice says to, keeps it)."""
        said = self._notice_sun
        if said is None:
            return
        if said[0] is None:
            stays = dm.same_sun(said, (az, self._above_horizon(az, el)), tol=RING_NOTICE_TOL)
        else:
            stays = dm.same_sun(said, (az, el))
        if not stays:
            self._show_search_notice("")

    def _above_horizon(self, az: float, el: float) -> float:
        """A dial sun's elevation above the true horizon (the camera's tilt taken off)."""
        pitch, roll = self.camera_tilt[:2]
        return float(sun_angles(sun_vector(az, el), pitch, roll)[1])

    def _prior_words(self, prior: Any) -> str:
        """Where an EXIF prior comes from, in words without its angles (those are the
        horizon's; the dial shows the camera's)."""
        if prior.azimuth is None:
            return "the elevation from the photo's time and place"
        return f"the photo's time, place and {self._heading_words()}"

    def _heading_words(self) -> str:
        """What gave the EXIF sun's azimuth, in words: the photo's compass heading, the
        heading from the sun in the frame, or the one the user typed."""
        if self.user_heading is None:
            return "the compass heading"
        if self.seen_heading is not None and abs(self.user_heading - self.seen_heading) < 0.05:
            return "the heading from the sun in the frame"
        return "the heading you typed"

    @_typed_numbers_first
    def use_exif_sun(self) -> None:
        sun = self.exif_sun()
        if sun is None or self.step is not Step.ALIGN:
            return
        self._user_moved_sun()  # (a search running: the EXIF's sun is the one asked for)
        self.align_panel.sun_panel.set_sun(*sun)
        self.request_shadow(*sun, preview=False)
        self._record(text="Sun from EXIF")
        self._show_search_notice("")  # the search's sun (or its advice) is not on the dial now
        magnetic = self.user_heading is None and getattr(
            getattr(self.loaded, "exif", None), "heading_ref", None) == "M"  # the EXIF's
        note = "; the heading is magnetic, so allow for the local declination" if magnetic else ""
        tilt = self.tilt_note()
        text = (f"Sun from EXIF: azimuth {sun[0]:.1f}°, elevation {sun[1]:.1f}°"
                f"{f' for a {tilt}' if tilt else ''} (check it against the shadows{note})")
        self.stage_label.setText(text)
        # (past the overlay's "Ready")
        self._held_message = text if self._status_pending() else ""

    def _apply_project(self, project: ProjectState) -> None:
        self.preset = project.preset  # the session was created with it
        self.preset_combo.blockSignals(True)
        self.preset_combo.setCurrentIndex(PRESET_NAMES.index(project.preset))
        self.preset_combo.blockSignals(False)
        self.timelapse_settings = project.timelapse
        self.align_panel.opacity_slider.setValue(round(project.overlay_opacity * 100))
        self.relight_panel.split_slider.setValue(round(project.split * 100))
        self.relight_panel.set_view(project.buffer_view)
        self.set_user_heading(project.heading)
        self.relight_panel.set_exposure(project.exposure)
        self.session.exposure = project.exposure
        self.relight_panel.set_daylight(project.daylight)
        self.session.daylight = project.daylight  # (the session just loaded: no job holds it)
        self._show_relighting(project.relighting)
        confirmed = project.original_sun is not None and not project.realigning
        if confirmed:
            self.align_panel.sun_panel.set_sun(*project.original_sun.as_tuple())
        elif project.align_sun is not None:  # saved in step 1, before (re-)confirming
            self.align_panel.sun_panel.set_sun(*project.align_sun.as_tuple())
        elif project.original_sun is not None:  # re-aligning, the dial's sun not kept
            self.align_panel.sun_panel.set_sun(*project.original_sun.as_tuple())
        if project.target_sun is not None:
            self.relight_panel.sun_panel.set_sun(*project.target_sun.as_tuple())
        if confirmed:
            self.confirm_original_sun(keep_target=project.target_sun is not None)
        else:
            if project.realigning and project.original_sun is not None:
                # as "Re-align original sun" left it: the new sun is kept
                self.original_sun = project.original_sun
                self.relight_panel.sun_panel.dial.set_reference(project.original_sun.as_tuple())
            self.request_shadow(preview=False)

    def _save_recent(self) -> None:
        self.settings.setValue("recent", self.recent.paths())
        self._rebuild_recent_menu()

    # ---- drag and drop
    def dragEnterEvent(self, event: QDragEnterEvent) -> None:
        urls = event.mimeData().urls() if event.mimeData().hasUrls() else []
        if urls and urls[0].isLocalFile():
            event.acceptProposedAction()
        else:
            event.ignore()

    def dropEvent(self, event: QDropEvent) -> None:
        urls = event.mimeData().urls()
        if urls and urls[0].isLocalFile():
            self.open_path(urls[0].toLocalFile())
            event.acceptProposedAction()

    # ================================================================== presets
    def set_preset(self, name: str) -> None:
        if name not in PRESET_NAMES or name == self.preset:
            return
        self.preset = name
        idx = PRESET_NAMES.index(name)
        if self.preset_combo.currentIndex() != idx:
            self.preset_combo.blockSignals(True)
            self.preset_combo.setCurrentIndex(idx)
            self.preset_combo.blockSignals(False)
        session = self.session
        if session is None:
            return

        edits = self.shadow_edits

        def job(ctx: JobContext) -> dict[str, Any]:
            session.set_shadow_edits(edits)  # before the found shadows are redone at its size
            redo = session.original_sun is not None  # (its shadows, at the new working size)
            session.set_preset(name, progress=session_progress(
                ctx, REDO_STAGE if redo else TILT_STAGE, 0.7 if redo else 0.9))
            if redo:
                ctx.progress(TILT_STAGE, 0.95)
            tilt = session.photo_tilt()  # this preset's depth: its ground plane
            return {"timings": _timings(session), "tilt": tilt, "session": session}

        self.runner.submit("preset", job, f"Switching to {name}")
        self._refresh_view()
        self._record()

    def _refresh_view(self) -> None:
        if self.step is Step.ALIGN:
            self.request_shadow(preview=False)
        elif self.step is Step.RELIGHT:
            self.request_relight(preview=False)

    # ================================================================== step 1
    def _on_original_sun_committed(self, az: float, el: float) -> None:
        self._user_moved_sun()
        self.request_shadow(az, el, False)
        self._record()

    def _user_moved_sun(self) -> None:
        """The user moved step 1's sun (the dial, its keys or the number fields; the search's
        and undo's moves emit nothing): a running Find sun is cancelled, as Confirm cancels
        it, and the user's sun stands (a user trial dragged during the search and the dial
        jumped to the found sun when it ended)."""
        if self.finding_sun():
            self._cancel_find_sun()

    def _on_target_sun_committed(self, az: float, el: float) -> None:
        self.request_relight(az, el, False)
        self._record()

    def _on_original_sun_changed(self, az: float, el: float, preview: bool) -> None:
        self._user_moved_sun()
        if preview:
            self.request_shadow(az, el, True)

    def request_shadow(
        self, az: float | None = None, el: float | None = None, preview: bool = False
    ) -> int | None:
        """Predict shadows for the original sun; a newer request replaces a waiting one."""
        session = self.session
        if session is None or self.step is not Step.ALIGN:
            return None
        if az is None or el is None:
            az, el = self.align_panel.sun_panel.sun()
        self._drop_stale_search_notice(az, el)  # every move of step 1's sun comes here

        def job(ctx: JobContext) -> dict[str, Any]:
            w = sun_vector(az, el)
            shadow = session.shadow(w, preview=preview)
            cos = cosine_term(session.normals, w) if session.normals is not None else None
            if cos is not None and cos.shape != shadow.shape:
                cos = None
            rgba = display.shadow_overlay_rgba(shadow, session.sky, cos)
            return {"sun": (az, el), "preview": preview, "overlay": rgba,
                    "timings": _timings(session)}  # fmt: skip

        return self.runner.submit("shadow", job, "Predicting shadows")

    def _on_shadow(self, result: dict[str, Any]) -> None:
        if self.step is Step.ALIGN:
            self.canvas.set_overlay(qimage_from_array(result["overlay"]))

    @_typed_numbers_first
    def _confirm_clicked(self) -> None:
        self.confirm_original_sun()

    def confirm_original_sun(self, keep_target: bool = False) -> None:
        """Fix the original sun and compute its refined shadow (step 1 -> step 2)."""
        session = self.session
        if session is None:
            return
        az, el = self.align_panel.sun_panel.sun()
        if self.finding_sun():  # the sun on the dial is the one confirmed, not the search's
            self._cancel_find_sun()
        # A new sun chosen in step 2 survives a re-alignment of the original sun.
        keep_target = keep_target or self.original_sun is not None
        current = self.edit_state()
        if current is not None:
            target = current.target_sun if keep_target else (az, el)
            self._record(replace(current, step="relight", align_sun=(az, el),
                                 original_sun=(az, el), target_sun=target))  # fmt: skip
        edits = self.shadow_edits
        look = self.relight_panel.look()

        def job(ctx: JobContext) -> dict[str, Any]:
            ctx.progress("refining", 0.1)
            session.set_shadow_edits(edits)  # (applied by set_original_sun)
            session.set_original_sun(sun_vector(az, el))
            look.apply(session)  # the preview is made ready for its relighting
            session.prepare_relight_preview()  # so the first drag in step 2 is as quick
            return {"sun": (az, el), "keep_target": keep_target, "timings": _timings(session)}

        self.runner.cancel("shadow")
        self.runner.submit("confirm", job, "Refining the original shadows")

    def _on_confirmed(self, result: dict[str, Any]) -> None:
        az, el = result["sun"]
        self.original_sun = Sun(az, el)
        rp = self.relight_panel.sun_panel
        rp.dial.set_reference((az, el))
        if not result["keep_target"]:
            rp.set_sun(az, el)
        self._set_step(Step.RELIGHT)
        self.request_relight(preview=False)

    def back_to_align(self) -> None:
        """Step 2 -> step 1: align the original sun again (the new sun is kept)."""
        if self.step is not Step.RELIGHT:
            return
        self._set_step(Step.ALIGN)
        self.request_shadow(preview=False)
        self._record()

    # ================================================================== step 2
    def _on_target_sun_changed(self, az: float, el: float, preview: bool) -> None:
        if preview:
            self.request_relight(az, el, True)

    def _on_view_changed(self, _index: int) -> None:
        self.relight_panel.split_slider.setEnabled(self.relight_panel.view() in SPLIT_VIEWS)
        self._update_shadow_tools()
        self._shadow_tools_into_view()
        self.request_relight(preview=False)

    def _shadow_tools_into_view(self) -> None:
        """The shadow tools, where they are available, scrolled into the side panel's view once
        laid out: they appear below the dial (on a small screen they were below the fold when
        the view was chosen, and again after the window was made smaller: user trials)."""
        if getattr(self, "relight_panel", None) is not None and self.shadow_tools_available():
            QTimer.singleShot(0, lambda: self.side_scroll.ensureWidgetVisible(
                self.relight_panel.shadow_tools, 0, 6))

    def resizeEvent(self, event: Any) -> None:  # noqa: N802 (Qt's name)
        super().resizeEvent(event)
        if event.size().height() < event.oldSize().height():  # (made smaller only: a user
            self._shadow_tools_into_view()  # who scrolled to the dial is not pulled back)

    # ---- correcting the found shadows
    def shadow_tools_available(self) -> bool:
        """Whether the shadow corrections can be made now: step 2, in a view of the photo's
        own shadows ("Shadows found", "Shadows removed")."""
        return (self.step is Step.RELIGHT and self.session is not None
                and self.relight_panel.view() in DESHADOW_VIEWS)

    def _update_shadow_tools(self) -> None:
        """Show the correction tools in the views they work in; elsewhere hide them, off."""
        available = self.shadow_tools_available()
        self.relight_panel.show_shadow_tools(available)
        self.act_brush_smaller.setEnabled(available)
        self.act_brush_larger.setEnabled(available)

    @Slot(float)
    def _on_brush_changed(self, radius: float) -> None:
        """The brush's size: the canvas's circle, remembered in the settings (in %)."""
        self.canvas.set_brush(radius)
        self.settings.setValue("brush_size", round(100.0 * radius, 2))

    @Slot(str)
    def _on_shadow_tool_changed(self, tool: str) -> None:
        """A correction tool turned on or off: the canvas's clicks and cursor, Esc, the hint."""
        on = bool(tool) and self.shadow_tools_available()
        self.canvas.set_click_tool(on)
        self.act_end_shadow_tool.setEnabled(on)
        if on:
            self.canvas.set_brush(self.relight_panel.brush(), BRUSH_COLOURS[tool],
                                  BRUSH_SOFTNESS[tool])
            self.stage_label.setText(SHADOW_TOOL_HINTS[tool])
            self.canvas.setFocus()  # Esc reaches the window's action from here
        elif not self._status_pending():
            self.stage_label.setText("Ready")

    def _step_brush(self, steps: int) -> None:
        """``[`` / ``]``: the brush a step smaller or larger, said in the status bar (only the
        spin box beside the tools changed, out of sight while one looks at the photo: a user
        trial)."""
        self.relight_panel.step_brush(steps)
        if self._status_pending():  # a job's status stays (as the tool hint leaves it)
            return
        self.stage_label.setText(
            f"Brush {self.relight_panel.brush_box.value():.1f} % of the photo's longer side"
            " · [ smaller, ] larger")

    def _status_jobs(self) -> set[int]:
        """The jobs waiting or running that say their end in the status bar."""
        return {i for i, ch, _ in self.runner.active() if self._says_status(ch)}

    def _undo_step(self, step: Callable[[], None], redo: bool = False) -> None:
        """Undo or redo (``step``; ``redo``: which), unless a brush stroke is being painted:
        then that stroke is cancelled, as Esc does, and nothing else happens. The status bar
        says what was undone or redone until a job the step started says what it did: a
        view kept from before (a de-shadowed photo) comes back at once, and the status kept
        the timing of the job the step undid (a user trial)."""
        if self.canvas.cancel_stroke():
            self.stage_label.setText("Stroke cancelled")
            return
        text = self.undo_stack.redoText() if redo else self.undo_stack.undoText()
        self._undo_note = None
        before = self._status_jobs()
        step()
        if text:
            note = f"{'Redone' if redo else 'Undone'} · {text}"
            self.stage_label.setText(note)
            # The jobs the step started say their end after it ("Undone · Confirm original
            # sun · predicting shadows took 0.01 s"): a user trial's undo went back to step 1
            # and the status said only the new job's timing. A step that started none (a
            # kept view) while others run: theirs says it alone when they end.
            started = self._status_jobs() - before
            if started:
                self._undo_note = (note, started, True)
            elif before:
                self._undo_note = (note, before, False)

    @Slot(float, float)
    def _on_canvas_clicked(self, x: float, y: float) -> None:
        tool = self.relight_panel.shadow_tool()
        if tool and self.shadow_tools_available():
            self.add_shadow_edit(x, y, shadow=tool == "shadow")

    @Slot(object, float)
    def _on_canvas_stroke(self, points: list[tuple[float, float]], radius: float) -> None:
        tool = self.relight_panel.shadow_tool()
        if tool and self.shadow_tools_available():  # (the radius the canvas spaced them for)
            self.add_shadow_stroke(points, shadow=tool == "shadow", radius=radius)

    def add_shadow_edit(self, x: float, y: float, shadow: bool) -> bool:
        """Correct the found shadows at the photo's point ``(x, y)`` (fractions of its width and
        height): ``shadow`` True, "this is a shadow"; False, "not a shadow". Undoable; the
        view is redrawn in the worker.

        Returns:
            Whether the correction was made (not outside the photo, not past
            :func:`~outcast_core.runtime.pipeline.photo_shadows.shadow_edit_limit`'s limits:
            the status bar says which).
        """
        if not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0):
            return False
        return self._add_shadow_edits((ShadowEdit(float(x), float(y), shadow),))

    def add_shadow_stroke(self, points: Iterable[tuple[float, float]], shadow: bool,
                          radius: float | None = None) -> bool:
        """Paint a brush stroke on the found shadows: a dab at each of ``points`` (fractions of
        the photo's width and height; those outside it left out) of ``radius`` (a fraction of
        the longer side; default: the panel's brush). "Not a shadow" drops all the brush
        covers where it holds a found shadow; "a shadow" adds the shadow under the stroke (its
        darker pixels; nothing on lit ground). One undo step, however many dabs; its first dab
        is marked as a stroke's start (so a stroke begun where the last ended is another).

        Returns:
            Whether the stroke was made (see :meth:`add_shadow_edit`).
        """
        radius = self.relight_panel.brush() if radius is None else float(radius)
        inside = [(float(x), float(y)) for x, y in points if 0.0 <= x <= 1.0 and 0.0 <= y <= 1.0]
        dabs = tuple(ShadowEdit(x, y, shadow, radius, start=i == 0)
                     for i, (x, y) in enumerate(inside))
        return self._add_shadow_edits(dabs)

    def _add_shadow_edits(self, new: tuple[ShadowEdit, ...]) -> bool:
        """Add a click's edit or a stroke's dabs to the corrections, as one undo step."""
        if not self.shadow_tools_available() or not new:
            return False
        if limit := shadow_edit_limit((*self.shadow_edits, *new)):
            self.stage_label.setText(f"{limit[:1].upper()}{limit[1:]}: clear the corrections "
                                     "or undo some first")
            return False
        self._edit_just_added = len(new)  # (read by the found-shadows job this submits)
        # Brought into view once the worker has made it, if it changed anything (set before
        # the job is submitted: its result must find it).
        self._edit_to_show = new if self.relight_panel.view() == "shadows_removed" else ()
        try:
            self.set_shadow_edits((*self.shadow_edits, *new), made=True)
        finally:
            self._edit_just_added = 0
        # What redo offered: this step replaces it, and gives it back if it changed nothing
        # (:meth:`_drop_idle_edit`; a user trial's idle click lost the redo of a correction).
        stack = self.undo_stack
        redo = [stack.command(i) for i in range(stack.index(), stack.count())]
        self._redo_before_edit = [(c.before, c.after, c.text()) for c in redo
                                  if isinstance(c, EditCommand)]
        self._record(text=shadow_edit_text(self.shadow_edits))
        return True

    def _show_correction_side(self, new: tuple[ShadowEdit, ...]) -> bool:
        """In "Shadows removed", a correction made wholly on the original's side of the
        before | after line would show no change (a user trial painted there and saw nothing
        happen): the line moves to just left of it, never closer to the photo's left edge
        than :data:`SPLIT_LEAST` (the original stays in view). Returns whether it moved."""
        rp = self.relight_panel
        rect = self.canvas.image_rect()
        if not new or rp.view() != "shadows_removed" or rect.width() <= 0:
            return False
        reach = max(rect.width(), rect.height()) / rect.width()  # radius -> width fraction
        right = max(e.x + e.radius * reach for e in new)
        left = min(e.x - e.radius * reach for e in new) - SPLIT_MARGIN
        value = max(round(100.0 * SPLIT_LEAST), math.floor(100.0 * left))
        # Not when it reaches the de-shadowed side, nor when it lies wholly left of
        # SPLIT_LEAST (moving would not show it either).
        if right >= rp.split_slider.value() / 100.0 or right <= value / 100.0:
            return False
        rp.split_slider.setValue(value)
        return True

    def _drop_idle_edit(self, idle: tuple[ShadowEdit, ...]) -> None:
        """Take back the click or the stroke that changed nothing (the last corrections, still
        the last undo step): not counted, not an undo step, no unsaved change (a user
        trial)."""
        stack = self.undo_stack
        top = stack.command(stack.index() - 1) if stack.index() > 0 else None
        n = len(idle)
        edits = self.shadow_edits
        if (not n or len(edits) < n or edits[-n:] != idle
                or stack.index() != stack.count() or not isinstance(top, EditCommand)
                or top.after != self._edit_state
                or top.before != replace(top.after, shadow_edits=edits[:-n])):
            return  # the last step is not that click or stroke alone (a sun moved since)
        before = top.before  # (Qt deletes the command in undo())
        top.setObsolete(True)
        stack.undo()  # an obsolete command is removed, not undone
        self._edit_state = before
        self._show_shadow_edits(before.shadow_edits)
        self._deshadow_key = self._deshadow_key_now()  # the images shown are the same
        self._restore_redo(before)
        self._update_title()

    def _restore_redo(self, now: EditState) -> None:
        """Put back the redo steps the idle click or stroke replaced (its push dropped them):
        pushed as done (their first redo does nothing), then undone without being shown, so
        the stack stands where it stood, with them to redo."""
        saved, self._redo_before_edit = self._redo_before_edit, []
        stack = self.undo_stack
        if not saved or saved[0][0] != now or stack.index() != stack.count():
            return
        for before, after, text in saved:
            stack.push(EditCommand(self, before, after, text))  # (never merged: no step_of)
        self._applying_redo_back = True
        try:
            for _ in saved:
                stack.undo()
        finally:
            self._applying_redo_back = False

    def clear_shadow_edits(self) -> None:
        """Take back every correction of the found shadows (one undo step)."""
        if not self.shadow_edits:
            return
        self.set_shadow_edits((), made=True)
        self._record(text=shadow_edit_text(()))

    def set_shadow_edits(self, edits: tuple[ShadowEdit, ...], made: bool = False) -> None:
        """Use ``edits`` as the photo's shadow corrections (records nothing) and draw what
        depends on them again: the step-2 view and an open time-lapse preview. ``made``: the
        user's click, stroke or clear made them (its result says so; an undo's does not)."""
        edits = tuple(edits)
        self._edit_made = edits if made else None
        if edits == self.shadow_edits:
            return
        self._show_shadow_edits(edits)
        if self.step is Step.RELIGHT:
            self.request_relight(preview=False)
            self._refresh_timelapse_preview()

    def _show_shadow_edits(self, edits: tuple[ShadowEdit, ...]) -> None:
        """The corrections, and their count in the panel (clicks and strokes, not dabs); no
        job (the next ones take them)."""
        self.shadow_edits = tuple(edits)
        photo = self._photo_qimage
        shape = (1, 1) if photo is None else (photo.height(), photo.width())
        self.relight_panel.set_shadow_edit_count(
            len(shadow_edit_strokes(self.shadow_edits, shape)))

    def _refresh_timelapse_preview(self) -> None:
        dialog = self._timelapse_dialog
        if dialog is not None and dialog.isVisible():
            dialog.refresh_preview()

    def _on_split_changed(self, value: int) -> None:
        view = self.relight_panel.view()
        self.relight_panel.split_slider.setEnabled(view in SPLIT_VIEWS)
        if self.step is Step.RELIGHT and view in SPLIT_VIEWS:
            after = self._after_label if view == "output" else "Shadows removed"
            self.canvas.set_split(value / 100.0, ("Original", after))

    def request_relight(
        self, az: float | None = None, el: float | None = None, preview: bool = False
    ) -> int | None:
        """Render the step-2 view for the target sun (relit photo or buffers)."""
        session = self.session
        if session is None or self.step is not Step.RELIGHT:
            return None
        view = self.relight_panel.view()
        if view in DESHADOW_VIEWS:
            return self.request_deshadow()
        if az is None or el is None:
            az, el = self.relight_panel.sun_panel.sun()
        look = self.relight_panel.look()
        exposure = look.exposure
        edits = self.shadow_edits

        def job(ctx: JobContext) -> dict[str, Any]:
            session.set_shadow_edits(edits)  # what lifts the photo's shadows
            look.apply(session)  # (in the worker: set_daylight, set_relighting)
            w = sun_vector(az, el)
            if view == "output":
                # While dragging: the working-size preview. On release: full resolution, so the
                # relit side of the split is as sharp as the photo.
                relit = (session.relight(w, preview=True, exposure=exposure) if preview
                         else session.relight_full(w, dtype=np.uint8, exposure=exposure))
                img = display.to_uint8_rgb(relit)
                level = None  # how much the new light changes the level at the photo's exposure
                if not preview and exposure == "photo":
                    from outcast_core.runtime.pipeline.relight import exposure_level

                    level = exposure_level(session.image_srgb,
                                           session.relight(w, exposure=exposure))  # cached
                return {"view": view, "image": img, "preview": preview, "level": level,
                        "timings": _timings(session)}  # fmt: skip
            bufs = session.buffers(w)
            tiles = {k: display.buffer_to_rgb(k, v, session.sky) for k, v in bufs.items()}
            tiles["input"] = display.to_uint8_rgb(session.image_srgb)
            return {"view": view, "tiles": tiles, "timings": _timings(session)}

        return self.runner.submit("relight", job, "Relighting")

    def request_deshadow(self) -> int | None:
        """Show the photo with its own shadows removed, or the shadows found (step-2 views).

        Computed in the worker once per photo, original sun, preset and shadow corrections (the
        found shadows' overlay always, cheap; the de-shadowed photo, at full resolution, for
        "Shadows removed" only); later requests show the kept images at once.

        Returns:
            The job's id, or ``None`` when nothing had to be computed.
        """
        session, key = self.session, self._deshadow_key_now()
        if session is None or key is None or self.step is not Step.RELIGHT:
            return None
        view = self.relight_panel.view()
        with_image = view == "shadows_removed"
        # A correction just made takes the job even when its images are kept (the same click
        # again after an undo): the job says what it did (nothing, or much: a review).
        kept = None if self._edit_just_added else self._deshadow_kept.get(key)
        if kept is not None and (kept[0] is not None or not with_image):
            self._deshadow_kept.move_to_end(key)
            self._deshadow_key, self._deshadow_images = key, kept
            self._edit_note = ""
            self._show_deshadow(view)  # (every job hands the session its own corrections)
            made, self._edit_made = self._edit_made, None
            if not self._status_pending():  # (an undo says itself after this)
                # Not the timing of the job shown before: what the correction just made did
                # (images kept: "Clear corrections" back to none), or what the tool that is
                # on does.
                tool = self.relight_panel.shadow_tool()
                self.stage_label.setText(
                    f"Ready · {edit_done_note(made)}" if made == self.shadow_edits
                    else SHADOW_TOOL_HINTS[tool] if tool else "Ready")
            return None
        if self._deshadow_job is not None:
            job_key, job_with_image, job_id = self._deshadow_job
            if job_key == key and (job_with_image or not with_image):
                waiting = self.runner.latest("relight") == job_id
                if waiting and any(i == job_id for i, _, _ in self.runner.active()):
                    return job_id  # already on its way (the new sun moved: nothing else to do)
        edits, just_added = self.shadow_edits, self._edit_just_added
        # The correction this job shows, if the user's (its result says what it did; a later
        # job, after a view switch or a sun move, says nothing of it: a review).
        made, self._edit_made = self._edit_made, None

        def job(ctx: JobContext) -> dict[str, Any]:
            click = bool(just_added) and edits[-1].shadow and edits[-1].radius == 0
            # What was marked before the click (measured: after an undo the session may
            # still hold the undone edit).
            marked = session.marked_share(edits[:-just_added]) if click else 0.0
            found = session.shadow_probability
            session.set_shadow_edits(edits)
            after = session.shadow_probability
            marked = session.marked_share() - marked  # what the click just marked
            # The correction just made (a click, or every dab of a stroke) changed nothing (no
            # found shadow near a "not a shadow" click, the sky or a shadow already under a
            # "mark shadow" one): said after Ready.
            used = session.shadow_edits_used
            idle_edits = (edits[-just_added:] if just_added and len(used) == len(edits)
                          and not any(used[-just_added:]) else None)
            # What the de-shadow lifts (the probability alone tinted a thin trunk's shadow
            # that the lift left dark: a user trial).
            overlay = display.found_shadow_overlay_rgba(session.lifted_shadows(), session.sky)
            image = None
            if with_image:
                ctx.progress("removing shadows", 0.1)
                image = display.to_uint8_rgb(session.deshadow_full(dtype=np.uint8))
            # Shown as found when the sun was confirmed, nothing redone: no timing to report.
            computed = with_image or after is not found
            return {"view": view, "key": key, "image": image, "overlay": overlay,
                    "idle_edits": idle_edits, "computed": computed,
                    "large_mark": marked if click and marked > LARGE_MARK_SHARE else 0.0,
                    "made": made, "timings": _timings(session)}  # fmt: skip

        words = "Removing the photo's shadows" if with_image else "Finding the photo's shadows"
        job_id = self.runner.submit("relight", job, words)
        self._deshadow_job = (key, with_image, job_id)
        if with_image:
            self._label_pending_removal()
        return job_id

    def _label_pending_removal(self) -> None:
        """Until the de-shadowed photo comes, the split's label says what the canvas still
        shows: a user trial read the relit photo as "Shadows removed" for the 8 s a 27 MP
        photo took (its result puts the view's own labels back)."""
        if self.canvas.after() is None or self.canvas.split() is None:
            return
        kept = self._deshadow_images[0] if self._deshadow_images is not None else None
        shown = ("Shadows removed · updating…" if self.canvas.after() is kept
                 else f"{self._after_label} · removing shadows…")
        self.canvas.set_split(self.canvas.split(), ("Original", shown))

    def _deshadow_key_now(self) -> tuple[Any, ...] | None:
        """What the deshadow views' images depend on: the session, the original sun, the preset
        and the shadow corrections."""
        if self.session is None or self.original_sun is None:
            return None
        return self._loads, self.original_sun.as_tuple(), self.preset, self.shadow_edits

    @staticmethod
    def _idle_note(edit: ShadowEdit) -> str:
        """What to say of a click or a stroke (``edit``, its last dab) that changed nothing."""
        if edit.radius > 0:
            return ("no shadow under the stroke (lit ground, the sky, or found or painted "
                    "already): paint over a shadow the app missed, or click inside a found one "
                    "to lift it to the lit ground round it" if edit.shadow else
                    "no found shadow under the stroke: paint over the magenta area of "
                    "\"Shadows found\"")
        return ("nothing was added there (the sky, lit ground, or a shadow already): click "
                "inside a shadow the app missed" if edit.shadow else
                "no found shadow there: click on the magenta area of \"Shadows found\"")

    def _keep_deshadow(self, key: tuple[Any, ...], image: QImage | None,
                       overlay: QImage) -> tuple[QImage | None, QImage]:
        """Keep a deshadow result (with the de-shadowed photo already kept for ``key`` when this
        one has none), within :data:`DESHADOW_KEEP_BYTES` besides the shown images."""
        old = self._deshadow_kept.pop(key, None)
        if image is None and old is not None:
            image = old[0]
        entry = (image, overlay)
        self._deshadow_kept[key] = entry

        def size(e: tuple[QImage | None, QImage]) -> int:
            return sum(int(i.sizeInBytes()) for i in e if i is not None)

        shown = self._deshadow_key
        others = [k for k in self._deshadow_kept if k not in (key, shown)]
        total = sum(size(self._deshadow_kept[k]) for k in others)
        for k in others:  # the oldest first
            if total <= DESHADOW_KEEP_BYTES:
                break
            total -= size(self._deshadow_kept.pop(k))
        return entry

    def _show_deshadow(self, view: str) -> None:
        """Put the kept de-shadowed photo (split with the original) or the found shadows up."""
        if self._deshadow_images is None:
            return
        image, overlay = self._deshadow_images
        self._photo_as_base()
        if view == "shadows_removed":
            if image is None:  # (only the overlay is kept: asked for by the other view)
                return
            self.canvas.set_overlay(None)
            self.canvas.set_after(image)
            self._on_split_changed(self.relight_panel.split_slider.value())
        else:
            self.canvas.set_after(None)
            self.canvas.set_split(None)
            self.canvas.set_overlay(overlay, least_opacity=FOUND_LEAST_OPACITY)

    def _photo_as_base(self) -> None:
        """The photo back as the canvas's image (after a buffer view), keeping the zoom when
        the shown image had the photo's size, fitting it when not (a user trial came back
        from the 256-px depth view at 414 %, the photo's top-left corner filling the view)."""
        photo, shown = self._photo_qimage, self.canvas.before()
        if photo is None or shown is photo:
            return
        self.canvas.set_image(photo, fit=shown is None or shown.size() != photo.size())

    def _on_relit(self, result: dict[str, Any]) -> None:
        view = result["view"]
        self._edit_done = ""  # (said by this result only, whatever it shows: a review)
        entry = None
        if view in DESHADOW_VIEWS and result["key"][0] == self._loads:  # (not another photo's)
            # Kept even when not shown now: for undo and redo, and the other deshadow view.
            image = result["image"]
            entry = self._keep_deshadow(
                result["key"], None if image is None else qimage_from_array(image),
                qimage_from_array(result["overlay"]))
        if self.step is not Step.RELIGHT:
            return
        if view != self.relight_panel.view():
            return  # the user chose another view since; its own request is on the way
        self._exposure_hint = self._edit_note = ""  # said only after the image it is about
        if view in DESHADOW_VIEWS:
            key = result["key"]
            if entry is None or key != self._deshadow_key_now():
                return  # for a photo, sun, preset or correction that has changed since
            self._deshadow_key, self._deshadow_images = key, entry
            idle = result.get("idle_edits")
            self._edit_note = "" if not idle else self._idle_note(idle[-1])
            self._show_deshadow(view)
            shown, self._edit_to_show = self._edit_to_show, ()
            if idle is not None:
                self._drop_idle_edit(idle)
            elif shown and self.shadow_edits[-len(shown):] == shown and (
                    self._show_correction_side(shown)):
                self._edit_note = "the before | after line moved left to show the correction"
            marked = float(result.get("large_mark", 0.0))
            if idle is None and marked > 0.0:
                # (short: whole in the status bar at 1024 px, a user trial; before the line's
                # note when the line moved too)
                self._edit_note = " · ".join(n for n in (
                    f"marked {marked * 100:.0f} % of the photo as shadow · Ctrl+Z takes it back",
                    self._edit_note) if n)
            made = result.get("made")
            if idle is None and made is not None and made == self.shadow_edits:
                # What the click, stroke or clear did, said in place of the tool's hint (a
                # user trial's "Not a shadow" click and "Clear corrections" left only it).
                self._edit_done = edit_done_note(made)
            return
        if view == "output":
            self._exposure_hint = "" if result.get("preview") else exposure_hint(
                result.get("level"))
            self._photo_as_base()
            self.canvas.set_overlay(None)
            self.canvas.set_after(qimage_from_array(result["image"]))
            self._after_label = "Relit · preview" if result.get("preview") else "Relit"
            self._on_split_changed(self.relight_panel.split_slider.value())
            return
        tiles = result["tiles"]
        image = self._montage(tiles) if view == "all" else qimage_from_array(tiles[view])
        same_size = self.canvas.before() is not None and self.canvas.before().size() == image.size()
        self.canvas.set_image(image, fit=not same_size)

    @staticmethod
    def _montage(tiles: dict[str, np.ndarray]) -> QImage:
        """The paper-figure grid: input, depth, normals / original shadow, new shadow, output."""
        order = ["input", "depth", "normals", "original_shadow", "new_shadow", "output"]
        first = tiles[order[0]]
        h, w = first.shape[:2]
        gap, label_h, cols = 6, 22, 3
        rows = 2
        out = QImage(
            cols * w + (cols - 1) * gap, rows * (h + label_h) + gap, QImage.Format.Format_RGB888
        )
        out.fill(QColor(30, 30, 32))
        p = QPainter(out)
        font = QFont()
        font.setPixelSize(14)
        p.setFont(font)
        for k, name in enumerate(order):
            r, c = divmod(k, cols)
            x, y = c * (w + gap), r * (h + label_h + gap)
            p.setPen(QColor(235, 235, 235))
            p.drawText(x + 2, y + label_h - 6, display.BUFFER_TITLES[name])
            p.drawImage(x, y + label_h, qimage_from_array(tiles[name]))
        p.end()
        return out

    # ================================================================== export still
    @_typed_numbers_first
    def export_still_dialog(self) -> None:
        if self.step is not Step.RELIGHT:
            return
        stem = Path(self.image_path).stem
        az, el = self.relight_panel.sun_panel.sun()
        path = self._ask_still_path("Export relit photo", f"{stem}_relit_az{az:.0f}_el{el:.0f}")
        if path:
            self.export_still(path, force=True)

    def export_folder(self) -> str:
        """Where export dialogs open: the folder of the last still or time-lapse exported
        (when it still exists), else the photo's."""
        folder = str(self.settings.value("export_folder", "") or "")
        if not folder or not os.path.isdir(folder):
            folder = str(Path(self.image_path).parent)
        return folder

    def remember_export_folder(self, path: str) -> None:
        """Export dialogs open in ``path``'s folder from now on (:meth:`export_folder`)."""
        self.settings.setValue("export_folder", str(Path(path).parent))

    def _ask_still_path(self, title: str, name: str) -> str | None:
        """Where to write a still named ``name`` (without its extension; None: cancelled). The
        dialog opens in the folder of the last still exported, with its type (a user trial:
        it always offered a PNG beside the photo), else beside the photo as a PNG. The file
        dialog asks before replacing an existing file, so a confirmed name may be
        overwritten; a name typed without an extension takes the chosen type's, asked about
        again when that file exists (:meth:`may_write_completed`); nothing is ever replaced
        without a question."""
        filters = STILL_FILTERS.split(";;")
        folder = self.export_folder()
        kind = str(self.settings.value("export_filter", "") or "")
        kind = kind if kind in filters else filters[0]
        suggestion = with_filter_extension(str(Path(folder) / name), kind, ())
        typed, chosen = QFileDialog.getSaveFileName(self, title, suggestion, STILL_FILTERS, kind)
        if not typed:
            return None
        from outcast_core.runtime.io.imageio import WRITE_EXTENSIONS

        path = with_filter_extension(typed, chosen or kind, WRITE_EXTENSIONS)
        if not self.may_write_completed(typed, path):
            return None
        self.remember_export_folder(path)
        self.settings.setValue("export_filter", next(
            (f for f in filters if f"*{Path(path).suffix.lower()}" in f), kind))
        return path

    def may_write_completed(self, typed: str, path: str) -> bool:
        """Whether an export may write ``path``, the name ``typed`` in a save dialog with an
        extension the app added: the dialog asked only about ``typed``, so an existing
        ``path`` is replaced only when the user says so (:func:`~app.leave_prompts.
        replace_file_question`). The photo itself is not asked about: the export refuses it."""
        if path == typed or not os.path.exists(path) or self.own_file_error(path) is not None:
            return True
        return self.ask(replace_file_question(path)) == REPLACE

    def export_still(self, path: str, force: bool = False) -> int | None:
        """Relight at full resolution and write PNG, JPEG or 16-bit TIFF (atomic); a PNG of a
        16-bit photo is 16-bit too."""
        from outcast_core.runtime.io.imageio import output_bit_depth

        session = self.session
        if session is None or self.step is not Step.RELIGHT:
            return None
        w = sun_vector(*self.relight_panel.sun_panel.sun())
        look = self.relight_panel.look()  # as asked, whatever is ticked later
        bits = output_bit_depth(path, getattr(self.loaded, "bit_depth", 8))
        dtype = np.float32 if bits == 16 else np.uint8

        def render() -> np.ndarray:
            look.apply(session)  # (in the worker: set_daylight, set_relighting)
            return session.relight_full(w, dtype=dtype, exposure=look.exposure)

        return self._export_image(
            "export_still", path, force, render, "relighting at full resolution",
        )  # fmt: skip

    @_typed_numbers_first
    def export_shadows_removed_dialog(self) -> None:
        """Ask where to write the photo with its own shadows removed, then export it."""
        if self.step is not Step.RELIGHT:
            return
        stem = Path(self.image_path).stem
        path = self._ask_still_path("Export shadows removed", f"{stem}_shadows_removed")
        if path:
            self.export_shadows_removed(path, force=True)

    def export_shadows_removed(self, path: str, force: bool = False) -> int | None:
        """Write the photo with its own shadows removed at full resolution (as the still: 8
        bits made as 8 bits, no full-size float buffer)."""
        from outcast_core.runtime.io.imageio import output_bit_depth

        session = self.session
        if session is None or self.step is not Step.RELIGHT:
            return None
        bits = output_bit_depth(path, getattr(self.loaded, "bit_depth", 8))
        dtype = np.float32 if bits == 16 else np.uint8
        return self._export_image(
            "export_shadows_removed", path, force, lambda: session.deshadow_full(dtype=dtype),
            "removing shadows at full resolution",
        )  # fmt: skip

    def _export_image(
        self, channel: str, path: str, force: bool, render: Callable[[], np.ndarray], stage: str
    ) -> int | None:
        """Render one full-resolution image in the worker and write it atomically.

        Every format keeps the photo's EXIF; ``.tif``, and a PNG of a 16-bit photo, are 16-bit
        (:func:`~outcast_core.runtime.io.imageio.output_bit_depth`). Without ``force`` an
        existing file is refused (here at once, and again by the writer). The shadow
        corrections are those of when it was asked for.

        Args:
            channel: one of :data:`IMAGE_EXPORT_CHANNELS`.
            path: the output file.
            force: replace an existing file (the user confirmed it).
            render: returns the ``H x W x 3`` sRGB image; runs in the worker.
            stage: progress text while ``render`` runs.

        Returns:
            The job's id, or ``None`` when the file exists and ``force`` is off.
        """
        session, loaded = self.session, self.loaded
        edits = self.shadow_edits  # as asked, whatever is corrected later
        if self.refuse_own_file(path):  # never, even confirmed in the file dialog
            return None
        if not force and os.path.exists(path):
            self.show_error(FileExistsError(f"'{path}' already exists"), "export")
            return None

        def job(ctx: JobContext) -> dict[str, Any]:
            from outcast_core.runtime.io.imageio import (
                in_file_channels,
                output_bit_depth,
                write_image,
            )

            session.set_shadow_edits(edits)  # the photo's shadows as corrected when asked
            ctx.progress(stage, 0.1)
            img = render()
            ctx.progress("writing", 0.8)
            bits = output_bit_depth(path, getattr(loaded, "bit_depth", 8))
            write_image(path, in_file_channels(img, loaded), bit_depth=bits, force=force,
                        quality=95, exif=getattr(loaded, "exif_bytes", None))
            return {"path": path, "timings": _timings(session)}

        return self.runner.submit(channel, job, f"Exporting {os.path.basename(path)}")

    def refuse_own_file(self, path: str) -> bool:
        """Whether ``path`` is one of :meth:`own_file`'s files, said in a warning ("Not
        exported"): an export may never replace it (as on the command line)."""
        exc = self.own_file_error(path)
        if exc is not None:
            self.show_error(exc, "export")
        return exc is not None

    def own_file_error(self, path: str) -> OwnFileError | None:
        """Why an export may not write ``path`` (:meth:`own_file`), or None."""
        own = self.own_file(path)
        return OwnFileError(f"'{os.path.basename(path)}' is {own}; choose another name") if (
            own) else None

    def own_file(self, path: str) -> str:
        """What ``path`` is to the open work ("the photo you opened", its depth map, a project
        file of it), or "" when it is none of them: an export may never replace those."""
        if not path or not os.path.exists(path):
            return ""
        project = str(project_path_for(self.image_path)) if self.image_path else ""
        mine = [(self.image_path, "the photo you opened"),
                (self.depth_path, "the photo's depth map"),
                (project, "the photo's project file"),
                *((p, "a project file of the photo") for p in self._project_files)]
        for other, what in mine:
            if same_file(path, other):
                return what
        return ""

    # ================================================================== time-lapse
    @_typed_numbers_first
    def open_timelapse(self) -> Any:
        if self.step is not Step.RELIGHT:
            return None
        from app.timelapse_dialog import TimelapseDialog

        if self._timelapse_dialog is None:
            self._timelapse_dialog = TimelapseDialog(self)
        self._timelapse_dialog.load_settings(self._timelapse_to_save())  # (filled in again)
        self._timelapse_dialog.show()
        self._timelapse_dialog.raise_()
        self._timelapse_dialog.activateWindow()  # the keys go to it (reopened behind too)
        return self._timelapse_dialog

    def load_depth_dialog(self) -> None:
        """Pick a depth map for the open photo and re-run the light-independent stages."""
        if not self.image_path:
            return
        path, _ = QFileDialog.getOpenFileName(
            self, "Load depth map", os.path.dirname(self.image_path),
            "Depth maps (*.npy *.png *.exr);;All files (*)",
        )
        if path:
            self.load_depth(path)

    def choose_depth_model_dialog(self) -> None:
        """Pick an ONNX depth model (remembered) and use it for the open photo."""
        start = os.path.dirname(self.depth_model or self.image_path or "")
        path, _ = QFileDialog.getOpenFileName(
            self, "Use depth model", start, "ONNX depth models (*.onnx);;All files (*)"
        )
        if path:
            self.set_depth_model(path)

    def set_depth_model(self, path: str) -> None:
        """Use the ONNX depth model at ``path`` ("" = OutCast's own), remember it, and re-run the
        open photo's depth (suns and step kept; a settings change, not an undoable edit).

        A model that cannot be loaded is refused here with a message, and nothing changes.
        """
        if path:
            from outcast_core.runtime.io.depth_models import load_depth_model
            from outcast_core.runtime.io.models import ModelError

            try:
                load_depth_model(path)
            except (ModelError, ValueError) as exc:
                self.show_error(exc, "depth-model")
                return
            path = os.path.abspath(path)
        self.depth_model = path
        self.settings.setValue("depth_model", path)
        self.act_builtin_depth.setEnabled(bool(path))
        current = self.edit_state()
        if current is not None and not self.depth_path:  # a loaded depth map still wins
            self._reload(current)

    def set_use_phone_depth(self, use: bool) -> None:
        """Use (or not) a phone photo's own depth map, remember it, and re-run the open photo's
        depth when that changes it (a settings change, not an undoable edit)."""
        use = bool(use)
        if self.act_phone_depth.isChecked() != use:
            self.act_phone_depth.setChecked(use)  # calls back here once
            return
        changed = use != self.use_phone_depth
        self.use_phone_depth = use
        self.settings.setValue("phone_depth", "true" if use else "false")
        current = self.edit_state()
        if not changed or current is None or self.depth_path or self.depth_model:
            return  # a loaded depth map or a chosen model wins over the photo's own
        if use or getattr(self.session, "depth_source", "") == "phone":
            self._reload(current)

    def load_depth(self, path: str) -> None:
        """Use ``path`` as the photo's depth (suns, step and settings are kept; undoable)."""
        current = self.edit_state()
        if current is None:
            return
        problem = depth_file_problem(path)
        if problem is not None:  # at once, not after the work queued in the worker
            self.show_error(ValueError(problem), "depth")
            return
        self._reload(replace(current, depth_path=os.path.abspath(path)), record_from=current)

    # ================================================================== projects
    def project_state(self) -> ProjectState:
        if self._timelapse_dialog is not None and self._timelapse_dialog.is_current():
            self.timelapse_settings = self._timelapse_dialog.settings()
        return ProjectState(
            image_path=self.image_path,
            photo=self.photo_identity,
            preset=self.preset,
            depth_source=str(getattr(self.session, "depth_source", "")),
            depth_path=self.depth_path,
            original_sun=self.original_sun,
            align_sun=Sun(*self.align_panel.sun_panel.sun()),
            realigning=self.step is Step.ALIGN and self.original_sun is not None,
            target_sun=Sun(*self.relight_panel.sun_panel.sun()) if self.original_sun else None,
            overlay_opacity=self.align_panel.opacity_slider.value() / 100.0,
            split=self.relight_panel.split_slider.value() / 100.0,
            buffer_view=self.relight_panel.view(),
            timelapse=self._timelapse_to_save(),
            heading=self.user_heading,
            exposure=self.relight_panel.exposure(),
            daylight=self.relight_panel.daylight(),
            relighting=self.relighting_choice,
            shadow_edits=self.shadow_edits,
        )

    def _timelapse_to_save(self) -> TimelapseSettings:
        """The time-lapse settings as a project keeps them: a heading the dialog filled in
        (:attr:`timelapse_auto_heading`) is not kept, so it is solved again from the confirmed
        sun when the project reopens (a user trial's reopened project kept an old heading), nor
        a UTC offset it guessed from the longitude (:attr:`timelapse_auto_offset`)."""
        settings, auto = self.timelapse_settings, self.timelapse_auto_heading
        if (settings.heading is not None and auto is not None
                and abs(settings.heading - auto) < 0.05):
            settings = replace(settings, heading=None)
        guess = self.timelapse_auto_offset  # (likewise an offset guessed from the longitude)
        if (settings.utc_offset is not None and guess is not None
                and abs(settings.utc_offset - guess) < 1e-6):
            settings = replace(settings, utc_offset=None)
        if self.timelapse_auto_sweep == (settings.sweep_from, settings.sweep_to):
            default = TimelapseSettings()  # (and the sweep filled in from the two suns)
            settings = replace(settings, sweep_from=default.sweep_from,
                               sweep_to=default.sweep_to)
        return settings

    def sweep_suns(self) -> tuple[Sun, Sun] | None:
        """The time-lapse's sweep as the user set the scene up: from the confirmed original
        sun to where the new-sun dial stands (the dial's angles, as a sweep takes them); None
        before a sun is confirmed or while the two stand within a degree of each other. The
        dialog offered a fixed sweep from (80, 15) to (280, 50) whatever the suns were (a
        user trial)."""
        if self.original_sun is None:
            return None
        az, el = self.relight_panel.sun_panel.sun()
        a, b = self.original_sun, Sun(float(az), float(el))
        if (abs((a.azimuth - b.azimuth + 180.0) % 360.0 - 180.0) < 1.0
                and abs(a.elevation - b.elevation) < 1.0):
            return None
        return a, b

    def _commit_typed_fields(self) -> None:
        """Take in a number still being typed (a spin box commits on Enter or when it loses the
        focus; a toolbar button takes no focus): the camera heading and both suns' fields.
        Without it "Save project" from the toolbar saved the heading box's old value, and
        quitting asked nothing (a user trial)."""
        if self._applying_edit:  # an undo, a redo or a load: not the user's typing
            return
        panels = (self.align_panel.sun_panel, self.relight_panel.sun_panel)
        for box in (self.align_panel.heading_box,
                    *(b for p in panels for b in (p.azimuth_box, p.elevation_box))):
            box.interpretText()

    @_typed_numbers_first
    def save_project(self, path: str | None = None) -> str | None:
        if not self.image_path:
            return None
        target = path or self._project_file or str(project_path_for(self.image_path))
        asked = path is not None
        if not is_project_file(target):  # "pool.jpg" or "mypool" typed in the save dialog
            # Never the photo itself (a user trial's "Save project as" replaced the JPEG with
            # the project's text), nor a name the app would not open as a project.
            target, asked = str(project_path_for(target)), False
        if not self._may_replace_project(target, dialog_asked=asked):
            return None
        try:
            save_project(self.project_state(), target)
        except (OSError, ValueError) as exc:
            self.show_error(exc, "save-project")
            return None
        self._project_files.add(os.path.abspath(target))
        self._project_file = os.path.abspath(target)
        self.recent.add(target)
        self._save_recent()
        if self._timelapse_baseline is not None:  # project_state() took the dialog's
            self._timelapse_baseline = self._timelapse_to_save()
        self.undo_stack.setClean()
        self.stage_label.setText(f"Saved project {os.path.basename(target)}")
        return target

    def _may_replace_project(self, target: str, dialog_asked: bool = False) -> bool:
        """Whether saving may write ``target``: it does not exist, or this window opened or
        saved it, or the user says to replace it: a project of this photo that was opened on
        its own (unless the file dialog asked already), or another photo's project (always:
        the file dialog's question does not say whose it is)."""
        if not os.path.exists(target):
            return True
        other = self._project_photo_if_other(target)
        if other is None and (dialog_asked
                              or any(same_file(target, own) for own in self._project_files)):
            return True
        saved = time.strftime("%Y-%m-%d %H:%M", time.localtime(os.path.getmtime(target)))
        return self.ask(replace_project_question(os.path.basename(target), saved,
                                                 other)) == REPLACE

    def _project_photo_if_other(self, target: str) -> str | None:
        """The name of the photo ``target`` is the project of, when it is not the open
        photo; None for this photo's project or a file that is not a readable project."""
        try:
            photo = load_project(target).image_path
        except (OSError, ValueError):
            return None
        if not photo or same_file(photo, self.image_path) or (
                os.path.abspath(photo) in (os.path.abspath(self.image_path),
                                           self._photo_moved_from)):
            return None  # (the place of this photo that the project said, before it moved)
        return os.path.basename(photo)

    def save_project_dialog(self) -> None:
        if not self.image_path:
            return
        path, _ = QFileDialog.getSaveFileName(
            self, "Save project", str(project_path_for(self.image_path)),
            "OutCast projects (*.outcast.json)",
        )  # fmt: skip
        if path:
            self.save_project(path)

    # ================================================================== job plumbing
    @Slot(int, str, str)
    def _on_job_started(self, job_id: int, channel: str, description: str) -> None:
        """The job now running, in the status bar: its words, and its progress bar for the
        jobs that have one; the bar of the one before goes (a user trial saw a quality switch's
        "100 %" stay through the view's job that followed it). A background job (the
        time-lapse dialog's timing) leaves the status as it is: the dialog says it."""
        if not self._says_status(channel):
            return
        self.stage_label.setText(f"{description or STAGE_WORDS.get(channel, channel)}…")
        if channel in ("load", "preset", "confirm", "find_sun", *EXPORT_CHANNELS):
            self.progress_bar.setRange(0, 0 if channel == "confirm" else 100)
            self.progress_bar.setValue(0)
            self.progress_bar.show()
        else:
            self.progress_bar.hide()

    def _status_pending(self) -> bool:
        """Whether a job that says its end in the status bar (:meth:`_says_status`) is
        waiting, running or not yet reported, so what the status says now will be replaced.
        Not the dialog's frames nor the background timing: a time-lapse frame queued behind
        the view's relighting left "Relighting…" up for good (a user trial: the light or the
        relighting switched with the time-lapse dialog open)."""
        return any(self._says_status(ch) for _, ch, _ in self.runner.active())

    def _says_status(self, channel: str) -> bool:
        """Whether a job of ``channel`` says its start and end in the status bar: not the
        background timing nor a dialog's own frames (:data:`DIALOG_CHANNELS`), which say theirs
        in the dialog, so the status keeps saying the user's jobs."""
        return channel not in self.runner.queue.background and channel not in DIALOG_CHANNELS

    @Slot(int, str, str, float)
    def _on_job_progress(self, job_id: int, channel: str, stage: str, fraction: float) -> None:
        if channel in EXPORT_CHANNELS:
            self._job_fraction[job_id] = fraction
        if channel in ("load", "preset", "find_sun", *EXPORT_CHANNELS):
            self.progress_bar.setRange(0, 100)
            self.progress_bar.setValue(round(100 * fraction))  # the percentage: in the bar
            base = STAGE_WORDS.get(channel, channel)
            # ("Exporting time-lapse: timelapse" said the stage twice: a user trial)
            same = stage.lower().replace("-", "") in base.lower().replace("-", "")
            self.stage_label.setText(base if same else f"{base}: {stage}")
        elif self._deshadow_job is not None and job_id == self._deshadow_job[2]:
            # Removing the photo's shadows at full size (seconds on a large photo; no stages to
            # count): a busy bar, hidden when the window is idle or the next job starts
            self.progress_bar.setRange(0, 0)
            self.progress_bar.show()
        if channel == "tl_export" and self._timelapse_dialog is not None:
            self._timelapse_dialog.on_export_progress(fraction)

    @Slot(int, str, object, float)
    def _on_job_finished(self, job_id: int, channel: str, result: Any, seconds: float) -> None:
        if channel in EXPORT_CHANNELS:
            self._saved_exports[job_id] = str(result["path"])
        if isinstance(result, dict) and "timings" in result:
            self.timings.update(result["timings"])
            self.timings_label.setText(self.timings.summary(limit=4))
            self.timings_label.setToolTip(
                "Last run of each stage:\n" + self.timings.summary(limit=50).replace(" · ", "\n")
            )
        # Results of superseded requests still show while dragging, but never an older one
        # after a newer one.
        if job_id < self._shown.get(channel, 0):
            return
        self._shown[channel] = job_id
        waiting = self._status_jobs()  # (what this job's handler starts is added below)
        if channel == "load":
            if not self._on_loaded(result):
                return  # declined: what the window said stays
        elif channel == "shadow":
            self._on_shadow(result)
        elif channel == "find_sun":
            self._on_found_sun(result)
        elif channel == "preset" and result.get("session") is self.session:
            self._set_camera_tilt(result["tilt"])
            self._update_exif_controls()
        elif channel == "confirm":
            self._on_confirmed(result)
        elif channel == "relight":
            self._on_relit(result)
        elif channel in IMAGE_EXPORT_CHANNELS:
            self.last_export = result["path"]
        elif (channel in ("tl_preview", "tl_export", "tl_estimate")
              and self._timelapse_dialog is not None):
            self._timelapse_dialog.on_job_finished(channel, result)
        # The status says the user's jobs (not the time-lapse dialog's timing, which says its
        # own result in the dialog and gives way to them).
        # Nor the dialog's preview frames ("rendering time-lapse frame took 0.00 s" for a
        # cached one replaced what the user's relighting said: a user trial).
        if (self._undo_note is not None and job_id in self._undo_note[1]
                and self._status_pending()):  # it started the next (confirm, then relight)
            self._undo_note[1].update(self._status_jobs() - waiting)
        if (channel != "find_sun" and self._says_status(channel)
                and not self._status_pending()):
            if channel in IMAGE_EXPORT_CHANNELS:
                text = f"Saved {os.path.basename(result['path'])} in {seconds:.1f} s"
            elif channel == "tl_export":
                text = f"Saved time-lapse {os.path.basename(str(result['path']))}"
            else:
                words = STAGE_WORDS.get(channel, channel)
                if isinstance(result, dict) and result.get("view") in DESHADOW_VIEWS:
                    words = "Removing shadows" if result.get("image") is not None else (
                        "Finding shadows")
                text = f"Ready · {words.lower()} took {seconds:.2f} s"
                if isinstance(result, dict) and result.get("computed") is False:
                    text = "Ready"  # the shadows found at confirming, shown: no work to time
                # (a project opens into step 2: what its opening said outlasts the relit view)
                held = channel in ("shadow", "relight") and bool(self._held_message)
                if held:
                    text, self._held_message = self._held_message, ""
                if channel == "relight" and self._exposure_hint:  # (the time: in the timings)
                    text = (f"{text} · {self._exposure_hint}" if held
                            else f"Ready · {self._exposure_hint}")
                tool = self.relight_panel.shadow_tool()
                if channel == "relight" and self._edit_note:
                    text = f"Ready · {self._edit_note}"  # what the correction did (nothing)
                elif channel == "relight" and self._edit_done:
                    text = f"Ready · {self._edit_done}"  # what the correction did
                elif channel == "relight" and tool:
                    text = SHADOW_TOOL_HINTS[tool]  # what the tool that is on does
            if self._undo_note is not None and job_id in self._undo_note[1]:
                note, _, own = self._undo_note  # what the undo did, before what its job did
                if channel in IMAGE_EXPORT_CHANNELS or channel == "tl_export":
                    text = f"{note} · {text}"  # (an export that was running: said too)
                elif own and text.startswith("Ready · "):
                    text = f"{note} · {text[len('Ready · '):]}"
                else:  # a tool's hint, or a result the undo made stale
                    text = note
            self._undo_note = None
            self._edit_done = ""  # (said once)
            self.stage_label.setText(text)

    @Slot(int, str, object)
    def _on_job_failed(self, job_id: int, channel: str, exc: Any) -> None:
        self.progress_bar.hide()
        self._undo_note = None  # (the failure is said instead)
        if channel == "find_sun":
            self.align_panel.set_finding(False)
        if channel == "load":
            self._pending_project = None
            self._pending_restore = self._pending_record_from = None
            self._drop_if_gone(self._last_load[0] if self._last_load else "")
        if (channel in ("tl_export", "tl_preview", "tl_estimate")
                and self._timelapse_dialog is not None):
            self._timelapse_dialog.on_job_failed(channel, exc)
        if channel == "tl_estimate":  # the dialog says it; the export itself may work
            return
        action = "export" if channel in EXPORT_CHANNELS else {"load": "open"}.get(channel, "")
        last = self._last_load
        restore = last[2] if channel == "load" and last is not None else None
        if isinstance(exc, DepthMapError) or (restore is not None
                                              and restore.depth_path != self.depth_path):
            action = "depth"  # a project's depth map, or another one for the same photo
        self.show_error(exc, action)
        if isinstance(exc, ModelError) and self.session_mode != "classic":
            if "depth" in str(exc):  # a broken depth model: use the ground-plane prior instead
                self.depth_mode = "prior"
            self._fall_back_to_classic(channel)

    def _fall_back_to_classic(self, channel: str) -> None:
        """A model is broken: carry on with Direct shadows + physics relighting."""
        self.session_mode = "classic"
        if channel == "load" and self._last_load is not None:
            self.open_image(*self._last_load)
        elif self.image_path:
            state = self.edit_state()
            self.open_image(self.image_path, project=self.project_state(), restore=state,
                            record_from=state)  # fmt: skip

    @Slot(int, str)
    def _on_job_cancelled(self, job_id: int, channel: str) -> None:
        if channel == "tl_export" and self._timelapse_dialog is not None:
            self._timelapse_dialog.on_export_cancelled()
        if channel == "find_sun":
            self.align_panel.set_finding(False)
        if channel in (*EXPORT_CHANNELS, "load", "find_sun"):
            self.progress_bar.hide()
            self.stage_label.setText(f"{STAGE_WORDS.get(channel, channel)}: cancelled")

    @Slot()
    def _on_idle(self) -> None:
        self.progress_bar.hide()

    # ================================================================== leaving
    def running_exports(self) -> list[RunningExport]:
        """Exports waiting or running in the worker."""
        active = [(i, d) for i, ch, d in self.runner.active() if ch in EXPORT_CHANNELS]
        self._job_fraction = {i: f for i, f in self._job_fraction.items()
                              if i in {j for j, _ in active}}  # fmt: skip
        return [
            RunningExport(d.removeprefix("Exporting ") or "a file", self._job_fraction.get(i))
            for i, d in active
        ]

    def question_box(self, question: Question) -> QMessageBox:
        """A message box for ``question``; each button carries its answer in ``"answer"``."""
        box = QMessageBox(QMessageBox.Icon.Warning, question.title, question.text, parent=self)
        box.setInformativeText(question.detail)
        roles = {
            "accept": QMessageBox.ButtonRole.AcceptRole,
            "reject": QMessageBox.ButtonRole.RejectRole,
            "destructive": QMessageBox.ButtonRole.DestructiveRole,
        }
        for choice in question.choices:
            button = box.addButton(choice.label, roles[choice.role])
            button.setProperty("answer", choice.key)
            if choice.key == question.default:
                box.setDefaultButton(button)
            if choice.key == question.escape:
                box.setEscapeButton(button)
        return box

    def ask(self, question: Question) -> str:
        """Show ``question`` modally; returns the answer (Esc gives ``question.escape``)."""
        box = self.question_box(question)
        box.exec()
        clicked = box.clickedButton()
        answer = clicked.property("answer") if clicked is not None else None
        return str(answer) if answer else question.escape

    def confirm_leave(self, action: str) -> bool:
        """Ask about running exports and unsaved edits before ``"quit"`` or ``"open"``.

        Returns:
            True to go ahead (exports stopped, the project saved or the edits dropped as the
            user chose); False to stay.
        """
        name = (os.path.basename(self._project_file) if self._project_file
                else project_path_for(self.image_path).name if self.image_path else "")
        self._commit_typed_fields()
        questions = leave_questions(
            action, self.running_exports(), self.has_unsaved_changes(), name,
            self.unsaved_parts(),
        )
        asked = {i for i, ch, _ in self.runner.active() if ch in EXPORT_CHANNELS}
        # Every question first, then what the answers say: "Stop export" followed by Cancel
        # on the next question must leave the export running (a user trial).
        answers = []
        for question in questions:
            answer = self.ask(question)
            if not question.goes_ahead(answer):
                return False
            answers.append(answer)
        if SAVE in answers and self.save_project() is None:
            return False
        if STOP in answers:
            for channel in EXPORT_CHANNELS:
                self.runner.cancel(channel)
            # An export may have finished while a question was open, or finish now (past its
            # last cancellation point, it writes): wait for each one's outcome, and say which
            # were saved.
            end = time.monotonic() + STOP_WAIT_S
            while time.monotonic() < end and asked & {i for i, _, _ in self.runner.active()}:
                # (no user input meanwhile: a second close or open would nest in this one)
                QApplication.processEvents(QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents)
                time.sleep(0.01)
            done = [self._saved_exports.pop(i) for i in sorted(asked) if i in self._saved_exports]
            if done:
                self.ask(finished_before_stop_notice(done))
        return True

    def close_without_asking(self) -> bool:
        """Close even with a running export or unsaved edits (scripts and benchmarks)."""
        self._close_without_asking = True
        return self.close()

    def closeEvent(self, event: QCloseEvent) -> None:
        if not self._close_without_asking and not self.confirm_leave("quit"):
            event.ignore()
            return
        self.runner.shutdown()
        # A job that ended while shutting down (a photo that finished loading as SIGTERM came)
        # has its result queued for this thread: dropped, not handled (it would ask the
        # stopped worker for more and raise).
        self.runner.blockSignals(True)
        if self._timelapse_dialog is not None:
            self._timelapse_dialog.close()
        super().closeEvent(event)


__all__ = ["MainWindow", "VIEW_CHOICES"]


#: :meth:`MainWindow.confirm_leave`: how long "Stop export" waits for the stopped exports'
#: outcomes (one past its last cancellation point still writes its file) before going on.
STOP_WAIT_S = 10.0



def photo_file_notes(loaded: Any) -> list[str]:
    """What the command line says of a photo file as it reads it, as sentences: the
    transparency filled with white, a panorama strip's shape (:func:`elongation_note`), a photo
    too small to relight meaningfully (:func:`small_photo_note`, its shorter side under
    ``MIN_PHOTO_SIDE`` pixels, as ``outcast batch`` warns: the app opened, relit and exported
    a tiny photo without a word, a user trial); empty for an ordinary photo or ``None``."""
    if loaded is None:
        return []
    notes = []
    if getattr(loaded, "has_alpha", False):  # composited on white as it was read
        notes.append("The photo has transparency; it is filled with white, and the relit photo "
                     "and the exports have none.")
    for note in (elongation_note(*loaded.original_size),  # a panorama strip: the depth sees
                 small_photo_note(*loaded.original_size)):  # a few rows of it
        if note:
            notes.append(f"{note[:1].upper()}{note[1:]}.")
    return notes


def photo_notes_html(notes: list[str]) -> str:
    """The status bar's "Photo notes" tooltip: a title and one paragraph a note (rich text, so
    Qt wraps the long ones); "" without notes.

    Example:
        >>> photo_notes_html(["A < B."])
        '<p><b>About this photo</b></p><p>A &lt; B.</p>'
    """
    if not notes:
        return ""
    return "<p><b>About this photo</b></p>" + "".join(f"<p>{html.escape(n, quote=False)}</p>"
                                                   for n in notes)


def exposure_hint(level: float | None) -> str:
    """What the status line says when, at the photo's exposure, the new light makes the scene
    much darker or brighter (``level``: :func:`~outcast_core.runtime.pipeline.relight.
    exposure_level`); "" otherwise.

    Short, so that the advice is whole in the status bar at 1024 px (the earlier wording, after
    the relighting's time, was cut before it: a user trial); the relighting's time stays in
    the timings beside it.

    Example:
        >>> exposure_hint(0.2)
        'the new light leaves the scene 5.0× darker: try "Meter the new light"'
        >>> exposure_hint(1.3)
        ''
    """
    if level is None or 1.0 / EXPOSURE_HINT_FACTOR < level < EXPOSURE_HINT_FACTOR:
        return ""
    factor, way = (1.0 / max(level, 1e-6), "darker") if level < 1.0 else (level, "brighter")
    return f"the new light leaves the scene {factor:.1f}× {way}: try \"Meter the new light\""


def process_until_idle(window: MainWindow, timeout: float = 120.0, poll: float = 0.002) -> None:
    """Run the event loop until ``window``'s worker is idle and its results are delivered.

    For scripts and benchmarks that drive the window without a running event loop (the
    screenshot script, ``benchmarks/bench_gui.py``); raises ``TimeoutError`` after ``timeout`` s.
    """
    app = QApplication.instance()
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        app.processEvents()
        if not window.runner.busy():
            app.processEvents()  # deliver results queued by the job that just finished
            if not window.runner.busy():
                return
        time.sleep(poll)
    raise TimeoutError("the worker did not finish")
