"""Tab goes through each step's side panel in the order its controls stand on screen."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QWidget

from app.state import Step


def _tab_order(start: QWidget, among: list[QWidget]) -> list[QWidget]:
    """The widgets of ``among`` in the order Tab reaches them from ``start`` (the focus chain;
    a spin box's line edit stands for its box, its focus proxy)."""
    order: list[QWidget] = []
    widget = start
    for _ in range(500):
        owner = next((w for w in among if w is widget or w.focusProxy() is widget), None)
        if owner is not None and owner not in order:
            order.append(owner)
        widget = widget.nextInFocusChain()
        if widget is start:
            break
    return order


def test_step_2_tabs_through_the_correction_tools_before_the_buttons_below(window):
    """A user trial: Tab went from "Keep the photo's light" to Export still, Time-lapse and
    Re-align, then to the correction tools, which stand above them on screen."""
    rp = window.relight_panel
    sun = rp.sun_panel
    tools = list(rp.shadow_tool_buttons.values())
    assert [b.text() for b in tools] == ["Not a shadow", "Mark shadow"]
    screen = [sun.dial, sun.azimuth_box, sun.elevation_box, rp.view_combo, rp.split_slider,
              rp.meter_check, rp.keep_light_check, *tools, rp.brush_box,
              rp.clear_shadow_edits_button, rp.realign_button, rp.export_button,
              rp.timelapse_button]
    assert all(w.focusPolicy() & Qt.FocusPolicy.TabFocus for w in screen)
    assert _tab_order(sun.dial, screen) == screen


def test_step_1_tabs_in_screen_order(window):
    """Step 1: Find sun stands above the EXIF button and the heading box (it was made after
    them)."""
    ap = window.align_panel
    sun = ap.sun_panel
    screen = [sun.dial, sun.azimuth_box, sun.elevation_box, ap.find_button, ap.exif_button,
              ap.heading_box, ap.opacity_slider, ap.confirm_button]
    assert _tab_order(sun.dial, screen) == screen


def test_tab_reaches_the_tools_from_the_light_boxes(qtbot, window, photo, settle):
    """With the tools shown (a view of the photo's shadows), Tab from the last light box goes
    to "Relighting", then "Not a shadow", then "Mark shadow"; from "Re-align" it goes to the
    footer's Export still."""
    window.open_path(photo)
    settle()
    window.confirm_original_sun()
    settle()
    assert window.step is Step.RELIGHT
    rp = window.relight_panel
    rp.set_view("shadows_found")
    settle()
    assert rp.shadow_tools.isVisible()
    rp.keep_light_check.setFocus(Qt.FocusReason.OtherFocusReason)
    qtbot.waitUntil(rp.keep_light_check.hasFocus)
    qtbot.keyClick(rp.keep_light_check, Qt.Key.Key_Tab)
    assert rp.relighting_combo.hasFocus()
    qtbot.keyClick(rp.relighting_combo, Qt.Key.Key_Tab)
    assert rp.shadow_tool_buttons["not_shadow"].hasFocus()
    qtbot.keyClick(rp.shadow_tool_buttons["not_shadow"], Qt.Key.Key_Tab)
    assert rp.shadow_tool_buttons["shadow"].hasFocus()
    rp.realign_button.setFocus(Qt.FocusReason.OtherFocusReason)
    qtbot.waitUntil(rp.realign_button.hasFocus)
    qtbot.keyClick(rp.realign_button, Qt.Key.Key_Tab)
    assert rp.export_button.hasFocus()


def test_the_side_panel_s_scroll_area_is_no_tab_stop(window):
    """Tab stopped on the side panel's scroll area, which shows no focus (a keyboard trial):
    it is no stop of its own; its controls are."""
    scroll = window.side_scroll
    assert not scroll.focusPolicy() & Qt.FocusPolicy.TabFocus
    sun = window.relight_panel.sun_panel
    assert sun.dial.focusPolicy() & Qt.FocusPolicy.TabFocus
