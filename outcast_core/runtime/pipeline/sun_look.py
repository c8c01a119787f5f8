"""The sun as the photo's look tells it: ``D``'s distribution over directions (numpy only).

``D`` (a ``sun.onnx`` in the models folder, made by ``outcast train
outcast_core/train/configs/sun.toml`` and ``outcast export``; the network is
:mod:`outcast_core.nets.sun`) gives a probability to each of ``K`` directions of a Fibonacci
lattice over the sphere of camera-space directions. The distribution at any direction is a von
Mises-Fisher kernel mixture of those bins (:meth:`SunLook.likelihood`), so
:func:`~outcast_core.runtime.pipeline.auto_sun.find_sun` can weigh any sun it tries by it
(``auto_sun.LOOK_WEIGHT``). No ``sun.onnx`` ships and the weight is 0: the ``D`` trained so far
helps on synthetic views and hurts on the real dev photos (``models/EVAL.md``, twelfth session).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

#: Direction bins and kernel concentration when a manifest does not give them (``D``'s
#: training defaults: :data:`outcast_core.nets.sun.BINS`, ``KAPPA``).
DEFAULT_BINS = 320
DEFAULT_KAPPA = 1.0 / math.radians(8.0) ** 2
#: Longer side (px) the photo is shrunk to for ``D`` when its manifest gives none.
DEFAULT_SIDE = 128


def direction_bins(k: int = DEFAULT_BINS) -> np.ndarray:
    """``k x 3`` unit vectors of a Fibonacci lattice over the sphere (camera space: x right,
    y down, z forward), float32; the same for a given ``k`` wherever it is built (``D``'s
    training uses this function too)."""
    if k < 2:
        raise ValueError(f"expected at least 2 direction bins, got {k}")
    i = np.arange(k, dtype=np.float64) + 0.5
    y = 1.0 - 2.0 * i / k
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1).astype(np.float32)


@dataclass(frozen=True)
class SunLook:
    """``D``'s reading of one photo.

    Attributes:
        probabilities: ``K`` bin probabilities (sum 1).
        bins: ``K x 3`` unit directions.
        kappa: the kernel's concentration.
    """

    probabilities: np.ndarray
    bins: np.ndarray
    kappa: float

    def likelihood(self, w: np.ndarray) -> np.ndarray:
        """Relative density at the camera-space directions ``w`` (``N x 3`` or ``3``): the
        kernel mixture over the bins, over its largest value at any bin (so in [0, ~1])."""
        w = np.atleast_2d(np.asarray(w, np.float64))
        w = w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-12)
        return self._density(w) / max(float(self._at_bins.max()), 1e-30)

    def _density(self, w: np.ndarray) -> np.ndarray:
        k = np.exp(self.kappa * (w @ self.bins.T.astype(np.float64) - 1.0))
        return k @ self.probabilities.astype(np.float64)

    @cached_property
    def _at_bins(self) -> np.ndarray:
        """The density at every bin (``K``; made once: the search asks at every stage)."""
        return self._density(self.bins.astype(np.float64))

    def peak(self) -> np.ndarray:
        """The bin direction of highest density (``3``)."""
        return self.bins[int(np.argmax(self._at_bins))].astype(np.float64)


def read_sun(model: object, image_srgb: np.ndarray, *, mirrored: bool = True) -> SunLook:
    """Run ``D`` on a photo resized to its training side (area filter when shrinking), both
    sides rounded to multiples of the network's ``pad_multiple``.

    Args:
        model: a loaded ``sun`` model (:class:`~outcast_core.runtime.io.models.Model`): input
            ``image`` (1 x 3 x H x W sRGB), output ``logits`` (1 x K); its manifest may give
            ``bins``, ``kappa`` and ``input_side``.
        image_srgb: ``H x W x 3`` sRGB in [0, 1].
        mirrored: also read the photo mirrored left to right and mix the two readings (the
            mirrored one's directions mirrored back): ``D`` was trained on random mirrorings,
            and the mix halves what either reading gets wrong on its own.

    Returns:
        A :class:`SunLook` (with ``mirrored``, its bins are ``D``'s and their mirror images).
    """
    image = np.asarray(image_srgb, np.float32)
    if image.ndim != 3 or image.shape[2] != 3 or min(image.shape[:2]) < 1:
        raise ValueError(f"expected an H x W x 3 image, got shape {image.shape}")
    manifest = getattr(model, "manifest", {}) or {}
    side = int(getattr(model, "input_side", None) or DEFAULT_SIDE)
    m = int(getattr(model, "pad_multiple", 16) or 16)
    h, w = image.shape[:2]
    # The longer side at the training side, both sides multiples of the network's (padding
    # would put edge rows into its global pooling, which training never saw).
    scale = side / max(h, w)
    size = (max(m, m * round(w * scale / m)), max(m, m * round(h * scale / m)))
    if size != (w, h):
        interp = cv2.INTER_AREA if size[0] < w else cv2.INTER_LINEAR
        image = cv2.resize(image, size, interpolation=interp)
    k = int(manifest.get("bins", DEFAULT_BINS))
    bins = direction_bins(k)
    views = [image, image[:, ::-1]] if mirrored else [image]
    probs, dirs = [], []
    for i, view in enumerate(views):
        x = np.ascontiguousarray(np.clip(view, 0.0, 1.0).transpose(2, 0, 1)[None])
        logits = np.asarray(model.run({"image": x})["logits"], np.float64).reshape(-1)  # type: ignore[attr-defined]
        if logits.size != k:
            raise ValueError(f"expected {k} logits from the sun model, got {logits.size}")
        p = np.exp(logits - logits.max())
        probs.append(p / p.sum() / len(views))
        # The mirrored photo's suns are the photo's mirrored (x -> -x in camera space).
        dirs.append(bins if i == 0 else bins * np.array([-1.0, 1.0, 1.0], np.float32))
    return SunLook(probabilities=np.concatenate(probs), bins=np.concatenate(dirs),
                   kappa=float(manifest.get("kappa", DEFAULT_KAPPA)))


__all__ = ["DEFAULT_BINS", "DEFAULT_KAPPA", "SunLook", "direction_bins", "read_sun"]
