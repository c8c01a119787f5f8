"""D's reading of a photo in the runtime: the direction bins, the kernel mixture, read_sun."""

from __future__ import annotations

import math

import numpy as np
import pytest

from outcast_core.runtime.geometry.camera import sun_vector
from outcast_core.runtime.pipeline.sun_look import (
    DEFAULT_KAPPA,
    SunLook,
    direction_bins,
    read_sun,
)


def test_direction_bins_cover_the_sphere_evenly() -> None:
    b = direction_bins(320)
    assert b.shape == (320, 3) and b.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(b, axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(b, direction_bins(320))  # the same wherever it is built
    # Every direction of the sphere has a bin within about one spacing (11 deg for 320).
    rng = np.random.default_rng(0)
    probe = rng.normal(size=(2000, 3))
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    nearest = np.degrees(np.arccos(np.clip((probe @ b.T).max(axis=1), -1, 1)))
    assert nearest.max() < 11.0
    assert abs(b.mean(axis=0)).max() < 0.01  # no half of the sphere favoured
    with pytest.raises(ValueError, match="at least 2"):
        direction_bins(1)


def _look_at(w: np.ndarray, k: int = 320) -> SunLook:
    bins = direction_bins(k)
    logits = DEFAULT_KAPPA * (bins @ w)
    p = np.exp(logits - logits.max())
    return SunLook(p / p.sum(), bins, DEFAULT_KAPPA)


def test_the_likelihood_peaks_at_the_looks_sun_and_falls_with_the_angle() -> None:
    w = sun_vector(130.0, 35.0)
    look = _look_at(w)
    assert math.degrees(math.acos(float(np.clip(look.peak() @ w, -1, 1)))) < 8.0
    angles = [0.0, 10.0, 30.0, 90.0, 180.0]
    lik = look.likelihood(np.stack([sun_vector(130.0 + a, 35.0 if a < 180 else -35.0)
                                    for a in angles]))
    assert lik[0] == pytest.approx(1.0, abs=0.1)  # the peak density is taken at the bins
    assert all(a > b for a, b in zip(lik, lik[1:], strict=False))
    assert lik[-1] < 1e-6
    # One direction or many, any length.
    assert look.likelihood(3.0 * w).shape == (1,)


class _FakeModel:
    """A loaded model's surface: manifest, input_side, run."""

    def __init__(self, logits: np.ndarray, side: int = 64) -> None:
        self.manifest = {"bins": int(logits.size), "kappa": DEFAULT_KAPPA}
        self.input_side = side
        self.pad_multiple = 16
        self.logits = logits
        self.seen: list[tuple[int, ...]] = []

    def run(self, feeds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        self.seen.append(feeds["image"].shape)
        return {"logits": self.logits[None].astype(np.float32)}


def test_read_sun_shrinks_the_photo_to_the_models_side_and_checks_the_logits() -> None:
    logits = np.zeros(64)
    logits[5] = 8.0
    model = _FakeModel(logits)
    look = read_sun(model, np.random.default_rng(0).random((480, 640, 3), np.float32),
                    mirrored=False)
    assert model.seen == [(1, 3, 48, 64)]
    assert look.probabilities.argmax() == 5 and look.probabilities.sum() == pytest.approx(1.0)
    read_sun(model, np.zeros((400, 600, 3), np.float32), mirrored=False)  # 42.7 rows -> 48
    assert model.seen[-1] == (1, 3, 48, 64)
    read_sun(model, np.zeros((8, 4, 3), np.float32), mirrored=False)  # tiny: brought up
    assert model.seen[-1] == (1, 3, 64, 32)
    # Read mirrored too (the default): the second reading's suns are mirrored back, so a
    # model that says "bin 5" whatever it sees gives bin 5 and its mirror image alike.
    b5 = direction_bins(64)[5].astype(np.float64)
    assert abs(b5[0]) > 0.2  # not on the mirror plane
    mirror = b5 * np.array([-1.0, 1.0, 1.0])
    both = read_sun(model, np.zeros((48, 64, 3), np.float32))
    assert len(model.seen) == 5 and both.probabilities.sum() == pytest.approx(1.0)
    lik = both.likelihood(np.stack([b5, mirror]))
    assert lik[0] == pytest.approx(lik[1], rel=0.05) and lik.min() > 0.5
    assert look.likelihood(mirror)[0] < 1e-3
    with pytest.raises(ValueError, match="expected 320 logits"):
        bad = _FakeModel(np.zeros(64))
        bad.manifest["bins"] = 320
        read_sun(bad, np.zeros((32, 32, 3), np.float32))
    with pytest.raises(ValueError, match="H x W x 3"):
        read_sun(model, np.zeros((32, 32), np.float32))
