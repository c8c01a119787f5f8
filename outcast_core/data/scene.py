"""Random outdoor scenes: layout, camera and suns, deterministic from a seed (no Mitsuba here).

World frame: z up, metres. The camera follows OutCast's OpenCV convention: ``rotation`` holds the
camera axes (x right, y down, z forward) as columns in world coordinates, so
``p_world = rotation @ p_cam + origin``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from outcast_core.data import props as pr
from outcast_core.data import textures as tx
from outcast_core.data.meshes import Mesh, box, concat, ellipsoid
from outcast_core.runtime.geometry.camera import camera_rotation, sun_vector

SCENE_KINDS = ("street", "plaza", "closeup")
# Kinds only drawn when asked for (``generate_scene(kind=...)``, ``outcast data make --kind``):
# the random mix of SCENE_KINDS, and so every standard set, stays as it was.
EXTRA_KINDS = ("landscape",)
MIN_SUN_ELEVATION, MAX_SUN_ELEVATION = 3.0, 85.0
GROUND_SIZE = 1500.0


@dataclass
class CameraPose:
    """Pinhole camera pose in the z-up world.

    Attributes:
        origin: ``(3,)`` camera centre.
        heading_deg: direction of the optical axis in the ground plane (0 = +x, 90 = +y).
        pitch_deg: up positive. roll_deg: clockwise (as seen by the photographer) positive.
        fov_deg: horizontal field of view.
    """

    origin: np.ndarray
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    fov_deg: float

    def level_frame(self) -> np.ndarray:
        """3x3 columns: the level camera's x (right), y (down), z (forward) in world coordinates."""
        h = math.radians(self.heading_deg)
        f = np.array([math.cos(h), math.sin(h), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        return np.stack([np.cross(f, up), -up, f], axis=1)

    @property
    def rotation(self) -> np.ndarray:
        """Camera-to-world rotation (columns = camera axes in world coordinates)."""
        # v_cam = R v_level, v_level = L^T v_world  =>  camera-to-world = L R^T.
        return self.level_frame() @ camera_rotation(self.pitch_deg, self.roll_deg).T

    def world_to_camera(self, points: np.ndarray) -> np.ndarray:
        """``... x 3`` world points to camera coordinates."""
        return (np.asarray(points, np.float64) - self.origin) @ self.rotation


@dataclass
class Sun:
    """One sun: azimuth relative to the camera heading, elevation above the horizon."""

    azimuth_deg: float
    elevation_deg: float

    def world_direction(self, camera: CameraPose) -> np.ndarray:
        """Unit vector from the scene toward the sun, world coordinates."""
        w_level = sun_vector(self.azimuth_deg, self.elevation_deg)
        return camera.level_frame() @ w_level

    def camera_direction(self, camera: CameraPose) -> np.ndarray:
        """Unit vector toward the sun in camera coordinates (DESIGN.md convention)."""
        return sun_vector(self.azimuth_deg, self.elevation_deg, camera.pitch_deg, camera.roll_deg)


@dataclass
class SceneSpec:
    """Everything needed to render one view."""

    kind: str
    materials: list[pr.Material]
    parts: list[tuple[Mesh, int]]
    camera: CameraPose
    suns: list[Sun]
    turbidity: float
    sky_albedo: float
    target: str = ""
    info: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------


def _ground(b: pr.SceneBuilder, kind: str | None = None) -> str:
    rng = b.rng
    kind = kind or str(rng.choice(tx.GROUND_KINDS))
    mat = b.material(tx.ground_texture(rng, kind))
    s = GROUND_SIZE / 2
    corners = np.array([[-s, -s], [s, -s], [s, s], [-s, s]], np.float64)
    z = np.array([b.ground_z(x, y) for x, y in corners])
    verts = np.concatenate([corners, z[:, None]], axis=1)
    b.add(Mesh(verts, np.array([[0, 1, 2], [0, 2, 3]]), corners.copy()), mat)
    return kind


def _scatter(
    b: pr.SceneBuilder,
    fns: list[pr.PropFn],
    n: int,
    xr: tuple[float, float],
    yr: tuple[float, float],
    tries: int = 8,
) -> None:
    rng = b.rng
    for _ in range(n):
        fn = fns[int(rng.integers(len(fns)))]
        for _ in range(tries):
            x, y = rng.uniform(*xr), rng.uniform(*yr)
            if not b.overlaps(x, y, 0.8):
                fn(b, x, y, rng.uniform(0, 2 * math.pi))
                break


def street(b: pr.SceneBuilder) -> None:
    """A street along x: road, raised pavements, building rows, street furniture."""
    rng = b.rng
    _ground(b, str(rng.choice(["asphalt", "asphalt", "paving", "concrete", "snow"])))
    road = rng.uniform(3.0, 8.0)  # half width
    walk = rng.uniform(2.0, 5.0)
    curb = rng.uniform(0.08, 0.2)
    pave = b.material(tx.ground_texture(rng, str(rng.choice(["paving", "tiles", "concrete"]))))
    for side in (-1, 1):
        y0 = side * (road + walk / 2)
        b.add(box(400.0, walk, curb + 0.5), pave, translation=np.array([60.0, y0, -0.5]))
        if rng.random() > 0.85:
            continue
        x = rng.uniform(-40, -10)
        setback = rng.uniform(0.0, 3.0)
        while x < 150:
            w = rng.uniform(6.0, 25.0)
            yb = side * (road + walk + setback)
            if side > 0:
                pr.building(b, x, yb, 0.0, w)
            else:  # front faces +y: rotate by pi, origin at the far end
                pr.building(b, x + w, yb, math.pi, w)
            x += w + (rng.uniform(0.5, 8.0) if rng.random() < 0.4 else 0.0)
    if rng.random() < 0.4:  # closing building across the street
        pr.building(b, rng.uniform(40, 120), -road - walk, math.pi / 2, 2 * (road + walk))
    # furniture along the pavements and cars along the road
    for side in (-1, 1):
        ys = side * (road + rng.uniform(0.5, walk - 0.5))
        fn = [pr.tree, pr.lamp_post, pr.bollard, pr.sign][int(rng.integers(4))]
        spacing = rng.uniform(4.0, 14.0)
        for x in np.arange(rng.uniform(-20, 0), 120, spacing):
            if rng.random() < 0.8 and not b.overlaps(x, ys, 0.5):
                fn(b, x, ys, rng.uniform(0, 2 * math.pi))
        for x in np.arange(rng.uniform(-20, 0), 120, rng.uniform(5.0, 12.0)):
            if rng.random() < 0.5:
                yc = side * (road - 1.2)
                if not b.overlaps(x, yc, 1.0):
                    pr.car(b, x, yc, rng.normal(0, 0.05) + (0 if rng.random() < 0.5 else math.pi))
    _scatter(b, pr.STREET_PROPS, int(rng.integers(3, 12)), (-10, 60), (-road - walk, road + walk))


def plaza(b: pr.SceneBuilder) -> None:
    """An open square: buildings around, props in the middle."""
    rng = b.rng
    if rng.random() < 0.5:
        b.slope = tuple(rng.uniform(-0.05, 0.05, 2))
    _ground(b)
    radius = rng.uniform(15.0, 60.0)
    for _ in range(int(rng.integers(2, 9))):
        a = rng.uniform(0, 2 * math.pi)
        w = rng.uniform(8.0, 30.0)
        # front faces the plaza centre: local -y toward the centre
        yaw = a - math.pi / 2 + math.pi
        x, y = radius * math.cos(a), radius * math.sin(a)
        ox, oy = x - math.cos(yaw) * w / 2, y - math.sin(yaw) * w / 2
        pr.building(b, ox, oy, yaw, w)
    _scatter(
        b,
        pr.STREET_PROPS + [pr.umbrella, pr.column, pr.tree],
        int(rng.integers(5, 25)),
        (-radius * 0.7, radius * 0.7),
        (-radius * 0.7, radius * 0.7),
    )


def closeup(b: pr.SceneBuilder) -> None:
    """A few small objects on the ground, sometimes a wall or steps behind them."""
    rng = b.rng
    if rng.random() < 0.4:
        b.slope = tuple(rng.uniform(-0.06, 0.06, 2))
    _ground(b)
    if rng.random() < 0.4:  # a wall behind
        mat = b.material(tx.wall_texture(rng))
        h = rng.uniform(0.5, 4.0)
        yw = rng.uniform(1.5, 5.0)
        b.add(box(30.0, 0.3, h + 1.0), mat, translation=np.array([0.0, yw, -1.0]))
        b.blockers.append((-15.0, 15.0, yw - 0.15, yw + 0.15))
    if rng.random() < 0.3:  # steps
        mat = b.material(tx.ground_texture(rng, str(rng.choice(["concrete", "paving", "tiles"]))))
        rise, run = rng.uniform(0.12, 0.2), rng.uniform(0.28, 0.45)
        y0 = rng.uniform(1.0, 4.0)
        n_steps = int(rng.integers(1, 6))
        steps = [
            box(12.0, 6.0, rise * (k + 1) + 0.5).transformed(
                np.eye(3), [0, y0 + k * run + 3.0, -0.5]
            )
            for k in range(n_steps)
        ]
        b.add(concat(steps), mat)
        b.blockers.append((-6.0, 6.0, y0, y0 + (n_steps - 1) * run + 6.0))
    n = int(rng.integers(1, 5))
    _scatter(b, pr.SMALL_PROPS, n, (-1.5, 1.5), (-1.5, 1.5))
    if rng.random() < 0.5:
        _scatter(
            b, [pr.tree, pr.lamp_post, pr.fence, pr.wall], int(rng.integers(1, 3)), (-8, 8), (2, 10)
        )


def _on_ground(b: pr.SceneBuilder, mesh: Mesh) -> Mesh:
    """``mesh`` built on z = 0 moved onto the (planar) ground, every vertex by its own height."""
    v = mesh.vertices.copy()
    v[:, 2] += np.array([b.ground_z(x, y) for x, y in v[:, :2]])
    return Mesh(v, mesh.faces, mesh.uv)


def _slab(
    b: pr.SceneBuilder, x0: float, x1: float, y0: float, y1: float, height: float, mat: int
) -> None:
    """A block whose top follows the ground ``height`` above it (a crop field, a hedge, a path).

    Slabs more than 0.1 m high become blockers: no prop and no camera stands in them.
    """
    m = box(x1 - x0, y1 - y0, height + 0.5).transformed(
        np.eye(3), [(x0 + x1) / 2, (y0 + y1) / 2, -0.5]
    )
    b.add(_on_ground(b, m), mat)
    if height > 0.1:
        b.blockers.append((x0, x1, y0, y1))


def landscape(b: pr.SceneBuilder) -> None:
    """Open country to the horizon along x: fields, a path, hedges, tree lines, hills, pylons.

    The camera stands on or beside the path at head height and looks along it (see
    :func:`_landscape_camera`), so the ground recedes to a far horizon, as in most holiday and
    hiking photos: a geometry the street, plaza and close-up layouts never show.
    """
    rng = b.rng
    r = rng.random()
    # Steep slopes only rise ahead (a hillside or ski run seen from below): a plane falling
    # away ahead or to a side would show the environment below the horizon between its
    # vanishing line and its far edge, which the renderer labels sky.
    if r < 0.5:
        b.slope = tuple(rng.uniform(-0.03, 0.03, 2))
    elif r < 0.75:
        b.slope = (float(rng.uniform(0.08, 0.3)), float(rng.uniform(-0.03, 0.03)))
    ground = str(rng.choice(["grass", "grass", "grass", "sand", "snow", "gravel", "field"]))
    _ground(b, ground)
    # The path: a strip along x from behind the camera to far ahead, a little above the ground.
    # Props keep off it (a blocker); the camera may stand on it (walkable).
    half = 0.0
    if rng.random() < 0.75:
        half = float(rng.uniform(0.6, 2.5))
        kind = str(rng.choice(["asphalt", "gravel", "sand", "concrete", "snow"]))
        mat = b.material(tx.ground_texture(rng, kind))
        _slab(b, -30.0, 400.0, -half, half, float(rng.uniform(0.01, 0.06)), mat)
        b.blockers.append((-30.0, 400.0, -half, half))
        b.walkable.append((-30.0, 400.0, -half, half))
    # Fields beside the path: raised crops or flat patches of another ground.
    for side in (-1, 1):
        x = -30.0
        while x < 300.0:
            length = float(rng.uniform(20.0, 120.0))
            if rng.random() < 0.6:
                edge = half + float(rng.uniform(0.3, 3.0))
                width = float(rng.uniform(10.0, 80.0))
                crop = rng.random() < 0.5
                kind = "field" if crop else str(rng.choice(["grass", "gravel", "sand", "field"]))
                mat = b.material(tx.ground_texture(rng, kind))
                h = float(rng.uniform(0.3, 1.2)) if crop else 0.02
                y0, y1 = sorted((side * edge, side * (edge + width)))
                _slab(b, x, x + length, y0, y1, h, mat)
            x += length + float(rng.uniform(0.0, 10.0))
    # Hedges and tree lines along the fields or across them (with a gap for the path).
    gap = half + 1.5
    for _ in range(int(rng.integers(0, 5))):
        along = rng.random() < 0.5
        dist = float(rng.uniform(15.0, 250.0))
        side = 1 if rng.random() < 0.5 else -1
        if rng.random() < 0.5:  # hedge
            leaf = tx.grainy(rng, np.array([0.05, 0.1, 0.03]) * rng.uniform(0.5, 1.6), 0.5, 0.3)
            mat = b.material(leaf)
            h, w = float(rng.uniform(1.0, 3.5)), float(rng.uniform(0.8, 3.0))
            span = float(rng.uniform(20.0, 200.0))
            if along:
                y = side * (half + dist * 0.3 + 2.0)
                x0 = float(rng.uniform(-10.0, 100.0))
                _slab(b, x0, x0 + span, y - w / 2, y + w / 2, h, mat)
            else:
                y0 = float(rng.uniform(-span, 0.0))
                for lo, hi in ((y0, min(y0 + span, -gap)), (max(y0, gap), y0 + span)):
                    if hi - lo > 1.0:
                        _slab(b, dist, dist + w, lo, hi, h, mat)
        else:  # a row of trees
            step = float(rng.uniform(4.0, 15.0))
            n = int(rng.integers(4, 20))
            start = float(rng.uniform(-40.0, 40.0))
            for k in range(n):
                t = start + k * step + float(rng.normal(0, step * 0.15))
                x, y = (t, side * (half + dist * 0.3 + 3.0)) if along else (dist, t)
                if not b.overlaps(x, y, 1.0):
                    pr.tree(b, x, y, float(rng.uniform(0, 2 * math.pi)))
    # Low hills on the horizon, sheared with the ground so that no rim floats.
    for _ in range(int(rng.integers(0, 3))):
        a = rng.uniform(-1.2, 1.2)
        d = float(rng.uniform(300.0, 700.0))
        rx, rz = float(rng.uniform(60.0, 250.0)), float(rng.uniform(8.0, 45.0))
        mat = b.material(tx.ground_texture(rng, str(rng.choice(["grass", "snow", "gravel"]))))
        hill = ellipsoid(rx, rx * float(rng.uniform(0.6, 1.4)), rz, 24)
        x, y = d * math.cos(a), d * math.sin(a)
        b.add(_on_ground(b, hill.transformed(np.eye(3), [x, y, -rz * 0.3])), mat)
    # Pylons and poles (lamp posts, tall columns), fence along the path, a few near props.
    for _ in range(int(rng.integers(0, 4))):
        x, y = float(rng.uniform(5.0, 150.0)), float(rng.uniform(-40.0, 40.0))
        if not b.overlaps(x, y, 1.0):
            if rng.random() < 0.5:
                pr.column(b, x, y, 0.0, height=float(rng.uniform(8.0, 25.0)))
            else:
                pr.lamp_post(b, x, y, float(rng.uniform(0, 2 * math.pi)))
    if half > 0 and rng.random() < 0.3:
        side = 1 if rng.random() < 0.5 else -1
        for x in np.arange(rng.uniform(-5.0, 5.0), rng.uniform(20.0, 80.0), 3.0):
            y = side * (half + 0.5)
            if not b.overlaps(x, y, 0.3):
                pr.fence(b, float(x), y, 0.0)
    _scatter(
        b,
        [pr.tree, pr.tree, pr.person, pr.bench, pr.sign, pr.bike, pr.wall, pr.ball_or_bin],
        int(rng.integers(4, 16)),
        (2.0, 50.0),
        (-12.0, 12.0),
    )


LAYOUTS = {"street": street, "plaza": plaza, "closeup": closeup, "landscape": landscape}


# --------------------------------------------------------------------------------------------
# Camera and suns
# --------------------------------------------------------------------------------------------


def _sight_blocked(b: pr.SceneBuilder, a: np.ndarray, c: np.ndarray) -> bool:
    """Whether the ground segment from ``a`` to 90 % of the way to ``c`` crosses a blocker."""
    return any(b.blocked(*(a + t * (c - a))) for t in np.linspace(0.0, 0.9, 24))


def _camera(b: pr.SceneBuilder, kind: str) -> tuple[CameraPose, str, float]:
    rng = b.rng
    fov = float(rng.uniform(35.0, 80.0))
    if kind == "landscape":
        return _landscape_camera(b, fov)
    candidates = (
        b.items if kind != "closeup" else [it for it in b.items if it.size < 4.0] or b.items
    )
    target = candidates[int(rng.integers(len(candidates)))]
    half = math.radians(fov) / 2
    for _ in range(30):
        fill = rng.uniform(0.5, 1.3) if kind == "closeup" else rng.uniform(0.35, 1.2)
        dist = max(target.size / fill / (2 * math.tan(half)), target.radius + 0.8)
        heading_from = rng.uniform(0, 2 * math.pi)
        cx = target.centre[0] + dist * math.cos(heading_from)
        cy = target.centre[1] + dist * math.sin(heading_from)
        if b.overlaps(cx, cy, 0.4) or _sight_blocked(b, np.array([cx, cy]), target.centre[:2]):
            continue
        if kind == "closeup":
            h = rng.uniform(0.3, 1.8)
        elif rng.random() < 0.8:
            h = rng.uniform(1.2, 2.2)
        else:
            h = rng.uniform(3.0, 15.0)
        cz = b.ground_z(cx, cy) + h
        break
    else:
        cx, cy, h = target.centre[0] - 10.0, target.centre[1], 1.6
        cz = b.ground_z(cx, cy) + h
    d = target.centre - np.array([cx, cy, cz])
    aim_z = target.centre[2] + rng.uniform(-0.3, 0.2) * target.height
    d[2] = aim_z - cz
    heading = math.degrees(math.atan2(d[1], d[0])) + rng.normal(0, fov / 8)
    pitch = math.degrees(math.atan2(d[2], math.hypot(d[0], d[1]))) + rng.normal(0, 3)
    pitch = float(np.clip(pitch, -50.0, 30.0))
    roll = float(np.clip(rng.normal(0, 1.5), -4.0, 4.0))
    return CameraPose(np.array([cx, cy, cz]), heading, pitch, roll, fov), target.name, float(h)


def landscape_stand_clear(b: pr.SceneBuilder, x: float, y: float, margin: float = 0.5) -> bool:
    """Whether a photographer can stand at ``x, y``: on open ground or a walkable path, not in
    a crop field, a hedge or another blocker, and ``margin`` clear of every item."""
    return not b.overlaps(x, y, margin, walk=True)


def _landscape_camera(b: pr.SceneBuilder, fov: float) -> tuple[CameraPose, str, float]:
    """On or beside the path near x = 0, looking roughly along it, the horizon in view."""
    rng = b.rng
    for _ in range(60):
        cx, cy = float(rng.uniform(-20.0, 0.0)), float(rng.uniform(-4.0, 4.0))
        if landscape_stand_clear(b, cx, cy):
            break
    else:  # the middle of the path (or of the open strip where a path would be)
        cx, cy = -10.0, 0.0
    h = float(rng.uniform(1.3, 2.0)) if rng.random() < 0.85 else float(rng.uniform(2.0, 8.0))
    heading = float(rng.normal(0.0, 25.0))
    # Look level with the slope ahead, then tilt, mostly down a little as people do, but never
    # so far that the horizon leaves the (square) frame.
    hd = math.radians(heading)
    ahead = math.degrees(math.atan(b.slope[0] * math.cos(hd) + b.slope[1] * math.sin(hd)))
    pitch = ahead + float(np.clip(rng.normal(-6.0, 7.0), -0.45 * fov, 0.45 * fov))
    roll = float(np.clip(rng.normal(0, 1.5), -4.0, 4.0))
    cz = b.ground_z(cx, cy) + h
    target = "path" if b.walkable else "open ground"
    return CameraPose(np.array([cx, cy, cz]), heading, pitch, roll, fov), target, h


def random_suns(rng: np.random.Generator, k: int) -> list[Sun]:
    """``k`` suns: azimuth uniform, elevation uniform in [3, 85] degrees."""
    return [
        Sun(float(rng.uniform(0, 360)), float(rng.uniform(MIN_SUN_ELEVATION, MAX_SUN_ELEVATION)))
        for _ in range(k)
    ]


def generate_scene(seed: int, suns: int = 4, kind: str | None = None) -> SceneSpec:
    """A random scene, camera and ``suns`` sun directions, fully determined by ``seed``.

    Args:
        seed: non-negative integer.
        suns: number of sun directions (K >= 1).
        kind: ``street``, ``plaza``, ``closeup`` or ``landscape``; random among the first three
            (40/25/35 %) when ``None``.

    Returns:
        A :class:`SceneSpec` (culling is done by the renderer).
    """
    if seed < 0:
        raise ValueError(f"expected a non-negative seed, got {seed}")
    if suns < 1:
        raise ValueError(f"expected at least one sun, got {suns}")
    if kind is not None and kind not in SCENE_KINDS + EXTRA_KINDS:
        raise ValueError(f"expected a scene kind in {SCENE_KINDS + EXTRA_KINDS}, got {kind!r}")
    rng = np.random.default_rng(seed)
    if kind is None:
        kind = str(rng.choice(SCENE_KINDS, p=[0.4, 0.25, 0.35]))
    b = pr.SceneBuilder(rng)
    LAYOUTS[kind](b)
    if not b.items:
        pr.bollard(b, 0.0, 0.0, 0.0)
    camera, target, cam_height = _camera(b, kind)
    sun_list = random_suns(rng, suns)
    return SceneSpec(
        kind,
        b.materials,
        b.parts,
        camera,
        sun_list,
        turbidity=float(rng.uniform(1.8, 7.0)),
        sky_albedo=float(rng.uniform(0.05, 0.4)),
        target=target,
        info={"seed": int(seed), "camera_height_m": cam_height},
    )
