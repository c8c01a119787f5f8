"""Issue 20, defect 8: manifests are validated, and a network must match its manifest and name."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from outcast_core.runtime.cli.main import main
from outcast_core.runtime.io.imageio import write_image
from outcast_core.runtime.io.models import DEFAULT_MODEL_DIR, ModelError, ModelRegistry, sha256_file
from outcast_core.runtime.pipeline.session import RelightSession


def _install(folder: Path, name: str, onnx_from: str | None = None, **changes) -> dict:
    """Install shipped model ``name`` in ``folder`` (its network taken from ``onnx_from``)."""
    folder.mkdir(exist_ok=True)
    manifest = json.loads((DEFAULT_MODEL_DIR / f"{name}.json").read_text())
    source = DEFAULT_MODEL_DIR / f"{onnx_from or name}.onnx"
    target = folder / manifest["file"]
    if not target.exists():
        os.symlink(source, target)
    manifest["sha256"] = sha256_file(source)
    for key, value in changes.items():
        if value is None:
            manifest.pop(key, None)
        else:
            manifest[key] = value
    (folder / f"{name}.json").write_text(json.dumps(manifest))
    return manifest


@pytest.mark.parametrize(
    ("changes", "key"),
    [
        ({"pad_multiple": 0}, "pad_multiple"),
        ({"pad_multiple": -8}, "pad_multiple"),
        ({"pad_multiple": 2.5}, "pad_multiple"),
        ({"pad_multiple": "16"}, "pad_multiple"),
        ({"pad_multiple": True}, "pad_multiple"),
        ({"input_side": 0}, "input_side"),
        ({"file": "../depth.onnx"}, "file"),
        ({"file": 5}, "file"),
        ({"sha256": "abc"}, "sha256"),
        ({"inputs": "image"}, "inputs"),
        ({"outputs": [{"shape": [1]}]}, "outputs"),
    ],
)
def test_bad_manifest_fields_are_model_errors(tmp_path, changes, key) -> None:
    _install(tmp_path, "shadow", **changes)
    with pytest.raises(ModelError, match=f"'{key}'") as info:
        ModelRegistry(tmp_path).load("shadow")
    assert "shadow.json" in str(info.value)


def test_pad_multiple_zero_is_a_one_line_cli_error(tmp_path, capsys, monkeypatch) -> None:
    models = tmp_path / "models"
    _install(models, "shadow", pad_multiple=0)
    monkeypatch.setenv("OUTCAST_MODEL_DIR", str(models))
    photo = tmp_path / "p.png"
    write_image(photo, np.full((24, 32, 3), 0.5, np.float32))
    assert main(["shadow", str(photo), "--sun", "90,30", "--mode", "learned",
                 "-o", str(tmp_path / "s.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pad_multiple" in err and "Traceback" not in err


def test_a_network_under_another_models_name_is_refused(tmp_path) -> None:
    _install(tmp_path, "shadow", onnx_from="depth")  # sha256 updated: the checksum passes
    with pytest.raises(ModelError, match="does not match its manifest"):
        ModelRegistry(tmp_path).load("shadow")


def test_a_manifest_rewritten_to_match_the_wrong_network_is_refused(tmp_path) -> None:
    depth = json.loads((DEFAULT_MODEL_DIR / "depth.json").read_text())
    _install(tmp_path, "shadow", onnx_from="depth", inputs=depth["inputs"],
             outputs=depth["outputs"])
    with pytest.raises(ModelError, match="is not a 'shadow' network"):
        ModelRegistry(tmp_path).load("shadow")


def test_manifest_rank_mismatch_is_refused(tmp_path) -> None:
    manifest = json.loads((DEFAULT_MODEL_DIR / "shadow.json").read_text())
    inputs = [dict(p) for p in manifest["inputs"]]
    inputs[0]["shape"] = ["B", "H", "W"]
    _install(tmp_path, "shadow", inputs=inputs)
    with pytest.raises(ModelError, match="dimensions"):
        ModelRegistry(tmp_path).load("shadow")


def test_every_shipped_model_matches_its_manifest() -> None:
    registry = ModelRegistry()
    for manifest in sorted(DEFAULT_MODEL_DIR.glob("*.json")):
        registry.load(manifest.stem)


def test_missing_refine_is_said_not_dropped_silently(tmp_path, capsys, monkeypatch) -> None:
    models = tmp_path / "models"
    for name in ("shadow", "relight"):
        _install(models, name)
    registry = ModelRegistry(models)
    session = RelightSession(registry=registry, shadow_mode="learned", relight_mode="learned",
                             refine="learned")
    assert session.shadow_mode == "learned" and session.refinement == "guided filter"
    _install(models, "refine")
    assert RelightSession(registry=ModelRegistry(models), refine="learned").refinement == "learned"
    assert RelightSession(registry=ModelRegistry(models)).refinement == "photo"
    (models / "refine.json").unlink()
    monkeypatch.setenv("OUTCAST_MODEL_DIR", str(models))
    photo = tmp_path / "p.png"
    write_image(photo, np.full((24, 32, 3), 0.5, np.float32))
    assert main(["relight", str(photo), "--from", "90,30", "--to", "200,40", "--refine", "learned",
                 "--depth",
                 str(_flat_depth(tmp_path)), "-o", str(tmp_path / "r.png")]) == 0
    err = capsys.readouterr().err
    assert "shadows: learned, refinement: guided filter" in err


def _flat_depth(tmp_path: Path) -> Path:
    path = tmp_path / "d.npy"
    np.save(path, np.full((24, 32), 5.0, np.float32))
    return path
