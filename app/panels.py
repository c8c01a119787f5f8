"""The side panels of the two steps: align the original sun, then relight."""

from __future__ import annotations

from itertools import pairwise

from PySide6.QtCore import QEvent, QObject, QSize, Qt, Signal
from PySide6.QtGui import QColor, QHideEvent, QShowEvent
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLayout,
    QPushButton,
    QSlider,
    QStackedWidget,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from app.qt_sun_dial import SunDialPanel
from app.state import RelitLook
from outcast_core.runtime.pipeline.photo_shadows import MAX_BRUSH_RADIUS

VIEW_CHOICES = (
    ("output", "Relit photo"),
    ("shadows_removed", "Shadows removed"),
    ("shadows_found", "Shadows found"),
    ("depth", "Depth"),
    ("normals", "Normals"),
    ("original_shadow", "Original shadow"),
    ("new_shadow", "New shadow"),
    ("all", "All buffers"),
)

#: Step 2's "Relighting" (key: ``RelightSession.relight_mode``, text, tooltip), the default
#: first.
RELIGHTING_CHOICES = (
    ("learned", "Learned",
     "The relighting network, with guards that keep the photo's colours, texture and "
     "exposure: measured best on real photographs (the default)"),
    ("physics", "Physics",
     "The photo times the change of light each pixel gets from the depth: old shadows lifted "
     "and new ones darkened in full, but colours shift more where both suns light a surface "
     "and the depth's relief can show as embossing"),
)
RELIGHTING_TIP = ("How the photo is relit: Learned (the default) keeps the photo's colours and "
                  "texture; Physics follows the depth to the letter")

#: Step 2's shadow-correction tools: key, button text, tooltip, status-bar hint while on.
SHADOW_TOOLS = (
    ("not_shadow", "Not a shadow",
     "Click an area marked as shadow that is not one (a dark object, foliage, a black car): "
     "it is no longer lifted. Or drag to paint over what is not a shadow: all the brush "
     "covers where it touches a marked area is dropped, and nothing beyond (many small "
     "pieces, a shadow joined to a dark object). "
     "Undo (Ctrl+Z) takes the click or the stroke back; [ and ] size the brush; Esc ends the "
     "tool.",
     "Click a marked area that is not a shadow (a dark object, foliage), or drag to paint "
     "over it"),
    ("shadow", "Mark shadow",
     "Click inside a shadow the app missed: the area of even brightness around the point is "
     "added and lifted. Or drag to paint the shadow with the brush: only the shadow under the "
     "stroke is added, not the lit ground it crosses. Undo (Ctrl+Z) takes the click or the "
     "stroke back; [ and ] size the brush; Esc ends the tool.",
     "Click inside a shadow the app missed, or drag to paint it"),
)


#: What step 1's "Sun from photo's EXIF" does (its tooltip when no note says more).
EXIF_BUTTON_TIP = "Place the sun from the photo's GPS position, capture time and compass heading"
#: The tools' hint while none is on.
SHADOW_TOOL_IDLE = ("Turn a tool on, then click or paint on the photo; magenta marks the "
                    "shadows found.")
#: The brush's size (radius, % of the photo's longer side): default, range (up to the
#: runtime's :data:`~outcast_core.runtime.pipeline.photo_shadows.MAX_BRUSH_RADIUS`, which the
#: CLI's ``X,Y,R`` and the project files keep to), and the factor ``[`` and ``]`` divide and
#: multiply it by.
BRUSH_DEFAULT = 2.0
BRUSH_RANGE = (0.5, 100.0 * MAX_BRUSH_RADIUS)
BRUSH_STEP = 1.25


def _header(text: str, hint: str, parent: QWidget) -> tuple[QWidget, QLabel]:
    """The step's title, in a widget of its own the window pins above the scrolling panel
    (``header``): scrolled to a tool below the dial on a small screen, the panel cut the title
    in half (a user trial); and the hint below it, in the panel."""
    header = QWidget(parent)
    title = QLabel(f"<span style='font-size:13pt; font-weight:600'>{text}</span>", header)
    row = QVBoxLayout(header)
    row.setContentsMargins(9, 9, 9, 0)
    row.addWidget(title)
    body = QLabel(hint, parent)
    body.setWordWrap(True)
    return header, body


def chain_tab_order(widgets: list[QWidget]) -> None:
    """Tab goes through ``widgets`` in this order (the order they stand on screen, top to
    bottom; Qt's default is the order they were made in)."""
    for first, second in pairwise(widgets):
        QWidget.setTabOrder(first, second)


def _percent_slider(value: int, parent: QWidget) -> QSlider:
    s = QSlider(Qt.Orientation.Horizontal, parent)
    s.setRange(0, 100)
    s.setValue(value)
    s.setSingleStep(5)
    s.setPageStep(10)
    return s


class PanelStack(QStackedWidget):
    """The steps' panels in the side panel's scroll area, as tall as the shown one needs at
    its least (:meth:`QLayout.minimumHeightForWidth`: the dial at its smallest, text
    wrapped at the panel's width): the scroll area gives it the room there is, and scrolls
    only when that is less. As a plain stack it asked for every panel's preferred height
    (the dial as wide as tall, and the tallest page's), so a window 800 pixels high cut off
    step 2's corrections and one 700 high hid its tools below the fold (a user trial)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.currentChanged.connect(lambda _i: self.updateGeometry())

    def _page_layout(self) -> QLayout | None:
        page = self.currentWidget()
        return None if page is None else page.layout()

    def heightForWidth(self, width: int) -> int:  # noqa: N802 (Qt's name)
        layout = self._page_layout()
        if layout is None:
            return super().heightForWidth(width)
        least = layout.minimumHeightForWidth(width) if layout.hasHeightForWidth() else -1
        return least if least > 0 else layout.minimumSize().height()

    def minimumSizeHint(self) -> QSize:  # noqa: N802 (Qt's name)
        layout = self._page_layout()
        return super().minimumSizeHint() if layout is None else layout.minimumSize()

    def sizeHint(self) -> QSize:  # noqa: N802 (Qt's name)
        page = self.currentWidget()
        return super().sizeHint() if page is None else page.sizeHint()


class SteppedSpinBox(QDoubleSpinBox):
    """A ``QDoubleSpinBox`` that tells a step from a typed value: :attr:`stepping` is true
    while it steps (arrow keys, Page Up/Down, its arrow buttons, the mouse wheel all step
    through :meth:`stepBy`), so the ``valueChanged`` it emits then can be told apart."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.stepping = False

    def stepBy(self, steps: int) -> None:  # noqa: N802 - Qt's name
        self.stepping = True
        try:
            super().stepBy(steps)
        finally:
            self.stepping = False


class AlignPanel(QWidget):
    """Step 1: drag the sun until the predicted shadows (tinted) match the photo's."""

    confirm_clicked = Signal()
    exif_clicked = Signal()
    find_sun_clicked = Signal()
    #: A heading entered: float (degrees from north) or None, and whether it came from a step
    #: (arrow keys, the box's arrows, the mouse wheel: :attr:`SteppedSpinBox.stepping`)
    #: rather than a typed value.
    heading_changed = Signal(object, bool)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.header, body = _header(
            "Step 1 · Find the photo's sun",
            "Drag the sun until the blue predicted shadows line up with the shadows in the "
            "photo, then confirm.",
            self,
        )
        # This step's warnings (the file, the depth source, what Find sun says): the window
        # places ``notice`` above the photo, across the canvas, and it shows while this step's
        # panel does. In the narrow panel, above the dial, a long one (Find sun's on the field
        # path) pushed the camera heading box it speaks of below the fold (a user trial).
        self.notice = QLabel(self)
        self.notice.setObjectName("step_notice")
        self.notice.setWordWrap(True)
        self.notice.setStyleSheet(  # (the label's own: its close button is not styled so)
            "QLabel#step_notice { background: #fff4d6; color: #5a4300; "
            "border: 1px solid #e0c070; border-radius: 4px; padding: 6px 28px 6px 8px; }"
        )
        self.notice.hide()
        # A long notice took a sixth of a 700-pixel-high window from the photo (a user
        # trial): it can be closed; it comes back when what it says changes (the status bar's
        # "Photo notes" keeps the load's part).
        self.notice_close = QToolButton(self.notice)
        self.notice_close.setText("\u00d7")
        self.notice_close.setAutoRaise(True)
        self.notice_close.setFixedSize(20, 20)
        self.notice_close.setStyleSheet(
            "QToolButton { color: #5a4300; border: none; padding: 0; font-size: 13pt; }"
            "QToolButton:hover { background: #f0dca8; border-radius: 3px; }")
        self.notice_close.setToolTip("Hide this note (it shows again when it changes)")
        self.notice_close.setAccessibleName("Hide the note")
        self.notice_close.clicked.connect(self.dismiss_notice)
        self.notice.installEventFilter(self)
        self._dismissed_notice = ""
        self.sun_panel = SunDialPanel("Original sun", QColor(255, 200, 40), self)
        self.exif_button = QPushButton("Sun from photo's EXIF", self)
        self.exif_button.setToolTip(EXIF_BUTTON_TIP)
        self.exif_button.setEnabled(False)
        self.exif_button.clicked.connect(self.exif_clicked)
        self.exif_note = QLabel(self)
        self.exif_note.setWordWrap(True)
        # The text's own colour: in palette(mid) it read as greyed out, hard to read (a user
        # trial); the button above is what is disabled.
        self.exif_note.setStyleSheet("font-size: 9pt;")
        self.exif_note.hide()
        self.heading_box = SteppedSpinBox(self)
        self.heading_box.setRange(-1.0, 359.9)
        self.heading_box.setDecimals(1)
        self.heading_box.setSuffix("°")
        self.heading_box.setWrapping(False)
        self.heading_box.setSpecialValueText("unknown")
        self.heading_box.setValue(-1.0)
        self.heading_box.setKeyboardTracking(False)
        self._heading_tip = (
            "The camera's compass heading (degrees clockwise from true north): with the "
            "photo's GPS position and time it gives the full sun. It replaces the one the "
            "photo's EXIF records, if any."
        )
        self.heading_box.setToolTip(self._heading_tip)
        self.heading_box.valueChanged.connect(
            lambda v: self.heading_changed.emit(None if v < 0 else float(v),
                                                self.heading_box.stepping)
        )
        self.find_button = QPushButton("Find sun from shadows", self)
        self.find_button.setToolTip(
            "Search the sky for the sun whose predicted shadows best match the shadows found in "
            "the photo (uses the photo's GPS and time when it has them; Ctrl+F). The dial shows "
            "how well each part of the sky fits."
        )
        self.find_button.clicked.connect(self.find_sun_clicked)
        self.opacity_slider = _percent_slider(60, self)
        self.opacity_slider.setToolTip("Opacity of the predicted-shadow overlay")
        self.opacity_label = QLabel("60 %", self)
        self.opacity_label.setMinimumWidth(40)
        self.opacity_slider.valueChanged.connect(lambda v: self.opacity_label.setText(f"{v} %"))
        self.confirm_button = QPushButton("Confirm sun  →", self)
        self.confirm_button.setDefault(True)
        self.confirm_button.setToolTip(
            "Fix this as the photo's sun and refine its shadows (Ctrl+Return)"
        )
        self.confirm_button.clicked.connect(self.confirm_clicked)

        row = QHBoxLayout()
        row.addWidget(QLabel("Overlay", self))
        row.addWidget(self.opacity_slider, 1)
        row.addWidget(self.opacity_label)
        layout = QVBoxLayout(self)
        layout.addWidget(body)
        layout.addWidget(self.sun_panel)
        layout.addWidget(self.find_button)
        layout.addWidget(self.exif_button)
        layout.addWidget(self.exif_note)
        heading_row = QHBoxLayout()
        heading_row.addWidget(QLabel("Camera heading", self))
        heading_row.addWidget(self.heading_box, 1)
        layout.addLayout(heading_row)
        layout.addLayout(row)
        layout.addStretch(1)
        # The step's main button sits below the scrolling panel (the window places
        # ``footer``), so it stays in view on a small screen.
        self.footer = QWidget(self)
        foot = QVBoxLayout(self.footer)
        foot.setContentsMargins(9, 4, 9, 6)
        foot.addWidget(self.confirm_button)
        sun = self.sun_panel
        chain_tab_order([sun.dial, sun.azimuth_box, sun.elevation_box, self.find_button,
                         self.exif_button, self.heading_box, self.opacity_slider,
                         self.confirm_button])

    def heading(self) -> float | None:
        """The heading typed by the user (degrees from north), or None."""
        v = self.heading_box.value()
        return None if v < 0 else float(v)

    def set_heading(self, heading: float | None, recorded: bool = False) -> None:
        """Show a heading without emitting ``heading_changed``; ``recorded``: it is the one the
        photo's EXIF records (said in the box and its tooltip)."""
        self.heading_box.blockSignals(True)
        self.heading_box.setValue(-1.0 if heading is None else float(heading) % 360.0)
        self.heading_box.blockSignals(False)
        self.mark_heading(recorded and heading is not None)

    def mark_heading(self, recorded: bool) -> None:
        """Say whether the heading shown is the EXIF's (``recorded``) or one typed."""
        self.heading_box.setPrefix("EXIF " if recorded else "")
        self.heading_box.setToolTip(
            "The camera's compass heading recorded in the photo's EXIF (degrees clockwise from "
            "true north); phone compasses are often off by tens of degrees: type another to "
            "correct it" if recorded else self._heading_tip)

    def set_finding(self, running: bool) -> None:
        """The find button becomes a cancel button while a search runs."""
        self.find_button.setText("Cancel finding the sun" if running else "Find sun from shadows")

    def set_exif_note(self, text: str) -> None:
        """Why the EXIF button is greyed out, or what the EXIF gives (hidden when empty), also
        the button's tooltip; without a note the button's own tooltip (a note that no longer
        holds stayed there: "No compass heading…" after a heading was typed, or for the next
        photo, which had one)."""
        self.exif_note.setText(text)
        self.exif_note.setVisible(bool(text))
        self.exif_button.setToolTip(text or EXIF_BUTTON_TIP)

    def show_notice(self, text: str) -> None:
        """A warning above the photo (hidden when empty, while another step is shown, and
        once closed until it says something else)."""
        if text != self._dismissed_notice:
            self._dismissed_notice = ""
        self.notice.setText(text)
        self._show_notice_if_any()

    def dismiss_notice(self) -> None:
        """Close the notice (its close button): it stays hidden until its text changes."""
        self._dismissed_notice = self.notice.text()
        self.notice.hide()

    def _show_notice_if_any(self) -> None:
        text = self.notice.text()
        self.notice.setVisible(bool(text) and not self.isHidden()
                               and text != self._dismissed_notice)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 (Qt's name)
        if watched is self.notice and event.type() == QEvent.Type.Resize:
            b = self.notice_close
            b.move(self.notice.width() - b.width() - 4, 4)  # its top right corner
        return super().eventFilter(watched, event)

    def showEvent(self, event: QShowEvent) -> None:  # noqa: N802 (Qt's name)
        super().showEvent(event)
        self._show_notice_if_any()

    def hideEvent(self, event: QHideEvent) -> None:  # noqa: N802 (Qt's name)
        super().hideEvent(event)
        self._show_notice_if_any()


class RelightPanel(QWidget):
    """Step 2: a target sun, before/after split, buffer views, exports."""

    export_still_clicked = Signal()
    timelapse_clicked = Signal()
    realign_clicked = Signal()
    exposure_changed = Signal(str)  # "photo" or "metered"
    #: "Keep the photo's light" cleared (True: the new sun's daylight) or ticked (False).
    daylight_changed = Signal(bool)
    #: "Relighting" chosen: ``"learned"`` or ``"physics"`` (``RelightSession.relight_mode``).
    relighting_changed = Signal(str)
    #: The shadow-correction tool turned on (a key of :data:`SHADOW_TOOLS`) or off (``""``).
    shadow_tool_changed = Signal(str)
    clear_shadow_edits_clicked = Signal()
    #: The brush's radius changed: a fraction of the photo's longer side.
    brush_changed = Signal(float)

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.header, body = _header(
            "Step 2 · Relight",
            "Drag the new sun (the faint one is the photo's own). View \u25b8 Shadows found "
            "shows the photo's shadows, to correct them.",
            self,
        )
        self.hint = body  # (hidden while the correction tools show: they have their own)
        self.sun_panel = SunDialPanel("New sun", QColor(255, 140, 30), self)
        self.view_combo = QComboBox(self)
        for key, text in VIEW_CHOICES:
            self.view_combo.addItem(text, key)
        self.view_combo.setToolTip(
            "What the canvas shows: the relit photo, the photo with its own shadows removed, "
            "the shadows found in it (tinted), or the buffers"
        )
        self.split_slider = _percent_slider(50, self)
        self.split_slider.setToolTip("Before/after split: left of the line is the original photo")
        self.meter_check = QCheckBox("Meter the new light", self)
        self.meter_check.setToolTip(
            "Expose the relit photo again, as a camera would at the new hour (one gain for the "
            "whole frame). Off: the photo's exposure is kept, so a scene the new sun puts in "
            "shade comes out dark."
        )
        self.meter_check.toggled.connect(
            lambda on: self.exposure_changed.emit("metered" if on else "photo"))
        self.keep_light_check = QCheckBox("Keep the photo's light", self)
        self.keep_light_check.setToolTip(
            "Off: the relit photo takes the new sun's daylight: near the horizon the sunlight "
            "is weaker and redder and the sky dimmer. On: the photo's light, its strength and "
            "colour, is kept at every sun."
        )
        self.keep_light_check.toggled.connect(lambda on: self.daylight_changed.emit(not on))
        self.relighting_combo = QComboBox(self)
        for key, text, tip in RELIGHTING_CHOICES:
            self.relighting_combo.addItem(text, key)
            self.relighting_combo.setItemData(self.relighting_combo.count() - 1, tip,
                                              Qt.ItemDataRole.ToolTipRole)
        self.relighting_combo.setToolTip(RELIGHTING_TIP)
        self.relighting_combo.currentIndexChanged.connect(
            lambda _i: self.relighting_changed.emit(self.relighting()))
        self.export_button = QPushButton("Export still…", self)
        self.export_button.setToolTip("Save the relit photo at full resolution (Ctrl+E)")
        self.timelapse_button = QPushButton("Time-lapse…", self)
        self.realign_button = QPushButton("←  Re-align original sun", self)
        self.realign_button.setFlat(True)
        self.export_button.clicked.connect(self.export_still_clicked)
        self.timelapse_button.clicked.connect(self.timelapse_clicked)
        self.realign_button.clicked.connect(self.realign_clicked)
        # Correcting the found shadows (the "Shadows found" / "Shadows removed" views only):
        # two checkable tools, at most one on (both may be off), and a reset.
        self.shadow_tools = QGroupBox("Correct the found shadows", self)
        self.shadow_tool_buttons: dict[str, QToolButton] = {}
        tools_row = QHBoxLayout()
        for key, text, tip, _hint in SHADOW_TOOLS:
            button = QToolButton(self.shadow_tools)
            button.setText(text)
            button.setCheckable(True)
            button.setToolTip(tip)
            button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
            # On must read as on at a glance (a user trial could not tell them apart).
            button.setStyleSheet("QToolButton:checked { background: palette(highlight); "
                                 "color: palette(highlighted-text); border-radius: 3px; "
                                 "padding: 3px 6px; }")
            button.toggled.connect(lambda on, k=key: self._on_tool_toggled(k, on))
            self.shadow_tool_buttons[key] = button
            tools_row.addWidget(button)
        tools_row.addStretch(1)
        self.clear_shadow_edits_button = QPushButton("Clear corrections", self.shadow_tools)
        self.clear_shadow_edits_button.setToolTip(
            "Take back every correction of the found shadows (undoable)")
        self.clear_shadow_edits_button.setEnabled(False)
        self.clear_shadow_edits_button.clicked.connect(self.clear_shadow_edits_clicked)
        self.shadow_edits_label = QLabel(self.shadow_tools)
        self.shadow_edits_label.setStyleSheet("font-size: 9pt;")
        # What the tool that is on does, in full (the status bar cuts it in a narrow window).
        self.shadow_tool_hint = QLabel(SHADOW_TOOL_IDLE, self.shadow_tools)
        self.shadow_tool_hint.setWordWrap(True)
        self.shadow_tool_hint.setStyleSheet("font-size: 9pt;")
        self.brush_box = QDoubleSpinBox(self.shadow_tools)
        self.brush_box.setRange(*BRUSH_RANGE)
        self.brush_box.setDecimals(1)
        self.brush_box.setSingleStep(0.5)
        self.brush_box.setSuffix(" %")
        self.brush_box.setValue(BRUSH_DEFAULT)
        self.brush_box.setAccessibleName("Brush size")
        self.brush_box.setToolTip(
            "The brush's radius, in % of the photo's longer side, when you drag to paint with "
            "a tool ([ and ] shrink and grow it)")
        self.brush_box.valueChanged.connect(lambda v: self.brush_changed.emit(v / 100.0))
        brush_row = QHBoxLayout()
        brush_row.addWidget(QLabel("Brush size", self.shadow_tools))
        brush_row.addWidget(self.brush_box)
        brush_row.addStretch(1)
        clear_row = QHBoxLayout()
        clear_row.addWidget(self.shadow_edits_label, 1)
        clear_row.addWidget(self.clear_shadow_edits_button)
        tools_layout = QVBoxLayout(self.shadow_tools)
        tools_layout.addLayout(tools_row)
        tools_layout.addLayout(brush_row)
        tools_layout.addWidget(self.shadow_tool_hint)
        tools_layout.addLayout(clear_row)
        self.set_shadow_edit_count(0)
        self.shadow_tools.hide()

        form = QFormLayout()
        form.addRow("View", self.view_combo)
        form.addRow("Before | after", self.split_slider)
        # Both change the relit photo's light: one row, packed (at 1024 x 700 a row of its own
        # took the dial's room).
        light = QVBoxLayout()
        light.setSpacing(0)
        light.addWidget(self.meter_check)
        light.addWidget(self.keep_light_check)
        form.addRow("Light", light)
        form.addRow("Relighting", self.relighting_combo)
        form.setVerticalSpacing(4)
        buttons = QHBoxLayout()
        buttons.addWidget(self.export_button)
        buttons.addWidget(self.timelapse_button)
        layout = QVBoxLayout(self)
        layout.addWidget(body)
        layout.addWidget(self.sun_panel)
        layout.addLayout(form)
        layout.addWidget(self.shadow_tools)
        layout.addStretch(1)
        # Below the scrolling panel, always in view: the way back to step 1 too (at 1024 x 700
        # with the correction tools shown it was below the fold: a user trial).
        self.footer = QWidget(self)
        footer = QVBoxLayout(self.footer)
        footer.setContentsMargins(9, 0, 9, 6)
        footer.setSpacing(2)
        footer.addWidget(self.realign_button, 0, Qt.AlignmentFlag.AlignLeft)
        buttons.setContentsMargins(0, 0, 0, 0)
        footer.addLayout(buttons)
        # The correction tools stand above "Re-align" and the footer's buttons, but were made
        # after them: Tab went from the light's boxes to Export still (a user trial).
        sun = self.sun_panel
        chain_tab_order([sun.dial, sun.azimuth_box, sun.elevation_box, self.view_combo,
                         self.split_slider, self.meter_check, self.keep_light_check,
                         self.relighting_combo,
                         *self.shadow_tool_buttons.values(), self.brush_box,
                         self.clear_shadow_edits_button, self.realign_button,
                         self.export_button, self.timelapse_button])

    def view(self) -> str:
        return str(self.view_combo.currentData())

    def exposure(self) -> str:
        """``"metered"`` when the new light is metered again, else ``"photo"``."""
        return "metered" if self.meter_check.isChecked() else "photo"

    def set_exposure(self, mode: str) -> None:
        """Show ``mode`` without emitting :attr:`exposure_changed`."""
        self.meter_check.blockSignals(True)
        self.meter_check.setChecked(mode == "metered")
        self.meter_check.blockSignals(False)

    def daylight(self) -> bool:
        """Whether relit photos take the new sun's daylight ("Keep the photo's light" clear)."""
        return not self.keep_light_check.isChecked()

    def set_daylight(self, on: bool) -> None:
        """Show ``on`` (the new sun's daylight) without emitting :attr:`daylight_changed`."""
        self.keep_light_check.blockSignals(True)
        self.keep_light_check.setChecked(not on)
        self.keep_light_check.blockSignals(False)

    def relighting(self) -> str:
        """Step 2's relighting: ``"learned"`` or ``"physics"``."""
        return str(self.relighting_combo.currentData())

    def set_relighting(self, mode: str) -> None:
        """Show ``mode`` without emitting :attr:`relighting_changed`."""
        self.relighting_combo.blockSignals(True)
        self.relighting_combo.setCurrentIndex(self.relighting_combo.findData(mode))
        self.relighting_combo.blockSignals(False)

    def set_learned_available(self, why_not: str) -> None:
        """Offer the learned relighting, or grey it out saying ``why_not`` (not ``""``)."""
        item = self.relighting_combo.model().item(self.relighting_combo.findData("learned"))
        item.setEnabled(not why_not)
        item.setToolTip(why_not or RELIGHTING_CHOICES[0][2])

    def learned_available(self) -> bool:
        """Whether the learned relighting may be chosen (:meth:`set_learned_available`)."""
        item = self.relighting_combo.model().item(self.relighting_combo.findData("learned"))
        return item.isEnabled()

    def look(self) -> RelitLook:
        """What a relighting takes from this panel as it is asked for."""
        return RelitLook(self.exposure(), self.daylight(), self.relighting())

    def set_view(self, key: str) -> None:
        idx = self.view_combo.findData(key)
        if idx >= 0:
            self.view_combo.setCurrentIndex(idx)

    # ---- correcting the found shadows
    def shadow_tool(self) -> str:
        """The shadow-correction tool that is on (a key of :data:`SHADOW_TOOLS`), or ``""``."""
        return next((k for k, b in self.shadow_tool_buttons.items() if b.isChecked()), "")

    def set_shadow_tool(self, key: str) -> None:
        """Turn the tool ``key`` on (the other off), or both off with ``""``; emits
        :attr:`shadow_tool_changed` when that changes what is on."""
        for k, button in self.shadow_tool_buttons.items():
            if k != key:
                button.setChecked(False)
        if key in self.shadow_tool_buttons:
            self.shadow_tool_buttons[key].setChecked(True)

    def _on_tool_toggled(self, key: str, on: bool) -> None:
        if on:  # exclusive, but both may be off (a QButtonGroup keeps one on)
            for k, button in self.shadow_tool_buttons.items():
                if k != key and button.isChecked():
                    button.blockSignals(True)
                    button.setChecked(False)
                    button.blockSignals(False)
        tool = self.shadow_tool()
        self.shadow_tool_hint.setText(next((hint for k, _, _, hint in SHADOW_TOOLS if k == tool),
                                           SHADOW_TOOL_IDLE))
        self.shadow_tool_changed.emit(tool)

    def show_shadow_tools(self, shown: bool) -> None:
        """Show the correction tools (the views of the photo's own shadows) or hide them, with
        the tool turned off; the step's hint shows when they do not."""
        if not shown:
            self.set_shadow_tool("")
        self.shadow_tools.setVisible(shown)
        self.shadow_tools.setEnabled(shown)
        # The step's hint (drag the sun; View > Shadows found to correct) is what the tools'
        # own words follow on from; hidden, its room goes to the dial (on a 700-pixel-high
        # window the panel scrolled and showed half of it: a user trial).
        self.hint.setVisible(not shown)

    def brush(self) -> float:
        """The brush's radius, a fraction of the photo's longer side."""
        return self.brush_box.value() / 100.0

    def set_brush(self, radius: float) -> None:
        """Set the brush's radius (a fraction of the longer side; kept within
        :data:`BRUSH_RANGE`); emits :attr:`brush_changed` when it changes."""
        self.brush_box.setValue(100.0 * radius)

    def step_brush(self, steps: int) -> None:
        """Grow (``steps > 0``) or shrink the brush by :data:`BRUSH_STEP` a step, as ``]`` and
        ``[`` do in photo editors (at least the box's last digit a step)."""
        box = self.brush_box
        old = box.value()
        new = round(old * BRUSH_STEP**steps, 1)
        if steps and new == old:
            new = old + (0.1 if steps > 0 else -0.1)
        box.setValue(new)

    def set_shadow_edit_count(self, count: int) -> None:
        """How many corrections there are (clicks and brush strokes): "Clear corrections" is
        enabled with any."""
        self.clear_shadow_edits_button.setEnabled(count > 0)
        self.shadow_edits_label.setText(
            "No corrections" if count == 0
            else f"{count} correction{'s' if count != 1 else ''}")
