"""Depth from elsewhere: any monocular ONNX depth model, and the phone's own map, as depth
sources for the session.

**Models.** :func:`load_depth_model` accepts an ONNX file with one image input
(``N x 3 x H x W``, a fixed or a dynamic size) and one output (``N x H' x W'`` or
``N x 1 x H' x W'``). Its conventions are detected, or declared in a sidecar JSON next to it
(``FILE.onnx.json``; see :func:`read_sidecar`):

* input size: a fixed size is used as it is (the photo is stretched to it); a dynamic one gets
  the photo with its aspect ratio, the shorter side at :data:`DEFAULT_SIDE` rounded to the
  model's multiple. The multiple is 14 (the ViT patch of Depth Anything) or 32 (CNN encoders,
  MiDaS): a dynamic model is tried at 14 first and at 32 when onnxruntime refuses that size,
  and the one that runs is kept;
* normalisation: ImageNet mean and std on sRGB in ``[0, 1]`` (Depth Anything, MiDaS v2.1);
* output: ``inverse-relative``, inverse depth up to an unknown scale and shift (Depth
  Anything, MiDaS); ``depth-relative``, depth up to a scale; ``metric``, depth in metres.

**Relative inverse depth to depth** (:func:`inverse_to_depth`). A model that gives
``r = a / z + b`` with unknown ``a > 0`` and ``b`` is solved for both:

* the *shift* ``b`` from the far region: the sky is at infinity, ``1 / z = 0``, so ``b`` is
  the median of ``r`` on the sky (:func:`far_sky`). With no sky in the frame, the ground is
  used: on a plane ``n . X = c`` the inverse depth ``1 / z = (n_x x + n_y y + n_z) / c`` is
  affine in the normalised image coordinates ``(x, y)``, so an affine fit of ``r`` over the
  lower half of the frame (RANSAC) finds the ground, and for a level camera (no pitch) its
  horizon passes through the principal point, where ``1 / z = 0``: ``b`` is the fit's value
  there. With neither, ``b = min(0, r_lo - 5 % of the range)`` (the model's own zero);
* the *scale* ``a`` from the ground plane and a camera height: the depth ``1 / (r - b)`` is
  given to :func:`~outcast_core.runtime.pipeline.depth_post.fit_ground_plane`, and scaled so the
  plane
  lies :data:`CAMERA_HEIGHT` metres below the camera. With no ground plane, the median surface
  depth is set to :data:`FALLBACK_MEDIAN_DEPTH` (the scale only sets units: shadows depend on
  depth ratios).

Relative depth is scaled the same way (no shift). **The model's far region becomes the sky
mask**: :func:`far_sky` takes the pixels whose inverse depth is within :data:`FAR_FRACTION` of
the range above its low end (1st percentile), with a sky's colour (bluish, or bright and
unsaturated: a far wall in a frame without sky stays a surface), connected to the top of the
frame.

**Sources** (:class:`ModelDepthSource`, :class:`PhoneDepthSource`): the session's depth hook
(``RelightSession.depth_provider``): called with the working image and camera, they return
``(depth, sky)`` and have a ``name`` shown as "depth: ..." (the model's with its time).
"""

from __future__ import annotations

import json
import math
import os
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np

from outcast_core.runtime.geometry.camera import Camera
from outcast_core.runtime.io.models import ModelError, onnx_session
from outcast_core.runtime.io.phone_depth import PhoneDepth, phone_depth_at
from outcast_core.runtime.pipeline.depth_post import (
    GROUND_ROWS,
    fit_ground_plane,
    sky_colour,
    top_connected,
)

#: Output conventions a model may have.
OUTPUT_KINDS = ("inverse-relative", "depth-relative", "metric")
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
#: Shorter side a dynamic model runs at, per multiple (Depth Anything's 518 = 37 x 14).
DEFAULT_SIDE = {14: 518, 32: 384}
#: Camera height above the ground (metres) that sets the scale of relative depth.
CAMERA_HEIGHT = 1.6
#: Median surface depth (metres) when no ground plane sets the scale.
FALLBACK_MEDIAN_DEPTH = 10.0
#: The far region: inverse depth within this fraction of its range above its low end.
FAR_FRACTION = 0.04
#: Least fraction of the frame the far region must cover to be sky.
MIN_SKY_FRACTION = 0.002
#: Affine ground fit in inverse depth: inlier tolerance (fraction of the range), trials, points
#: sampled (at most), least points, least inlier fraction of the lower half.
AFFINE_TOL = 0.02
AFFINE_TRIALS = 200
AFFINE_POINTS = 4000
AFFINE_MIN_POINTS = 24
AFFINE_MIN_INLIERS = 0.4
#: A trial whose three points' ``[x, y, 1]`` rows have a determinant below this (collinear
#: points) fixes no plane and is skipped.
AFFINE_MIN_DET = 1e-9
#: Trials scored together: their residuals (16 x 4000 float64, 0.5 MB) stay in the cache, which
#: scored 200 trials 2x as fast as a Python loop and 3x as fast as one 200 x 4000 block (here).
AFFINE_BLOCK = 16
#: Largest side / input size a sidecar may declare.
MAX_SIDE = 4096
SIDECAR_KEYS = frozenset({"input_size", "multiple", "mean", "std", "output"})


class DepthProvider(Protocol):
    """A depth source for the session: ``(image_srgb, camera) -> (depth, sky)``."""

    name: str

    def __call__(self, image_srgb: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        ...


# --------------------------------------------------------------------------------------------
# Plain functions


def far_sky(inverse_depth: np.ndarray, image_srgb: np.ndarray | None = None) -> np.ndarray:
    """The far region of an inverse-depth map connected to the top of the frame (the sky).

    Args:
        inverse_depth: ``H x W`` inverse depth up to scale and shift (larger = nearer).
        image_srgb: the photo at the same size, if known: then only far pixels with a sky's
            colour count (:func:`~outcast_core.runtime.pipeline.depth_post.sky_colour`), so the far
            wall
            of a frame without sky is not taken for it.

    Returns:
        ``H x W`` bool; all False when the region covers less than :data:`MIN_SKY_FRACTION`.
    """
    r = np.asarray(inverse_depth, np.float64)
    if r.ndim != 2 or min(r.shape) < 1:
        raise ValueError(f"expected an H x W inverse depth, got shape {r.shape}")
    finite = np.isfinite(r)
    if not finite.any():
        return np.zeros(r.shape, bool)
    lo, hi = np.percentile(r[finite], [1.0, 99.0])
    if not hi > lo:
        return np.zeros(r.shape, bool)
    far = finite & (r <= lo + FAR_FRACTION * (hi - lo))
    if image_srgb is not None:
        image = np.asarray(image_srgb, np.float32)
        if image.shape[:2] != r.shape:
            raise ValueError(f"expected an image of the map's size {r.shape}, got "
                             f"{image.shape[:2]}")
        far &= sky_colour(image)
    sky = top_connected(far)
    return sky if sky.mean() >= MIN_SKY_FRACTION else np.zeros(r.shape, bool)


def _image_coords(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    x = (np.arange(camera.width) + 0.5 - camera.cx) / camera.focal
    y = (np.arange(camera.height) + 0.5 - camera.cy) / camera.focal
    return np.broadcast_to(x[None, :], (camera.height, camera.width)), np.broadcast_to(
        y[:, None], (camera.height, camera.width))


def fit_affine_ground(inverse: np.ndarray, sky: np.ndarray, camera: Camera, seed: int = 0
                      ) -> tuple[float, float, float] | None:
    """The ground of an inverse-depth map as ``r = alpha x + beta y + gamma`` (or None).

    A plane's inverse depth is affine in the normalised image coordinates ``(x, y)``, and stays
    so under any scale and shift of the inverse depth; RANSAC over the bottom
    :data:`~outcast_core.runtime.pipeline.depth_post.GROUND_ROWS` of the frame finds the largest
    such region: :data:`AFFINE_TRIALS` planes through random triples of at most
    :data:`AFFINE_POINTS` sampled pixels, all drawn and solved at once (deterministic for a
    ``seed``, like :func:`~outcast_core.runtime.pipeline.depth_post.fit_ground_plane`); the one
    with the most pixels within :data:`AFFINE_TOL` of the range is refitted to them by least
    squares. Only a ground below the camera (``beta > 0``: nearer toward the bottom) holding at
    least :data:`AFFINE_MIN_INLIERS` of those pixels counts.
    """
    r = np.asarray(inverse, np.float64)
    xs, ys = _image_coords(camera)
    top = min(r.shape[0] - 1, int(r.shape[0] * (1.0 - GROUND_ROWS)))
    ok = np.isfinite(r) & ~np.asarray(sky, bool)
    ok[:top] = False
    if ok.sum() < AFFINE_MIN_POINTS:
        return None
    pts = np.stack([xs[ok], ys[ok], np.ones(int(ok.sum()))], axis=1)  # P x 3
    vals = r[ok]
    rng = np.random.default_rng(seed)
    if len(vals) > AFFINE_POINTS:
        pick = rng.choice(len(vals), AFFINE_POINTS, replace=False)
        pts, vals = pts[pick], vals[pick]
    lo, hi = np.percentile(np.asarray(inverse)[np.isfinite(inverse)], [1.0, 99.0])
    tol = AFFINE_TOL * max(hi - lo, 1e-12)
    # Every trial at once: the plane through each random point triple, where it has one.
    tri = rng.integers(0, len(vals), (AFFINE_TRIALS, 3))
    a, b = pts[tri], vals[tri]  # T x 3 x 3, T x 3
    good = np.abs(np.linalg.det(a)) >= AFFINE_MIN_DET
    if not good.any():
        return None
    coef = np.linalg.solve(a[good], b[good][:, :, None])[:, :, 0]  # T' x 3
    pts_t = np.ascontiguousarray(pts.T)
    counts = np.concatenate([  # inliers per trial, scored AFFINE_BLOCK trials at a time
        np.count_nonzero(np.abs(block @ pts_t - vals) < tol, axis=1)
        for block in np.split(coef, range(AFFINE_BLOCK, len(coef), AFFINE_BLOCK))])
    best = np.abs(pts @ coef[int(np.argmax(counts))] - vals) < tol  # the first of the most
    if best.mean() < AFFINE_MIN_INLIERS:
        return None
    coef = np.linalg.lstsq(pts[best], vals[best], rcond=None)[0]
    if not coef[1] > 0:
        return None
    return float(coef[0]), float(coef[1]), float(coef[2])


def inverse_shift(inverse: np.ndarray, sky: np.ndarray, camera: Camera) -> float:
    """The value of a relative inverse depth at infinity (see the module notes)."""
    r = np.asarray(inverse, np.float64)
    sky = np.asarray(sky, bool)
    if sky.any():
        return float(np.median(r[sky]))
    ground = fit_affine_ground(r, sky, camera)
    if ground is not None:
        return ground[2]
    lo, hi = np.percentile(r[np.isfinite(r)], [1.0, 99.0])
    return float(min(0.0, lo - 0.05 * (hi - lo)))


def scale_to_ground(depth: np.ndarray, sky: np.ndarray, camera: Camera,
                    camera_height: float = CAMERA_HEIGHT) -> np.ndarray:
    """Scale a depth map so its ground plane lies ``camera_height`` below the camera.

    Args:
        depth: ``H x W`` depth up to scale, finite and > 0 off the sky.
        sky: ``H x W`` bool.
        camera: intrinsics of the map.
        camera_height: metres.

    Returns:
        ``H x W`` float32; with no ground plane, scaled to a median surface depth of
        :data:`FALLBACK_MEDIAN_DEPTH`.
    """
    if not (math.isfinite(camera_height) and camera_height > 0):
        raise ValueError(f"expected a camera height > 0, got {camera_height}")
    d = np.asarray(depth, np.float32)
    sky = np.asarray(sky, bool)
    plane = fit_ground_plane(d, sky, camera)
    if plane is not None:
        k = camera_height / -plane.offset
    else:
        surface = d[~sky & np.isfinite(d) & (d > 0)]
        k = FALLBACK_MEDIAN_DEPTH / float(np.median(surface)) if surface.size else 1.0
    return (d * np.float32(k)).astype(np.float32)


def inverse_to_depth(inverse: np.ndarray, sky: np.ndarray, camera: Camera,
                     camera_height: float = CAMERA_HEIGHT) -> np.ndarray:
    """Relative inverse depth (``r = a / z + b``, unknown ``a > 0``, ``b``) -> depth.

    Args:
        inverse: ``H x W`` model output (larger = nearer).
        sky: ``H x W`` bool far region (:func:`far_sky`).
        camera: intrinsics of the map.
        camera_height: metres above the ground plane.

    Returns:
        ``H x W`` float32 depth, finite and > 0 (sky pixels get the farthest surface's depth).

    Example:
        >>> cam = Camera(8, 8, 8.0)
        >>> d = inverse_to_depth(np.full((8, 8), 2.0), np.zeros((8, 8), bool), cam)
        >>> bool(np.isfinite(d).all())
        True
    """
    r = np.asarray(inverse, np.float64)
    sky = np.asarray(sky, bool)
    if r.shape != (camera.height, camera.width) or sky.shape != r.shape:
        raise ValueError(f"expected inverse depth and sky of the camera's size "
                         f"{(camera.height, camera.width)}, got {r.shape} and {sky.shape}")
    t = inverse_shift(r, sky, camera)
    u = r - t
    surface = ~sky & np.isfinite(u)
    top = float(np.percentile(u[surface], 99.0)) if surface.any() else 1.0
    u = np.where(np.isfinite(u), np.maximum(u, max(top, 1e-12) * 1e-3), np.nan)
    depth = 1.0 / u
    far = float(np.nanmax(depth[surface])) if surface.any() else float(np.nanmax(depth))
    depth = np.where(sky | ~np.isfinite(depth), far, depth).astype(np.float32)
    return scale_to_ground(depth, sky, camera, camera_height)


# --------------------------------------------------------------------------------------------
# ONNX models


@dataclass(frozen=True)
class DepthModelSpec:
    """How to run a depth model.

    Attributes:
        input_name: the image input.
        output_name: the depth output.
        fixed_size: ``(H, W)`` of a fixed-size input, or None (dynamic).
        multiple: a dynamic input's sides are rounded to a multiple of this (None: find out).
        side: a dynamic input's shorter side (before rounding); None: :data:`DEFAULT_SIDE`.
        mean: per-channel mean subtracted from sRGB in ``[0, 1]``.
        std: per-channel std divided by.
        output: one of :data:`OUTPUT_KINDS`.
    """

    input_name: str
    output_name: str
    fixed_size: tuple[int, int] | None = None
    multiple: int | None = None
    side: int | None = None
    mean: tuple[float, float, float] = IMAGENET_MEAN
    std: tuple[float, float, float] = IMAGENET_STD
    output: str = "inverse-relative"

    def input_shape(self, height: int, width: int, multiple: int) -> tuple[int, int]:
        """``(H, W)`` the model is run at for a ``height x width`` image."""
        if self.fixed_size is not None:
            return self.fixed_size
        side = self.side or DEFAULT_SIDE.get(multiple, 384)
        scale = side / min(height, width)
        return (max(multiple, round(height * scale / multiple) * multiple),
                max(multiple, round(width * scale / multiple) * multiple))


def sidecar_path(model_path: str | os.PathLike[str]) -> Path:
    """``FILE.onnx`` -> ``FILE.onnx.json``."""
    p = Path(model_path)
    return p.with_name(p.name + ".json")


def read_sidecar(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read and check a depth model's sidecar JSON.

    Keys (all optional): ``input_size`` (an int, a dynamic input's shorter side, or
    ``[H, W]``, a fixed size), ``multiple`` (14 or 32, or any positive int), ``mean`` and
    ``std`` (three numbers each, for sRGB in ``[0, 1]``), ``output`` (one of
    :data:`OUTPUT_KINDS`).

    Example (Depth Anything V2 Small):
        ``{"input_size": 518, "multiple": 14, "mean": [0.485, 0.456, 0.406],
        "std": [0.229, 0.224, 0.225], "output": "inverse-relative"}``

    Returns:
        The fields as :class:`DepthModelSpec` keywords (``fixed_size``, ``side``, ...).

    Raises:
        ValueError: not JSON, an unknown key, or a value out of range.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"cannot read depth model settings '{path}': {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"expected a JSON object in '{path}', got {type(data).__name__}")
    unknown = sorted(set(data) - SIDECAR_KEYS)
    if unknown:
        raise ValueError(f"unknown keys {unknown} in '{path}'; expected some of "
                         f"{sorted(SIDECAR_KEYS)}")
    out: dict[str, Any] = {}
    size = data.get("input_size")
    if isinstance(size, int) and not isinstance(size, bool) and 1 <= size <= MAX_SIDE:
        out["side"] = size
    elif (isinstance(size, list) and len(size) == 2
          and all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_SIDE
                  for v in size)):
        out["fixed_size"] = (size[0], size[1])
    elif size is not None:
        raise ValueError(f"expected input_size as an int or [H, W] in 1..{MAX_SIDE} in "
                         f"'{path}', got {size!r}")
    multiple = data.get("multiple")
    if multiple is not None:
        if not (isinstance(multiple, int) and not isinstance(multiple, bool)
                and 1 <= multiple <= 256):
            raise ValueError(f"expected multiple as an int in 1..256 in '{path}', "
                             f"got {multiple!r}")
        out["multiple"] = multiple
    for key in ("mean", "std"):
        v = data.get(key)
        if v is None:
            continue
        if not (isinstance(v, list) and len(v) == 3
                and all(isinstance(x, int | float) and not isinstance(x, bool)
                        and math.isfinite(x) for x in v)):
            raise ValueError(f"expected {key} as three numbers in '{path}', got {v!r}")
        if key == "std" and min(v) <= 0:
            raise ValueError(f"expected std > 0 in '{path}', got {v!r}")
        out[key] = (float(v[0]), float(v[1]), float(v[2]))
    kind = data.get("output")
    if kind is not None:
        if kind not in OUTPUT_KINDS:
            raise ValueError(f"expected output in {list(OUTPUT_KINDS)} in '{path}', "
                             f"got {kind!r}")
        out["output"] = kind
    return out


def _dims(shape: list[Any]) -> list[int | None]:
    return [d if isinstance(d, int) and d > 0 else None for d in shape]


def inspect_depth_model(session: Any, path: Path) -> DepthModelSpec:
    """Check a model's inputs and outputs and detect its conventions (before the sidecar)."""
    inputs, outputs = session.get_inputs(), session.get_outputs()
    if len(inputs) != 1 or len(outputs) != 1:
        raise ValueError(f"expected a depth model with one image input and one output, got "
                         f"{len(inputs)} inputs and {len(outputs)} outputs in '{path}'")
    shape = _dims(list(inputs[0].shape))
    if len(shape) != 4 or shape[1] != 3:
        raise ValueError(f"expected the depth model's input as N x 3 x H x W, got "
                         f"{list(inputs[0].shape)} in '{path}'")
    if "float" not in str(inputs[0].type):
        raise ValueError(f"expected a float image input, got {inputs[0].type} in '{path}'")
    out_shape = list(outputs[0].shape)
    if len(out_shape) not in (2, 3, 4):
        raise ValueError(f"expected the depth model's output as N x H x W or N x 1 x H x W, "
                         f"got {out_shape} in '{path}'")
    fixed = (shape[2], shape[3]) if shape[2] and shape[3] else None
    multiple = None
    if fixed is not None:
        multiple = 14 if fixed[0] % 14 == 0 and fixed[1] % 14 == 0 else 32
    return DepthModelSpec(inputs[0].name, outputs[0].name, fixed, multiple)


@dataclass
class OnnxDepthModel:
    """A monocular depth model in an ONNX file, ready to run (see :func:`load_depth_model`)."""

    path: Path
    spec: DepthModelSpec
    session: Any
    last_seconds: float = 0.0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def name(self) -> str:
        return self.path.name

    def _feed(self, image: np.ndarray, multiple: int) -> np.ndarray:
        """The model's input: ``image`` (float, sRGB in ``[0, 1]``, any size) resized to the
        input size, normalised, as float32 ``1 x 3 x h x w``."""
        h, w = self.spec.input_shape(image.shape[0], image.shape[1], multiple)
        small = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA
                           if h < image.shape[0] else cv2.INTER_LINEAR)
        x = (small.astype(np.float32, copy=False) - np.float32(self.spec.mean)) / np.float32(
            self.spec.std)
        return np.ascontiguousarray(x.transpose(2, 0, 1)[None], np.float32)  # 1 x 3 x h x w

    def run(self, image_srgb: np.ndarray, out_hw: tuple[int, int] | None = None) -> np.ndarray:
        """The model's raw output for an ``H x W x 3`` sRGB photo, resized to ``H x W`` (or to
        ``out_hw``)."""
        image = np.asarray(image_srgb)
        if image.ndim != 3 or image.shape[2] != 3 or min(image.shape[:2]) < 1:
            raise ValueError(f"expected an H x W x 3 image, got shape {image.shape}")
        if image.dtype == np.uint8:
            # 0..255 (read with keep_uint8): to [0, 1] before it is shrunk, as a uint8 resize
            # would round every average to a whole level
            image = image / np.float32(255.0)
        elif image.dtype not in (np.float32, np.float64):
            image = image.astype(np.float32)
        # float32 and float64 photos are shrunk as they are (no full-size copy) and made
        # float32 at the model's input size
        t0 = time.perf_counter()
        multiples = [self.spec.multiple] if self.spec.multiple else [14, 32]
        out = None
        with self._lock:
            for i, m in enumerate(multiples):
                try:
                    out = self.session.run([self.spec.output_name],
                                           {self.spec.input_name: self._feed(image, m)})[0]
                except Exception as exc:  # onnxruntime's own types: a size it cannot take
                    if i + 1 < len(multiples):
                        continue
                    raise ModelError(f"depth model '{self.path}' failed: "
                                     f"{' '.join(str(exc).split())[:300]}") from exc
                if self.spec.multiple is None:
                    self.spec = replace(self.spec, multiple=m)  # found: keep it
                break
        pred = np.asarray(out, np.float32)
        while pred.ndim > 2 and pred.shape[0] == 1:
            pred = pred[0]  # drop N (and a channel of 1)
        if pred.ndim != 2 or min(pred.shape) < 1:
            raise ValueError(f"expected the depth model to give one H x W map, got shape "
                             f"{np.asarray(out).shape} from '{self.path}'")
        if not np.isfinite(pred).all():
            raise ValueError(f"the depth model '{self.path}' gave non-finite values")
        h, w = out_hw if out_hw is not None else image.shape[:2]
        pred = cv2.resize(pred, (w, h), interpolation=cv2.INTER_AREA if h < pred.shape[0]
                          else cv2.INTER_LINEAR)
        self.last_seconds = time.perf_counter() - t0
        return pred

    def estimate(self, image_srgb: np.ndarray, camera: Camera,
                 camera_height: float = CAMERA_HEIGHT, photo_srgb: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Depth (finite, > 0) and sky of a photo at the camera's size.

        Args:
            image_srgb: ``H x W x 3`` sRGB in ``[0, 1]``, the camera's size.
            camera: its intrinsics.
            camera_height: metres above the ground, for relative outputs.
            photo_srgb: the same photo at a higher resolution, if at hand: the model sees it
                (resized straight to its input) instead of the working image.

        Returns:
            ``(depth, sky)``: ``H x W`` float32 and bool.
        """
        if np.asarray(image_srgb).shape[:2] != (camera.height, camera.width):
            raise ValueError(f"expected an image of the camera's size "
                             f"{(camera.height, camera.width)}, got "
                             f"{np.asarray(image_srgb).shape[:2]}")
        src = image_srgb
        if photo_srgb is not None:
            ph, pw = np.asarray(photo_srgb).shape[:2]
            if abs(pw / ph - camera.width / camera.height) <= 0.02 * camera.width / camera.height:
                src = photo_srgb
        pred = self.run(src, (camera.height, camera.width))
        return model_output_to_depth(pred, self.spec.output, camera, camera_height, image_srgb)


def model_output_to_depth(pred: np.ndarray, kind: str, camera: Camera,
                          camera_height: float = CAMERA_HEIGHT,
                          image_srgb: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """A model's ``H x W`` output of kind ``kind`` (:data:`OUTPUT_KINDS`) -> ``(depth, sky)``.

    ``image_srgb`` (the photo at the same size) lets :func:`far_sky` check the sky's colour.
    """
    pred = np.asarray(pred, np.float64)
    if kind == "inverse-relative":
        sky = far_sky(pred, image_srgb)
        return inverse_to_depth(pred, sky, camera, camera_height), sky
    if kind not in ("depth-relative", "metric"):
        raise ValueError(f"expected an output kind in {list(OUTPUT_KINDS)}, got {kind!r}")
    positive = pred[np.isfinite(pred) & (pred > 0)]
    if positive.size == 0:
        raise ValueError("expected the depth model to give some positive depth, got none")
    d = np.clip(pred, float(positive.min()), None)
    sky = far_sky(1.0 / d, image_srgb)
    if kind == "metric":
        return d.astype(np.float32), sky
    return scale_to_ground(d.astype(np.float32), sky, camera, camera_height), sky


def load_depth_model(path: str | os.PathLike[str], threads: int | None = None
                     ) -> OnnxDepthModel:
    """Load an ONNX depth model and its sidecar settings (``FILE.onnx.json``, if present).

    Args:
        path: the ``.onnx`` file.
        threads: onnxruntime intra-op threads (None: its default).

    Returns:
        An :class:`OnnxDepthModel`.

    Raises:
        ModelError: missing, unreadable or not an ONNX model.
        ValueError: not a monocular depth model (inputs/outputs), or a bad sidecar.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise ModelError(f"depth model '{path}' not found")
    try:  # the shipped models' session settings (CPU, quiet, the thread count)
        session = onnx_session(path, threads)
    except ModelError as exc:
        cause = exc.__cause__ or exc  # onnxruntime's own error
        raise ModelError(f"depth model '{path}' is not a readable ONNX model "
                         f"({' '.join(str(cause).split())[:200]})") from cause
    spec = inspect_depth_model(session, path)
    side = sidecar_path(path)
    if side.is_file():
        fields = read_sidecar(side)
        if "fixed_size" in fields and spec.fixed_size and fields["fixed_size"] != spec.fixed_size:
            raise ValueError(f"'{side}' says input_size {list(fields['fixed_size'])}, but the "
                             f"model's input is fixed at {list(spec.fixed_size)}")
        if "side" in fields and spec.fixed_size:
            fields.pop("side")  # a fixed input has one size
        spec = replace(spec, **fields)
    return OnnxDepthModel(path, spec, session)


# --------------------------------------------------------------------------------------------
# Sources for the session


class ModelDepthSource:
    """A session depth provider running an :class:`OnnxDepthModel`; its name has the time."""

    def __init__(self, model: OnnxDepthModel, camera_height: float = CAMERA_HEIGHT,
                 photo_srgb: np.ndarray | None = None) -> None:
        self.model = model
        self.camera_height = camera_height
        #: The full-resolution photo, if at hand: the model sees it rather than the working image.
        self.photo_srgb = photo_srgb
        self.name = f"model {model.name}"

    def __call__(self, image_srgb: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        depth, sky = self.model.estimate(image_srgb, camera, self.camera_height,
                                         self.photo_srgb)
        self.name = f"model {self.model.name} ({self.model.last_seconds:.2f} s)"
        return depth, sky


class PhoneDepthSource:
    """A session depth provider serving the photo's own embedded depth map."""

    def __init__(self, phone: PhoneDepth) -> None:
        self.phone = phone
        self.name = "phone"

    def __call__(self, image_srgb: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        depth = phone_depth_at(self.phone, camera)
        sky = far_sky(1.0 / depth, image_srgb)
        if sky.any():
            depth = np.where(sky, float(depth[~sky].max()) if (~sky).any() else depth,
                             depth).astype(np.float32)
        return depth, sky


def pick_depth_source(
    photo_path: str | os.PathLike[str],
    photo_hw: tuple[int, int] | None = None,
    *,
    model_path: str | os.PathLike[str] | None = None,
    use_phone: bool = True,
    strict: bool = True,
    photo_srgb: np.ndarray | None = None,
) -> tuple[DepthProvider | None, str]:
    """The depth source for a photo: a depth model when given, else the photo's own depth map.

    Args:
        photo_path: the photo (its embedded depth map is read from it).
        photo_hw: the upright photo's ``(height, width)`` (default: from its header).
        model_path: an ONNX depth model to use, or None.
        use_phone: read the photo's own depth map when there is no model.
        strict: a model that cannot be loaded raises (the command line); False: it is noted
            and the photo's own map or the shipped model is used (the app's remembered model).
        photo_srgb: the decoded photo at full resolution, for the model to see.

    Returns:
        ``(provider, note)``: the provider (None: the session's depth model) and a one-line
        note saying what was not used and why ("" when nothing was dropped).

    Raises:
        ModelError, ValueError: with ``strict``, a model that is missing, corrupt or not a
            monocular depth model.
    """
    note = ""
    if model_path:
        try:
            return ModelDepthSource(load_depth_model(model_path), photo_srgb=photo_srgb), ""
        except (ModelError, ValueError) as exc:
            if strict:
                raise
            note = f"the depth model is not used: {exc}"
    if not use_phone:
        return None, note
    from outcast_core.runtime.io.phone_depth import PhoneDepthError, read_phone_depth

    try:
        phone = read_phone_depth(photo_path, photo_hw)
    except (PhoneDepthError, OSError) as exc:
        more = f"the photo's own depth map is not used: {exc}"
        return None, f"{note}; {more}" if note else more
    return (PhoneDepthSource(phone) if phone is not None else None), note
