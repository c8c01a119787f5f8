"""Camera geometry, the one place where OutCast's conventions live.

Conventions (see DESIGN.md):

* Pinhole camera, OpenCV axes: x right, y down, z forward. Principal point at the image centre.
  Pixel ``(row j, column i)`` has its centre at ``(u, v) = (i + 0.5, j + 0.5)``.
* Depth is the z coordinate of the visible point, ``> 0``; sky is ``+inf`` (ground truth) or any
  non-finite / non-positive value, which every function here treats as "no surface".
* The sun direction ``w`` is a unit vector in camera space pointing from the scene to the sun.
  Azimuth 0 = straight ahead, 90 = right, 180 = behind the camera; elevation 0 = horizon,
  90 = zenith: ``w = (cos(el) sin(az), -sin(el), cos(el) cos(az))`` for a level camera.

Every function is plain numpy. The functions whose maths the torch networks need as well
(``normals_from_depth``, ``view_directions``, the ray-march coordinates in :mod:`raymarch`) are
written against a small array namespace so that the torch twin
in ``outcast_core.nets.geometry_torch``
runs the same lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

DEFAULT_FOV_DEG = 60.0
_EPS = 1e-12


@dataclass(frozen=True)
class Camera:
    """Pinhole intrinsics for an image of ``height x width`` pixels.

    Attributes:
        height: image height in pixels.
        width: image width in pixels.
        focal: focal length in pixels (square pixels).
    """

    height: int
    width: int
    focal: float

    def __post_init__(self) -> None:
        if self.height < 1 or self.width < 1:
            raise ValueError(f"expected a positive image size, got {self.height}x{self.width}")
        if not (math.isfinite(self.focal) and self.focal > 0):
            raise ValueError(f"expected a finite focal length > 0, got {self.focal}")

    @property
    def cx(self) -> float:
        return self.width / 2.0

    @property
    def cy(self) -> float:
        return self.height / 2.0

    @property
    def fov_deg(self) -> float:
        """Horizontal field of view in degrees."""
        return math.degrees(2.0 * math.atan(self.width / (2.0 * self.focal)))

    @classmethod
    def from_fov(cls, height: int, width: int, fov_deg: float = DEFAULT_FOV_DEG) -> Camera:
        return cls(height, width, focal_from_fov(width, fov_deg))

    def resized(self, height: int, width: int) -> Camera:
        """The same camera seen at another resolution (field of view kept)."""
        return Camera(height, width, self.focal * width / self.width)

    def matrix(self) -> np.ndarray:
        """3x3 intrinsic matrix K."""
        return np.array(
            [[self.focal, 0.0, self.cx], [0.0, self.focal, self.cy], [0.0, 0.0, 1.0]],
            dtype=np.float64,
        )


def focal_from_fov(width: int, fov_deg: float) -> float:
    """Focal length in pixels from a horizontal field of view.

    Args:
        width: image width in pixels.
        fov_deg: horizontal field of view in degrees, in (0, 180).

    Returns:
        Focal length in pixels.

    Example:
        >>> round(focal_from_fov(200, 90.0), 6)
        100.0
    """
    if not (math.isfinite(fov_deg) and 0.0 < fov_deg < 180.0):
        raise ValueError(f"expected a field of view in (0, 180) degrees, got {fov_deg}")
    if width < 1:
        raise ValueError(f"expected a positive width, got {width}")
    return width / (2.0 * math.tan(math.radians(fov_deg) / 2.0))


def focal_from_35mm(width: int, height: int, focal_35mm: float) -> float:
    """Focal length in pixels from EXIF ``FocalLengthIn35mmFilm``.

    The 36 mm side of a full frame lies along the image's longer side, so this is
    ``max(W, H) * f35 / 36`` (``W * f35 / 36`` for a landscape photo).
    """
    if not (math.isfinite(focal_35mm) and focal_35mm > 0):
        raise ValueError(f"expected a 35 mm focal length > 0, got {focal_35mm}")
    return max(width, height) * focal_35mm / 36.0


def pixel_centres(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous image coordinates of the pixel centres.

    Returns:
        ``(u, v)``, each ``H x W`` float64: ``u = column + 0.5``, ``v = row + 0.5``.
    """
    u = np.arange(width, dtype=np.float64) + 0.5
    v = np.arange(height, dtype=np.float64) + 0.5
    uu, vv = np.meshgrid(u, v)  # H x W each
    return uu, vv


def valid_depth(depth: np.ndarray) -> np.ndarray:
    """Mask of pixels with a surface: finite and strictly positive depth."""
    depth = np.asarray(depth)
    return np.isfinite(depth) & (depth > 0)


#: Range of :func:`relative_depth` for a valid surface: 1e12 times nearer or farther than the
#: median is already at every limit (ray ratios are capped), and products of two such values
#: stay finite in float32.
RELATIVE_DEPTH_RANGE = (1e-12, 1e12)


def relative_depth(depth: np.ndarray) -> np.ndarray:
    """Depth divided by its median surface depth, clamped to :data:`RELATIVE_DEPTH_RANGE`.

    Every consumer of depth here is scale-invariant (normals, the sampler's ratios, the shadow
    networks), so this is the one place that turns depth in any unit or range, down to values
    near the float32 limits, into well-conditioned numbers.

    Returns:
        ``H x W`` float64; NaN where there is no surface (see :func:`valid_depth`).
    """
    depth = np.asarray(depth)
    valid = valid_depth(depth)
    out = np.full(depth.shape, np.nan)
    if valid.any():
        d = depth[valid].astype(np.float64)
        out[valid] = np.clip(d / np.median(d), *RELATIVE_DEPTH_RANGE)
    return out


def network_depth(depth: np.ndarray) -> np.ndarray:
    """The depth input of the shadow networks: :func:`relative_depth` with 0 where no surface.

    ``S`` and ``2D`` only use depth ratios, so the relative depth changes nothing for them, but
    it keeps a depth map in any unit or range finite inside the float32 graph; 0 is the models
    contract's "no surface" (``+inf`` is not allowed by every runtime).

    Returns:
        ``H x W`` float32.
    """
    return np.nan_to_num(relative_depth(depth), nan=0.0).astype(np.float32)


def _check_depth(depth: np.ndarray) -> np.ndarray:
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"expected depth of shape H x W, got shape {depth.shape}")
    if depth.shape[0] < 1 or depth.shape[1] < 1:
        raise ValueError(f"expected a non-empty depth map, got shape {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        depth = depth.astype(np.float32)
    return depth


def backproject(depth: np.ndarray, camera: Camera) -> np.ndarray:
    """Camera-space points of every pixel.

    Args:
        depth: ``H x W`` z depth. Invalid depth gives NaN points.
        camera: intrinsics matching the depth map's size.

    Returns:
        ``H x W x 3`` float32 points ``(x, y, z)``.
    """
    depth = _check_depth(depth)
    if depth.shape != (camera.height, camera.width):
        raise ValueError(
            f"expected depth of shape {(camera.height, camera.width)}, got {depth.shape}"
        )
    uu, vv = pixel_centres(camera.height, camera.width)
    d = np.where(valid_depth(depth), depth, np.nan).astype(np.float64)
    x = (uu - camera.cx) / camera.focal * d
    y = (vv - camera.cy) / camera.focal * d
    return np.stack([x, y, d], axis=-1).astype(np.float32)  # H x W x 3


def project(points: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates ``(u, v)`` of camera-space points (``... x 3``); NaN where ``z <= 0``."""
    points = np.asarray(points, dtype=np.float64)
    if points.shape[-1] != 3:
        raise ValueError(f"expected points of shape ... x 3, got {points.shape}")
    z = points[..., 2]
    zs = np.where(z > 0, z, np.nan)
    u = camera.focal * points[..., 0] / zs + camera.cx
    v = camera.focal * points[..., 1] / zs + camera.cy
    return u, v


def sun_in_frame(w: Any, camera: Camera) -> bool:
    """Whether the sun direction ``w`` (camera space, toward the sun) projects inside the image.

    Example:
        >>> sun_in_frame((0.0, -0.1, 1.0), Camera.from_fov(48, 64, 60.0))
        True
    """
    u, v = project(np.asarray(w, np.float64), camera)
    return bool(np.isfinite(u) and 0 <= u < camera.width and 0 <= v < camera.height)


def view_directions(camera: Camera) -> np.ndarray:
    """The per-pixel unit view direction map ``Psi`` (from the camera through each pixel).

    Returns:
        ``H x W x 3`` float32 unit vectors.
    """
    uu, vv = pixel_centres(camera.height, camera.width)
    rays = np.stack(
        [(uu - camera.cx) / camera.focal, (vv - camera.cy) / camera.focal, np.ones_like(uu)],
        axis=-1,
    )  # H x W x 3
    return (rays / np.linalg.norm(rays, axis=-1, keepdims=True)).astype(np.float32)


def _sobel_xy(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sobel derivatives along u (columns) and v (rows) of ``H x W x C`` with edge replication."""
    pad = np.pad(p, ((1, 1), (1, 1), (0, 0)), mode="edge")  # (H+2) x (W+2) x C
    h, w = p.shape[:2]

    def s(dy: int, dx: int) -> np.ndarray:
        return pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]

    du = (s(-1, 1) + 2 * s(0, 1) + s(1, 1)) - (s(-1, -1) + 2 * s(0, -1) + s(1, -1))
    dv = (s(1, -1) + 2 * s(1, 0) + s(1, 1)) - (s(-1, -1) + 2 * s(-1, 0) + s(-1, 1))
    return du / 8.0, dv / 8.0


def normals_from_depth(depth: np.ndarray, camera: Camera) -> np.ndarray:
    """Unit surface normals from a depth map, facing the camera.

    Back-projects every pixel, takes Sobel derivatives of the point map along u and v, crosses
    them and flips the result toward the camera. Pixels without a surface (and pixels whose
    neighbourhood gives a degenerate cross product) get the zero vector, so their cosine term is 0.

    Args:
        depth: ``H x W`` z depth.
        camera: intrinsics matching the depth map.

    Returns:
        ``H x W x 3`` float32; unit length where valid, zero elsewhere.

    Example:
        >>> cam = Camera.from_fov(4, 4, 60.0)
        >>> n = normals_from_depth(np.full((4, 4), 2.0, np.float32), cam)
        >>> np.allclose(n[..., 2], -1.0)
        True
    """
    depth = _check_depth(depth)
    valid = valid_depth(depth)
    # Scale invariance: normals do not depend on the depth scale; normalising keeps any range sane.
    d = relative_depth(depth)
    # Invalid pixels take their nearest valid neighbour's depth for the stencil only.
    d_filled = fill_invalid(d, valid)
    pts = backproject(d_filled.astype(np.float32), camera).astype(np.float64)  # H x W x 3
    du, dv = _sobel_xy(pts)
    n = np.cross(du, dv)  # H x W x 3
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    good = (norm[..., 0] > _EPS) & valid & np.isfinite(norm[..., 0])
    n = np.where(good[..., None], n / np.where(norm > _EPS, norm, 1.0), 0.0)
    facing = np.sum(n * pts, axis=-1, keepdims=True)  # > 0: points away from the camera
    n = np.where(facing > 0, -n, n)
    return n.astype(np.float32)


def fill_invalid(d: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Replace invalid depth by the nearest valid value (or 1 when nothing is valid)."""
    if valid.all():
        return d
    if not valid.any():
        return np.ones_like(d)
    import cv2

    # distanceTransform with labels gives, for each pixel, the label of the nearest zero pixel.
    src = np.where(valid, 0, 1).astype(np.uint8)
    _, labels = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL)
    lab_vals = np.zeros(labels.max() + 1, dtype=np.float64)
    lab_vals[labels[valid]] = d[valid]
    return np.where(valid, d, lab_vals[labels])


# --------------------------------------------------------------------------------------------
# Sun direction
# --------------------------------------------------------------------------------------------


def camera_rotation(pitch_deg: float = 0.0, roll_deg: float = 0.0) -> np.ndarray:
    """Rotation taking vectors from the level-camera frame to the camera frame.

    The level frame shares the camera's position and heading, with y pointing straight down.
    ``pitch_deg > 0`` tilts the camera up; ``roll_deg > 0`` turns it clockwise as seen by the
    photographer (the right side of the frame goes down).

    Returns:
        3x3 float64 matrix ``R`` with ``v_camera = R @ v_level``.
    """
    for name, val in (("pitch", pitch_deg), ("roll", roll_deg)):
        if not math.isfinite(val):
            raise ValueError(f"expected a finite {name} angle, got {val}")
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    # Rows are the camera axes expressed in the level frame.
    # Pitch about x: forward goes up (-y).
    rp = np.array([[1, 0, 0], [0, math.cos(p), math.sin(p)], [0, -math.sin(p), math.cos(p)]])
    # Roll about z.
    rr = np.array([[math.cos(r), math.sin(r), 0], [-math.sin(r), math.cos(r), 0], [0, 0, 1]])
    return rr @ rp


def sun_vector(
    azimuth_deg: float, elevation_deg: float, pitch_deg: float = 0.0, roll_deg: float = 0.0
) -> np.ndarray:
    """Camera-space unit sun direction from azimuth/elevation relative to the camera.

    Args:
        azimuth_deg: 0 = straight ahead (backlit), 90 = right, 180 = behind the camera.
        elevation_deg: 0 = horizon, 90 = zenith (negative: below the horizon).
        pitch_deg: camera pitch (up positive).
        roll_deg: camera roll (clockwise positive).

    Returns:
        ``(3,)`` float64 unit vector.

    Example:
        >>> np.round(sun_vector(0.0, 90.0), 6).tolist()
        [0.0, -1.0, 0.0]
    """
    for name, val in (("azimuth", azimuth_deg), ("elevation", elevation_deg)):
        if not math.isfinite(val):
            raise ValueError(f"expected a finite sun {name}, got {val}")
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    w = np.array([math.cos(el) * math.sin(az), -math.sin(el), math.cos(el) * math.cos(az)])
    if pitch_deg or roll_deg:
        w = camera_rotation(pitch_deg, roll_deg) @ w
    return w / np.linalg.norm(w)


def sun_angles(
    w: np.ndarray | tuple[float, float, float], pitch_deg: float = 0.0, roll_deg: float = 0.0
) -> tuple[float, float]:
    """Inverse of :func:`sun_vector`: ``(azimuth_deg in [0, 360), elevation_deg in [-90, 90])``.

    At the zenith or nadir the azimuth is undefined and returned as 0.
    """
    v = normalize_sun(w)
    if pitch_deg or roll_deg:
        v = camera_rotation(pitch_deg, roll_deg).T @ v
    el = math.degrees(math.asin(max(-1.0, min(1.0, -v[1]))))
    horiz = math.hypot(v[0], v[2])
    az = 0.0 if horiz < 1e-12 else math.degrees(math.atan2(v[0], v[2])) % 360.0
    return az, el


def normalize_sun(w: Any) -> np.ndarray:
    """Validate and normalise a sun direction; raises ``ValueError`` for zero / non-finite input."""
    v = np.asarray(w, dtype=np.float64).reshape(-1)
    if v.shape != (3,):
        raise ValueError(f"expected a sun direction of 3 components, got shape {np.shape(w)}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"expected a finite sun direction, got {v.tolist()}")
    scale = float(np.abs(v).max())  # scaled first: the norm of (1e308, 1e308, 0) overflows
    if scale < 1e-9:
        raise ValueError("expected a non-zero sun direction, got a zero vector")
    v = v / scale
    return v / float(np.linalg.norm(v))


def cosine_term(normals: np.ndarray, w: Any) -> np.ndarray:
    """``max(0, N . w)`` per pixel; 0 where the normal is the zero vector.

    Args:
        normals: ``H x W x 3`` unit normals (zero where there is no surface).
        w: camera-space sun direction.

    Returns:
        ``H x W`` float32 in [0, 1].
    """
    normals = np.asarray(normals)
    if normals.ndim != 3 or normals.shape[-1] != 3:
        raise ValueError(f"expected normals of shape H x W x 3, got {normals.shape}")
    v = normalize_sun(w)
    c = normals.astype(np.float64) @ v  # H x W
    return np.clip(np.nan_to_num(c, nan=0.0), 0.0, 1.0).astype(np.float32)
