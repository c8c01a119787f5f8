"""Triangle-mesh primitives for the synthetic scenes, in plain numpy.

Every primitive is built in its own local frame with real dimensions (metres), then placed with a
rigid transform. Texture coordinates are in metres (a texture's period is applied later by the
material), so bricks and tiles keep their physical size on every face. All meshes are flat shaded
(no vertex normals): the geometric normal is the shading normal, which keeps the stored normals,
the shadow image's cosine term and the path tracer in agreement.

World frame: z up, metres; the ground is the plane ``z = ground(x, y)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Mesh:
    """A triangle soup.

    Attributes:
        vertices: ``V x 3`` float64 positions.
        faces: ``F x 3`` int64 vertex indices (counter-clockwise seen from outside).
        uv: ``V x 2`` float64 texture coordinates in metres.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> Mesh:
        """The mesh moved by ``x -> rotation @ x + translation``."""
        v = self.vertices @ np.asarray(rotation, np.float64).T + np.asarray(translation, np.float64)
        return Mesh(v, self.faces, self.uv)


def concat(meshes: list[Mesh]) -> Mesh:
    """One mesh holding all of ``meshes``."""
    if not meshes:
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2)))
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return Mesh(
        np.concatenate([m.vertices for m in meshes]),
        np.concatenate([m.faces + o for m, o in zip(meshes, offsets, strict=True)]),
        np.concatenate([m.uv for m in meshes]),
    )


def rot_z(angle_rad: float) -> np.ndarray:
    """Rotation about the world's up axis."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_from_z(direction: np.ndarray) -> np.ndarray:
    """A rotation taking the local +z axis to ``direction``."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, d)
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    return np.stack([x, y, d], axis=1)


def _quad(corners: np.ndarray, uv: np.ndarray) -> Mesh:
    """Two triangles from 4 corners in counter-clockwise order."""
    return Mesh(corners, np.array([[0, 1, 2], [0, 2, 3]]), uv)


def box(sx: float, sy: float, sz: float) -> Mesh:
    """Axis-aligned box ``[-sx/2, sx/2] x [-sy/2, sy/2] x [0, sz]``: base on z = 0, 6 faces."""
    hx, hy = sx / 2.0, sy / 2.0
    quads = []
    # (normal axis, sign): corners counter-clockwise seen from outside; uv = in-face metres.
    p = np.array
    quads.append((p([[-hx, -hy, 0], [-hx, hy, 0], [hx, hy, 0], [hx, -hy, 0]]), (sx, sy)))  # -z
    quads.append((p([[-hx, -hy, sz], [hx, -hy, sz], [hx, hy, sz], [-hx, hy, sz]]), (sx, sy)))  # +z
    quads.append((p([[-hx, -hy, 0], [hx, -hy, 0], [hx, -hy, sz], [-hx, -hy, sz]]), (sx, sz)))  # -y
    quads.append((p([[hx, hy, 0], [-hx, hy, 0], [-hx, hy, sz], [hx, hy, sz]]), (sx, sz)))  # +y
    quads.append((p([[hx, -hy, 0], [hx, hy, 0], [hx, hy, sz], [hx, -hy, sz]]), (sy, sz)))  # +x
    quads.append((p([[-hx, hy, 0], [-hx, -hy, 0], [-hx, -hy, sz], [-hx, hy, sz]]), (sy, sz)))  # -x
    meshes = []
    for corners, (a, b) in quads:
        uv = np.array([[0, 0], [a, 0], [a, b], [0, b]], np.float64)
        meshes.append(_quad(corners.astype(np.float64), uv))
    return concat(meshes)


def box_between(p0: np.ndarray, p1: np.ndarray, width: float, depth: float) -> Mesh:
    """A beam of cross-section ``width x depth`` from point ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    length = float(np.linalg.norm(p1 - p0))
    return box(width, depth, length).transformed(rotation_from_z(p1 - p0), p0)


def cylinder(radius: float, height: float, segments: int = 20, caps: bool = True) -> Mesh:
    """Vertical prism approximating a cylinder, base at z = 0."""
    t = np.linspace(0.0, 2 * math.pi, segments + 1)
    x, y = radius * np.cos(t), radius * np.sin(t)
    circ = 2 * math.pi * radius
    meshes = []
    for i in range(segments):
        c = np.array(
            [
                [x[i], y[i], 0],
                [x[i + 1], y[i + 1], 0],
                [x[i + 1], y[i + 1], height],
                [x[i], y[i], height],
            ]
        )
        u0, u1 = circ * i / segments, circ * (i + 1) / segments
        meshes.append(_quad(c, np.array([[u0, 0], [u1, 0], [u1, height], [u0, height]])))
    if caps:
        for z, sign in ((0.0, -1), (height, 1)):
            ring = np.stack([x[:-1], y[:-1], np.full(segments, z)], axis=1)
            verts = np.concatenate([[[0.0, 0.0, z]], ring])
            idx = np.arange(segments)
            f = np.stack([np.zeros(segments, np.int64), 1 + idx, 1 + (idx + 1) % segments], axis=1)
            if sign < 0:
                f = f[:, [0, 2, 1]]
            meshes.append(Mesh(verts, f, verts[:, :2].copy()))
    return concat(meshes)


def tube(p0: np.ndarray, p1: np.ndarray, radius: float, segments: int = 10) -> Mesh:
    """A capped cylinder from ``p0`` to ``p1`` (any direction)."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    length = float(np.linalg.norm(p1 - p0))
    return cylinder(radius, length, segments).transformed(rotation_from_z(p1 - p0), p0)


def ellipsoid(rx: float, ry: float, rz: float, segments: int = 20, stretch: float = 0.0) -> Mesh:
    """UV ellipsoid centred at the origin; ``stretch > 0`` pulls the halves apart (a capsule)."""
    rings = max(4, segments // 2)
    th = np.linspace(0.0, math.pi, rings + 1)  # polar angle
    ph = np.linspace(0.0, 2 * math.pi, segments + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")  # (rings+1) x (segments+1)
    x = rx * np.sin(T) * np.cos(P)
    y = ry * np.sin(T) * np.sin(P)
    z = rz * np.cos(T)
    z = z + np.sign(z) * stretch / 2.0
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    uv = np.stack([P * max(rx, ry), T * rz], axis=-1).reshape(-1, 2)
    faces = []
    n = segments + 1
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j
            if i > 0:
                faces.append([a, d, b])
            if i < rings - 1:
                faces.append([b, d, c])
    return Mesh(verts, np.array(faces, np.int64), uv)


def cone(radius: float, height: float, segments: int = 16, base: bool = True) -> Mesh:
    """Cone with its base disc at z = 0 and apex at z = height."""
    t = np.linspace(0.0, 2 * math.pi, segments + 1)[:-1]
    ring = np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(segments)], axis=1)
    verts = np.concatenate([ring, [[0.0, 0.0, height], [0.0, 0.0, 0.0]]])
    idx = np.arange(segments)
    apex, centre = segments, segments + 1
    faces = [np.stack([idx, (idx + 1) % segments, np.full(segments, apex)], axis=1)]
    if base:
        faces.append(np.stack([(idx + 1) % segments, idx, np.full(segments, centre)], axis=1))
    return Mesh(verts, np.concatenate(faces), verts[:, :2].copy())


def gable_roof(sx: float, sy: float, height: float, overhang: float = 0.0) -> Mesh:
    """Triangular prism roof over ``sx x sy`` (ridge along x), base at z = 0."""
    hx, hy = sx / 2.0 + overhang, sy / 2.0 + overhang
    slope = math.hypot(hy, height)
    p = np.array
    meshes = [
        _quad(
            p([[-hx, -hy, 0], [hx, -hy, 0], [hx, 0, height], [-hx, 0, height]], float),
            p([[0, 0], [2 * hx, 0], [2 * hx, slope], [0, slope]], float),
        ),
        _quad(
            p([[hx, hy, 0], [-hx, hy, 0], [-hx, 0, height], [hx, 0, height]], float),
            p([[0, 0], [2 * hx, 0], [2 * hx, slope], [0, slope]], float),
        ),
        _quad(
            p([[-hx, -hy, 0], [-hx, hy, 0], [hx, hy, 0], [hx, -hy, 0]], float),
            p([[0, 0], [2 * hy, 0], [2 * hy, 2 * hx], [0, 2 * hx]], float),
        ),
    ]
    for x, order in ((hx, [0, 1, 2]), (-hx, [0, 2, 1])):
        v = p([[x, -hy, 0], [x, hy, 0], [x, 0, height]], float)
        meshes.append(Mesh(v, np.array([order]), v[:, 1:].copy()))
    return concat(meshes)


def arch_wall(
    span: float,
    pier: float,
    spring: float,
    rise_extra: float,
    thickness: float,
    count: int,
    segments: int = 10,
) -> Mesh:
    """An arcade: ``count`` round arches of width ``span`` between piers, extruded along y.

    The wall lies in the x-z plane, from ``x = 0`` to ``count * (span + pier) + pier``, between
    ``y = -thickness/2`` and ``+thickness/2``; arches spring at height ``spring``; the wall top is
    ``spring + span/2 + rise_extra``.
    """
    r = span / 2.0
    top = spring + r + rise_extra
    hy = thickness / 2.0
    parts: list[Mesh] = []
    pitch = span + pier
    for k in range(count + 1):  # piers
        parts.append(box(pier, thickness, top).transformed(np.eye(3), [k * pitch + pier / 2, 0, 0]))
    for k in range(count):
        cx = k * pitch + pier + r
        # Spandrel: between the half circle and the rectangle [cx-r, cx+r] x [spring, top]
        # is star-shaped from the arch centre: strip of quads between circle and rectangle.
        corner = math.atan2(top - spring, r)
        angles = np.unique(
            np.concatenate([np.linspace(0, math.pi, segments + 1), [corner, math.pi - corner]])
        )
        inner = np.stack([cx + r * np.cos(angles), spring + r * np.sin(angles)], axis=1)
        outer = []
        for a in angles:
            c, s = math.cos(a), math.sin(a)
            tx = r / abs(c) if abs(c) > 1e-9 else np.inf
            ty = (top - spring) / s if s > 1e-9 else np.inf
            t = min(tx, ty)
            outer.append([cx + t * c, spring + t * s])
        outer = np.array(outer)
        n = len(angles)
        for y, flip in ((-hy, False), (hy, True)):
            verts = np.concatenate(
                [
                    np.stack([inner[:, 0], np.full(n, y), inner[:, 1]], axis=1),
                    np.stack([outer[:, 0], np.full(n, y), outer[:, 1]], axis=1),
                ]
            )
            f = []
            for i in range(n - 1):
                a, b, c, d = i, i + 1, n + i + 1, n + i
                f += [[a, d, c], [a, c, b]] if not flip else [[a, c, d], [a, b, c]]
            parts.append(Mesh(verts, np.array(f), verts[:, [0, 2]].copy()))
        # Intrados (the curved underside), facing the arch centre.
        for i in range(n - 1):
            a0, a1 = inner[i], inner[i + 1]
            c = np.array(
                [[a0[0], -hy, a0[1]], [a0[0], hy, a0[1]], [a1[0], hy, a1[1]], [a1[0], -hy, a1[1]]]
            )
            length = float(np.linalg.norm(a1 - a0))
            parts.append(
                _quad(c, np.array([[0, 0], [thickness, 0], [thickness, length], [0, length]]))
            )
    total = count * pitch + pier
    # Top face and end faces are covered by a thin box: the outer faces of the spandrels.
    parts.append(box(total, thickness, 0.02).transformed(np.eye(3), [total / 2, 0, top - 0.02]))
    return concat(parts)
