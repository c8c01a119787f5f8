"""Export parity: every network kind in onnxruntime equals torch to 1e-4 at several sizes."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort
import pytest
import torch

from outcast_core.export.onnx_export import (
    PARITY_TOL,
    SPECS,
    check_parity,
    export_onnx,
    sample_inputs,
    write_manifest,
)
from outcast_core.nets import build
from outcast_core.runtime.models import sha256_file


@pytest.mark.parametrize("kind", sorted(SPECS))
def test_export_parity_and_manifest(kind: str, tmp_path) -> None:
    torch.manual_seed(0)
    kw = {"steps": 8} if kind == "shadow" else {}
    net = build(kind, **kw)
    if kind in ("refine", "relight", "relight_pix2pix"):  # make the zero-init head non-trivial
        torch.nn.init.normal_(net.unet.head.weight, std=0.1)
    path = tmp_path / f"{kind}.onnx"
    m = net.pad_multiple
    worst = export_onnx(net, kind, path, [(2 * m, 2 * m), (3 * m, 5 * m), (5 * m, 2 * m)])
    assert worst <= PARITY_TOL
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == [n for n, _ in SPECS[kind].inputs]
    assert [o.name for o in sess.get_outputs()] == [n for n, _ in SPECS[kind].outputs]
    man = json.loads(write_manifest(net, kind, path, {"steps": 0}, {"x": 1.0}).read_text())
    assert man["sha256"] == sha256_file(path)
    assert man["file"] == path.name and man["colour_space"] == "srgb"
    assert man["pad_multiple"] == m
    if kind == "shadow":
        assert man["march_steps"] == 8 and man["volume_scale"] == 0.5


def test_batch_of_two_runs_in_onnxruntime(tmp_path) -> None:
    net = build("shadow", steps=8).eval()
    path = tmp_path / "s.onnx"
    export_onnx(net, "shadow", path, [(32, 32)])
    one = sample_inputs("shadow", 32, 48, seed=1)
    two = {k: np.concatenate([v, v]) for k, v in one.items()}
    out = ort.InferenceSession(str(path)).run(None, two)[0]
    with torch.no_grad():
        ref = net(*[torch.from_numpy(v) for v in two.values()]).numpy()
    assert np.abs(out - ref).max() <= PARITY_TOL


def test_parity_check_catches_a_different_network(tmp_path) -> None:
    torch.manual_seed(0)
    net = build("refine")
    torch.nn.init.normal_(net.unet.head.weight, std=0.5)
    path = tmp_path / "r.onnx"
    export_onnx(net, "refine", path, [(16, 16)])
    torch.nn.init.normal_(net.unet.head.weight, std=0.5)  # the torch net changes after export
    with pytest.raises(RuntimeError, match="differs"):
        check_parity(net, "refine", path, [(16, 16)])
