"""Export a network to ONNX (legacy exporter, opset 17, dynamic H/W), check it, write its manifest.

Every exported file is run in onnxruntime right after export on inputs of several sizes and
compared with torch (max abs difference at most :data:`PARITY_TOL`); a file that fails is deleted
and the export raises. The manifest follows ``.notes/MODELS_API.md``: name, version, file, sha256,
inputs / outputs with shapes, colour space, pad multiple, march settings for shadow networks,
parameter count, training record, metrics and the creation date.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from outcast_core.runtime.io.models import sha256_file

OPSET = 17
PARITY_TOL = 1e-4
MANIFEST_VERSION = 1


@dataclass(frozen=True)
class IOSpec:
    """Input and output names of one exported network kind and how to make sample inputs.

    ONNX tensor names are unique within a graph, so an output cannot share an input's name:
    refine's output is ``shadow_out`` and the relight networks' output is ``image_out``.
    """

    inputs: tuple[tuple[str, int | None], ...]  # (name, channels; None = a B x 3/1 vector)
    outputs: tuple[tuple[str, int | None], ...]  # (name, channels; None = a B x K vector)
    vectors: dict[str, int]  # vector inputs and outputs: name -> length


SPECS: dict[str, IOSpec] = {
    "depth": IOSpec((("image", 3),), (("depth", 1), ("sky", 1)), {}),
    "shadow": IOSpec(
        (("image", 3), ("depth", 1), ("normals", 3), ("sun", None), ("focal", None)),
        (("shadow", 1),), {"sun": 3, "focal": 1},
    ),
    "refine": IOSpec(
        (("shadow", 1), ("image", 3), ("sun", None)), (("shadow_out", 1),), {"sun": 3}
    ),
    "relight": IOSpec(
        (("image", 3), ("shadow_old", 1), ("shadow_new", 1), ("normals", 3), ("sun_old", None),
         ("sun_new", None), ("view_dirs", 3)),
        (("image_out", 3),), {"sun_old": 3, "sun_new": 3},
    ),
    "relight_pix2pix": IOSpec(
        (("image", 3), ("normals", 3), ("sun_old", None), ("sun_new", None), ("view_dirs", 3)),
        (("image_out", 3),), {"sun_old": 3, "sun_new": 3},
    ),
}
SPECS["shadow_2d"] = SPECS["shadow"]
#: ``D``: one probability logit per direction bin (``outcast_core.nets.sun.BINS``).
SPECS["sun"] = IOSpec((("image", 3),), (("logits", None),), {"logits": 320})
#: ``L`` with the physics base (``RelightNet(base="physics")``) takes the light ratio as well.
RELIGHT_PHYSICS = IOSpec(
    SPECS["relight"].inputs + (("light_ratio", None),), SPECS["relight"].outputs,
    {"sun_old": 3, "sun_new": 3, "light_ratio": 3},
)


def spec_for(kind: str, net: nn.Module | None = None) -> IOSpec:
    """The I/O spec of network ``kind``; ``net`` picks the variant where a kind has two."""
    if kind not in SPECS:
        raise ValueError(f"expected a kind in {sorted(SPECS)}, got {kind!r}")
    if kind == "relight" and getattr(net, "base", "photo") == "physics":
        return RELIGHT_PHYSICS
    if kind == "sun" and net is not None:  # as many logits as the network has bins
        return IOSpec(SPECS["sun"].inputs, SPECS["sun"].outputs,
                      {"logits": int(net.bins.shape[0])})
    return SPECS[kind]


def sample_inputs(
    kind: str, height: int, width: int, seed: int = 0, spec: IOSpec | None = None
) -> dict[str, np.ndarray]:
    """Plausible random inputs for ``kind`` (or ``spec``) at ``height x width`` (batch 1).

    Depth maps and normals hold a sky band (depth 0: ``+inf`` is not allowed by every runtime,
    and the contract also defines 0 as "no surface"; normals 0); suns are unit vectors above the
    horizon; normals below the band and view directions are unit vectors; focal is the 60 degree
    focal length; light ratios are positive, in the range a photo gives.
    """
    spec = spec or spec_for(kind)
    rng = np.random.default_rng(seed)
    out: dict[str, np.ndarray] = {}
    for name, ch in spec.inputs:
        if name == "focal":
            out[name] = np.array([[width / (2 * math.tan(math.radians(30)))]], np.float32)
        elif name == "light_ratio":
            out[name] = rng.uniform(0.5, 8.0, (1, 3)).astype(np.float32)
        elif ch is None:
            v = rng.normal(size=(1, 3))
            v[0, 1] = -abs(v[0, 1]) - 0.2
            out[name] = (v / np.linalg.norm(v)).astype(np.float32)
        elif name == "depth":
            d = (1.0 + 4.0 * rng.random((1, 1, height, width))).astype(np.float32)
            d[..., : height // 5, :] = 0.0
            out[name] = d
        elif name in ("normals", "view_dirs"):
            v = rng.normal(size=(1, 3, height, width))
            v = v / np.linalg.norm(v, axis=1, keepdims=True)
            if name == "normals":
                v[..., : height // 5, :] = 0.0  # the sky band has no surface normal
            out[name] = v.astype(np.float32)
        else:
            out[name] = rng.random((1, ch, height, width)).astype(np.float32)
    return out


def _torch_outputs(net: nn.Module, inputs: dict[str, np.ndarray]) -> list[np.ndarray]:
    with torch.no_grad():
        out = net(*[torch.from_numpy(v) for v in inputs.values()])
    if isinstance(out, torch.Tensor):
        out = (out,)
    return [o.numpy() for o in out]


def check_parity(
    net: nn.Module, kind: str, path: Path, sizes: list[tuple[int, int]],
    tol: float = PARITY_TOL,
) -> float:
    """Max abs difference between onnxruntime and torch over ``sizes``; raises above ``tol``."""
    import onnxruntime as ort

    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    spec = spec_for(kind, net)
    worst = 0.0
    for i, (h, w) in enumerate(sizes):
        inputs = sample_inputs(kind, h, w, seed=i, spec=spec)
        ref = _torch_outputs(net, inputs)
        got = sess.run(None, inputs)
        for r, g in zip(ref, got, strict=True):
            if r.shape != g.shape:
                raise RuntimeError(f"{path.name}: shape {g.shape} != torch {r.shape} at {h}x{w}")
            worst = max(worst, float(np.max(np.abs(r - g))))
    if not worst <= tol:
        raise RuntimeError(f"{path.name}: onnxruntime differs from torch by {worst} > {tol}")
    return worst


def export_onnx(
    net: nn.Module, kind: str, path: Path, parity_sizes: list[tuple[int, int]] | None = None,
) -> float:
    """Export ``net`` (an instance of network ``kind``) to ``path`` and check it.

    Args:
        net: the network (put in eval mode here).
        kind: a key of :data:`SPECS`.
        path: the ``.onnx`` file to write.
        parity_sizes: ``(H, W)`` pairs to compare at (multiples of the net's pad multiple);
            default: three sizes including a non-square one.

    Returns:
        The worst max abs difference seen (at most :data:`PARITY_TOL`).
    """
    spec = spec_for(kind, net)
    net = net.eval()
    m = int(getattr(net, "pad_multiple", 8))
    if parity_sizes is None:
        parity_sizes = [(4 * m, 4 * m), (3 * m, 5 * m), (6 * m, 4 * m)]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    h0, w0 = parity_sizes[0]
    example = sample_inputs(kind, h0, w0, spec=spec)
    names_in = [n for n, _ in spec.inputs]
    names_out = [n for n, _ in spec.outputs]
    dynamic: dict[str, dict[int, str]] = {}
    for n, ch in spec.inputs:
        dynamic[n] = {0: "batch"} if ch is None else {0: "batch", 2: "height", 3: "width"}
    for n, ch in spec.outputs:
        dynamic[n] = {0: "batch"} if ch is None else {0: "batch", 2: "height", 3: "width"}
    with torch.no_grad(), warnings.catch_warnings():
        # The legacy exporter is chosen on purpose (dynamic H/W at opset 17); silence its
        # deprecation notice and the tracer's notes about the input checks (constant at trace).
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", FutureWarning)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", message=".*legacy TorchScript-based ONNX export.*")
        torch.onnx.export(
            net, tuple(torch.from_numpy(example[n]) for n in names_in), str(path),
            input_names=names_in, output_names=names_out, dynamic_axes=dynamic,
            opset_version=OPSET, dynamo=False, do_constant_folding=True,
        )
    try:
        return check_parity(net, kind, path, parity_sizes)
    except Exception:
        path.unlink(missing_ok=True)
        raise


def io_shapes(
    kind: str, net: nn.Module | None = None
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Manifest ``inputs`` / ``outputs`` lists for ``kind`` (``net`` picks the variant)."""
    spec = spec_for(kind, net)

    def shape(ch: int | None, name: str) -> list[Any]:
        if ch is None:
            return ["B", spec.vectors[name]]
        return ["B", ch, "H", "W"]

    ins = [{"name": n, "shape": shape(c, n)} for n, c in spec.inputs]
    outs = [{"name": n, "shape": shape(c, n)} for n, c in spec.outputs]
    return ins, outs


def write_manifest(
    net: nn.Module, kind: str, onnx_path: Path, training: dict[str, Any],
    metrics: dict[str, Any] | None = None, parity: float | None = None,
    onnx_name: str | None = None, extra: dict[str, Any] | None = None,
) -> Path:
    """Write ``<name>.json`` beside ``onnx_path`` per the models contract; returns its path."""
    onnx_path = Path(onnx_path)
    name = onnx_name or onnx_path.stem
    ins, outs = io_shapes(kind, net)
    manifest: dict[str, Any] = {
        "name": name,
        "version": MANIFEST_VERSION,
        "file": onnx_path.name,
        "sha256": sha256_file(onnx_path),
        "inputs": ins,
        "outputs": outs,
        "colour_space": "srgb",
        "pad_multiple": int(getattr(net, "pad_multiple", 8)),
        "parameters": sum(p.numel() for p in net.parameters()),  # frozen ones too
        "training": training,
        "metrics": metrics or {},
        "created": dt.datetime.now(dt.UTC).date().isoformat(),
        "opset": OPSET,
    }
    if parity is not None:
        manifest["onnx_parity_max_abs_diff"] = parity
    if kind == "relight":
        manifest["base"] = getattr(net, "base", "photo")
    if kind == "depth" and (training.get("config") or {}).get("size"):
        # The runtime shrinks larger photos to this side before Z (depth_post.run_depth_model).
        manifest["input_side"] = int(training["config"]["size"])
    if kind == "sun":  # what the runtime needs to read D's logits (runtime.pipeline.sun_look)
        manifest["bins"] = int(net.bins.shape[0])
        manifest["kappa"] = _sun_kappa()
        manifest["input_side"] = int((training.get("config") or {}).get("size") or 128)
    if kind in ("shadow", "shadow_2d") and hasattr(net, "steps"):
        manifest["march_steps"] = int(net.steps)
        manifest["march_step"] = float(net.step)
        manifest["volume_scale"] = float(net.volume_scale)
    if extra:
        manifest.update(extra)
    out = onnx_path.with_suffix(".json")
    out.write_text(json.dumps(manifest, indent=2) + "\n")
    return out


def _sun_kappa() -> float:
    from outcast_core.nets.sun import KAPPA

    return float(KAPPA)


def update_metrics(manifest_path: Path, metrics: dict[str, Any]) -> None:
    """Merge ``metrics`` into an existing manifest (the ONNX file and its sha256 are unchanged)."""
    data = json.loads(Path(manifest_path).read_text())
    data.setdefault("metrics", {}).update(metrics)
    Path(manifest_path).write_text(json.dumps(data, indent=2) + "\n")


ExportFn = Callable[[nn.Module, str, Path], float]
