"""Fixtures shared by the runtime tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.io.imageio import write_image


@pytest.fixture
def photo(tmp_path: Path) -> Path:
    """A small noisy grey photo, ``tmp_path / "photo.png"`` (60 x 80)."""
    rng = np.random.default_rng(3)
    img = np.clip(0.5 + 0.1 * rng.standard_normal((60, 80, 3)), 0, 1).astype(np.float32)
    path = tmp_path / "photo.png"
    write_image(path, img)
    return path


@pytest.fixture
def exposures_relit(monkeypatch) -> list[str]:
    """The exposure of every ``RelightSession.relight_full`` call made in the test, in order
    (the relighting itself runs as usual)."""
    from outcast_core.runtime.pipeline.session import RelightSession

    seen: list[str] = []
    real = RelightSession.relight_full

    def spy(self, w, **kw):
        seen.append(kw.get("exposure") or self.exposure)
        return real(self, w, **kw)

    monkeypatch.setattr(RelightSession, "relight_full", spy)
    return seen
