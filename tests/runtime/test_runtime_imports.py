"""The runtime and the app never import torch (checked in a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys

MODULES = [
    "outcast_core.runtime.geometry.camera",
    "outcast_core.runtime.geometry.raymarch",
    "outcast_core.runtime.geometry.shadows",
    "outcast_core.runtime.pipeline.relight",
    "outcast_core.runtime.pipeline.session",
    "outcast_core.runtime.io.models",
    "outcast_core.runtime.io.imageio",
    "outcast_core.runtime.cli.main",
    "outcast_core.runtime.io.phone_depth",
    "outcast_core.runtime.io.depth_models",
]


def test_runtime_imports_no_torch_and_no_qt() -> None:
    code = (
        "import sys\n"
        f"for m in {MODULES!r}: __import__(m)\n"
        "from outcast_core.runtime.cli.main import build_parser\n"
        "build_parser([])\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
        "{'torch', 'PySide6', 'mitsuba', 'drjit'})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"runtime imported: {out.stdout.strip()}"
