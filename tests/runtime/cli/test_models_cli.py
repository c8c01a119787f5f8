"""``outcast models --load``: each model file is hashed once, and the report is unchanged."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from outcast_core.runtime.cli import models_cli
from outcast_core.runtime.io import models as models_module
from outcast_core.runtime.io.models import DEFAULT_MODEL_DIR, ModelRegistry


def _copy_model(name: str, folder: Path, onnx_from: str | None = None) -> Path:
    """Copy ``name``'s manifest to ``folder`` with its ONNX file (or ``onnx_from``'s, the
    manifest's file name and sha256 kept pointing at it); returns the ONNX copy."""
    folder.mkdir(parents=True, exist_ok=True)
    manifest = json.loads((DEFAULT_MODEL_DIR / f"{name}.json").read_text(encoding="utf-8"))
    if onnx_from is not None:
        other = json.loads((DEFAULT_MODEL_DIR / f"{onnx_from}.json").read_text(encoding="utf-8"))
        manifest.update(file=other["file"], sha256=other["sha256"])
    (folder / f"{name}.json").write_text(json.dumps(manifest), encoding="utf-8")
    shutil.copy2(DEFAULT_MODEL_DIR / manifest["file"], folder / manifest["file"])
    return folder / manifest["file"]


@pytest.fixture
def hashed(monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """The files hashed (by the command or the registry) while a test runs."""
    calls: list[Path] = []
    real = models_module.sha256_file

    def counting(path: Path) -> str:
        calls.append(Path(path))
        return real(path)

    monkeypatch.setattr(models_module, "sha256_file", counting)
    monkeypatch.setattr(models_cli, "sha256_file", counting)
    return calls


@pytest.mark.parametrize("load", [False, True])
def test_each_model_is_hashed_once(tmp_path: Path, hashed: list[Path], load: bool) -> None:
    onnx = _copy_model("refine", tmp_path)
    rows = models_cli.model_report(ModelRegistry(tmp_path, threads=1), ("refine",), load=load)
    assert [(r["status"], r["message"]) for r in rows] == [("ok", "")]
    assert hashed == [onnx]


def test_load_still_reports_corrupt_and_wrong_networks(tmp_path: Path,
                                                       hashed: list[Path]) -> None:
    onnx = _copy_model("refine", tmp_path / "corrupt")
    onnx.write_bytes(b"not a model")
    rows = models_cli.model_report(ModelRegistry(tmp_path / "corrupt", threads=1), ("refine",),
                                   load=True)
    assert [(r["status"], r["message"]) for r in rows] == [
        ("corrupt", "sha256 does not match the manifest")]
    # An intact file that is another network: its checksum holds, loading it does not.
    _copy_model("refine", tmp_path / "wrong", onnx_from="shadow")
    registry = ModelRegistry(tmp_path / "wrong", threads=1)
    unloaded = models_cli.model_report(registry, ("refine",))
    assert unloaded[0]["status"] == "ok"
    loaded = models_cli.model_report(registry, ("refine",), load=True)
    assert loaded[0]["status"] == "error" and "does not match its manifest" in loaded[0]["message"]
    assert len(hashed) == 3
