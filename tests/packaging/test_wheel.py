"""The wheel: it carries the shipped models, and installed alone (no checkout, no torch) it runs.

``test_wheel_contents`` builds the wheel from a copy of the source tree (a few seconds);
``test_wheel_installs_and_relights`` (slow: a virtual environment, the runtime dependencies from
the package index, about 30 s) installs it with the ``gui`` extra and runs ``outcast relight`` in
learned mode and ``outcast-gui --self-test`` from a folder outside the checkout.
"""

from __future__ import annotations

import email
import json
import os
import re
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from outcast_core.runtime.io.models import SOURCE_MODEL_DIR, sha256_file

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "samples" / "exif_003_th_pool.jpg"
#: Requirements of the training side; none may be a base (non-extra) dependency of the wheel.
TRAINING_SIDE = {"torch", "torchvision", "onnx", "mitsuba", "drjit", "pytest"}


def build_wheel(out_dir: Path) -> Path:
    """Build the wheel from a clean copy of the source tree; returns its path.

    Args:
        out_dir: an empty folder; the copy and the wheel go below it.

    Returns:
        The ``outcast-*.whl`` file.
    """
    src = out_dir / "src"
    src.mkdir(parents=True)
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", "dist")
    for name in ("outcast_core", "app", "models"):
        shutil.copytree(ROOT / name, src / name, ignore=ignore)
    run = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
         "--disable-pip-version-check", "-q", "-w", str(out_dir / "dist"), str(src)],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    wheels = sorted((out_dir / "dist").glob("outcast-*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_wheel(tmp_path_factory.mktemp("wheel"))


def _base_requirements(metadata: str) -> list[str]:
    msg = email.message_from_string(metadata)
    reqs = msg.get_all("Requires-Dist") or []
    return [r for r in reqs if "extra ==" not in r]


def test_wheel_contents(wheel: Path, tmp_path: Path) -> None:
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
        metadata = zf.read(meta).decode()
        zf.extractall(tmp_path)
    shipped = tmp_path / "outcast_core" / "shipped_models"
    manifests = sorted(p.name for p in SOURCE_MODEL_DIR.glob("*.json"))
    assert manifests and sorted(p.name for p in shipped.glob("*.json")) == manifests
    for name in manifests:
        manifest = json.loads((shipped / name).read_text())
        onnx = shipped / manifest["file"]
        assert onnx.is_file(), f"{manifest['file']} is not in the wheel"
        assert sha256_file(onnx) == manifest["sha256"]
    assert (shipped / "README.md").is_file()  # the model cards
    assert "app/resources/outcast.svg" in names and "outcast_core/runtime/cli/main.py" in names
    base = {re.split(r"[ ;<>=!~\[]", r, maxsplit=1)[0].lower() for r in
            _base_requirements(metadata)}
    assert base and not base & TRAINING_SIDE, base
    assert "pyside6-essentials" not in base  # the desktop app is the ``gui`` extra
    entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    with zipfile.ZipFile(wheel) as zf:
        points = zf.read(entry).decode()
    assert "outcast = outcast_core.runtime.cli.main:main" in points
    assert "outcast-gui = app.main:main" in points


def _venv_env(home: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "OUTCAST_MODEL_DIR", "VIRTUAL_ENV", "PYTHONHOME")}
    env.update(HOME=str(home), XDG_DATA_HOME=str(home / "data"), QT_QPA_PLATFORM="offscreen",
               XDG_CONFIG_HOME=str(home / "config"), XDG_CACHE_HOME=str(home / "cache"))
    if "PIP_CACHE_DIR" not in os.environ:  # keep using the machine's pip cache
        env["PIP_CACHE_DIR"] = os.path.join(os.path.expanduser("~"), ".cache", "pip")
    return env


@pytest.mark.slow
def test_wheel_installs_and_relights(wheel: Path, tmp_path: Path) -> None:
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py, bin_dir = env_dir / "bin" / "python", env_dir / "bin"
    env = _venv_env(tmp_path / "home")
    install = subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check",
         f"{wheel}[gui]"], capture_output=True, text=True, env=env, timeout=900,
    )
    assert install.returncode == 0, install.stdout + install.stderr[-3000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    photo = work / SAMPLE.name
    shutil.copy2(SAMPLE, photo)

    def run(*cmd: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(list(cmd), capture_output=True, text=True, env=env, cwd=work,
                              timeout=300)

    probe = run(str(py), "-c", "import importlib.util as u, outcast_core, app; "
                "print(outcast_core.__file__); print(app.__file__); "
                "print(u.find_spec('torch') is None)")
    assert probe.returncode == 0, probe.stderr
    core, app_file, no_torch = probe.stdout.split()
    assert core.startswith(str(env_dir)) and app_file.startswith(str(env_dir))
    assert no_torch == "True"  # torch was not pulled in

    models = run(str(bin_dir / "outcast"), "models", "--json")
    assert models.returncode == 0, models.stdout + models.stderr
    report = json.loads(models.stdout)
    assert report["search_path"][-1].startswith(str(env_dir))
    assert {m["status"] for m in report["models"]} == {"ok"}

    relit = run(str(bin_dir / "outcast"), "relight", photo.name, "--from", "273,67", "--to",
                "90,30", "--mode", "learned", "--shadows", "learned", "--preset", "fast",
                "-o", "relit.jpg")
    assert relit.returncode == 0, relit.stderr
    assert "shadows: learned" in relit.stderr and "relighting: learned" in relit.stderr
    assert (work / "relit.jpg").stat().st_size > 10_000

    gui = run(str(bin_dir / "outcast-gui"), photo.name, "--self-test", "still.png")
    assert gui.returncode == 0, gui.stdout + gui.stderr
    result = json.loads(gui.stdout.strip().splitlines()[-1])
    assert result["exif_sun"] == pytest.approx([273.5, 66.8], abs=0.2)
    assert "learned" in result["mode"] and result["models"].startswith(str(env_dir))
    assert result["size"] == [2016, 1512] and (work / "still.png").is_file()


def test_gui_without_pyside6_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import builtins

    from app.main import main

    real_import = builtins.__import__

    def no_qt(name: str, *args: object, **kwargs: object) -> object:
        if name.startswith("PySide6"):
            raise ImportError(f"No module named '{name}'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_qt)
    assert main(["photo.jpg"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'outcast[gui]'" in err
