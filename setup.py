"""Build hook: ship the ONNX models of ``models/`` inside the wheel.

Everything else about the package is in ``pyproject.toml``. The models live at the top of the
source tree (``models/``, where training exports them); a regular build copies each manifest
(``*.json``), the ONNX file it names and the model cards into the package folder
``outcast_core/shipped_models/``, where :mod:`outcast_core.runtime.io.models` finds them once
installed. An editable install (``pip install -e .``) copies nothing: it reads ``models/`` in the
checkout.
"""

from __future__ import annotations

import json
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
#: Folder (inside the ``outcast_core`` package) the wheel carries the models in.
SHIPPED = ("outcast_core", "shipped_models")


def model_files(models: Path) -> list[Path]:
    """The files of ``models/`` a wheel carries: manifests, their ONNX files, model cards.

    Args:
        models: the ``models/`` folder of the source tree.

    Returns:
        Sorted paths; a manifest whose ONNX file is missing raises ``FileNotFoundError``.
    """
    files: list[Path] = []
    for manifest in sorted(models.glob("*.json")):
        data = json.loads(manifest.read_text(encoding="utf-8"))
        onnx = models / str(data["file"])
        if not onnx.is_file():
            raise FileNotFoundError(f"{manifest.name} names {onnx.name}, which is missing")
        files += [manifest, onnx]
    files += [p for p in (models / "README.md", models / "EVAL.md") if p.is_file()]
    return sorted(set(files))


class BuildPyWithModels(build_py):
    """``build_py`` that also copies ``models/`` into ``outcast_core/shipped_models/``."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        models = ROOT / "models"
        if not models.is_dir():  # building from an sdist made without the models
            return
        target = Path(self.build_lib, *SHIPPED)
        self.mkpath(str(target))
        for src in model_files(models):
            self.copy_file(str(src), str(target / src.name))


setup(cmdclass={"build_py": BuildPyWithModels})
