"""Model cards come from manifests; evaluation metrics and the sweep table behave."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from outcast_core.eval.cli import render_sweep, render_table
from outcast_core.eval.metrics import dssim, mse
from outcast_core.eval.table import plot_speed_accuracy, save_sheet
from outcast_core.export.cards import render_cards
from outcast_core.export.onnx_export import export_onnx, write_manifest
from outcast_core.nets import build


def test_metrics() -> None:
    rng = np.random.default_rng(0)
    a = rng.random((32, 32, 3)).astype(np.float32)
    assert mse(a, a) == 0.0 and abs(dssim(a, a)) < 1e-6
    b = np.clip(a + 0.1, 0, 1)
    assert mse(a, b) > 0 and 0 < dssim(a, b) < dssim(a, 1 - a) <= 1
    with pytest.raises(ValueError, match="one shape"):
        mse(a, a[:8])


def test_cards_render_from_manifests(tmp_path) -> None:
    torch.manual_seed(0)
    net = build("refine")
    path = tmp_path / "refine.onnx"
    export_onnx(net, "refine", path, [(16, 16)])
    write_manifest(net, "refine", path, {"config": {"stage": "relight", "run": "r", "batch": 4},
                                          "steps": 12, "wall_time_s": 3.5},
                   {"heldout_dssim": 0.1})
    text = render_cards(tmp_path, "preamble")
    assert "`refine.onnx`" in text and "12 steps" in text and "heldout_dssim" in text
    assert "preamble" in text


def test_tables_and_pictures(tmp_path) -> None:
    res = {"rows": {"Ours": {"dssim": 0.1, "mse": 0.01, "shadow_mse": 0.02, "time_s": 0.5},
                    "Input": {"dssim": 0.2, "mse": 0.03, "time_s": 0.0}}}
    text = render_table(res)
    assert text.index("Input") < text.index("Ours") and "0.0200" in text
    sweep = [{"steps": z, "size": s, "shadow_mse": 0.01 * z / s, "latency_ms": z * s / 100}
             for z in (8, 16) for s in (96, 128)]
    assert render_sweep(sweep).count("\n") == 3
    png = plot_speed_accuracy(sweep, tmp_path / "p.png")
    sheet = save_sheet([{"a": np.zeros((8, 8, 3)), "b": np.ones((8, 8))}], tmp_path / "s.png")
    assert png.stat().st_size > 1000 and sheet.stat().st_size > 100
