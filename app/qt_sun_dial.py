"""``QtSunDial``: the sky hemisphere seen from above with a draggable sun, and its panel.

Maths lives in :mod:`app.sun_dial_math`; this module only paints and turns events into angles.
Painting happens in small overridable steps (``paint_sky``, ``paint_heat_map``, ``paint_grid``,
``paint_horizon``, ``paint_prior``, ``paint_camera``, ``paint_shadow_ruler``,
``paint_reference``, ``paint_sun``).
The heat map (:meth:`QtSunDial.set_heat_map`) shows how well suns over the dome explain the
photo's shadows ("Find sun"); the dashed ring (:meth:`QtSunDial.set_prior_elevation`) is the
elevation the photo's EXIF time and place give. The dial's angles are the camera's: for a camera
pitched or rolled (:meth:`QtSunDial.set_tilt`) that ring is drawn where the camera sees it, and
the suns under the true horizon are shaded (``paint_horizon``).

Keyboard (dial focused, a ring round the disc shows it): Left/Right turn the azimuth, Up/Down
raise/lower the sun; 1 degree per press, 10 with Shift, 0.1 with Ctrl.

The direction labels (front, right, behind, left) stand outside the disc, :data:`LABEL_GAP`
from its rim, at every size (:meth:`QtSunDial.label_rects`: the disc is made as large as leaves
them room); the shadow ruler stays inside the disc (:meth:`QtSunDial.shadow_ruler_line`) and
the elevation rings' labels move off the sun and the ruler
(:meth:`QtSunDial.ring_label_rects`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from PySide6.QtCore import QLineF, QPointF, QRectF, QSize, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QFocusEvent,
    QFont,
    QFontMetricsF,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPainterPath,
    QPainterPathStroker,
    QPaintEvent,
    QPen,
    QPolygonF,
    QRadialGradient,
)
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QGridLayout,
    QLabel,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from app import sun_dial_math as dm

HANDLE_RADIUS = 9.0
#: How far the sun's rays reach from its centre.
RAY_RADIUS = 15.0
#: Between the disc's rim and the direction labels: the focus ring (:data:`FOCUS_RING_WIDTH`
#: wide) is drawn in it, clear of both. A user trial saw "right" clipped by the disc in a
#: narrow panel (the labels' room was a fixed 22 px, and a label moved into the disc to stay
#: in the widget) and the shadow ruler's "…" on "behind".
LABEL_GAP = 6.0
FOCUS_RING_WIDTH = 2.0
#: The direction labels by azimuth.
DIRECTION_LABELS = {0: "front", 90: "right", 180: "behind", 270: "left"}
#: The dial's tooltip, and what it adds while a heat map shows.
DIAL_TIP = ("Drag the sun: around = azimuth, rim to centre = elevation.\n"
            "Arrow keys nudge 1°, Shift 10°, Ctrl 0.1°.")
HEAT_MAP_TIP = ("Coloured cells (Find sun): suns whose predicted shadows agree with the "
                "photo's better than a typical sun's; the more opaque and red, the better.")
#: The elevation rings (their dashed circles and labels).
RING_ELEVATIONS = (30.0, 60.0)
#: A capped shadow ruler (longer than the disc) ends this far inside the rim, in an arrowhead
#: :data:`RULER_ARROW` long that says it goes on; its ticks reach 4 px to each side.
RULER_INSET = 2.0
RULER_ARROW = 8.0
RULER_REACH = 5.0


class QtSunDial(QWidget):
    """Custom-painted sun dial.

    Signals:
        sun_changed(azimuth, elevation): the user moved the sun (drag, click or key).
        drag_started(): a drag began.
        drag_finished(azimuth, elevation): the mouse was released (time for a full-quality pass).
        sun_committed(azimuth, elevation): a final position (release or keyboard nudge).
    """

    sun_changed = Signal(float, float)
    drag_started = Signal()
    drag_finished = Signal(float, float)
    sun_committed = Signal(float, float)

    def __init__(self, parent: QWidget | None = None, colour: QColor | None = None):
        super().__init__(parent)
        self._azimuth = 135.0
        self._elevation = 45.0
        self._fov = 60.0
        self._vfov = 45.0
        self._dragging = False
        self._reference: tuple[float, float] | None = None
        self._heat: list[tuple[int, int, float, float, float, float]] = []
        self._heat_values: list[list[float]] = []
        self._prior_elevation: float | None = None
        self._tilt = (0.0, 0.0)
        self._ring_cache: dict[tuple[float, ...], QPainterPath] = {}
        self.sun_colour = colour or QColor(255, 196, 40)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        # 300 px high where there is room, as small as 150 px on a small screen (step 2's
        # corrections need the room: a user trial at 1024 x 700).
        self.setMinimumSize(150, 150)
        self.setMaximumHeight(300)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Preferred)
        self.setToolTip(DIAL_TIP)
        self.setAccessibleName("Sun dial")

    # ------------------------------------------------------------------ state
    def azimuth(self) -> float:
        return self._azimuth

    def elevation(self) -> float:
        return self._elevation

    def sun(self) -> tuple[float, float]:
        return self._azimuth, self._elevation

    def is_dragging(self) -> bool:
        return self._dragging

    def set_sun(self, azimuth: float, elevation: float, emit: bool = False) -> None:
        """Move the sun programmatically; emits ``sun_changed`` only when ``emit``."""
        az, el = dm.wrap_azimuth(azimuth), dm.clamp_elevation(elevation)
        if (az, el) == (self._azimuth, self._elevation):
            return
        self._azimuth, self._elevation = az, el
        self.update()
        if emit:
            self.sun_changed.emit(az, el)

    def set_fov(self, fov_deg: float, vfov_deg: float | None = None) -> None:
        """The camera's horizontal (and vertical) field of view in degrees."""
        dm.fov_wedge(fov_deg)  # validates
        self._fov = float(fov_deg)
        if vfov_deg is not None:
            dm.fov_wedge(vfov_deg)
            self._vfov = float(vfov_deg)
        self.update()

    def fov(self) -> tuple[float, float]:
        return self._fov, self._vfov

    def sun_in_view(self) -> bool:
        """Whether the sun lies inside the photo's frame (it would be visible in the picture)."""
        return dm.sun_in_view(self._azimuth, self._elevation, self._fov, self._vfov)

    def set_reference(self, sun: tuple[float, float] | None) -> None:
        """A second, faint sun (e.g. the original sun on the target dial)."""
        self._reference = sun
        self.update()

    def set_heat_map(
        self,
        azimuths: Sequence[float] | None,
        elevations: Sequence[float] | None = None,
        values: Sequence[Sequence[float]] | None = None,
    ) -> None:
        """Show an agreement map: ``values[row][col]`` in [0, 1] (0: no colour) at
        ``elevations[row]``, ``azimuths[col]``; ``None`` clears it."""
        if azimuths is None or elevations is None or values is None:
            self._heat, self._heat_values = [], []
        else:
            rows = [[float(v) for v in row] for row in values]
            if len(rows) != len(elevations) or any(len(r) != len(azimuths) for r in rows):
                raise ValueError(f"expected {len(elevations)} x {len(azimuths)} values, got "
                                 f"{len(rows)} rows")
            self._heat = dm.heat_cells(azimuths, elevations)
            self._heat_values = rows
        self._show_heat_tip()
        self.update()

    def has_heat_map(self) -> bool:
        return bool(self._heat)

    def _show_heat_tip(self) -> None:
        """The tooltip says what the heat map is while one shows (a user trial found nothing
        on screen that explained the coloured cells)."""
        self.setToolTip(DIAL_TIP + ("\n" + HEAT_MAP_TIP if self._heat else ""))

    def set_prior_elevation(self, elevation: float | None) -> None:
        """A dashed ring at the elevation the photo's time and place give (None hides it)."""
        self._prior_elevation = None if elevation is None else dm.clamp_elevation(elevation)
        self.update()

    def prior_elevation(self) -> float | None:
        return self._prior_elevation

    def set_tilt(self, pitch: float, roll: float) -> None:
        """The camera's pitch and roll in degrees: where the true horizon and the EXIF ring lie
        on the dial's camera-relative angles."""
        if not (math.isfinite(pitch) and math.isfinite(roll)):
            raise ValueError(f"expected a finite camera pitch and roll, got {pitch}, {roll}")
        self._tilt = (float(pitch), float(roll))
        self._ring_cache.clear()
        self.update()

    def tilt(self) -> tuple[float, float]:
        return self._tilt

    def _tilted(self) -> bool:
        from outcast_core.runtime.pipeline.auto_sun import is_tilted

        return is_tilted(*self._tilt)

    def below_horizon(self, azimuth: float, elevation: float) -> bool:
        """Whether a sun at these dial angles is under the true horizon (the camera's tilt)."""
        from outcast_core.runtime.geometry.camera import sun_angles, sun_vector

        if not self._tilted():
            return elevation < 0.0
        return sun_angles(sun_vector(azimuth, elevation), *self._tilt)[1] < 0.0

    def _ring_path(self, elevation: float, cx: float, cy: float, r: float, *,
                   closed: bool) -> QPainterPath:
        """The true-elevation circle on the dial: ``closed``, with the points off the dial on
        its rim (an area); else only its arcs on the dial (a line). Cached per geometry: the
        dial repaints on every drag step."""
        key = (elevation, cx, cy, r, float(closed))
        path = self._ring_cache.get(key)
        if path is not None:
            return path
        pts = dm.tilted_ring(elevation, *self._tilt)
        path = QPainterPath()
        pen_down = False
        for a, e in [*pts, pts[0]] if not closed else pts:
            p = QPointF(*dm.sun_to_point(a, e, cx, cy, r))
            if not closed and e < 0.0:
                pen_down = False
            elif pen_down:
                path.lineTo(p)
            else:
                path.moveTo(p)
                pen_down = True
        if closed:
            path.closeSubpath()
        self._ring_cache[key] = path
        return path

    # ------------------------------------------------------------------ geometry
    def label_font(self) -> QFont:
        """The font of the direction and ring labels: a little smaller than the widget's."""
        font = QFont(self.font())
        font.setPointSizeF(max(7.0, font.pointSizeF() * 0.85))
        return font

    def _label_sizes(self) -> dict[int, tuple[float, float]]:
        """Each direction label's ``(width, height)`` in pixels, a pixel to spare."""
        fm = QFontMetricsF(self.label_font())
        return {az: (fm.horizontalAdvance(text) + 2.0, fm.height())
                for az, text in DIRECTION_LABELS.items()}

    def dial_geometry(self) -> tuple[float, float, float]:
        """``(cx, cy, radius)`` of the disc in widget pixels: as large as leaves the direction
        labels their room outside it, :data:`LABEL_GAP` from the rim (:meth:`label_rects`)."""
        sizes = self._label_sizes()
        side = max(sizes[90][0], sizes[270][0]) + LABEL_GAP + 1.0
        top = max(sizes[0][1], sizes[180][1]) + LABEL_GAP + 1.0
        radius = max(10.0, min(self.width() / 2.0 - side, self.height() / 2.0 - top))
        return self.width() / 2.0, self.height() / 2.0, radius

    def label_rects(self) -> dict[int, QRectF]:
        """Where the direction labels are drawn, by azimuth: outside the disc, each
        :data:`LABEL_GAP` from the rim along its direction."""
        cx, cy, r = self.dial_geometry()
        sizes = self._label_sizes()
        (fw, fh), (rw, rh), (bw, bh), (lw, lh) = (sizes[az] for az in (0, 90, 180, 270))
        d = r + LABEL_GAP
        return {
            0: QRectF(cx - fw / 2.0, cy - d - fh, fw, fh),
            90: QRectF(cx + d, cy - rh / 2.0, rw, rh),
            180: QRectF(cx - bw / 2.0, cy + d, bw, bh),
            270: QRectF(cx - d - lw, cy - lh / 2.0, lw, lh),
        }

    def shadow_ruler_line(self) -> tuple[QLineF, bool]:
        """The shadow ruler (:meth:`paint_shadow_ruler`) from the disc's centre, and whether it
        is capped: a shadow longer than the disc ends :data:`RULER_INSET` inside the rim, its
        arrowhead included, clear of the labels outside."""
        cx, cy, r = self.dial_geometry()
        (x0, y0), (x1, y1), capped = dm.shadow_ruler(self._azimuth, self._elevation, cx, cy,
                                                      r / 3.0)
        length = math.hypot(x1 - x0, y1 - y0)
        room = r - RULER_INSET
        if length > room:
            x1, y1 = x0 + (x1 - x0) * room / length, y0 + (y1 - y0) * room / length
            capped = True
        return QLineF(x0, y0, x1, y1), capped

    def _obstacles(self) -> list[QPainterPath]:
        """What the ring labels must not sit on: the sun with its rays, the faint reference
        sun, the shadow ruler with its ticks and arrowhead, the camera at the centre, and a
        tilted camera's band of suns under the horizon (on a small dial the labels sat on the
        camera and the band: a user trial)."""
        cx, cy, r = self.dial_geometry()
        sun = QPainterPath()
        sun.addEllipse(self.handle_position(), RAY_RADIUS + 1.0, RAY_RADIUS + 1.0)
        camera = QPainterPath()
        camera.addRect(QRectF(cx - 8.0, cy - 8.0, 16.0, 16.0))  # (paint_camera's body)
        paths = [sun, camera]
        if self._tilted():
            disc = QPainterPath()
            disc.addEllipse(QPointF(cx, cy), r, r)
            paths.append(disc.subtracted(self._ring_path(0.0, cx, cy, r, closed=True)))
        if self._reference is not None:
            ref = QPainterPath()
            x, y = dm.sun_to_point(self._reference[0], self._reference[1], cx, cy, r)
            ref.addEllipse(QPointF(x, y), HANDLE_RADIUS, HANDLE_RADIUS)
            paths.append(ref)
        line, _ = self.shadow_ruler_line()
        if line.length() > 0.5:
            ruler = QPainterPath(line.p1())
            ruler.lineTo(line.p2())
            stroker = QPainterPathStroker()
            stroker.setWidth(2.0 * RULER_REACH)  # (its ticks and its arrowhead inside)
            paths.append(stroker.createStroke(ruler))
        return paths

    def ring_label_rects(self) -> list[tuple[str, QRectF]]:
        """The elevation rings' labels and where they are drawn: each outside its ring, beside
        the front-behind line (clear of a ruler along it), inside the disc, on the first side
        the sun, the faint sun and the shadow ruler leave free (in front, right of the line,
        where they were); none where no side is (on a small dial the sun sat on "30°": a user
        trial)."""
        cx, cy, r = self.dial_geometry()
        fm = QFontMetricsF(self.label_font())
        obstacles = self._obstacles()
        for above in (True, False):
            for right in (True, False):
                placed = []
                for el in RING_ELEVATIONS:
                    text, rr = f"{el:.0f}°", r * (90.0 - el) / 90.0
                    w, h = fm.horizontalAdvance(text) + 2.0, fm.height()
                    x = cx + RULER_REACH + 1.0 if right else cx - RULER_REACH - 1.0 - w
                    y = cy - rr - h if above else cy + rr
                    placed.append((text, QRectF(x, y, w, h)))
                inside = all(math.hypot(c.x() - cx, c.y() - cy) <= r for _, rect in placed
                             for c in (rect.topLeft(), rect.topRight(), rect.bottomLeft(),
                                       rect.bottomRight()))
                if inside and not any(path.intersects(rect) for _, rect in placed
                                      for path in obstacles):
                    return placed
        return []

    def focus_ring_visible(self) -> bool:
        """Whether the focus ring is drawn: the dial has the keyboard focus (its arrow keys move
        the sun)."""
        return self.hasFocus()

    def focus_ring_radius(self) -> float:
        """The focus ring's radius: round the disc, in the gap before the labels."""
        return self.dial_geometry()[2] + LABEL_GAP / 2.0

    def handle_position(self) -> QPointF:
        cx, cy, r = self.dial_geometry()
        return QPointF(*dm.sun_to_point(self._azimuth, self._elevation, cx, cy, r))

    def sizeHint(self) -> QSize:
        return QSize(300, 300)

    # ------------------------------------------------------------------ painting
    def paintEvent(self, event: QPaintEvent) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        cx, cy, r = self.dial_geometry()
        self.paint_sky(p, cx, cy, r)
        self.paint_heat_map(p, cx, cy, r)
        self.paint_grid(p, cx, cy, r)
        self.paint_horizon(p, cx, cy, r)
        self.paint_prior(p, cx, cy, r)
        self.paint_camera(p, cx, cy, r)
        self.paint_shadow_ruler(p, cx, cy, r)
        self.paint_reference(p, cx, cy, r)
        self.paint_sun(p, cx, cy, r)
        self.paint_focus_ring(p, cx, cy, r)
        p.end()

    def paint_focus_ring(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """A ring round the disc in the highlight colour while the dial has the focus (it
        takes the arrow keys; a user trial tabbed onto it and saw nothing)."""
        if not self.focus_ring_visible():
            return
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(QPen(self.palette().highlight().color(), FOCUS_RING_WIDTH))
        rr = self.focus_ring_radius()
        p.drawEllipse(QPointF(cx, cy), rr, rr)

    def focusInEvent(self, event: QFocusEvent) -> None:  # noqa: N802 (Qt's name)
        super().focusInEvent(event)
        self.update()

    def focusOutEvent(self, event: QFocusEvent) -> None:  # noqa: N802 (Qt's name)
        super().focusOutEvent(event)
        self.update()

    def paint_sky(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        grad = QRadialGradient(QPointF(cx, cy), r)
        enabled = self.isEnabled()
        grad.setColorAt(0.0, QColor(72, 124, 196) if enabled else QColor(90, 90, 96))
        grad.setColorAt(1.0, QColor(168, 200, 232) if enabled else QColor(130, 130, 136))
        p.setPen(QPen(QColor(40, 50, 70), 1.5))
        p.setBrush(grad)
        p.drawEllipse(QPointF(cx, cy), r, r)

    def paint_heat_map(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """The agreement map: an annular sector per sample, warmer where suns fit better."""
        if not self._heat:
            return
        p.setPen(Qt.PenStyle.NoPen)
        for row, col, a0, a1, e0, e1 in self._heat:
            colour = dm.heat_colour(self._heat_values[row][col])
            if colour[3] == 0:
                continue
            outer = r * (90.0 - e0) / 90.0
            inner = r * (90.0 - e1) / 90.0
            path = QPainterPath()
            # Qt angles: counter-clockwise from 3 o'clock; azimuth a sits at 90 - a.
            path.arcMoveTo(QRectF(cx - outer, cy - outer, 2 * outer, 2 * outer), 90.0 - a0)
            path.arcTo(QRectF(cx - outer, cy - outer, 2 * outer, 2 * outer), 90.0 - a0,
                       -(a1 - a0))
            if inner > 0.5:
                path.arcTo(QRectF(cx - inner, cy - inner, 2 * inner, 2 * inner), 90.0 - a1,
                           a1 - a0)
            else:
                path.lineTo(QPointF(cx, cy))
            path.closeSubpath()
            p.setBrush(QColor(*colour))
            p.drawPath(path)

    def paint_horizon(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """For a tilted camera: the suns under the true horizon, shaded like ground."""
        if not self._tilted():
            return
        key = (-1.0, cx, cy, r, 2.0)  # the ground itself, cached with the rings
        ground = self._ring_cache.get(key)
        if ground is None:
            disc = QPainterPath()
            disc.addEllipse(QPointF(cx, cy), r, r)
            ground = disc.subtracted(self._ring_path(0.0, cx, cy, r, closed=True))
            self._ring_cache[key] = ground
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(QColor(110, 84, 50, 170))
        p.drawPath(ground)

    def paint_prior(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """The EXIF elevation (:meth:`set_prior_elevation`): a dashed ring, where the camera
        sees that elevation."""
        if self._prior_elevation is None:
            return
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(QPen(QColor(255, 225, 120, 230), 2.0, Qt.PenStyle.DashLine))
        if not self._tilted():
            rr = r * (90.0 - self._prior_elevation) / 90.0
            p.drawEllipse(QPointF(cx, cy), rr, rr)
            return
        p.drawPath(self._ring_path(self._prior_elevation, cx, cy, r, closed=False))

    def paint_grid(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(QPen(QColor(255, 255, 255, 90), 1.0, Qt.PenStyle.DashLine))
        for el in RING_ELEVATIONS:
            rr = r * (90.0 - el) / 90.0
            p.drawEllipse(QPointF(cx, cy), rr, rr)
        p.setPen(QPen(QColor(255, 255, 255, 140), 1.0))
        for az in range(0, 360, 30):
            a = math.radians(az)
            inner = r - (8.0 if az % 90 == 0 else 4.0)
            p.drawLine(
                QPointF(cx + inner * math.sin(a), cy - inner * math.cos(a)),
                QPointF(cx + r * math.sin(a), cy - r * math.cos(a)),
            )
        p.setFont(self.label_font())
        p.setPen(self.palette().windowText().color())
        for az, box in self.label_rects().items():
            p.drawText(box, Qt.AlignmentFlag.AlignCenter, DIRECTION_LABELS[az])
        p.setPen(QColor(255, 255, 255, 170))
        for text, box in self.ring_label_rects():
            p.drawText(box, Qt.AlignmentFlag.AlignCenter, text)

    def paint_camera(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """The camera at the centre and its horizontal field of view toward azimuth 0."""
        left, right = dm.fov_wedge(self._fov)
        path = QPainterPath(QPointF(cx, cy))
        # Qt angles: degrees counter-clockwise from 3 o'clock; azimuth a sits at 90 - a.
        path.arcTo(QRectF(cx - r, cy - r, 2 * r, 2 * r), 90.0 - left, -(right - left))
        path.closeSubpath()
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(QColor(255, 255, 255, 45))
        p.drawPath(path)
        # A small camera body pointing up.
        p.setBrush(QColor(30, 34, 44))
        p.drawRoundedRect(QRectF(cx - 7.0, cy - 3.0, 14.0, 10.0), 2.0, 2.0)
        p.drawRect(QRectF(cx - 3.0, cy - 7.0, 6.0, 4.0))

    def paint_shadow_ruler(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        """The shadow of a pole ``r/3`` tall at the centre: 1/tan(el) long, a tick per height;
        one longer than the disc ends in an arrowhead inside the rim
        (:meth:`shadow_ruler_line`)."""
        unit = r / 3.0
        line, capped = self.shadow_ruler_line()
        length = line.length()
        if length <= 1e-6:
            return
        x0, y0 = line.x1(), line.y1()
        ux, uy = line.dx() / length, line.dy() / length
        colour = QColor(20, 20, 30, 200)
        end = line.p2()
        if capped:  # the line stops where the arrowhead starts
            end = QPointF(line.x2() - ux * RULER_ARROW, line.y2() - uy * RULER_ARROW)
        p.setPen(QPen(colour, 3.0, Qt.PenStyle.SolidLine, Qt.PenCapStyle.FlatCap))
        p.drawLine(line.p1(), end)
        # Ticks every object height along the shadow.
        p.setPen(QPen(colour, 1.5))
        k = 1
        while k * unit <= length + 1e-6:
            tx, ty = x0 + ux * k * unit, y0 + uy * k * unit
            p.drawLine(QPointF(tx - uy * 4, ty + ux * 4), QPointF(tx + uy * 4, ty - ux * 4))
            k += 1
        if capped:  # the shadow goes on past the rim
            p.setPen(Qt.PenStyle.NoPen)
            p.setBrush(colour)
            half = RULER_ARROW / 2.0
            p.drawPolygon(QPolygonF([
                line.p2(),
                QPointF(end.x() - uy * half, end.y() + ux * half),
                QPointF(end.x() + uy * half, end.y() - ux * half),
            ]))

    def paint_reference(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        if self._reference is None:
            return
        x, y = dm.sun_to_point(self._reference[0], self._reference[1], cx, cy, r)
        p.setPen(QPen(QColor(255, 255, 255, 200), 1.5, Qt.PenStyle.DashLine))
        p.setBrush(QColor(255, 230, 150, 90))
        p.drawEllipse(QPointF(x, y), HANDLE_RADIUS - 2.0, HANDLE_RADIUS - 2.0)

    def paint_sun(self, p: QPainter, cx: float, cy: float, r: float) -> None:
        pos = self.handle_position()
        p.setPen(QPen(QColor(255, 240, 180, 150), 2.0))
        for k in range(8):  # rays
            a = math.radians(k * 45.0)
            p.drawLine(
                QPointF(pos.x() + 11.0 * math.cos(a), pos.y() + 11.0 * math.sin(a)),
                QPointF(pos.x() + RAY_RADIUS * math.cos(a), pos.y() + RAY_RADIUS * math.sin(a)),
            )
        edge = QColor(255, 255, 255) if self.hasFocus() else QColor(120, 80, 0)
        p.setPen(QPen(edge, 2.0))
        p.setBrush(self.sun_colour if self.isEnabled() else QColor(170, 170, 170))
        p.drawEllipse(pos, HANDLE_RADIUS, HANDLE_RADIUS)

    # ------------------------------------------------------------------ interaction
    def _move_to(self, pos: QPointF) -> None:
        cx, cy, r = self.dial_geometry()
        az, el = dm.point_to_sun(pos.x(), pos.y(), cx, cy, r)
        self.set_sun(az, el, emit=True)

    def mousePressEvent(self, event: QMouseEvent) -> None:
        if event.button() != Qt.MouseButton.LeftButton:
            return super().mousePressEvent(event)
        cx, cy, r = self.dial_geometry()
        pos = event.position()
        handle = self.handle_position()
        on_handle = dm.hit_handle(pos.x(), pos.y(), handle.x(), handle.y(), HANDLE_RADIUS)
        if not on_handle and math.hypot(pos.x() - cx, pos.y() - cy) > r + 6.0:
            return super().mousePressEvent(event)
        self._dragging = True
        self.drag_started.emit()
        if not on_handle:  # click on the sky: jump there
            self._move_to(pos)
        event.accept()

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if self._dragging:
            self._move_to(event.position())
            event.accept()
        else:
            super().mouseMoveEvent(event)

    def mouseReleaseEvent(self, event: QMouseEvent) -> None:
        if self._dragging and event.button() == Qt.MouseButton.LeftButton:
            self._move_to(event.position())
            self._dragging = False
            self.drag_finished.emit(self._azimuth, self._elevation)
            self.sun_committed.emit(self._azimuth, self._elevation)
            event.accept()
        else:
            super().mouseReleaseEvent(event)

    def keyPressEvent(self, event: QKeyEvent) -> None:
        mods = event.modifiers()
        step = 1.0
        if mods & Qt.KeyboardModifier.ShiftModifier:
            step = 10.0
        elif mods & Qt.KeyboardModifier.ControlModifier:
            step = 0.1
        deltas = {
            Qt.Key.Key_Left: (-step, 0.0),
            Qt.Key.Key_Right: (step, 0.0),
            Qt.Key.Key_Up: (0.0, step),
            Qt.Key.Key_Down: (0.0, -step),
        }
        d = deltas.get(Qt.Key(event.key()))
        if d is None:
            return super().keyPressEvent(event)
        az, el = dm.nudge(self._azimuth, self._elevation, *d)
        self.set_sun(az, el, emit=True)
        self.sun_committed.emit(self._azimuth, self._elevation)
        event.accept()


class SunDialPanel(QWidget):
    """A titled :class:`QtSunDial` with azimuth/elevation fields and the shadow-length read-out.

    Signals:
        sun_changed(azimuth, elevation, preview): every change; ``preview`` is True while dragging.
        sun_committed(azimuth, elevation): a settled position (release, key, typed value).
    """

    sun_changed = Signal(float, float, bool)
    sun_committed = Signal(float, float)

    def __init__(self, title: str, colour: QColor | None = None, parent: QWidget | None = None):
        super().__init__(parent)
        self.dial = QtSunDial(self, colour)
        self.title = QLabel(f"<b>{title}</b>", self)
        self.azimuth_box = QDoubleSpinBox(self)
        self.azimuth_box.setRange(0.0, 359.9)
        self.azimuth_box.setWrapping(True)
        self.azimuth_box.setDecimals(1)
        self.azimuth_box.setSuffix("°")
        self.azimuth_box.setToolTip("0° = sun straight ahead (backlit), 90° = right, 180° = behind")
        self.elevation_box = QDoubleSpinBox(self)
        self.elevation_box.setRange(0.0, 90.0)
        self.elevation_box.setDecimals(1)
        self.elevation_box.setSuffix("°")
        self.elevation_box.setToolTip("0° = horizon, 90° = straight overhead")
        for box in (self.azimuth_box, self.elevation_box):
            box.setKeyboardTracking(False)
            box.setAccelerated(True)
        self.shadow_label = QLabel(self)
        self.shadow_label.setWordWrap(True)  # "· in the frame" must not widen the panel
        self.shadow_label.setToolTip("Where the sun is, and the length of the shadow of an "
                                     "upright pole on flat ground")

        grid = QGridLayout()
        grid.addWidget(QLabel("Azimuth", self), 0, 0)
        grid.addWidget(self.azimuth_box, 0, 1)
        grid.addWidget(QLabel("Elevation", self), 1, 0)
        grid.addWidget(self.elevation_box, 1, 1)
        # No taller than its parts at their largest (the dial's 300 px): a panel's spare
        # height goes below its last row, not between these rows.
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.title)
        layout.addWidget(self.dial, 1)
        layout.addLayout(grid)
        layout.addWidget(self.shadow_label)

        self.dial.sun_changed.connect(self._on_dial_changed)
        self.dial.sun_committed.connect(self._on_dial_committed)
        self.azimuth_box.valueChanged.connect(self._on_box_changed)
        self.elevation_box.valueChanged.connect(self._on_box_changed)
        self._sync_fields()

    def sun(self) -> tuple[float, float]:
        return self.dial.sun()

    def set_sun(self, azimuth: float, elevation: float) -> None:
        """Set without emitting signals."""
        self.dial.set_sun(azimuth, elevation)
        self._sync_fields()

    def set_fov(self, fov_deg: float, vfov_deg: float | None = None) -> None:
        self.dial.set_fov(fov_deg, vfov_deg)
        self._sync_fields()

    def set_tilt(self, pitch: float, roll: float) -> None:
        """The camera's pitch and roll (:meth:`QtSunDial.set_tilt`)."""
        self.dial.set_tilt(pitch, roll)
        self._sync_fields()

    def _sync_fields(self) -> None:
        az, el = self.dial.sun()
        for box, value in ((self.azimuth_box, az), (self.elevation_box, el)):
            box.blockSignals(True)
            box.setValue(round(value, 1) % 360.0 if box is self.azimuth_box else value)
            box.blockSignals(False)
        ratio = dm.shadow_length_ratio(el)
        length = "very long" if ratio > dm.MAX_SHADOW_RATIO else f"{ratio:.2f} × height"
        in_frame = " · in the frame" if self.dial.sun_in_view() else ""
        if self.dial.below_horizon(az, el):
            in_frame += " · under the horizon for this camera's tilt"
        self.shadow_label.setText(f"Sun {dm.describe_sun(az, el)} · shadows {length}"
                                  f"{in_frame}")

    def _on_dial_changed(self, az: float, el: float) -> None:
        self._sync_fields()
        self.sun_changed.emit(az, el, self.dial.is_dragging())

    def _on_dial_committed(self, az: float, el: float) -> None:
        self.sun_committed.emit(az, el)

    def _on_box_changed(self, _value: float) -> None:
        az, el = self.azimuth_box.value(), self.elevation_box.value()
        self.dial.set_sun(az, el)
        self._sync_fields()
        self.sun_changed.emit(*self.dial.sun(), False)
        self.sun_committed.emit(*self.dial.sun())
