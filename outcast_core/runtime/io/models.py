"""Shipped ONNX models: manifests, checksum-verified loading, padded inference.

Each model is ``models/<name>.onnx`` with a manifest ``models/<name>.json`` (see
``models/README.md``). Loading checks that both exist, that the manifest parses and that the
file's sha256 matches; anything else raises :class:`ModelError` naming the file.

Where a model is looked up, first match wins:

1. an explicit folder (``ModelRegistry(directory=...)``): every model comes from it;
2. ``$OUTCAST_MODEL_DIR``: every model comes from it (an empty folder means "no models");
3. the user's model folder, ``$XDG_DATA_HOME/outcast/models`` (``~/.local/share/outcast/models``),
   model by model: a ``NAME.json`` there replaces the shipped ``NAME``;
4. the shipped models: ``outcast_core/shipped_models/`` in an installed wheel (see ``setup.py``),
   else ``models/`` of the source checkout (editable installs, the PyInstaller bundle).
"""

from __future__ import annotations

import hashlib
import json
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: ``models/`` at the top of the source tree (a checkout, an editable install, the bundle).
SOURCE_MODEL_DIR = Path(__file__).resolve().parents[3] / "models"
#: The models an installed wheel carries (copied from ``models/`` by ``setup.py``).
PACKAGED_MODEL_DIR = Path(__file__).resolve().parents[2] / "shipped_models"
#: Where the shipped models live: the wheel's copy when installed, else the source tree's.
DEFAULT_MODEL_DIR = PACKAGED_MODEL_DIR if PACKAGED_MODEL_DIR.is_dir() else SOURCE_MODEL_DIR
#: The model names the runtime knows.
KNOWN_MODELS = ("depth", "shadow", "refine", "relight", "shadow_2d", "relight_pix2pix")


#: The input names the runtime feeds each known model (a network shipped under another
#: model's name, with its manifest and sha256 edited to match, is refused on load).
EXPECTED_INPUTS: dict[str, frozenset[str]] = {
    "depth": frozenset({"image"}),
    "shadow": frozenset({"image", "depth", "normals", "sun", "focal"}),
    "shadow_2d": frozenset({"image", "depth", "normals", "sun", "focal"}),
    "refine": frozenset({"shadow", "image", "sun"}),
    "relight": frozenset(
        {"image", "shadow_old", "shadow_new", "normals", "sun_old", "sun_new", "view_dirs"}
    ),
    "relight_pix2pix": frozenset({"image", "normals", "sun_old", "sun_new", "view_dirs"}),
    "sun": frozenset({"image"}),
}
#: Inputs the runtime also feeds, which some variants use (L on the physics base).
OPTIONAL_INPUTS: dict[str, frozenset[str]] = {"relight": frozenset({"light_ratio"})}
#: Largest ``pad_multiple`` / ``input_side`` a manifest may give.
MAX_PAD_MULTIPLE = 256
MAX_INPUT_SIDE = 8192


class ModelError(RuntimeError):
    """A model file is missing, corrupt or does not match its manifest."""


def user_model_dir() -> Path:
    """The user's model folder: ``$XDG_DATA_HOME/outcast/models`` (default
    ``~/.local/share/outcast/models``); it need not exist."""
    data = os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local",
                                                           "share")
    return Path(data) / "outcast" / "models"


def model_search_path() -> list[Path]:
    """The folders models are looked up in, first match wins (see the module docstring).

    Returns:
        ``[$OUTCAST_MODEL_DIR]`` when that is set (it replaces the others), else the user's
        model folder followed by the shipped models' folder.
    """
    env = os.environ.get("OUTCAST_MODEL_DIR")
    if env:
        return [Path(env).expanduser()]
    return [user_model_dir(), DEFAULT_MODEL_DIR]


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


@dataclass
class Model:
    """A loaded ONNX model and its manifest; ``run`` pads spatial inputs and crops outputs."""

    name: str
    path: Path
    manifest: dict[str, Any]
    session: Any
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def pad_multiple(self) -> int:
        return int(self.manifest.get("pad_multiple", 16))

    @property
    def input_side(self) -> int | None:
        """Longer image side the network was trained at (``input_side`` in the manifest, else its
        training config's ``size``), or None when the manifest does not say. ``Z`` is run at this
        scale (:func:`outcast_core.runtime.pipeline.depth_post.run_depth_model`)."""
        side = self.manifest.get("input_side")
        if side is None:
            side = (self.manifest.get("training") or {}).get("config", {}).get("size")
        return int(side) if side else None

    @property
    def input_names(self) -> list[str]:
        return [i.name for i in self.session.get_inputs()]

    def run(self, feeds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Run with NCHW inputs of any size: pads H, W (edge replication) and crops outputs.

        Args:
            feeds: input name -> array. 4-D arrays are treated as NCHW images.

        Returns:
            output name -> float32 array cropped to the input size.
        """
        missing = set(self.input_names) - set(feeds)
        if missing:
            raise ValueError(
                f"expected inputs {sorted(self.input_names)}, missing {sorted(missing)}"
            )
        m = self.pad_multiple
        size = None
        padded: dict[str, np.ndarray] = {}
        for name in self.input_names:
            x = np.ascontiguousarray(feeds[name], dtype=np.float32)
            if x.ndim == 4:
                h, w = x.shape[2:]
                if size is None:
                    size = (h, w)
                elif size != (h, w):
                    raise ValueError(f"expected all images of size {size}, got {name} {(h, w)}")
                ph, pw = (-h) % m, (-w) % m
                if ph or pw:
                    x = np.pad(x, ((0, 0), (0, 0), (0, ph), (0, pw)), mode="edge")
            padded[name] = x
        with self._lock:
            outs = self.session.run(None, padded)
        names = [o.name for o in self.session.get_outputs()]
        result = {}
        for n, y in zip(names, outs, strict=True):
            y = np.asarray(y, dtype=np.float32)
            if y.ndim == 4 and size is not None:
                y = y[:, :, : size[0], : size[1]]
            result[n] = y
        return result


class ModelRegistry:
    """Finds, verifies and lazily loads the shipped models (one ONNX session per model).

    Args:
        directory: the one folder to load every model from; default: the search path of
            :func:`model_search_path` (``$OUTCAST_MODEL_DIR``, else the user's folder, then the
            shipped models).
        threads: intra-op threads for onnxruntime (default: all cores).
    """

    def __init__(self, directory: Path | str | None = None, threads: int | None = None) -> None:
        self.search_path = (
            [Path(directory)] if directory is not None else model_search_path()
        )
        self._from_environment = directory is None
        self.threads = threads
        self._loaded: dict[str, Model] = {}
        self._lock = threading.Lock()

    def directory_for(self, name: str) -> Path:
        """The first folder of the search path with a manifest ``name.json`` (else the last)."""
        for folder in self.search_path:
            if (folder / f"{name}.json").is_file():
                return folder
        return self.search_path[-1]

    def manifest_path(self, name: str) -> Path:
        return self.directory_for(name) / f"{name}.json"

    def available(self, name: str) -> bool:
        """Whether a manifest for ``name`` is present (the file itself is verified on load)."""
        return self.manifest_path(name).is_file()

    def manifest(self, name: str) -> dict[str, Any]:
        path = self.manifest_path(name)
        if not path.is_file():
            where = "" if path.parent.is_dir() else f"; the folder {path.parent} does not exist"
            if os.environ.get("OUTCAST_MODEL_DIR") and self._from_environment:
                where += " (OUTCAST_MODEL_DIR points there: unset it for the shipped models)"
            raise ModelError(
                f"model '{name}' is not installed: {path} is missing{where}; reinstall "
                "OutCast, or use Direct shadows and physics relighting, which need no model"
            )
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ModelError(f"model manifest {path} is unreadable: {exc}") from exc
        for key in ("file", "sha256"):
            if key not in data:
                raise ModelError(f"model manifest {path} lacks the key '{key}'")
        check_manifest(data, path)
        return data

    def load(self, name: str, *, threads: int | None = None) -> Model:
        """Load (once) and return a verified model; :class:`ModelError` if missing or corrupt.

        Args:
            name: the model.
            threads: intra-op threads for this instance, when it differs from the registry's
                (a second session of the same file, loaded once too): the session runs its
                small drag-preview inputs on one thread, which on two shared cores was 2-3x
                faster than two (``benchmarks/bench_runtime.py``).
        """
        if threads is not None and threads != self.threads:
            with self._lock:
                key = f"{name}@{threads}"
                if key in self._loaded:
                    return self._loaded[key]
            base = self.load(name)  # verified once, with the registry's threads
            model = Model(name, base.path, base.manifest,
                          onnx_session(base.path, threads))
            with self._lock:
                return self._loaded.setdefault(key, model)
        with self._lock:
            if name in self._loaded:
                return self._loaded[name]
            manifest = self.manifest(name)
            onnx_path = self.manifest_path(name).parent / manifest["file"]
            if not onnx_path.is_file():
                raise ModelError(f"model file {onnx_path} is missing (listed in {name}.json)")
            digest = sha256_file(onnx_path)
            if digest != manifest["sha256"]:
                raise ModelError(
                    f"model file {onnx_path} is corrupt: sha256 {digest[:12]}... does not match "
                    f"the manifest's {str(manifest['sha256'])[:12]}...; reinstall the models"
                )
            sess = onnx_session(onnx_path, self.threads)
            check_model_io(name, manifest, sess, onnx_path)
            model = Model(name, onnx_path, manifest, sess)
            self._loaded[name] = model
            return model


def onnx_session(onnx_path: Path, threads: int | None) -> Any:
    """An onnxruntime CPU session for ``onnx_path`` (``threads`` intra-op threads, or
    onnxruntime's default), or :class:`ModelError` saying why the file could not be loaded.
    Checks nothing about what the model computes: :meth:`ModelRegistry.load` verifies the
    manifest and checksum first."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    if threads:
        opts.intra_op_num_threads = threads
    opts.log_severity_level = 3
    try:
        return ort.InferenceSession(
            str(onnx_path), sess_options=opts, providers=["CPUExecutionProvider"]
        )
    except Exception as exc:  # onnxruntime raises its own exception types
        raise ModelError(f"model file {onnx_path} could not be loaded: {exc}") from exc


def check_manifest(data: Any, path: Path) -> None:
    """Check a manifest's fields (types and ranges); :class:`ModelError` naming the bad one.

    Args:
        data: the parsed JSON.
        path: the manifest file (for the message).
    """
    if not isinstance(data, dict):
        raise ModelError(f"model manifest {path} is not a JSON object")

    def bad(key: str, expected: str) -> ModelError:
        return ModelError(f"model manifest {path}: expected '{key}' to be {expected}, "
                          f"got {data.get(key)!r}")

    file = data.get("file")
    if not isinstance(file, str) or not file or Path(file).name != file:
        raise bad("file", "a file name in the model folder")
    digest = data.get("sha256")
    if not (isinstance(digest, str) and len(digest) == 64
            and all(c in "0123456789abcdef" for c in digest)):
        raise bad("sha256", "64 lower-case hex digits")
    pad = data.get("pad_multiple", 16)
    if isinstance(pad, bool) or not isinstance(pad, int) or not 1 <= pad <= MAX_PAD_MULTIPLE:
        raise bad("pad_multiple", f"a whole number in [1, {MAX_PAD_MULTIPLE}]")
    side = data.get("input_side")
    if side is not None and (isinstance(side, bool) or not isinstance(side, int)
                             or not 1 <= side <= MAX_INPUT_SIDE):
        raise bad("input_side", f"a whole number in [1, {MAX_INPUT_SIDE}]")
    for key in ("inputs", "outputs"):
        ports = data.get(key)
        if ports is None:
            continue
        if not isinstance(ports, list) or not ports or not all(
            isinstance(p, dict) and isinstance(p.get("name"), str)
            and isinstance(p.get("shape", []), list) for p in ports
        ):
            raise bad(key, "a list of {name, shape} objects")


def check_model_io(name: str, manifest: dict[str, Any], session: Any, path: Path) -> None:
    """Check a loaded network's inputs and outputs against its manifest and the runtime.

    The input and output names must be the manifest's (when it lists them), with the ranks of
    their shapes; the inputs must be those the runtime feeds a model called ``name``
    (:data:`EXPECTED_INPUTS`, plus any of :data:`OPTIONAL_INPUTS`).

    Raises:
        ModelError: naming the file and the mismatch.
    """
    actual = {"inputs": {i.name: len(i.shape) for i in session.get_inputs()},
              "outputs": {o.name: len(o.shape) for o in session.get_outputs()}}
    for key in ("inputs", "outputs"):
        listed = manifest.get(key)
        if listed is None:
            continue
        expected = {p["name"]: len(p.get("shape", [])) for p in listed}
        if set(expected) != set(actual[key]):
            raise ModelError(
                f"model file {path} does not match its manifest: {key} "
                f"{sorted(actual[key])}, the manifest lists {sorted(expected)}"
            )
        ranks = {n: (expected[n], actual[key][n]) for n in expected
                 if "shape" in next(p for p in listed if p["name"] == n)}
        wrong = {n: r for n, r in ranks.items() if r[0] != r[1]}
        if wrong:
            n, (want, got) = next(iter(wrong.items()))
            raise ModelError(f"model file {path} does not match its manifest: {key[:-1]} "
                             f"'{n}' has {got} dimensions, the manifest says {want}")
    wanted = EXPECTED_INPUTS.get(name)
    optional = OPTIONAL_INPUTS.get(name, frozenset())
    got = set(actual["inputs"])
    if wanted is not None and not wanted <= got <= wanted | optional:
        extra = f" (optionally also {sorted(optional)})" if optional else ""
        raise ModelError(
            f"model file {path} is not a '{name}' network: inputs {sorted(got)}, "
            f"expected {sorted(wanted)}{extra}"
        )
