"""Build the desktop bundle with PyInstaller and smoke-test it.

Usage (from anywhere; paths are relative to the repository root)::

    python3 packaging/build_bundle.py              # build dist/outcast-gui/, then smoke-test it
    python3 packaging/build_bundle.py --no-build   # smoke-test an existing bundle
    python3 packaging/build_bundle.py --dist /tmp/bundle --json report.json

Building installs PyInstaller first when it is missing (``pip install pyinstaller``). The
smoke test runs the bundled ``outcast-gui --self-test`` offscreen on the sample photo (open it,
take the sun from its EXIF, confirm it, export a full-resolution still; see
``app/self_test.py``), checks that torch is not in the bundle and that the shipped models are,
and prints the bundle's size and the times taken. Exit status 0 when everything holds.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "packaging" / "outcast-gui.spec"
SAMPLE = ROOT / "samples" / "exif_003_th_pool.jpg"
NAME = "outcast-gui"
#: Files whose presence means torch (or the training side) leaked into the bundle.
FORBIDDEN = ("torch", "libtorch", "mitsuba", "drjit")


def build(dist: Path, work: Path) -> float:
    """Run PyInstaller on the spec; returns the seconds it took.

    Args:
        dist: where ``outcast-gui/`` is written (replaced).
        work: PyInstaller's build folder.

    Raises:
        RuntimeError: PyInstaller failed (its last output lines in the message).
    """
    if importlib.util.find_spec("PyInstaller") is None:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q",
                        "--disable-pip-version-check", "pyinstaller>=6.10"], check=True)
    t0 = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "PyInstaller", "--noconfirm", "--clean", "--log-level", "WARN",
         "--distpath", str(dist), "--workpath", str(work), str(SPEC)],
        cwd=ROOT, capture_output=True, text=True,
    )
    if run.returncode != 0:
        tail = "\n".join((run.stdout + run.stderr).splitlines()[-30:])
        raise RuntimeError(f"PyInstaller failed:\n{tail}")
    return time.perf_counter() - t0


def folder_size(folder: Path) -> int:
    """Bytes of all regular files under ``folder`` (links not followed)."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


def forbidden_files(bundle: Path) -> list[str]:
    """Paths in ``bundle`` that belong to torch or the training side (should be none)."""
    bad = []
    for p in bundle.rglob("*"):
        if any(p.name == f or p.name.startswith(f"{f}.") or p.name.startswith(f"{f}-")
               or p.name.startswith(f"{f}_") for f in FORBIDDEN):
            bad.append(str(p.relative_to(bundle)))
    return sorted(bad)


def smoke(bundle: Path, photo: Path = SAMPLE, timeout: float = 600.0) -> dict[str, Any]:
    """Run the bundled app's self-test offscreen from an empty folder; returns its report.

    Args:
        bundle: the ``outcast-gui/`` folder PyInstaller made.
        photo: a photo with an EXIF sun.
        timeout: seconds the app may take.

    Raises:
        RuntimeError: the app failed or its report does not hold.
    """
    exe = bundle / NAME
    if not exe.is_file():
        raise RuntimeError(f"{exe} is missing; build the bundle first")
    with tempfile.TemporaryDirectory(prefix="outcast-bundle-smoke-") as tmp:
        work = Path(tmp)
        shutil.copy2(photo, work / photo.name)
        env = {k: v for k, v in os.environ.items()
               if k not in ("PYTHONPATH", "PYTHONHOME", "OUTCAST_MODEL_DIR")}
        env.update(QT_QPA_PLATFORM="offscreen", HOME=str(work), XDG_DATA_HOME=str(work / "d"),
                   XDG_CONFIG_HOME=str(work / "c"), XDG_CACHE_HOME=str(work / "x"))
        t0 = time.perf_counter()
        run = subprocess.run([str(exe), photo.name, "--self-test", "still.png"], cwd=work,
                             env=env, capture_output=True, text=True, timeout=timeout)
        seconds = time.perf_counter() - t0
        if run.returncode != 0:
            raise RuntimeError(f"the bundled app failed ({run.returncode}): "
                               f"{(run.stdout + run.stderr)[-3000:]}")
        report = json.loads(run.stdout.strip().splitlines()[-1])
        report["wall_seconds"] = round(seconds, 2)
        report["still_bytes"] = (work / "still.png").stat().st_size
    if "learned" not in report.get("mode", ""):
        raise RuntimeError(f"the bundle did not use the learned models: {report.get('mode')}")
    if not str(report.get("models", "")).startswith(str(bundle.resolve())):
        raise RuntimeError(f"the bundle's models came from {report.get('models')}, not from "
                           "inside the bundle")
    return report


def main(argv: list[str] | None = None) -> int:
    """Build (unless ``--no-build``) and smoke-test the bundle; print the report."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dist", default=str(ROOT / "dist"), help="output folder (default dist/)")
    p.add_argument("--work", default=str(ROOT / "build" / "pyinstaller"),
                   help="PyInstaller's build folder")
    p.add_argument("--no-build", action="store_true", help="smoke-test an existing bundle")
    p.add_argument("--no-smoke", action="store_true", help="only build")
    p.add_argument("--json", default="", help="also write the report here")
    args = p.parse_args(argv)
    dist = Path(args.dist).resolve()
    bundle = dist / NAME
    report: dict[str, Any] = {"bundle": str(bundle)}
    try:
        if not args.no_build:
            report["build_seconds"] = round(build(dist, Path(args.work).resolve()), 1)
        report["size_mb"] = round(folder_size(bundle) / 1e6, 1)
        report["forbidden"] = forbidden_files(bundle)
        shipped = bundle / "_internal" / "outcast_core" / "shipped_models"
        report["models"] = sorted(p.name for p in shipped.glob("*.onnx"))
        if report["forbidden"]:
            raise RuntimeError(f"torch or the training side is in the bundle: "
                               f"{report['forbidden'][:5]}")
        if not report["models"]:
            raise RuntimeError(f"no shipped models in {shipped}")
        if not args.no_smoke:
            report["smoke"] = smoke(bundle)
    except (RuntimeError, OSError, subprocess.SubprocessError, ValueError) as exc:
        print(f"build_bundle: error: {exc}", file=sys.stderr)
        return 2
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
