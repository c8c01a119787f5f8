"""Issue 20, defect 10: checkpoints load as tensors and plain data; a pickle never runs code."""

from __future__ import annotations

import os

import pytest
import torch

from outcast_core.train.trainer import load_checkpoint, load_checkpoint_nets


class _Payload:
    """Unpickling this makes a folder: the proof that a checkpoint ran code."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (self.marker,))


def test_a_checkpoint_that_runs_code_is_refused(tmp_path) -> None:
    marker = tmp_path / "pwned"
    path = tmp_path / "evil.pt"
    torch.save({"nets": {}, "net_kwargs": {}, "x": _Payload(str(marker))}, path)
    with pytest.raises(ValueError, match="refusing to load checkpoint"):
        load_checkpoint_nets(path)
    assert not marker.exists()


def test_the_export_and_eval_commands_refuse_it_in_one_line(tmp_path, capsys) -> None:
    from outcast_core.runtime.cli.main import main

    marker = tmp_path / "pwned"
    path = tmp_path / "evil.pt"
    torch.save({"nets": {}, "x": _Payload(str(marker))}, path)
    assert main(["export", str(path), "--out", str(tmp_path / "models")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "refusing to load checkpoint" in err
    assert not marker.exists()


@pytest.mark.parametrize("content", [b"", b"not a checkpoint", b"PK\x03\x04broken"])
def test_broken_checkpoints_are_value_errors(tmp_path, content) -> None:
    path = tmp_path / "b.pt"
    path.write_bytes(content)
    with pytest.raises(ValueError, match="checkpoint"):
        load_checkpoint(path)


def test_plain_checkpoints_still_load(tmp_path) -> None:
    path = tmp_path / "ok.pt"
    torch.save({"nets": {"a": {"w": torch.ones(2)}}, "config": {"lr": 1e-3, "gamma": [1, 2]},
                "lr_history": [(0, 1e-3)], "numpy_rng": {"state": {"state": 2**100}}}, path)
    ckpt = load_checkpoint(path)
    assert ckpt["lr_history"] == [(0, 1e-3)] and torch.equal(ckpt["nets"]["a"]["w"], torch.ones(2))
