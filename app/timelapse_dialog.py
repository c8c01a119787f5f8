"""The time-lapse dialog: a sun path (sweep or the real sun), a scrubber, and export.

The dialog builds :class:`~outcast_core.runtime.pipeline.timelapse.SunSample` lists with the
runtime's
time-lapse module (the same code as ``outcast timelapse``) and sends previews and the export to
the main window's worker: ``tl_preview`` (latest wins) and ``tl_export`` (progress + cancel).
"""

from __future__ import annotations

import datetime as dt
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from PySide6.QtCore import QDate, Qt, QTime
from PySide6.QtGui import QCloseEvent, QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDateEdit,
    QDialog,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QStackedWidget,
    QTimeEdit,
    QVBoxLayout,
    QWidget,
)

from app import display
from app.canvas import qimage_from_array
from app.errors import message_for
from app.state import Step, Sun, TimelapseSettings, with_filter_extension
from app.workers import JobCancelledError, JobContext
from outcast_core.runtime.pipeline import timelapse as tl
from outcast_core.runtime.pipeline.relight import EXPOSURE_HINT_FACTOR, exposure_level

if TYPE_CHECKING:
    from app.main_window import MainWindow

SIZE_CHOICES = (
    ("working", "Working size"),
    ("720p", "720p"),
    ("1080p", "1080p"),
    ("4k", "4K"),
    ("full", "Full resolution"),
)
#: The heading's "From photo" button when it can solve one.
SOLVE_TIP = "Solve the heading from the aligned sun and the photo's capture time and GPS"
#: Added to the frame's caption when its preview is dark with the photo's exposure kept (the
#: status line's hint: :data:`~outcast_core.runtime.pipeline.relight.EXPOSURE_HINT_FACTOR`
#: times darker): a day's first and last frames came out near black, unexplained (a user
#: trial).
DARK_FRAME_WORDS = (" · dark with the photo's exposure kept: step 2's \u201cMeter the new "
                    "light\u201d meters each frame")
#: Frames of the short export the estimate times (spread evenly along the path), one fewer
#: above :data:`ESTIMATE_LARGE_MP` megapixels a frame.
ESTIMATE_FRAMES = 4
ESTIMATE_LARGE_MP = 8.0
FORMAT_CHOICES = (
    ("mp4", "MP4 video (H.264)", "MP4 video (*.mp4)"),
    ("gif", "Animated GIF", "GIF animation (*.gif)"),
    ("webp", "Animated WebP", "WebP animation (*.webp)"),
    ("png", "PNG sequence (folder)", "Folder name (*)"),
)


def samples_for(
    settings: TimelapseSettings, tilt: tuple[float, float] = (0.0, 0.0)
) -> list[tl.SunSample]:
    """The sun path described by the settings (Qt-free; raises ValueError with what is missing).

    ``tilt`` is the photo's camera ``(pitch, roll)``: the real sun is given against the horizon
    (a sweep is drawn on the dial, in the camera's own frame, and ignores it)."""
    settings.validate()
    if settings.kind == "sweep":
        a0, a1 = settings.sweep_from.azimuth, settings.sweep_to.azimuth
        d = (a1 - a0) % 360.0  # clockwise distance A -> B
        shorter = d if d <= 180.0 else d - 360.0
        longer = shorter - 360.0 if shorter > 0 else shorter + 360.0
        if d == 0.0:
            longer = 0.0
        d = shorter if settings.way == "shorter" else longer
        return tl.sweep_path(
            (a0, settings.sweep_from.elevation),
            (a0 + d, settings.sweep_to.elevation),
            settings.frames,
            settings.easing,
        )
    if settings.latitude is None or settings.longitude is None:
        raise ValueError("expected a latitude and longitude for the real sun path")
    if settings.heading is None:
        raise ValueError("expected the camera heading for the real sun path")
    day = dt.date.fromisoformat(settings.date) if settings.date else dt.date.today()
    start = dt.time.fromisoformat(settings.start) if settings.start else None
    end = dt.time.fromisoformat(settings.end) if settings.end else None
    return tl.real_sun_path(
        day,
        settings.latitude,
        settings.longitude,
        settings.heading,
        settings.frames,
        start,
        end,
        settings.utc_offset,
        tilt,
    )


def size_entries(photo: tuple[int, int] | None,
                 working: tuple[int, int] | None) -> list[tuple[str, str, str]]:
    """The size menu for a photo of ``photo`` ``(H, W)`` at the working size ``working``:
    ``(key, label, tooltip)`` with each size's pixels, one entry a frame size. A video size
    as large as the photo is the photo's size: only "Full resolution" is listed then, its
    tooltip says which sizes it stands for (the menu listed "4K · 2016 × 1512 (the photo's
    size)" and "Full resolution · 2016 × 1512": a user trial). Without a photo: every size,
    without pixels.

    Example:
        >>> size_entries((1512, 2016), (288, 384))[3]
        ('full', 'Full resolution · 2016 × 1512', "The photo's size (4K would be larger)")
    """
    if photo is None or working is None:
        return [(key, text, "") for key, text in SIZE_CHOICES]
    shape_of = {key: tl.frame_shape(key, photo, working) for key, _ in SIZE_CHOICES}
    kept: dict[tuple[int, int], str] = {}  # frame size -> the key listed for it
    for key, _ in SIZE_CHOICES:
        if shape_of[key] not in kept or key == "full":
            kept[shape_of[key]] = key
    names = dict(SIZE_CHOICES)
    entries = []
    for key, text in SIZE_CHOICES:
        h, w = shape_of[key]
        if kept[(h, w)] != key:
            continue
        label = f"{text} · {w} × {h}" + (" (fastest)" if key == "working" else "")
        larger = [names[k] for k, _ in SIZE_CHOICES
                  if k not in (key, "working") and shape_of[k] == (h, w)]
        tip = "The photo's size" if key == "full" else ""
        if larger:
            tip += f" ({' and '.join(larger)} would be larger)"
        entries.append((key, label, tip))
    return entries


def video_length(frames: int, fps: float) -> str:
    """How long ``frames`` frames play at ``fps``: ``"4 s"``, ``"0.25 s"``, ``"2 min 5 s"``.

    Example:
        >>> video_length(48, 12), video_length(3, 12), video_length(500, 12)
        ('4 s', '0.25 s', '41.7 s')
        >>> video_length(1500, 12), video_length(720, 12)
        ('2 min 5 s', '1 min')
    """
    seconds = frames / fps
    if seconds >= 59.5:
        minutes, rest = divmod(round(seconds), 60)
        return f"{minutes} min {rest} s" if rest else f"{minutes} min"
    return f"{seconds:.3g} s"


@dataclass(frozen=True)
class ExportTiming:
    """How long an export of ``frames`` frames took (seconds), and what a frame more adds:
    the one-off work (the encoder starting, the photo brought to the frame size, the file
    finished) is in ``seconds`` once."""

    frames: int
    seconds: float
    per_frame: float

    @classmethod
    def from_stamps(cls, stamps: list[float], total: float) -> ExportTiming:
        """From a short export: the seconds until each of its frames was rendered, and until
        it was written. A frame more costs what a frame in the middle took to render (the
        next sun's shadow is computed beside it; the last frame's is not, and it is cheaper),
        or to encode when the encoder is the slower (it runs beside the rendering, and the
        time after the first frame is then its own).

        Example:
            >>> ExportTiming.from_stamps([1.0, 1.5, 2.0, 2.2], 2.3).seconds_for(10)
            5.3
        """
        frames = len(stamps)
        middle = stamps[:-1] if frames > 2 else stamps
        rendering = ((middle[-1] - middle[0]) / (len(middle) - 1) if len(middle) > 1
                     else stamps[0])
        return cls(frames, total, max(rendering, (total - stamps[0]) / frames))

    def seconds_for(self, frames: int) -> float:
        """Estimated seconds for an export of ``frames`` frames."""
        return max(0.0, self.seconds + (frames - self.frames) * self.per_frame)


def _angle_box(lo: float, hi: float, value: float, wrap: bool = False) -> QDoubleSpinBox:
    b = QDoubleSpinBox()
    b.setRange(lo, hi)
    b.setDecimals(1)
    b.setSuffix("°")
    b.setWrapping(wrap)
    b.setValue(value)
    b.setKeyboardTracking(False)
    return b


class TimelapseDialog(QDialog):
    """Non-modal dialog owned by the main window."""

    def __init__(self, main: MainWindow):
        super().__init__(main)
        self.main = main
        self.setWindowTitle("Time-lapse")
        self.setModal(False)
        self._samples: list[tl.SunSample] = []
        self._ready = False  # no reactions to widget changes until load_settings() ran
        self._exporting = False
        self.last_export: str = ""
        self.last_result: str = ""

        # ---- path kind
        self.kind_combo = QComboBox(self)
        self.kind_combo.addItem("Sweep from A to B", "sweep")
        self.kind_combo.addItem("Real sun path of a day", "sun")
        self.pages = QStackedWidget(self)

        sweep = QWidget(self)
        self.from_az = _angle_box(0.0, 359.9, 90.0, wrap=True)
        self.from_el = _angle_box(0.0, 90.0, 15.0)
        self.to_az = _angle_box(0.0, 359.9, 270.0, wrap=True)
        self.to_el = _angle_box(0.0, 90.0, 15.0)
        self.easing_combo = QComboBox(self)
        for e in tl.EASINGS:
            self.easing_combo.addItem(e.replace("-", " "), e)
        self.way_combo = QComboBox(self)
        self.way_combo.addItem("the shorter way around", "shorter")
        self.way_combo.addItem("the longer way around", "longer")
        self.way_combo.setToolTip("Which way the azimuth turns from A to B")
        g = QGridLayout(sweep)
        g.addWidget(QLabel(""), 0, 0)
        g.addWidget(QLabel("Azimuth"), 0, 1)
        g.addWidget(QLabel("Elevation"), 0, 2)
        g.addWidget(QLabel("From (A)"), 1, 0)
        g.addWidget(self.from_az, 1, 1)
        g.addWidget(self.from_el, 1, 2)
        g.addWidget(QLabel("To (B)"), 2, 0)
        g.addWidget(self.to_az, 2, 1)
        g.addWidget(self.to_el, 2, 2)
        g.addWidget(QLabel("Easing"), 3, 0)
        g.addWidget(self.easing_combo, 3, 1, 1, 2)
        g.addWidget(QLabel("Go"), 4, 0)
        g.addWidget(self.way_combo, 4, 1, 1, 2)

        sun = QWidget(self)
        self.date_edit = QDateEdit(self)
        self.date_edit.setCalendarPopup(True)
        self.date_edit.setDisplayFormat("yyyy-MM-dd")
        last = tl.LAST_DAY  # (the calendar's last day has no sunset to look for after it)
        self.date_edit.setMaximumDate(QDate(last.year, last.month, last.day))
        self.lat_box = QDoubleSpinBox(self)
        self.lat_box.setRange(-90.0, 90.0)
        self.lat_box.setDecimals(5)
        self.lon_box = QDoubleSpinBox(self)
        self.lon_box.setRange(-180.0, 180.0)
        self.lon_box.setDecimals(5)
        self.heading_box = _angle_box(0.0, 359.9, 180.0, wrap=True)
        self.heading_box.setToolTip("Compass direction the camera faces (0 = north, 90 = east)")
        self.solve_button = QPushButton("From photo", self)
        self.solve_button.setToolTip(SOLVE_TIP)
        self.solve_button.clicked.connect(self.solve_heading)
        self.daylight_check = QCheckBox("Sunrise to sunset", self)
        self.daylight_check.setChecked(True)
        self.start_edit = QTimeEdit(QTime(7, 0), self)
        self.end_edit = QTimeEdit(QTime(19, 0), self)
        for t in (self.start_edit, self.end_edit):
            t.setDisplayFormat("HH:mm")
        self.daylight_check.toggled.connect(self._on_daylight_toggled)
        self.offset_box = QDoubleSpinBox(self)
        self.offset_box.setRange(-14.0, 14.0)
        self.offset_box.setSingleStep(0.25)
        self.offset_box.setDecimals(2)
        self.offset_box.setPrefix("UTC ")
        self.offset_box.setSuffix(" h")
        self.place_hint = QLabel("", self)
        self.place_hint.setWordWrap(True)
        f = QFormLayout(sun)
        f.addRow("Date", self.date_edit)
        f.addRow("Latitude", self.lat_box)
        f.addRow("Longitude", self.lon_box)
        heading_row = QHBoxLayout()
        heading_row.addWidget(self.heading_box, 1)
        heading_row.addWidget(self.solve_button)
        f.addRow("Camera heading", heading_row)
        f.addRow("", self.daylight_check)
        times = QHBoxLayout()
        times.addWidget(self.start_edit)
        times.addWidget(QLabel("to"))
        times.addWidget(self.end_edit)
        f.addRow("Time", times)
        f.addRow("Local time", self.offset_box)
        f.addRow(self.place_hint)
        self.pages.addWidget(sweep)
        self.pages.addWidget(sun)
        self.pages.currentChanged.connect(self._fit_pages)
        self.kind_combo.currentIndexChanged.connect(self.pages.setCurrentIndex)
        self._fit_pages(self.pages.currentIndex())

        # ---- output
        self.frames_box = QSpinBox(self)
        self.frames_box.setRange(2, 2000)
        self.frames_box.setValue(48)
        self.fps_box = QDoubleSpinBox(self)
        self.fps_box.setRange(1.0, 60.0)
        self.fps_box.setValue(12.0)
        self.format_combo = QComboBox(self)
        for key, text, _ in FORMAT_CHOICES:
            self.format_combo.addItem(text, key)
        self.size_combo = QComboBox(self)
        for key, text in SIZE_CHOICES:
            self.size_combo.addItem(text, key)
        self.size_combo.setToolTip(
            "Frame size. 720p, 1080p and 4K set the shorter side (720, 1080, 2160 px) and keep "
            "the photo's shape; no size is larger than the photo. Working size is the quality "
            "preset's own (fastest, small)."
        )
        self.estimate_label = QLabel("", self)
        self.estimate_label.setWordWrap(True)
        # Room for its two lines: at the dialog's smallest size the second ("... s to
        # export") was cut in half (a user trial).
        self.estimate_label.setMinimumHeight(2 * self.estimate_label.fontMetrics().lineSpacing())
        #: Timed exports: (photo load, preset, size, format, step 2's look) -> ExportTiming.
        self._timings: dict[tuple[Any, ...], ExportTiming] = {}
        self._untimed: set[tuple[Any, ...]] = set()  # settings whose timing failed
        #: The settings of the timing submitted last and not yet back (none twice at once).
        self._timing_key: tuple[Any, ...] | None = None
        out_form = QFormLayout()
        out_form.addRow("Frames", self.frames_box)
        out_form.addRow("Frames per second", self.fps_box)
        out_form.addRow("Format", self.format_combo)
        out_form.addRow("Size", self.size_combo)
        out_form.addRow(self.estimate_label)  # (the form's width: two lines, not three)

        # ---- preview + scrubber
        self.preview = QLabel("Preview", self)
        self.preview.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.preview.setMinimumSize(360, 240)
        self.preview.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.preview.setStyleSheet("background: #262628; color: #aaa;")
        self.scrubber = QSlider(Qt.Orientation.Horizontal, self)
        self.scrubber.setRange(0, 47)
        self.scrubber.valueChanged.connect(self._on_scrub)
        self.caption = QLabel("", self)
        self.caption.setWordWrap(True)  # a long caption (a sun below the horizon) must not
        self.caption.setMinimumWidth(1)  # widen the dialog when the day's page is shown
        # Room for three lines, so the preview does not jump in height as a caption wraps
        # from two lines to three while scrubbing (a user trial).
        self.caption.setMinimumHeight(3 * self.caption.fontMetrics().lineSpacing())
        self.caption.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.preview.setToolTip("A quick preview at a small size; the export is drawn at the "
                                "size chosen under Output")
        self._preview_pixmap: QPixmap | None = None
        self._caption = ""  # the shown frame's caption, before what its preview says
        self._unsolved = ""  # why _solved_heading gave None, when it can say
        self._zone_from = ""  # where the local time's offset came from (load_settings)
        self._place_words = ""

        # ---- export row
        self.progress = QProgressBar(self)
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        self.progress.setTextVisible(False)  # no "0 %" before any export (a user trial)
        # Idle, an empty bar looked like a text field to type into (a user trial): it shows
        # while an export runs and after one finishes; hidden, it keeps its room.
        policy = self.progress.sizePolicy()
        policy.setRetainSizeWhenHidden(True)
        self.progress.setSizePolicy(policy)
        self.progress.setVisible(False)
        self.status = QLabel("", self)
        self.status.setWordWrap(True)
        self.export_button = QPushButton("Export…", self)
        self.export_button.clicked.connect(self.export_dialog)
        self.cancel_button = QPushButton("Cancel export", self)
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancel_export)
        close_button = QPushButton("Close", self)
        close_button.clicked.connect(self.close)

        left = QVBoxLayout()
        left.addWidget(QLabel("<b>Sun path</b>"))
        left.addWidget(self.kind_combo)
        left.addWidget(self.pages)
        left.addWidget(QLabel("<b>Output</b>"))
        left.addLayout(out_form)
        left.addStretch(1)
        right = QVBoxLayout()
        right.addWidget(self.preview, 1)
        right.addWidget(self.scrubber)
        right.addWidget(self.caption)
        top = QHBoxLayout()
        top.addLayout(left, 0)
        top.addLayout(right, 1)
        bottom = QHBoxLayout()
        bottom.addWidget(self.progress, 1)
        bottom.addWidget(self.export_button)
        bottom.addWidget(self.cancel_button)
        bottom.addWidget(close_button)
        layout = QVBoxLayout(self)
        layout.addLayout(top, 1)
        layout.addWidget(self.status)
        layout.addLayout(bottom)
        self.resize(900, 560)

        for w in (self.from_az, self.from_el, self.to_az, self.to_el, self.lat_box, self.lon_box,
                  self.heading_box, self.offset_box, self.fps_box):  # fmt: skip
            w.valueChanged.connect(self._settings_changed)
        self.frames_box.valueChanged.connect(self._settings_changed)
        for c in (self.easing_combo, self.kind_combo, self.way_combo):
            c.currentIndexChanged.connect(self._settings_changed)
        for c in (self.size_combo, self.format_combo):  # (the estimate; kept as unsaved work)
            c.currentIndexChanged.connect(self._update_estimate)
        self.lon_box.valueChanged.connect(self._on_longitude_changed)
        self.offset_box.valueChanged.connect(self._show_place_hint)
        self.date_edit.dateChanged.connect(self._settings_changed)
        self.start_edit.timeChanged.connect(self._settings_changed)
        self.end_edit.timeChanged.connect(self._settings_changed)
        self._on_daylight_toggled(True)

    def _fit_pages(self, index: int) -> None:
        """Size the path's pages to the one shown (a stack is as tall as its tallest page).

        Without this the short sweep page sat above a gap as tall as the day's page.
        """
        for i in range(self.pages.count()):
            page = self.pages.widget(i)
            policy = QSizePolicy.Policy.Preferred if i == index else QSizePolicy.Policy.Ignored
            page.setSizePolicy(policy, policy)
        self.pages.updateGeometry()

    # ------------------------------------------------------------------ settings <-> widgets
    def load_settings(self, s: TimelapseSettings) -> None:
        """Show ``s``, filling place, date and heading from the photo's EXIF where unset."""
        exif = getattr(self.main.loaded, "exif", None)
        widgets = [self.kind_combo, self.from_az, self.from_el, self.to_az, self.to_el,
                   self.easing_combo, self.frames_box, self.date_edit, self.lat_box,
                   self.lon_box, self.heading_box, self.start_edit, self.end_edit,
                   self.offset_box, self.fps_box, self.format_combo, self.daylight_check,
                   self.way_combo, self.size_combo]  # fmt: skip
        for w in widgets:
            w.blockSignals(True)
        try:
            self.kind_combo.setCurrentIndex(0 if s.kind == "sweep" else 1)
            self.pages.setCurrentIndex(self.kind_combo.currentIndex())
            self.from_az.setValue(s.sweep_from.azimuth)
            self.from_el.setValue(s.sweep_from.elevation)
            self.to_az.setValue(s.sweep_to.azimuth)
            self.to_el.setValue(s.sweep_to.elevation)
            self._fill_sweep(s)
            self.way_combo.setCurrentIndex(max(0, self.way_combo.findData(s.way)))
            self.easing_combo.setCurrentIndex(max(0, self.easing_combo.findData(s.easing)))
            self.frames_box.setValue(s.frames)
            self.fps_box.setValue(s.fps)
            self.format_combo.setCurrentIndex(max(0, self.format_combo.findData(s.format)))
            self._fill_sizes()
            self._select_size(s.size)
            lat = s.latitude if s.latitude is not None else getattr(exif, "latitude", None)
            lon = s.longitude if s.longitude is not None else getattr(exif, "longitude", None)
            self.lat_box.setValue(lat or 0.0)
            self.lon_box.setValue(lon or 0.0)
            when = getattr(exif, "capture_time", None)
            if s.date:
                day = dt.date.fromisoformat(s.date)
            else:
                day = when.date() if when is not None else dt.date.today()
            self.date_edit.setDate(QDate(day.year, day.month, day.day))
            offset, own = s.utc_offset, tl.photo_utc_offset(exif)
            if offset is None and own is not None:
                offset = own
                self._zone_from = "exif"
            elif offset is None:  # guessed, and guessed again when the longitude changes
                offset = tl.default_utc_offset(lon or 0.0)
                self._zone_from = "longitude"
            else:
                self._zone_from = "saved"
            self.offset_box.setValue(offset)
            self.main.timelapse_auto_offset = (offset if self._zone_from == "longitude"
                                               else None)
            self.daylight_check.setChecked(not (s.start and s.end))
            if s.start:
                self.start_edit.setTime(QTime.fromString(s.start, "HH:mm"))
            if s.end:
                self.end_edit.setTime(QTime.fromString(s.end, "HH:mm"))
            heading = s.heading
            if heading is None:
                heading = self._solved_heading()
            if heading is None and getattr(exif, "heading_deg", None) is not None:
                heading = exif.heading_deg
            self.heading_box.setValue(heading if heading is not None else 180.0)
            if s.heading is None:  # filled in, not typed: filled in again next time
                self.main.timelapse_auto_heading = self.heading_box.value()
        finally:
            for w in widgets:
                w.blockSignals(False)
        self._ready = True
        self._on_daylight_toggled(self.daylight_check.isChecked())
        self._place_words = (
            "Place and date from the photo's EXIF." if lat is not None and lon is not None else
            "The photo has no GPS position: enter the place."
        )  # fmt: skip
        self._show_place_hint()
        solvable = self._solved_heading() is not None  # (and _unsolved says why not)
        self.solve_button.setEnabled(solvable)
        # Off: say why (a night-time EXIF clock's sun is below the horizon: a robustness trial).
        self.solve_button.setToolTip(
            SOLVE_TIP if solvable else
            f"Off: {self._unsolved}" if self._unsolved else
            "Off: the heading is solved from the photo's EXIF capture time and GPS, and this "
            "photo has not both")
        self.main.set_timelapse_settings(self.settings(), shown=True)
        self._settings_changed()

    def _fill_sweep(self, s: TimelapseSettings) -> None:
        """A sweep the user never set (the defaults) shown from the photo's confirmed sun to
        the new sun (:meth:`MainWindow.sweep_suns`), and remembered as filled in
        (``timelapse_auto_sweep``: a project does not keep it)."""
        self.main.timelapse_auto_sweep = None
        default = TimelapseSettings()
        suns = self.main.sweep_suns()
        if (s.sweep_from, s.sweep_to) != (default.sweep_from, default.sweep_to) or suns is None:
            return
        self.from_az.setValue(suns[0].azimuth % 360.0)
        self.from_el.setValue(suns[0].elevation)
        self.to_az.setValue(suns[1].azimuth % 360.0)
        self.to_el.setValue(suns[1].elevation)
        self.main.timelapse_auto_sweep = (Sun(self.from_az.value(), self.from_el.value()),
                                          Sun(self.to_az.value(), self.to_el.value()))

    def settings(self) -> TimelapseSettings:
        """The settings the widgets show."""
        d = self.date_edit.date()
        daylight = self.daylight_check.isChecked()
        return TimelapseSettings(
            kind=str(self.kind_combo.currentData()),
            sweep_from=Sun(self.from_az.value(), self.from_el.value()),
            sweep_to=Sun(self.to_az.value(), self.to_el.value()),
            way=str(self.way_combo.currentData()),
            frames=self.frames_box.value(),
            easing=str(self.easing_combo.currentData()),
            date=dt.date(d.year(), d.month(), d.day()).isoformat(),
            latitude=self.lat_box.value(),
            longitude=self.lon_box.value(),
            heading=self.heading_box.value(),
            start="" if daylight else self.start_edit.time().toString("HH:mm"),
            end="" if daylight else self.end_edit.time().toString("HH:mm"),
            utc_offset=self.offset_box.value(),
            fps=self.fps_box.value(),
            format=str(self.format_combo.currentData()),
            full_resolution=self.size() == "full",
            size=self.size(),
        )

    def size(self) -> str:
        """The chosen frame size (one of
        :data:`outcast_core.runtime.pipeline.timelapse.FRAME_SIZES`)."""
        return str(self.size_combo.currentData())

    def _shapes(self) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """``(photo, working)`` sizes ``(H, W)`` of the open photo, if any."""
        session = self.main.session
        full = getattr(session, "full_image_srgb", None)
        work = getattr(session, "image_srgb", None)
        if full is None or work is None:
            return None
        return tuple(full.shape[:2]), tuple(work.shape[:2])  # type: ignore[return-value]

    def frame_shape(self) -> tuple[int, int] | None:
        """``(H, W)`` of the frames at the chosen size."""
        shapes = self._shapes()
        return None if shapes is None else tl.frame_shape(self.size(), *shapes)

    def _fill_sizes(self) -> None:
        """The size menu for this photo (:func:`size_entries`), the chosen size kept."""
        shapes = self._shapes()
        chosen = self.size()
        self.size_combo.clear()
        for key, label, tip in size_entries(*(shapes or (None, None))):
            self.size_combo.addItem(label, key)
            self.size_combo.setItemData(self.size_combo.count() - 1, tip,
                                        Qt.ItemDataRole.ToolTipRole)
        self._select_size(chosen)

    def _select_size(self, key: str) -> None:
        """Choose ``key``'s entry, or the one of its frame size when the menu lists that
        size under another name (a project's "4k" for a photo smaller than 4K: "full")."""
        index = self.size_combo.findData(key)
        shapes = self._shapes()
        if index < 0 and shapes is not None and key in tl.FRAME_SIZES:
            shape = tl.frame_shape(key, *shapes)
            index = next((i for i in range(self.size_combo.count())
                          if tl.frame_shape(str(self.size_combo.itemData(i)), *shapes) == shape),
                         -1)
        self.size_combo.setCurrentIndex(max(0, index))

    def _estimate_key(self) -> tuple[Any, ...]:
        """What an export's time depends on besides its number of frames: the photo as loaded
        (and its depth), the preset, the frame size, the format, and step 2's exposure, light
        (the new sun's daylight or the photo's) and relighting (:class:`~app.state.RelitLook`)."""
        return (self.main.loads, self.main.preset, self.frame_shape(),
                str(self.format_combo.currentData()), self.main.relight_panel.look())

    def estimate(self) -> float | None:
        """Estimated seconds to export the current path at the chosen size and format: from a
        short export of it timed in the worker (:meth:`_time_export`), or the last export
        at these settings; None until one was timed."""
        timing = self._timings.get(self._estimate_key())
        if timing is None or not self._samples:
            return None
        return timing.seconds_for(len(self._samples))

    def _update_estimate(self, *_args: Any) -> None:
        """The frames, their size, the video's length and the time to export them (timed
        first when these settings were not)."""
        shape = self.frame_shape()
        if shape is None or not self._samples:
            self.estimate_label.setText("")
            return
        n, fps = len(self._samples), self.fps_box.value()
        key = self._estimate_key()
        timing = self._timings.get(key)
        seconds = None if timing is None else timing.seconds_for(n)
        untimed = key in self._untimed
        if seconds is None and not untimed:
            self._time_export()
        how_long = (f"{tl.describe_seconds(seconds)} to export" if seconds is not None
                    else "the export could not be timed" if untimed
                    else "timing a short export…")
        self.estimate_label.setText(f"{n} frames of {shape[1]} × {shape[0]}, "
                                    f"{video_length(n, fps)} at {fps:g} fps: {how_long}")
        self.estimate_label.setToolTip(
            "" if timing is None else
            f"From an export of {timing.frames} frames of this path at this size and format, "
            f"timed on this computer ({timing.seconds:.1f} s); a busy computer is slower")
        if self._ready:
            self.main.set_timelapse_settings(self.settings())

    def _time_export(self) -> None:
        """Time what an export does, for :meth:`estimate`: :data:`ESTIMATE_FRAMES` frames of
        this path, spread evenly along it (one fewer above :data:`ESTIMATE_LARGE_MP` megapixels
        a frame), relit as an export relights them (the
        next sun's shadow beside this one's relighting, a thread each), made at the chosen
        size and written in the chosen format to a temporary file, in the worker. The
        estimate from the last interactive relighting's stages timed another thing (the
        networks on every core, one after the other, not the export's one thread each side
        by side; and whatever ran last) and was 4x off at working size (a user trial: 3 s
        estimated for 11.6 s). Not while hidden or exporting. A timing of other settings still
        under way is cancelled (its result would be for nobody, and hold up this one)."""
        session = self.main.session
        if (session is None or session.original_sun is None or not self.isVisible()
                or self._exporting or not self._samples):
            return
        key = self._estimate_key()
        if key == self._timing_key:  # timing these settings already (a review)
            return
        shape = key[2]
        n = len(self._samples)
        k = min(n, ESTIMATE_FRAMES - (shape[0] * shape[1] > ESTIMATE_LARGE_MP * 1e6))
        picks = [self._samples[round((i + 1) * (n - 1) / (k + 1))] for i in range(k)]
        size, fmt, fps = self.size(), key[3], self.fps_box.value()
        look, edits = key[4], self.main.shadow_edits
        exposure = look.exposure

        def job(ctx: JobContext) -> dict[str, Any]:
            stamps: list[float] = []
            try:  # all of it: a failure is said for its settings, never timed again (a review)
                session.set_shadow_edits(edits)  # as the export does
                look.apply(session)
                with tempfile.TemporaryDirectory(prefix="outcast-estimate-") as folder:
                    out = Path(folder) / ("frames" if fmt == "png" else f"estimate.{fmt}")
                    t0 = time.perf_counter()
                    tl.render_timelapse(
                        session, picks, out, fps=fps, size=size, fmt=fmt,
                        progress=lambda _stage, _f: stamps.append(time.perf_counter() - t0),
                        cancel=ctx.cancel_event, exposure=exposure,
                    )  # fmt: skip
                    total = time.perf_counter() - t0
            except (JobCancelledError, tl.ExportCancelledError):
                raise
            except Exception as exc:  # said under the size, for these settings (its key)
                if ctx.cancelled():  # stopped (for another job, or for good), not failed
                    raise JobCancelledError("timing cancelled") from exc
                return {"key": key, "failed": exc}
            return {"key": key, "timing": ExportTiming.from_stamps(stamps, total)}

        self.main.runner.cancel("tl_estimate")  # timing other settings: for nobody now
        self._timing_key = key
        self.main.runner.submit("tl_estimate", job, "Timing a short time-lapse export")

    def samples(self) -> list[tl.SunSample]:
        """The current sun path (ValueError when the settings are incomplete)."""
        return samples_for(self.settings(), self.main.camera_tilt[:2])

    def exporting(self) -> bool:
        """Whether an export from this dialog runs (its progress and Cancel are here)."""
        return self._exporting

    def is_current(self) -> bool:
        """Whether the widgets hold the open photo's settings (not before :meth:`load_settings`,
        nor once :meth:`set_stale` said another photo was opened)."""
        return self._ready

    def set_stale(self) -> None:
        """Another photo was opened: hidden, and its widgets (the last photo's place, day,
        heading) no longer read or written back until :meth:`load_settings` (a review found a
        hidden dialog writing one photo's settings into the next photo's project)."""
        self.hide()
        self._ready = False

    def refresh_path(self) -> None:
        """Recompute the sun path (the photo's camera tilt has changed)."""
        self._settings_changed()

    def refresh_preview(self) -> None:
        """Draw the shown frame again (the exposure, the light or the shadow corrections have
        changed), and say the export's time for them (timed again for another exposure or
        light)."""
        self._on_scrub(self.scrubber.value())
        self._update_estimate()

    def _offset_guessed(self) -> bool:
        """Whether the local time's offset is still the one guessed from the longitude (the
        user has not typed another)."""
        auto = getattr(self.main, "timelapse_auto_offset", None)
        return auto is not None and abs(self.offset_box.value() - auto) < 1e-6

    def _show_place_hint(self) -> None:
        """The place hint, with where the local time's offset comes from: the EXIF's is said,
        a guess from the longitude is said to be one (national time zones and summer time
        differ from it by an hour or more, and every time of the day moves with it)."""
        zone = ""
        if self._offset_guessed():
            zone = (f" Local time UTC{self.offset_box.value():+g}\u00a0h is guessed from the "
                    "longitude (the photo's EXIF gives no time zone): correct it if the place "
                    "keeps another.")
        elif (self._zone_from == "exif" and self._exif_offset() is not None
              and abs(self.offset_box.value() - self._exif_offset()) < 1e-6):
            zone = " Local time's offset from the photo's EXIF."
        self.place_hint.setText(self._place_words + zone)

    def _exif_offset(self) -> float | None:
        exif = getattr(self.main.loaded, "exif", None)
        tz = getattr(exif, "tz_offset", None)
        return None if tz is None else tz.total_seconds() / 3600.0

    def _on_longitude_changed(self, value: float) -> None:
        """A longitude typed while the offset is the guessed one: guessed again from it."""
        if self._ready and self._offset_guessed():
            guess = tl.default_utc_offset(value)
            self.main.timelapse_auto_offset = guess
            self.offset_box.setValue(guess)
        self._show_place_hint()

    def _on_daylight_toggled(self, checked: bool) -> None:
        self.start_edit.setEnabled(not checked)
        self.end_edit.setEnabled(not checked)
        self._settings_changed()

    def _settings_changed(self, *_args: Any) -> None:
        if not self._ready:
            return
        self.main.set_timelapse_settings(self.settings())
        try:
            self._samples = self.samples()
        except ValueError as exc:
            self._samples = []
            self.estimate_label.setText("")
            self.status.setText(f"⚠ {exc}")
            self.export_button.setEnabled(False)
            return
        self.status.setText("")
        first, last = self._samples[0].time, self._samples[-1].time
        if self.daylight_check.isChecked() and first is not None and last is not None:
            for edit, t in ((self.start_edit, first), (self.end_edit, last)):
                edit.blockSignals(True)
                edit.setTime(QTime(t.hour, t.minute))
                edit.blockSignals(False)
        self.export_button.setEnabled(not self._exporting)
        self.scrubber.blockSignals(True)
        self.scrubber.setRange(0, len(self._samples) - 1)
        self.scrubber.blockSignals(False)
        self._on_scrub(self.scrubber.value())  # (its frame first, then the export's timing)
        self._update_estimate()

    # ------------------------------------------------------------------ heading
    def _solved_heading(self) -> float | None:
        """The heading solved from the aligned sun and the photo's EXIF time and GPS, or None
        (:attr:`_unsolved` then says why, when it is the sun below the horizon then)."""
        self._unsolved = ""
        exif = getattr(self.main.loaded, "exif", None)
        when = getattr(exif, "capture_time", None)
        lat, lon = getattr(exif, "latitude", None), getattr(exif, "longitude", None)
        if when is None or lat is None or lon is None or self.main.original_sun is None:
            return None
        offset = None
        if when.tzinfo is None:
            offset = self.offset_box.value()
        sun = self.main.original_sun
        try:
            return tl.solve_heading(when, lat, lon, sun.azimuth, offset,
                                    original_elevation=sun.elevation,
                                    tilt=self.main.camera_tilt[:2])
        except tl.SunBelowHorizonError as exc:  # a night-time EXIF clock: none from it
            self._unsolved = str(exc)
            return None

    def solve_heading(self) -> float | None:
        heading = self._solved_heading()
        if heading is not None:
            self.heading_box.setValue(round(heading, 1))
            tilt = self.main.tilt_note()
            self.status.setText(
                f"Heading {heading:.1f}° solved from the aligned sun and the photo's time and GPS"
                f"{f', for a {tilt}' if tilt else ''}."
            )
        return heading

    # ------------------------------------------------------------------ preview
    def _on_scrub(self, index: int) -> None:
        if not self._samples:
            return
        index = max(0, min(index, len(self._samples) - 1))
        s = self._samples[index]
        when = f" · {s.time:%H:%M}" if s.time is not None else ""
        below = " (below the horizon: shown at the horizon)" if s.elevation < 0 else ""
        # The real sun is given against the horizon and the camera's heading (its frame: the
        # photo's tilt); a sweep in the dial's (the camera's) angles.
        frame = " above the horizon" if any(s.tilt) and s.elevation >= 0 else ""
        look = self.main.relight_panel.look()  # as the user sees it now
        # Step 2's relighting when it is not the default (a user trial: the dialog never said
        # which one its frames and the export use)
        how = ", physics relighting" if look.relighting == "physics" else ""
        self._caption = (f"Frame {index + 1}/{len(self._samples)}{when} · azimuth "
                         f"{s.azimuth:.1f}°, elevation {s.elevation:.1f}°{frame}{below} · quick "
                         f"preview{how}")
        self.caption.setText(self._caption)
        session = self.main.session
        if session is None or session.original_sun is None or not self.isVisible():
            return  # (hidden: drawn when shown; a closed dialog's frame, redrawn after a
            # change of quality, said "rendering time-lapse frame took …": a user trial)
        w = tl.sun_vectors([s])[0]
        exposure = look.exposure
        edits = self.main.shadow_edits  # the photo's shadows as corrected now

        def job(ctx: JobContext) -> dict[str, Any]:
            session.set_shadow_edits(edits)
            look.apply(session)  # (in the worker: MainWindow.set_daylight, set_relighting)
            relit = session.relight(w, preview=True, exposure=exposure)
            # A dark frame with the photo's exposure kept (dawn, dusk) is said with what to
            # do, as the command line says it.
            dark = (exposure == "photo" and session.image_srgb is not None
                    and exposure_level(session.image_srgb, relit) * EXPOSURE_HINT_FACTOR < 1.0)
            return {"index": index, "image": display.to_uint8_rgb(relit), "dark": dark}

        self.main.runner.submit("tl_preview", job, "Rendering time-lapse frame")

    def _show_preview(self) -> None:
        if self._preview_pixmap is None:
            return
        self.preview.setPixmap(
            self._preview_pixmap.scaled(
                self.preview.size(),
                Qt.AspectRatioMode.KeepAspectRatio,
                Qt.TransformationMode.SmoothTransformation,
            )
        )

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._show_preview()

    def showEvent(self, event: Any) -> None:  # noqa: N802 (Qt's name)
        super().showEvent(event)
        if self._ready:  # the frame and the estimate as the settings are now
            self._on_scrub(self.scrubber.value())
            self._update_estimate()

    def hideEvent(self, event: Any) -> None:  # noqa: N802 (Qt's name)
        super().hideEvent(event)
        self.main.runner.cancel("tl_estimate")  # for nobody now
        self._timing_key = None

    # ------------------------------------------------------------------ export
    def export_dialog(self) -> None:
        fmt = str(self.format_combo.currentData())
        filt = next(f for k, _, f in FORMAT_CHOICES if k == fmt)
        stem = Path(self.main.image_path).stem or "timelapse"
        ext = "" if fmt == "png" else f".{fmt}"
        # In the folder of the last export, as the still's dialog (a user trial: this one
        # always offered the photo's folder).
        suggestion = str(Path(self.main.export_folder()) / f"{stem}_timelapse{ext}")
        typed, _ = QFileDialog.getSaveFileName(self, "Export time-lapse", suggestion, filt)
        if not typed:
            self.status.setText("")  # (not a refusal kept from an earlier try)
            return
        # The format chosen in this dialog: its extension, unless the name has one of its own
        # ("tl.m4v" for MP4; "tl.gif" for MP4 becomes "tl.gif.mp4").
        path = with_filter_extension(typed, filt, (s for s, f in tl.VIDEO_SUFFIXES.items()
                                                   if f == fmt))
        # The save dialog has asked before replacing the name typed; the main window asks
        # about a name this dialog completed.
        if self.main.may_write_completed(typed, path):
            self.main.remember_export_folder(path)
            self.export(path, force=True)
        else:
            self.status.setText("")  # (not a refusal kept from an earlier try)

    def export(self, path: str, force: bool = False) -> int | None:
        """Render the path's frames and write them; progress and cancel in this dialog."""
        session = self.main.session
        if (session is None or session.original_sun is None or self._exporting
                or self.main.step is not Step.RELIGHT):  # (re-aligning: no confirmed sun)
            return None
        try:
            samples = self.samples()
        except ValueError as exc:
            return self._refuse(exc)
        fmt = str(self.format_combo.currentData())
        fps = self.fps_box.value()
        size = self.size()
        own = self.main.own_file_error(path)
        if own is not None:  # never, even confirmed (a WebP photo, say)
            return self._refuse(own)
        if not force and os.path.exists(path):
            return self._refuse(FileExistsError(f"'{path}' already exists"))
        problem = tl.frames_folder_problem(path) if fmt == "png" else None
        if problem:  # never empty a folder the user keeps other files in
            return self._refuse(IsADirectoryError(problem))

        look = self.main.relight_panel.look()  # as asked, whatever is chosen later
        exposure = look.exposure
        edits = self.main.shadow_edits  # and the shadow corrections
        key = self._estimate_key()

        def job(ctx: JobContext) -> dict[str, Any]:
            session.set_shadow_edits(edits)
            look.apply(session)  # the stream takes them as it starts
            t0 = time.perf_counter()
            out = tl.render_timelapse(
                session, samples, path, fps=fps, size=size, fmt=fmt, force=force,
                progress=ctx.progress, cancel=ctx.cancel_event, exposure=exposure,
            )  # fmt: skip
            seconds = time.perf_counter() - t0
            return {"path": str(out), "frames": len(samples), "timings": dict(session.timings),
                    "key": key, "timing": ExportTiming(len(samples), seconds,
                                                       seconds / len(samples))}

        self.main.runner.cancel("tl_estimate")  # the worker is the export's now
        self._timing_key = None
        self._set_exporting(True)
        self.progress.setValue(0)
        self.progress.setTextVisible(True)
        self.progress.setVisible(True)
        shape = self.frame_shape()
        pixels = f" of {shape[1]} × {shape[0]}" if shape is not None else ""
        self.status.setText(f"Exporting {len(samples)} frames{pixels} to {os.path.basename(path)}…")
        return self.main.runner.submit("tl_export", job, f"Exporting {os.path.basename(path)}")

    def _refuse(self, exc: BaseException) -> None:
        """An export refused before it starts: the dialog (a warning when it kept a file, an
        error otherwise), and the status line says so
        (it still said the last export's "Saved 24 frames to …": a user trial)."""
        self.main.show_error(exc, "export")
        self._say_failed(exc)

    def _say_failed(self, exc: BaseException) -> None:
        """The status line for an export that failed or was refused, in the error dialog's
        words: a folder that cannot be written is named, never the hidden temporary file
        (``.clip.p20hmmbi.part.mp4``, "[Errno 1] ...": a user trial)."""
        msg = message_for(exc, "export")
        self.status.setText(f"{msg.title}: {msg.what}. {msg.todo}")

    def cancel_export(self) -> None:
        if self._exporting:
            self.status.setText("Cancelling…")
            self.main.runner.cancel("tl_export")

    def _set_exporting(self, on: bool, finished: bool = False) -> None:
        """An export starts or ends; one that stopped short (cancelled or failed) leaves no
        percentage under "nothing was written" (a user trial saw "0 %"), a finished one its
        "100 %"."""
        self._exporting = on
        self.export_button.setEnabled(not on and bool(self._samples))
        self.cancel_button.setEnabled(on)
        if not on:
            self.progress.setTextVisible(finished)
            self.progress.setVisible(finished)
            if finished:
                self.progress.setValue(self.progress.maximum())

    # ---- called by the main window (GUI thread)
    def on_export_progress(self, fraction: float) -> None:
        self.progress.setValue(round(100 * fraction))

    def on_job_finished(self, channel: str, result: dict[str, Any]) -> None:
        if channel == "tl_preview":
            if result["index"] == self.scrubber.value():
                self._preview_pixmap = QPixmap.fromImage(qimage_from_array(result["image"]))
                self._show_preview()
                self.caption.setText(self._caption + (DARK_FRAME_WORDS if result.get("dark")
                                                      else ""))
            return
        if channel == "tl_estimate":
            if result["key"] == self._timing_key:
                self._timing_key = None
            if "failed" in result:  # these settings' timing, not the current ones'
                self._untimed.add(result["key"])
            else:
                self._timings[result["key"]] = result["timing"]
            self._update_estimate()
            return
        # An export done: how long these settings take from now on.
        self._timings[result["key"]] = result["timing"]
        self._set_exporting(False, finished=True)
        self.last_export = result["path"]
        self.last_result = "finished"
        self.status.setText(f"Saved {result['frames']} frames to {result['path']}")
        self._update_estimate()

    def on_export_cancelled(self) -> None:
        self._set_exporting(False)
        self.progress.setValue(0)
        self.last_result = "cancelled"
        self.status.setText("Export cancelled; nothing was written.")
        self._update_estimate()  # (its timing was cancelled for the export)

    def on_job_failed(self, channel: str, exc: BaseException) -> None:
        if channel == "tl_export":
            self._set_exporting(False)
            self.last_result = "failed"
            self._say_failed(exc)
            self._update_estimate()
        elif channel == "tl_estimate":  # (a timing's own failure comes back as its result)
            if self._timing_key is not None:  # not timed again for these settings
                self._untimed.add(self._timing_key)
            self._timing_key = None
            self._update_estimate()

    def closeEvent(self, event: QCloseEvent) -> None:
        if self._ready:
            self.main.set_timelapse_settings(self.settings())
        super().closeEvent(event)
