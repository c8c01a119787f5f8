"""Where models are found: explicit folder, $OUTCAST_MODEL_DIR, the user's folder, shipped."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io import models as models_module
from outcast_core.runtime.io.models import (
    DEFAULT_MODEL_DIR,
    ModelError,
    ModelRegistry,
    model_search_path,
    user_model_dir,
)


@pytest.fixture
def data_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.delenv("OUTCAST_MODEL_DIR", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    return tmp_path / "data"


def _copy_model(name: str, folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    manifest = json.loads((DEFAULT_MODEL_DIR / f"{name}.json").read_text())
    shutil.copy2(DEFAULT_MODEL_DIR / f"{name}.json", folder / f"{name}.json")
    shutil.copy2(DEFAULT_MODEL_DIR / manifest["file"], folder / manifest["file"])
    return folder / manifest["file"]


def test_search_path_order(data_home: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert user_model_dir() == data_home / "outcast" / "models"
    assert model_search_path() == [data_home / "outcast" / "models", DEFAULT_MODEL_DIR]
    monkeypatch.setenv("OUTCAST_MODEL_DIR", str(data_home / "env"))
    assert model_search_path() == [data_home / "env"]  # it replaces the others
    assert ModelRegistry(data_home / "given").search_path == [data_home / "given"]


def test_user_folder_overrides_one_model(data_home: Path) -> None:
    user = data_home / "outcast" / "models"
    _copy_model("relight", user)
    registry = ModelRegistry(threads=1)
    assert registry.directory_for("relight") == user
    assert registry.directory_for("shadow") == DEFAULT_MODEL_DIR
    assert registry.load("relight").path.parent == user
    assert registry.load("shadow").path.parent == DEFAULT_MODEL_DIR


def test_corrupt_user_model_is_refused(data_home: Path) -> None:
    onnx = _copy_model("refine", data_home / "outcast" / "models")
    onnx.write_bytes(onnx.read_bytes()[:-10] + b"0123456789")
    with pytest.raises(ModelError, match="corrupt"):
        ModelRegistry(threads=1).load("refine")


def test_shipped_folder_prefers_the_wheel_copy(tmp_path: Path) -> None:
    # In a checkout there is no outcast_core/shipped_models, so models/ is used.
    if not models_module.PACKAGED_MODEL_DIR.is_dir():
        assert DEFAULT_MODEL_DIR == models_module.SOURCE_MODEL_DIR
    else:
        assert DEFAULT_MODEL_DIR == models_module.PACKAGED_MODEL_DIR


def test_models_command(data_home: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["search_path"] == [str(p) for p in model_search_path()]
    assert {m["status"] for m in report["models"]} == {"ok"}
    onnx = _copy_model("relight", data_home / "outcast" / "models")
    onnx.write_bytes(b"not a model")
    assert main(["models"]) == 2
    out, err = capsys.readouterr()
    assert "relight" in out and "corrupt" in out and str(onnx) in out
    assert err.strip() == "outcast models: error: not usable: relight"
    assert main(["models", "--dir", str(data_home / "empty")]) == 2
    assert "missing" in capsys.readouterr().out
