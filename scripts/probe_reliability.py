"""Re-run issue 20's reliability probes and print the counts.

Each probe runs ``outcast`` (or, for project files, the app offscreen) in a fresh process on a
deliberately bad input and checks that it ends with one clean line (no traceback), within a
time limit (no hang), with nothing left behind in its output folder (no ``.*.tmp.*``,
``.*.part*``), and, for decompression bombs, that the refusal costs under a second and under
200 MB (the child's wall time and peak RSS, Python start-up and imports included).

Usage::

    python scripts/probe_reliability.py            # counts, and one line per failed probe
    python scripts/probe_reliability.py -v         # one line per probe
    python scripts/probe_reliability.py --keep     # keep the work folder

Exit status 0 when every count is clean, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin

REPO = Path(__file__).resolve().parents[1]
HANG_SECONDS = 120.0
BOMB_SECONDS = 1.0
BOMB_MB = 200.0


@dataclass
class Probe:
    """One probe: ``outcast ARGV`` that should fail cleanly (or succeed, ``ok=True``)."""

    name: str
    argv: list[str]
    ok: bool = False
    bomb: bool = False
    expect: str = ""  # a fragment the last stderr line (errors) or stderr (successes) holds
    outputs: tuple[str, ...] = ()  # files a success may leave in its folder
    planted: tuple[str, ...] = ()  # files put in the output folder beforehand (kept)
    env: dict[str, str] = field(default_factory=dict)
    signal_after: str = ""  # send SIGTERM/SIGINT once a hidden partial output appears
    sig: int = signal.SIGTERM


@dataclass
class Result:
    probe: Probe
    rc: int | None
    seconds: float
    rss_mb: float
    stderr: str
    left: list[str]
    problems: list[str]


# --------------------------------------------------------------------------------------------
# Inputs


def _chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


def _png(path: Path, width: int, height: int, colour: int, bits: int = 8,
         idat: bytes | None = None) -> None:
    ihdr = struct.pack(">IIBBBBB", width, height, bits, colour, 0, 0, 0)
    idat = zlib.compress(b"\0" * 64) if idat is None else idat
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat)
                     + _chunk(b"IEND", b""))


def _real_bomb(path: Path, side: int) -> None:
    """A complete grey PNG of zeros: ``side``^2 bytes of pixels in about side^2 / 1000 bytes."""
    co = zlib.compressobj(9)
    row = b"\0" * (side + 1)
    parts = [co.compress(row) for _ in range(side)]
    parts.append(co.flush())
    _png(path, side, side, 0, idat=b"".join(parts))


def _tiff_bomb(path: Path, side: int) -> None:
    entries = [(256, 4, 1, side), (257, 4, 1, side), (258, 3, 1, 8), (259, 3, 1, 1),
               (262, 3, 1, 1), (273, 4, 1, 8), (277, 3, 1, 1), (278, 4, 1, side),
               (279, 4, 1, side * side)]
    ifd = struct.pack("<H", len(entries)) + b"".join(
        struct.pack("<HHII", tag, kind, count, value) for tag, kind, count, value in entries
    ) + struct.pack("<I", 0)
    path.write_bytes(b"II*\x00" + struct.pack("<I", 16) + b"\0" * 8 + ifd)


def make_inputs(folder: Path) -> None:
    folder.mkdir(parents=True)
    rng = np.random.default_rng(0)
    y = np.linspace(0, 1, 48)[:, None, None]
    photo = np.where(y < 0.4, [0.5, 0.7, 0.95], [0.6, 0.5, 0.4]) * np.ones((1, 64, 1))
    photo = np.clip(photo + rng.normal(0, 0.02, photo.shape), 0, 1)
    exif = Image.Exif()
    exif[0x0132] = "2024:06:21 12:00:00"
    exif[0x8825] = {1: "N", 2: (48.0, 51.0, 24.0), 3: "E", 4: (2.0, 21.0, 3.0)}
    Image.fromarray((photo * 255).astype(np.uint8)).save(folder / "photo.jpg", exif=exif)
    Image.fromarray((photo * 255).astype(np.uint8)).save(folder / "photo.png")
    (folder / "text.jpg").write_text("this is text, not a photo\n")
    (folder / "empty.png").write_bytes(b"")
    data = (folder / "photo.jpg").read_bytes()
    (folder / "truncated.jpg").write_bytes(data[: len(data) // 2])
    Image.new("RGB", (8, 8)).save(folder / "anim.gif")
    (folder / "shot.cr2").write_bytes(b"II*\x00 raw data")
    (folder / "folder.png").mkdir()
    _png(folder / "bomb50k_rgb.png", 50000, 50000, 2)
    _png(folder / "bomb50k_rgba.png", 50000, 50000, 6)
    _png(folder / "bomb50k_grey16.png", 50000, 50000, 0, bits=16)
    _real_bomb(folder / "bomb20k_full.png", 20000)  # 400 MB of pixels in about 400 kB
    _tiff_bomb(folder / "bomb50k.tif", 50000)
    _png(folder / "depth_bomb.png", 50000, 50000, 0, bits=16)
    with open(folder / "depth_bomb.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": (100000, 100000)})
        f.write(b"\0" * 64)
    for name, fill in (("zeros", 0.0), ("nan", np.nan), ("negative", -1.0), ("inf", np.inf)):
        np.save(folder / f"depth_{name}.npy", np.full((48, 64), fill, np.float32))
    info = PngImagePlugin.PngInfo()
    info.add_text("outcast:depth_scale", "1e308")
    Image.fromarray(np.full((48, 64), 1000, np.uint16)).save(folder / "depth_1e308.png",
                                                             pnginfo=info)
    (folder / "depth_text.npy").write_text("1 2 3\n4 5 6\n")
    np.save(folder / "depth_square.npy", np.full((64, 64), 5.0, np.float32))
    np.save(folder / "depth_ok.npy", np.full((48, 64), 5.0, np.float32))


def make_models(folder: Path) -> dict[str, Path]:
    """Model folders with a broken manifest, no refine.json, and a network under another name."""
    from outcast_core.runtime.io.models import DEFAULT_MODEL_DIR, sha256_file

    def install(target: Path, name: str, onnx_from: str | None = None, **changes) -> None:
        target.mkdir(parents=True, exist_ok=True)
        manifest = json.loads((DEFAULT_MODEL_DIR / f"{name}.json").read_text())
        source = DEFAULT_MODEL_DIR / f"{onnx_from or name}.onnx"
        if not (target / manifest["file"]).exists():
            os.symlink(source, target / manifest["file"])
        manifest["sha256"] = sha256_file(source)
        manifest.update(changes)
        (target / f"{name}.json").write_text(json.dumps(manifest))

    dirs = {k: folder / k for k in ("pad0", "norefine", "renamed")}
    for name in ("depth", "shadow", "refine", "relight"):
        install(dirs["pad0"], name, **({"pad_multiple": 0} if name == "shadow" else {}))
    for name in ("depth", "shadow", "relight"):
        install(dirs["norefine"], name)
    for name in ("depth", "refine", "relight"):
        install(dirs["renamed"], name)
    install(dirs["renamed"], "shadow", onnx_from="depth")
    return dirs


# --------------------------------------------------------------------------------------------
# Probes


def probes(inp: Path, models: dict[str, Path]) -> list[Probe]:
    p = str(inp / "photo.jpg")
    rel = ["relight", p, "--from", "273,67", "--to", "90,30", "--preset", "fast"]
    sh = ["shadow", p, "--sun", "90,30", "--preset", "fast"]
    tl = ["timelapse", p, "--from", "273,67", "--sweep", "90,20:270,20", "--preset", "fast"]
    out: list[Probe] = []
    for name in ("text.jpg", "empty.png", "truncated.jpg", "anim.gif", "shot.cr2",
                 "folder.png", "missing.jpg"):
        out.append(Probe(f"relight {name}", ["relight", str(inp / name), *rel[2:], "-o",
                                              "{out}/r.jpg"]))
    for name in ("bomb50k_rgb.png", "bomb50k_rgba.png", "bomb50k_grey16.png",
                 "bomb20k_full.png", "bomb50k.tif"):
        out.append(Probe(f"bomb relight {name}", ["relight", str(inp / name), *rel[2:], "-o",
                                                   "{out}/r.jpg"], bomb=True, expect="MP limit"))
        out.append(Probe(f"bomb shadow {name}", ["shadow", str(inp / name), *sh[2:], "-o",
                                                  "{out}/s.png"], bomb=True, expect="MP limit"))
    for name in ("depth_bomb.png", "depth_bomb.npy"):
        out.append(Probe(f"bomb --depth {name}", [*rel, "--depth", str(inp / name), "-o",
                                                   "{out}/r.jpg"], bomb=True, expect="MP limit"))
    out += [
        Probe("--steps 1000000000", [*sh, "--mode", "direct", "--steps", "1000000000", "-o",
                                     "{out}/s.png"], expect="--steps"),
        Probe("--steps 0", [*sh, "--mode", "direct", "--steps", "0", "-o", "{out}/s.png"],
              expect="--steps"),
        Probe("--steps in learned mode", [*sh, "--mode", "learned", "--steps", "64", "-o",
                                          "{out}/s.png"], ok=True, outputs=("s.png",),
              expect="--steps applies to Direct shadows only"),
    ]
    for fov in ("0", "-10", "500", "nan"):
        out.append(Probe(f"--fov {fov}", [*sh, f"--fov={fov}", "-o", "{out}/s.png"],
                         expect="field of view"))
    for name in ("zeros", "nan", "negative", "inf"):
        out.append(Probe(f"--depth all {name}", [*rel, "--depth", str(inp / f"depth_{name}.npy"),
                                                 "-o", "{out}/r.jpg"], expect="no valid pixel"))
    out += [
        Probe("--depth PNG scale 1e308", [*rel, "--depth", str(inp / "depth_1e308.png"), "-o",
                                          "{out}/r.jpg"], expect="depth_scale"),
        Probe("--depth text as .npy", [*rel, "--depth", str(inp / "depth_text.npy"), "-o",
                                       "{out}/r.jpg"], expect="not a NumPy .npy file"),
        Probe("--depth wrong aspect", [*rel, "--depth", str(inp / "depth_square.npy"), "-o",
                                       "{out}/r.jpg"], expect="aspect ratio"),
        Probe("timelapse -o out.avi", [*tl, "--frames", "3", "-o", "{out}/out.avi"],
              expect="time-lapse output"),
        Probe("timelapse --fps 1e-9", [*tl, "--frames", "3", "--fps", "1e-9", "-o",
                                       "{out}/t.mp4"], expect="frames per second"),
        Probe("timelapse --from 273,95", [*tl[:3], "273,95", *tl[4:], "--frames", "3", "-o",
                                          "{out}/t.mp4"], expect="elevation"),
        Probe("timelapse --frames 1e12", [*tl, "--frames", "1000000000000", "-o",
                                          "{out}/t.mp4"], expect="frame count"),
        Probe("relight -o existing file", [*rel, "-o", "{out}/exists.jpg"],
              planted=("exists.jpg",), expect="already exists"),
        Probe("relight -o out.avi", [*rel, "-o", "{out}/out.avi"], expect="extension"),
        Probe("shadow -o s.jpg", [*sh, "-o", "{out}/s.jpg"], expect="extension"),
        Probe("depth -o d.jpg", ["depth", p, "-o", "{out}/d.jpg"], expect="extension"),
        Probe("relight parent is a file", [*rel, "-o", "{out}/afile/r.jpg"],
              planted=("afile",), expect="is a file, not a folder"),
        Probe("relight -o input --force", [*rel, "-o", str(inp / "photo.jpg"), "--force"],
              expect="input file"),
        Probe("--sun-dir 1e308,1e308,0", ["shadow", p, "--sun-dir", "1e308,1e308,0", "--mode",
                                          "direct", "-o", "{out}/s.png"], ok=True,
              outputs=("s.png",)),
        Probe("relight keeps EXIF", [*rel, "-o", "{out}/r.jpg"], ok=True, outputs=("r.jpg",)),
        Probe("manifest pad_multiple 0", [*sh, "--mode", "learned", "-o", "{out}/s.png"],
              env={"OUTCAST_MODEL_DIR": str(models["pad0"])}, expect="pad_multiple"),
        Probe("manifest: no refine.json", [*rel, "--refine", "learned", "--depth",
                                           str(inp / "depth_ok.npy"), "-o", "{out}/r.jpg"],
              ok=True, outputs=("r.jpg",),
              env={"OUTCAST_MODEL_DIR": str(models["norefine"])},
              expect="refinement: guided filter"),
        Probe("manifest: depth net as shadow.onnx", [*sh, "--mode", "learned", "-o",
                                                     "{out}/s.png"],
              env={"OUTCAST_MODEL_DIR": str(models["renamed"])}, expect="does not match"),
        Probe("SIGTERM timelapse MP4", [*tl, "--frames", "400", "-o", "{out}/tl.mp4"],
              signal_after=".tl."),
        Probe("SIGTERM timelapse PNG folder", [*tl, "--frames", "400", "-o", "{out}/frames"],
              signal_after=".frames"),
        Probe("SIGINT timelapse MP4", [*tl, "--frames", "400", "-o", "{out}/tl.mp4"],
              signal_after=".tl.", sig=signal.SIGINT),
    ]
    if os.geteuid() != 0:
        out.append(Probe("relight read-only folder", [*rel, "-o", "{out}/ro/r.jpg"],
                         planted=("ro",), expect="not writable"))
    return out


def _run_child(cmd: list[str], env: dict[str, str], watch: Path | None, prefix: str,
               sig: int) -> tuple[int | None, float, float, str, bool]:
    """Run ``cmd``; returns (rc, seconds, peak RSS MB, stderr, timed out)."""
    with tempfile.TemporaryFile() as err_file:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err_file, env=env,
                                cwd=REPO)
        timed_out, sent = False, False
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            elapsed = time.perf_counter() - t0
            if watch is not None and not sent and any(
                n.startswith(prefix) for n in os.listdir(watch)
            ):
                time.sleep(0.5)  # a few frames into the partial file
                proc.send_signal(sig)
                sent = True
            if elapsed > HANG_SECONDS and not timed_out:
                proc.kill()
                timed_out = True
            time.sleep(0.01)
        seconds = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err_file.seek(0)
        stderr = err_file.read().decode("utf-8", "replace")
    if watch is not None and not sent:
        stderr += "\n(probe: the partial output never appeared; no signal sent)"
    return proc.returncode, seconds, usage.ru_maxrss / 1024.0, stderr, timed_out


def run_probe(probe: Probe, folder: Path, inp: Path) -> Result:
    folder.mkdir(parents=True)
    for name in probe.planted:
        if name == "ro":
            (folder / name).mkdir()
            (folder / name).chmod(0o555)
        else:
            (folder / name).write_bytes(b"planted")
    argv = [a.replace("{out}", str(folder)) for a in probe.argv]
    env = {**os.environ, "PYTHONPATH": str(REPO), **probe.env}
    cmd = [sys.executable, "-m", "outcast_core.runtime.cli.main", *argv]
    watch = folder if probe.signal_after else None
    before_inputs = sorted(os.listdir(inp))
    rc, seconds, rss, stderr, timed_out = _run_child(cmd, env, watch, probe.signal_after,
                                                     probe.sig)
    problems: list[str] = []
    lines = [ln for ln in stderr.strip().splitlines() if not ln.startswith("\r")]
    last = lines[-1] if lines else ""
    if "Traceback" in stderr:
        problems.append("traceback")
    if timed_out:
        problems.append("hang")
    if probe.signal_after:
        wanted = 143 if probe.sig == signal.SIGTERM else 130
        if rc != wanted:
            problems.append(f"exit {rc}, expected {wanted}")
    elif probe.ok and rc != 0:
        problems.append(f"exit {rc}, expected 0: {last}")
    elif not probe.ok and rc != 2:
        problems.append(f"exit {rc}, expected 2")
    if probe.expect and probe.expect not in (stderr if probe.ok else last):
        problems.append(f"message lacks {probe.expect!r}: {last!r}")
    allowed = set(probe.planted) | (set(probe.outputs) if rc == 0 else set())
    left = sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                  if p.relative_to(folder).parts[0] not in allowed)
    if sorted(os.listdir(inp)) != before_inputs:
        left.append(f"(inputs folder changed: {sorted(set(os.listdir(inp)) ^ set(before_inputs))})")
    if left:
        problems.append(f"left behind: {left}")
    if probe.bomb and (seconds >= BOMB_SECONDS or rss >= BOMB_MB):
        problems.append(f"bomb cost {seconds:.2f} s, {rss:.0f} MB")
    if probe.name == "relight keeps EXIF" and rc == 0:
        with Image.open(folder / "r.jpg") as im:
            if im.getexif().get(0x0132) != "2024:06:21 12:00:00":
                problems.append("EXIF dropped")
    if "ro" in probe.planted:
        (folder / "ro").chmod(0o755)
    return Result(probe, rc, seconds, rss, stderr, left, problems)


# --------------------------------------------------------------------------------------------
# Project files (the app, offscreen)

_GUI_CHILD = r"""
import json, sys, traceback
from PySide6.QtWidgets import QApplication, QMessageBox
seen = []
QMessageBox.critical = staticmethod(lambda *a, **k: seen.append(a[2]))
app = QApplication([])
from app.main_window import MainWindow
w = MainWindow()
results = []
for path in sys.argv[1:]:
    seen.clear()
    try:
        w.open_path(path)
        escaped = ""
    except BaseException as exc:
        escaped = type(exc).__name__
    results.append({"path": path, "dialogs": len(seen), "escaped": escaped,
                    "text": seen[0].replace("\n", " ")[:160] if seen else ""})
w.runner.shutdown()
print(json.dumps(results))
"""


def malformed_projects(folder: Path, photo: Path) -> list[tuple[Path, str]]:
    """(project file, the field its one dialog must name)."""
    base = {"outcast_project": 1, "image": str(photo)}
    cases: list[tuple[str, object, str]] = [
        ("timelapse", {"date": 20240101}, "timelapse.date"),
        ("timelapse", {"start": 5}, "timelapse.start"),
        ("timelapse", {"end": [1]}, "timelapse.end"),
        ("timelapse", {"frames": 10**12}, "timelapse.frames"),
        ("timelapse", {"frames": 1}, "timelapse.frames"),
        ("timelapse", {"latitude": "abc"}, "timelapse.latitude"),
        ("timelapse", {"longitude": 500}, "timelapse.longitude"),
        ("timelapse", {"full_resolution": "yes"}, "timelapse.full_resolution"),
        ("timelapse", {"fps": 1e-9}, "timelapse.fps"),
        ("timelapse", {"fps": "x"}, "timelapse.fps"),
        ("timelapse", {"easing": 3}, "timelapse.easing"),
        ("timelapse", {"kind": "orbit"}, "timelapse.kind"),
        ("timelapse", {"way": None}, "timelapse.way"),
        ("timelapse", {"format": "avi"}, "timelapse.format"),
        ("timelapse", {"heading": "north"}, "timelapse.heading"),
        ("timelapse", {"utc_offset": 99}, "timelapse.utc_offset"),
        ("timelapse", {"sweep_from": "east"}, "timelapse.sweep_from"),
        ("timelapse", {"sweep_to": {"azimuth": 1}}, "timelapse.sweep_to"),
        ("timelapse", None, "timelapse"),
        ("timelapse", [], "timelapse"),
        ("image", 5, "image"),
        ("image", ["a"], "image"),
        ("image_absolute", {}, "image_absolute"),
        ("depth_path", 3, "depth_path"),
        ("depth_source", [], "depth_source"),
        ("preset", "ultra", "preset"),
        ("preset", ["fast"], "preset"),
        ("buffer_view", {}, "buffer_view"),
        ("overlay_opacity", "half", "overlay_opacity"),
        ("overlay_opacity", 2, "overlay_opacity"),
        ("split", float("nan"), "split"),
        ("original_sun", "noon", "original_sun"),
        ("original_sun", {"azimuth": 10, "elevation": 95}, "original_sun"),
        ("target_sun", [1, 2, 3], "target_sun"),
        ("target_sun", {"azimuth": "a", "elevation": 2}, "target_sun"),
        ("outcast_project", 99, "version"),
    ]
    out = []
    for i, (key, value, fld) in enumerate(cases):
        path = folder / f"p{i:02d}.outcast.json"
        path.write_text(json.dumps({**base, key: value}))
        out.append((path, fld))
    extra = [('{"outcast_project": 1, "timelapse": ' + "[" * 100000 + "]" * 100000 + "}",
              "nested"), ("not json", "JSON"), ("[]", "outcast_project"),
             ('{"outcast_project": 1, "image": "x.jpg", "split": 1e999}', "split")]
    for j, (text, fld) in enumerate(extra):
        path = folder / f"q{j:02d}.outcast.json"
        path.write_text(text)
        out.append((path, fld))
    big = folder / "big.outcast.json"
    big.write_text(json.dumps({**base, "depth_source": "x" * 2_000_000}))
    out.append((big, "MB"))
    return out


def run_projects(folder: Path, photo: Path) -> tuple[int, list[str]]:
    try:
        import PySide6  # noqa: F401
    except ImportError:
        return 0, ["(PySide6 not installed: project probes skipped)"]
    folder.mkdir()
    cases = malformed_projects(folder, photo)
    env = {**os.environ, "PYTHONPATH": str(REPO), "QT_QPA_PLATFORM": "offscreen",
           "HOME": str(folder)}
    r = subprocess.run([sys.executable, "-c", _GUI_CHILD, *(str(p) for p, _ in cases)],
                       capture_output=True, text=True, env=env, cwd=REPO, timeout=HANG_SECONDS)
    problems = []
    if r.returncode != 0 or "Traceback" in r.stderr:
        return len(cases), [f"app child failed (exit {r.returncode}): {r.stderr[-500:]}"]
    for (path, fld), res in zip(cases, json.loads(r.stdout.strip().splitlines()[-1]),
                                strict=True):
        if res["escaped"] or res["dialogs"] != 1 or fld not in res["text"]:
            problems.append(f"{path.name}: {res}")
    return len(cases), problems


_APP_EXPORT_CHILD = r"""
import sys
from PySide6.QtCore import QTimer
from app import main_window
from app.main import main
opened = main_window.MainWindow.open_path
def when_idle(window, then):
    def poll():
        if window.runner.busy():
            QTimer.singleShot(100, poll)
        else:
            then()
    QTimer.singleShot(100, poll)
def open_and_export(self, path):
    opened(self, path)
    def export():
        dialog = self.open_timelapse()
        dialog.frames_box.setValue(2000)
        dialog.export(sys.argv[2])
    when_idle(self, lambda: (self.confirm_original_sun(), when_idle(self, export)))
main_window.MainWindow.open_path = open_and_export
sys.exit(main([sys.argv[1], "--classic", "--preset", "fast"]))
"""


def run_app_sigterm(folder: Path, photo: Path) -> list[str]:
    """SIGTERM the app during a time-lapse export: exit 143, no partial file left."""
    try:
        import PySide6  # noqa: F401
    except ImportError:
        return []
    out, home = folder / "out", folder / "home"
    out.mkdir(parents=True)
    home.mkdir()
    env = {**os.environ, "PYTHONPATH": str(REPO), "QT_QPA_PLATFORM": "offscreen",
           "HOME": str(home)}
    cmd = [sys.executable, "-c", _APP_EXPORT_CHILD, str(photo), str(out / "tl.mp4")]
    rc, seconds, _, stderr, timed_out = _run_child(cmd, env, out, ".tl.", signal.SIGTERM)
    problems = []
    if timed_out:
        problems.append("hang")
    if "Traceback" in stderr:
        problems.append("traceback")
    if rc != 143:
        problems.append(f"exit {rc}, expected 143: {stderr.strip().splitlines()[-1:]}")
    left = sorted(p.name for p in out.iterdir())
    if left:
        problems.append(f"left behind: {left}")
    return problems


# --------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-v", "--verbose", action="store_true", help="one line per probe")
    ap.add_argument("--keep", action="store_true", help="keep the work folder")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="outcast-probe-"))
    try:
        inp = work / "in"
        make_inputs(inp)
        models = make_models(work / "models")
        results = []
        for i, probe in enumerate(probes(inp, models)):
            res = run_probe(probe, work / f"out{i:02d}", inp)
            results.append(res)
            if args.verbose or res.problems:
                flag = "ok  " if not res.problems else "FAIL"
                print(f"{flag} {probe.name:38s} exit {res.rc!s:>4} {res.seconds:6.2f} s "
                      f"{res.rss_mb:6.0f} MB  {'; '.join(res.problems)}", flush=True)
        n_projects, project_problems = run_projects(work / "projects", inp / "photo.jpg")
        for line in project_problems:
            print(f"FAIL project {line}")
        app_problems = run_app_sigterm(work / "app", inp / "photo.jpg")
        if args.verbose or app_problems:
            flag = "FAIL" if app_problems else "ok  "
            print(f"{flag} SIGTERM app time-lapse export  {'; '.join(app_problems)}")
        n_projects += 1
        bombs = [r for r in results if r.probe.bomb]
        counts = {
            "probes": len(results) + n_projects,
            "tracebacks": sum("traceback" in r.problems for r in results)
            + ("traceback" in app_problems),
            "hangs": sum("hang" in r.problems for r in results) + ("hang" in app_problems),
            "files left behind": sum(bool(r.left) for r in results)
            + any(p.startswith("left behind") for p in app_problems),
            "app SIGTERM failures": len(app_problems),
            "other failures": sum(bool(r.problems) and not r.left
                                  and not {"traceback", "hang"} & set(r.problems)
                                  for r in results),
            "project files failing": len(project_problems),
            "bombs": len(bombs),
            "bombs over 1 s or 200 MB": sum(any(p.startswith("bomb cost") for p in r.problems)
                                           for r in bombs),
        }
        print()
        for k, v in counts.items():
            print(f"{k:28s} {v}")
        if bombs:
            print(f"{'bomb refusal, slowest':28s} {max(r.seconds for r in bombs):.2f} s "
                  "(whole process: Python start-up and imports included)")
            print(f"{'bomb refusal, peak RSS':28s} {max(r.rss_mb for r in bombs):.0f} MB")
        bad = sum(v for k, v in counts.items() if k not in ("probes", "bombs"))
        return 1 if bad else 0
    finally:
        if args.keep:
            print(f"work folder: {work}")
        else:
            for ro in work.rglob("ro"):
                ro.chmod(0o755)
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
