"""Procedural props and buildings for the synthetic scenes.

Each builder adds triangle meshes to a :class:`SceneBuilder` (in world coordinates, z up) and
returns an :class:`Item` describing where the thing stands, which the camera uses to aim.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from outcast_core.data import textures as tx
from outcast_core.data.meshes import (
    Mesh,
    arch_wall,
    box,
    box_between,
    concat,
    cone,
    cylinder,
    ellipsoid,
    gable_roof,
    rot_x,
    rot_z,
    tube,
)


@dataclass
class Material:
    """Surface description: albedo texture plus BSDF family (``diffuse`` or ``plastic``)."""

    texture: tx.Texture
    kind: str = "diffuse"
    roughness: float = 0.3


@dataclass
class Item:
    """A placed object: footprint centre/radius (metres) and its height range."""

    name: str
    centre: np.ndarray  # (3,) world point at the middle of the object
    radius: float  # horizontal footprint radius
    height: float  # total height
    size: float  # the size the camera frames (metres)


@dataclass
class SceneBuilder:
    """Collects meshes per material; ``ground_z(x, y)`` gives the ground height."""

    rng: np.random.Generator
    slope: tuple[float, float] = (0.0, 0.0)  # dz/dx, dz/dy
    materials: list[Material] = field(default_factory=list)
    parts: list[tuple[Mesh, int]] = field(default_factory=list)
    items: list[Item] = field(default_factory=list)
    # Axis-aligned ground footprints (xmin, xmax, ymin, ymax) of large solids that are not items
    # (walls and steps behind close-ups): no camera or prop goes inside, no camera looks through.
    blockers: list[tuple[float, float, float, float]] = field(default_factory=list)
    # Blockers a camera may stand in all the same (a path props keep off).
    walkable: list[tuple[float, float, float, float]] = field(default_factory=list)

    def ground_z(self, x: float, y: float) -> float:
        return self.slope[0] * x + self.slope[1] * y

    def base_z(self, x: float, y: float, radius: float) -> float:
        """Ground height under a footprint, sunk so that nothing floats on a slope."""
        return self.ground_z(x, y) - radius * math.hypot(*self.slope)

    def material(self, texture: tx.Texture, kind: str = "diffuse", roughness: float = 0.3) -> int:
        self.materials.append(Material(texture, kind, roughness))
        return len(self.materials) - 1

    def paint(self, lo: float = 0.03, hi: float = 0.75, saturation: float = 0.6) -> int:
        return self.material(
            tx.plain(self.rng, tx.random_colour(self.rng, lo, hi, saturation), 0.05)
        )

    def add(
        self,
        mesh: Mesh,
        material: int,
        rotation: np.ndarray | None = None,
        translation: np.ndarray | None = None,
    ) -> None:
        if rotation is not None or translation is not None:
            mesh = mesh.transformed(
                np.eye(3) if rotation is None else rotation,
                np.zeros(3) if translation is None else translation,
            )
        self.parts.append((mesh, material))

    def blocked(self, x: float, y: float, margin: float = 0.0, walk: bool = False) -> bool:
        """Whether a ground point lies inside a blocker footprint (grown by ``margin``); with
        ``walk``, walkable blockers (paths) do not count."""
        return any(
            x0 - margin <= x <= x1 + margin and y0 - margin <= y <= y1 + margin
            for x0, x1, y0, y1 in self.blockers
            if not (walk and (x0, x1, y0, y1) in self.walkable)
        )

    def overlaps(self, x: float, y: float, radius: float, walk: bool = False) -> bool:
        """Whether a footprint hits an already placed item or a blocker (with ``walk``: a
        blocker other than a walkable one, as for a person standing there)."""
        if self.blocked(x, y, radius, walk):
            return True
        for it in self.items:
            if math.hypot(it.centre[0] - x, it.centre[1] - y) < it.radius + radius:
                return True
        return False


PropFn = Callable[[SceneBuilder, float, float, float], Item]


def _place(
    b: SceneBuilder, meshes: list[tuple[Mesh, int]], x: float, y: float, yaw: float, radius: float
) -> float:
    z = b.base_z(x, y, radius)
    R = rot_z(yaw)
    for m, mat in meshes:
        b.add(m, mat, R, np.array([x, y, z]))
    return z


def _item(
    b: SceneBuilder,
    name: str,
    x: float,
    y: float,
    z: float,
    radius: float,
    height: float,
    size: float | None = None,
) -> Item:
    it = Item(
        name,
        np.array([x, y, z + height / 2]),
        radius,
        height,
        size if size is not None else max(2 * radius, height),
    )
    b.items.append(it)
    return it


# --------------------------------------------------------------------------------------------
# Small props
# --------------------------------------------------------------------------------------------


def bollard(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    r, h = rng.uniform(0.06, 0.16), rng.uniform(0.45, 1.1)
    mat = b.paint(0.03, 0.6)
    if rng.random() < 0.6:
        m = concat(
            [cylinder(r, h, 24), ellipsoid(r, r, r * 0.5, 24).transformed(np.eye(3), [0, 0, h])]
        )
    else:
        m = box(2 * r, 2 * r, h)
    z = _place(b, [(m, mat)], x, y, yaw, r)
    return _item(b, "bollard", x, y, z, r, h)


def lamp_post(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    r, h = rng.uniform(0.05, 0.12), rng.uniform(3.0, 8.0)
    mat = b.paint(0.02, 0.3, 0.3)
    arm = rng.uniform(0.3, 1.8)
    parts = [cylinder(r, h, 10), box_between([0, 0, h - 0.1], [arm, 0, h + 0.1], 0.06, 0.06)]
    if rng.random() < 0.5:
        parts.append(box(0.5, 0.25, 0.15).transformed(np.eye(3), [arm, 0, h - 0.1]))
    else:
        parts.append(ellipsoid(0.2, 0.2, 0.25, 10).transformed(np.eye(3), [arm, 0, h - 0.15]))
    z = _place(b, [(concat(parts), mat)], x, y, yaw, r)
    return _item(b, "lamp", x, y, z, max(r, 0.3), h, size=h)


def column(b: SceneBuilder, x: float, y: float, yaw: float, height: float | None = None) -> Item:
    rng = b.rng
    r = rng.uniform(0.15, 0.5)
    h = height if height is not None else rng.uniform(2.5, 8.0)
    mat = b.material(tx.wall_texture(rng)) if rng.random() < 0.5 else b.paint(0.3, 0.8, 0.2)
    parts = [cylinder(r, h, 16) if rng.random() < 0.7 else box(2 * r, 2 * r, h)]
    cap = r * rng.uniform(1.2, 1.6)
    parts.append(box(2 * cap, 2 * cap, 0.2 * r + 0.1).transformed(np.eye(3), [0, 0, h]))
    parts.append(box(2 * cap, 2 * cap, 0.2 * r + 0.1))
    z = _place(b, [(concat(parts), mat)], x, y, yaw, cap)
    return _item(b, "column", x, y, z, cap, h + 0.2 * r + 0.1)


def tree(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    h_trunk = rng.uniform(1.5, 4.5)
    r_trunk = rng.uniform(0.08, 0.35)
    bark = b.material(tx.grainy(rng, tx.random_colour(rng, 0.05, 0.2, 0.3), 0.3, 0.5))
    leaf_col = (
        np.array([0.05, 0.1, 0.03]) * rng.uniform(0.5, 1.8) * (1 + 0.35 * rng.uniform(-1, 1, 3))
    )
    if rng.random() < 0.15:  # autumn
        leaf_col = np.array([0.25, 0.12, 0.02]) * rng.uniform(0.6, 1.4)
    leaves = b.material(tx.grainy(rng, leaf_col, 0.5, 0.3, beta=0.5))
    parts_trunk = [cylinder(r_trunk, h_trunk + 0.5, 10)]
    crown_r = rng.uniform(1.0, 4.0)
    crown_h = crown_r * rng.uniform(0.8, 1.8)
    canopy = []
    style = rng.random()
    if style < 0.2:  # conifer
        canopy.append(
            cone(crown_r, crown_h * 2.0, 12).transformed(np.eye(3), [0, 0, h_trunk * 0.6])
        )
        top = h_trunk * 0.6 + crown_h * 2.0
    elif style < 0.5:  # one blob
        canopy.append(
            ellipsoid(crown_r, crown_r * rng.uniform(0.8, 1.2), crown_h / 2, 22).transformed(
                rot_z(rng.uniform(0, 6.3)), [0, 0, h_trunk + crown_h / 2]
            )
        )
        top = h_trunk + crown_h
    else:  # clusters with holes between them
        n = rng.integers(3, 9)
        top = h_trunk
        for _ in range(n):
            rr = crown_r * rng.uniform(0.3, 0.6)
            off = rng.normal(size=3) * np.array([crown_r, crown_r, crown_h]) * 0.45
            c = np.array([off[0], off[1], h_trunk + crown_h / 2 + off[2]])
            canopy.append(
                ellipsoid(rr, rr, rr * rng.uniform(0.6, 1.0), 14).transformed(np.eye(3), c)
            )
            top = max(top, c[2] + rr)
            # a branch to hold it
            parts_trunk.append(tube([0, 0, h_trunk * 0.8], c, r_trunk * 0.35, 6))
    z = _place(b, [(concat(parts_trunk), bark), (concat(canopy), leaves)], x, y, yaw, r_trunk)
    return _item(b, "tree", x, y, z, crown_r, top, size=max(top, 2 * crown_r))


def bench(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    length, depth, seat_h = rng.uniform(1.2, 2.4), rng.uniform(0.4, 0.6), rng.uniform(0.4, 0.5)
    wood = b.material(tx.planks(rng, tx.random_colour(rng, 0.08, 0.45, 0.4)))
    metal = b.paint(0.02, 0.4, 0.3)
    n = int(rng.integers(3, 6))
    gap = rng.uniform(0.01, 0.04)
    slat = (depth - (n - 1) * gap) / n
    seat = [
        box(length, slat, 0.04).transformed(
            np.eye(3), [0, -depth / 2 + slat / 2 + i * (slat + gap), seat_h]
        )
        for i in range(n)
    ]
    frame = []
    for sx in (-length / 2 + 0.1, length / 2 - 0.1):
        frame.append(box(0.06, depth, 0.05).transformed(np.eye(3), [sx, 0, seat_h - 0.05]))
        for sy in (-depth / 2 + 0.05, depth / 2 - 0.05):
            frame.append(box(0.05, 0.05, seat_h - 0.05).transformed(np.eye(3), [sx, sy, 0]))
    if rng.random() < 0.7:  # backrest
        for i in range(int(rng.integers(2, 4))):
            seat.append(
                box(length, 0.03, 0.09).transformed(
                    rot_x(0.2), [0, depth / 2, seat_h + 0.12 + i * 0.13]
                )
            )
        for sx in (-length / 2 + 0.1, length / 2 - 0.1):
            frame.append(
                box(0.05, 0.05, 0.45).transformed(rot_x(0.2), [sx, depth / 2 + 0.02, seat_h])
            )
    z = _place(b, [(concat(seat), wood), (concat(frame), metal)], x, y, yaw, length / 2)
    return _item(b, "bench", x, y, z, length / 2, seat_h + 0.5, size=length)


def car(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    L, W = rng.uniform(3.6, 5.0), rng.uniform(1.6, 1.95)
    body_h, cabin_h = rng.uniform(0.55, 0.8), rng.uniform(0.45, 0.65)
    clear = 0.2
    paint = b.material(
        tx.plain(rng, tx.random_colour(rng, 0.02, 0.7, 0.8), 0.02),
        "plastic",
        rng.uniform(0.05, 0.3),
    )
    glass = b.material(tx.plain(rng, np.array([0.02, 0.025, 0.03]), 0.0), "plastic", 0.05)
    tyre = b.material(tx.plain(rng, np.array([0.03, 0.03, 0.03]), 0.0))
    body = box(L, W, body_h).transformed(np.eye(3), [0, 0, clear + 0.15])
    cab_len = L * rng.uniform(0.45, 0.6)
    cabin = box(cab_len, W * 0.85, cabin_h).transformed(
        np.eye(3), [rng.uniform(-0.3, 0.1) * L / 2, 0, clear + 0.15 + body_h]
    )
    wheels = []
    wr = rng.uniform(0.3, 0.38)
    for sx in (-L / 2 + 0.8, L / 2 - 0.8):
        for sy in (-W / 2 + 0.1, W / 2 - 0.1):
            wheels.append(tube([sx, sy - 0.12, wr], [sx, sy + 0.12, wr], wr, 12))
    z = _place(b, [(body, paint), (cabin, glass), (concat(wheels), tyre)], x, y, yaw, L / 2)
    return _item(b, "car", x, y, z, L / 2, clear + 0.15 + body_h + cabin_h, size=L)


def person(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    h = rng.uniform(1.1, 1.9)
    r = h * rng.uniform(0.12, 0.16)
    cloth = b.paint(0.02, 0.6, 0.7)
    skin = b.material(tx.plain(rng, np.array([0.5, 0.3, 0.2]) * rng.uniform(0.15, 1.1), 0.02))
    body_h = h * 0.82
    body = ellipsoid(r, r * 0.7, r, 18, stretch=body_h - 2 * r).transformed(
        np.eye(3), [0, 0, body_h / 2]
    )
    head_r = h * 0.065
    head = ellipsoid(head_r, head_r, head_r * 1.2, 14).transformed(
        np.eye(3), [0, 0, h - head_r * 1.2]
    )
    z = _place(b, [(body, cloth), (head, skin)], x, y, yaw, r)
    return _item(b, "person", x, y, z, r, h)


def umbrella(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    R, h = rng.uniform(0.9, 2.2), rng.uniform(2.0, 2.7)
    fabric = b.material(
        tx.stripes(
            rng,
            tx.random_colour(rng, 0.1, 0.8, 0.8),
            tx.random_colour(rng, 0.3, 0.8, 0.3),
            rng.uniform(0.2, 0.5),
        )
        if rng.random() < 0.5
        else tx.plain(rng, tx.random_colour(rng, 0.1, 0.8, 0.8))
    )
    pole = b.paint(0.05, 0.6, 0.2)
    canopy = cone(R, R * rng.uniform(0.2, 0.45), int(rng.choice([6, 8, 12])), base=False)
    parts = [
        (canopy.transformed(np.eye(3), [0, 0, h - 0.3]), fabric),
        (cylinder(0.025, h, 6), pole),
    ]
    if rng.random() < 0.6:  # a table under it
        parts.append(
            (
                concat(
                    [
                        cylinder(0.04, 0.72, 6),
                        cylinder(rng.uniform(0.35, 0.6), 0.03, 16).transformed(
                            np.eye(3), [0, 0, 0.72]
                        ),
                    ]
                ),
                pole,
            )
        )
    z = _place(b, parts, x, y, yaw, 0.3)
    return _item(b, "umbrella", x, y, z, R, h + 0.3, size=2 * R)


def fence(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    """A fence or railing with slats / bars: striped shadows."""
    rng = b.rng
    length = rng.uniform(2.0, 12.0)
    h = rng.uniform(0.8, 2.0)
    mat = (
        b.material(tx.planks(rng, tx.random_colour(rng, 0.1, 0.5, 0.4)))
        if rng.random() < 0.5
        else b.paint(0.02, 0.6, 0.5)
    )
    style = rng.random()
    parts = []
    if style < 0.5:  # vertical slats / bars
        slat_w = rng.uniform(0.02, 0.15)
        gap = rng.uniform(0.03, 0.15)
        n = int(length / (slat_w + gap))
        bar = rng.random() < 0.5
        for i in range(n):
            sx = -length / 2 + i * (slat_w + gap)
            parts.append(
                cylinder(slat_w / 2, h, 6).transformed(np.eye(3), [sx, 0, 0])
                if bar
                else box(slat_w, 0.025, h).transformed(np.eye(3), [sx, 0, 0])
            )
        for zz in (0.15, h - 0.1):
            parts.append(box(length, 0.04, 0.06).transformed(np.eye(3), [0, 0.03, zz]))
    else:  # horizontal rails between posts
        n_rails = int(rng.integers(2, 7))
        for k in range(n_rails):
            zz = (k + 0.5) * h / n_rails
            parts.append(
                box(length, 0.03, min(0.15, h / n_rails * rng.uniform(0.2, 0.7))).transformed(
                    np.eye(3), [0, 0, zz]
                )
            )
        for sx in np.arange(-length / 2, length / 2 + 0.01, rng.uniform(1.0, 2.5)):
            parts.append(box(0.08, 0.08, h + 0.05).transformed(np.eye(3), [sx, 0.05, 0]))
    z = _place(b, [(concat(parts), mat)], x, y, yaw, 0.3)
    return _item(b, "fence", x, y, z, length / 2, h, size=length)


def wall(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    length, h, t = rng.uniform(2.0, 15.0), rng.uniform(0.4, 3.0), rng.uniform(0.15, 0.5)
    mat = b.material(tx.wall_texture(rng))
    parts = [box(length, t, h)]
    if rng.random() < 0.4:  # coping
        parts.append(box(length + 0.1, t + 0.1, 0.08).transformed(np.eye(3), [0, 0, h]))
    z = _place(b, [(concat(parts), mat)], x, y, yaw, t)
    return _item(b, "wall", x, y, z, length / 2, h, size=length)


def bike(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    """A bike-sized frame of thin tubes with polygonal wheels."""
    rng = b.rng
    mat = b.paint(0.02, 0.7, 0.8)
    tyre = b.material(tx.plain(rng, np.array([0.03, 0.03, 0.03]), 0.0))
    wr = rng.uniform(0.3, 0.36)
    wb = rng.uniform(0.95, 1.1)
    rear, front = np.array([-wb / 2, 0, wr]), np.array([wb / 2, 0, wr])
    seat = np.array([-wb / 2 + 0.3, 0, wr + 0.55])
    crank = np.array([-0.05, 0, wr - 0.02])
    head = np.array([wb / 2 - 0.15, 0, wr + 0.5])
    tubes = [
        (rear, seat),
        (rear, crank),
        (crank, seat),
        (seat, head),
        (crank, head),
        (head, front),
        (head, head + [-0.05, 0, 0.15]),
        (seat, seat + [-0.05, 0, 0.1]),
    ]
    frame = [tube(p, q, 0.018, 6) for p, q in tubes]
    frame.append(box(0.03, 0.5, 0.03).transformed(np.eye(3), head + [-0.05, 0, 0.15]))
    frame.append(box(0.25, 0.1, 0.05).transformed(np.eye(3), seat + [-0.05, 0, 0.1]))
    wheels = []
    for c in (rear, front):
        t = np.linspace(0, 2 * math.pi, 17)
        pts = [c + wr * np.array([math.cos(a), 0, math.sin(a)]) for a in t]
        wheels += [tube(pts[i], pts[i + 1], 0.02, 5) for i in range(16)]
        for a in t[:-1:2]:
            wheels.append(tube(c, c + wr * np.array([math.cos(a), 0, math.sin(a)]), 0.004, 3))
    z = _place(b, [(concat(frame), mat), (concat(wheels), tyre)], x, y, yaw, 0.3)
    return _item(b, "bike", x, y, z, wb / 2 + wr, 2 * wr + 0.3, size=wb + 2 * wr)


def planter(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    s, h = rng.uniform(0.4, 1.5), rng.uniform(0.3, 0.9)
    pot = b.material(tx.wall_texture(rng))
    leaf = b.material(
        tx.grainy(rng, np.array([0.05, 0.12, 0.03]) * rng.uniform(0.5, 1.5), 0.5, 0.2, beta=0.4)
    )
    bush_h = rng.uniform(0.2, 1.0)
    parts = [
        (box(s, s, h) if rng.random() < 0.6 else cylinder(s / 2, h, 16), pot),
        (
            ellipsoid(s / 2, s / 2, bush_h / 2, 16).transformed(np.eye(3), [0, 0, h + bush_h / 3]),
            leaf,
        ),
    ]
    z = _place(b, parts, x, y, yaw, s / 2)
    return _item(b, "planter", x, y, z, s / 2, h + bush_h)


def chair_table(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    mat = b.paint(0.05, 0.7, 0.6)
    parts = []
    s = rng.uniform(0.4, 0.5)
    for sx in (-s / 2 + 0.02, s / 2 - 0.02):
        for sy in (-s / 2 + 0.02, s / 2 - 0.02):
            parts.append(cylinder(0.015, 0.45, 5).transformed(np.eye(3), [sx, sy, 0]))
    parts.append(box(s, s, 0.03).transformed(np.eye(3), [0, 0, 0.45]))
    for i in range(int(rng.integers(2, 5))):
        parts.append(box(s, 0.02, 0.05).transformed(np.eye(3), [0, s / 2, 0.55 + i * 0.1]))
    for sx in (-s / 2 + 0.02, s / 2 - 0.02):
        parts.append(cylinder(0.015, 0.45, 5).transformed(np.eye(3), [sx, s / 2, 0.45]))
    z = _place(b, [(concat(parts), mat)], x, y, yaw, s / 2)
    return _item(b, "chair", x, y, z, s / 2, 0.9, size=1.0)


def ball_or_bin(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    mat = b.paint(0.03, 0.75, 0.8)
    if rng.random() < 0.5:
        r = rng.uniform(0.1, 0.4)
        m = ellipsoid(r, r, r, 28).transformed(np.eye(3), [0, 0, r])
        h = 2 * r
    else:
        r, h = rng.uniform(0.2, 0.35), rng.uniform(0.6, 1.0)
        m = concat(
            [cylinder(r, h, 14), cylinder(r * 1.08, 0.06, 14).transformed(np.eye(3), [0, 0, h])]
        )
    z = _place(b, [(m, mat)], x, y, yaw, r)
    return _item(b, "ball", x, y, z, r, h)


def sign(b: SceneBuilder, x: float, y: float, yaw: float) -> Item:
    rng = b.rng
    h = rng.uniform(1.8, 3.2)
    pole = b.paint(0.1, 0.5, 0.1)
    panel = b.paint(0.05, 0.8, 0.9)
    w = rng.uniform(0.4, 1.0)
    parts = [
        (cylinder(0.035, h, 8), pole),
        (box(w, 0.03, rng.uniform(0.3, 0.8)).transformed(np.eye(3), [0, 0.05, h - 0.6]), panel),
    ]
    z = _place(b, parts, x, y, yaw, 0.1)
    return _item(b, "sign", x, y, z, w / 2, h)


SMALL_PROPS: list[PropFn] = [
    bollard,
    bench,
    bike,
    planter,
    chair_table,
    ball_or_bin,
    sign,
    person,
    fence,
    wall,
]
STREET_PROPS: list[PropFn] = [
    tree,
    tree,
    lamp_post,
    bollard,
    bench,
    car,
    car,
    person,
    person,
    umbrella,
    fence,
    wall,
    column,
    planter,
    sign,
    bike,
]


# --------------------------------------------------------------------------------------------
# Buildings
# --------------------------------------------------------------------------------------------


def building(b: SceneBuilder, x: float, y: float, yaw: float, width: float | None = None) -> Item:
    """A building whose front (local -y face) starts at ``(x, y)``, ``width`` long along local x."""
    rng = b.rng
    W = width if width is not None else rng.uniform(6.0, 25.0)
    D = rng.uniform(6.0, 18.0)
    floors = int(rng.integers(1, 8))
    storey = rng.uniform(2.8, 3.8)
    H = floors * storey + rng.uniform(0.0, 1.0)
    wall_tex = tx.wall_texture(rng)
    bay = rng.uniform(2.0, 4.5)
    win_w = bay * rng.uniform(0.3, 0.7)
    win_h = storey * rng.uniform(0.35, 0.6)
    glass = np.array([0.03, 0.04, 0.05]) * rng.uniform(0.5, 2.5)
    frame = tx.random_colour(rng, 0.05, 0.8, 0.3)
    shutters = tx.random_colour(rng, 0.05, 0.5, 0.8) if rng.random() < 0.2 else None
    fac = b.material(
        tx.facade(rng, wall_tex, bay, storey, win_w, win_h, storey * 0.3, glass, frame, shutters)
    )
    trim = b.material(tx.plain(rng, tx.random_colour(rng, 0.1, 0.8, 0.25)))
    parts: list[tuple[Mesh, int]] = []
    sink = 2.0
    parts.append((box(W, D, H + sink).transformed(np.eye(3), [W / 2, D / 2, -sink]), fac))
    roof_top = H
    if rng.random() < 0.45:  # pitched roof
        roof = b.material(
            tx.tiles(
                rng,
                tx.random_colour(rng, 0.05, 0.35, 0.5),
                tx.random_colour(rng, 0.03, 0.2, 0.2),
                tile=0.3,
            )
        )
        rh = rng.uniform(1.5, 5.0)
        ov = rng.uniform(0.0, 0.8)
        if rng.random() < 0.5:
            parts.append((gable_roof(W, D, rh, ov).transformed(np.eye(3), [W / 2, D / 2, H]), roof))
        else:
            parts.append(
                (gable_roof(D, W, rh, ov).transformed(rot_z(math.pi / 2), [W / 2, D / 2, H]), roof)
            )
        roof_top = H + rh
    else:  # flat roof with parapet or cornice
        ov = rng.uniform(0.0, 0.9) if rng.random() < 0.6 else 0.0
        parts.append(
            (box(W + 2 * ov, D + 2 * ov, 0.3).transformed(np.eye(3), [W / 2, D / 2, H]), trim)
        )
        roof_top = H + 0.3
    if rng.random() < 0.5:  # ledges between floors
        dep = rng.uniform(0.08, 0.35)
        for f in range(1, floors):
            parts.append(
                (
                    box(W, dep, 0.15).transformed(np.eye(3), [W / 2, -dep / 2, f * storey - 0.15]),
                    trim,
                )
            )
    if floors > 1 and rng.random() < 0.45:  # balconies with railings
        rail = b.paint(0.02, 0.6, 0.4)
        bdep = rng.uniform(0.8, 1.6)
        n_bays = max(1, int(W / bay))
        for f in range(1, floors):
            if rng.random() < 0.3:
                continue
            for k in range(n_bays):
                if rng.random() < 0.4:
                    continue
                cx = (k + 0.5) * W / n_bays
                bw = min(bay * rng.uniform(0.7, 1.0), W / n_bays)
                z0 = f * storey
                parts.append(
                    (box(bw, bdep, 0.15).transformed(np.eye(3), [cx, -bdep / 2, z0]), trim)
                )
                bars = [box(bw, 0.04, 0.05).transformed(np.eye(3), [cx, -bdep + 0.02, z0 + 1.0])]
                for bx in np.arange(cx - bw / 2 + 0.05, cx + bw / 2, rng.uniform(0.1, 0.2)):
                    bars.append(
                        box(0.025, 0.025, 0.85).transformed(
                            np.eye(3), [bx, -bdep + 0.02, z0 + 0.15]
                        )
                    )
                parts.append((concat(bars), rail))
    r = rng.random()
    if r < 0.2 and W > 6:  # ground-floor arcade in front of the facade
        span = rng.uniform(2.0, 4.0)
        pier = rng.uniform(0.4, 0.9)
        count = max(1, int((W - pier) / (span + pier)))
        depth = rng.uniform(2.0, 4.0)
        spring = rng.uniform(2.0, 3.5)
        t = 0.5
        arc = arch_wall(span, pier, spring, rng.uniform(0.3, 1.0), t, count)
        total = count * (span + pier) + pier
        top = spring + span / 2
        arc_mat = b.material(tx.wall_texture(rng)) if rng.random() < 0.5 else fac
        parts.append((arc.transformed(np.eye(3), [(W - total) / 2, -depth, 0]), arc_mat))
        # the gallery ceiling
        parts.append(
            (box(total, depth, 0.3).transformed(np.eye(3), [W / 2, -depth / 2, top + 0.3]), trim)
        )
    elif r < 0.5:  # awnings over shop windows
        fabric = b.material(
            tx.stripes(
                rng,
                tx.random_colour(rng, 0.1, 0.7, 0.9),
                tx.random_colour(rng, 0.4, 0.8, 0.2),
                rng.uniform(0.15, 0.4),
            )
            if rng.random() < 0.6
            else tx.plain(rng, tx.random_colour(rng, 0.05, 0.7, 0.9))
        )
        n = max(1, int(W / bay))
        ad = rng.uniform(0.8, 2.0)
        tilt = rng.uniform(0.15, 0.5)
        for k in range(n):
            if rng.random() < 0.3:
                continue
            cx = (k + 0.5) * W / n
            aw = W / n * 0.85
            # slab hinged at the wall at 2.7 m, sloping down outward (local -y)
            m = box(aw, ad, 0.04).transformed(
                rot_x(tilt), [cx, -ad / 2 * math.cos(tilt), 2.7 - ad / 2 * math.sin(tilt)]
            )
            parts.append((m, fabric))
    R = rot_z(yaw)
    z = b.ground_z(x, y)
    for m, mat in parts:
        b.add(m, mat, R, np.array([x, y, z]))
    centre = np.array([x, y, z]) + R @ np.array([W / 2, D / 2, roof_top / 2])
    it = Item("building", centre, math.hypot(W, D) / 2, roof_top, size=max(W, roof_top))
    b.items.append(it)
    return it
