"""Desktop packaging: the desktop entry and metainfo validate; the PyInstaller bundle runs.

The bundle test builds ``dist/outcast-gui`` in a temporary folder with PyInstaller (about 35 s on
2 cores, 600 MB on disk; PyInstaller is installed when missing) and runs the bundled app's
self-test offscreen. It is slow and opt-in: ``OUTCAST_BUILD_BUNDLE=1 python3 -m pytest
tests/packaging/test_bundle.py`` (or run ``python3 packaging/build_bundle.py``).
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "packaging"
APP_ID = "io.github.outcast.OutCast"
_spec = importlib.util.spec_from_file_location("build_bundle", PKG / "build_bundle.py")
assert _spec is not None and _spec.loader is not None
build_bundle = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(build_bundle)


def _tool(name: str) -> str:
    """The path of a validator; a Debian machine without it fails (scripts/setup.sh installs
    it), any other skips."""
    path = shutil.which(name)
    if path is None:
        if shutil.which("apt-get"):
            pytest.fail(f"{name} is missing: run scripts/setup.sh (Debian packages "
                        "desktop-file-utils, appstream)")
        pytest.skip(f"{name} is not installed")
    return path


def test_desktop_entry_validates() -> None:
    run = subprocess.run([_tool("desktop-file-validate"), str(PKG / f"{APP_ID}.desktop")],
                         capture_output=True, text=True)
    assert run.returncode == 0 and "error" not in run.stdout, run.stdout + run.stderr


def test_metainfo_validates_strictly() -> None:
    run = subprocess.run([_tool("appstreamcli"), "validate", "--no-net", "--strict",
                          str(PKG / f"{APP_ID}.metainfo.xml")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_bundle_checks(tmp_path: Path) -> None:
    fake = tmp_path / "outcast-gui" / "_internal"
    (fake / "numpy").mkdir(parents=True)
    (fake / "numpy" / "core.so").write_bytes(b"x" * 10)
    assert build_bundle.forbidden_files(fake.parent) == []
    (fake / "torch" / "lib").mkdir(parents=True)
    (fake / "libtorch_cpu.so").write_bytes(b"")
    assert build_bundle.forbidden_files(fake.parent) == ["_internal/libtorch_cpu.so",
                                                         "_internal/torch"]
    assert build_bundle.folder_size(fake.parent) == 10
    spec = (PKG / "outcast-gui.spec").read_text()
    assert '"torch"' in spec and "shipped_models" in spec


def _spec_datas() -> list[tuple[str, str]]:
    """The ``datas`` the spec gives PyInstaller (run with PyInstaller's globals stubbed)."""
    seen: dict[str, Any] = {}

    def analysis(*args: Any, **kwargs: Any) -> SimpleNamespace:
        seen.update(kwargs)
        return SimpleNamespace(pure=[], scripts=[], binaries=[], datas=[])

    def stub(*args: Any, **kwargs: Any) -> None:
        return None

    spec = PKG / "outcast-gui.spec"
    code = compile(spec.read_text(encoding="utf-8"), str(spec), "exec")
    exec(code, {"SPECPATH": str(PKG), "Analysis": analysis, "PYZ": stub, "EXE": stub,
                "COLLECT": stub})
    return seen["datas"]


def test_spec_ships_the_wheels_model_files() -> None:
    """The bundle carries exactly what the wheel does: setup.py's ``model_files``."""
    shipped = sorted(Path(src) for src, dest in _spec_datas()
                     if dest == "outcast_core/shipped_models")
    models = ROOT / "models"
    manifests = sorted(models.glob("*.json"))
    assert manifests, "no model manifests in models/"
    for manifest in manifests:
        assert manifest in shipped
        assert models / json.loads(manifest.read_text(encoding="utf-8"))["file"] in shipped
    assert models / "README.md" in shipped
    assert not [p for p in shipped if p.suffix == ".png"]  # the sheets stay out, as in the wheel
    assert len(shipped) == len(set(shipped))


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("OUTCAST_BUILD_BUNDLE") != "1",
                    reason="builds a 600 MB bundle: set OUTCAST_BUILD_BUNDLE=1")
def test_bundle_builds_and_runs_offscreen(tmp_path: Path) -> None:
    report = tmp_path / "report.json"
    code = build_bundle.main(["--dist", str(tmp_path / "dist"), "--work", str(tmp_path / "w"),
                              "--json", str(report)])
    assert code == 0
    data = json.loads(report.read_text())
    assert data["forbidden"] == [] and "relight.onnx" in data["models"]
    smoke = data["smoke"]
    assert smoke["exif_sun"] == pytest.approx([273.5, 66.8], abs=0.2)
    assert smoke["size"] == [2016, 1512] and "learned" in smoke["mode"]
    print(f"bundle {data['size_mb']} MB, built in {data['build_seconds']} s, self-test "
          f"{smoke['wall_seconds']} s")
