"""Export the networks of a training checkpoint with their training record."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from outcast_core.export.onnx_export import SPECS, export_onnx, write_manifest
from outcast_core.train.config import run_dir
from outcast_core.train.trainer import load_checkpoint_nets


def resolve_checkpoint(ref: str | Path) -> Path:
    """A checkpoint path, or the ``last.pt`` of the run named ``ref``."""
    p = Path(ref)
    if p.is_file():
        return p
    candidate = run_dir(str(ref)) / "last.pt"
    if candidate.is_file():
        return candidate
    raise ValueError(f"expected a checkpoint file or a run name, got {ref}")


def data_record(data_dir: str) -> dict[str, Any]:
    """What the data folder says about itself (its manifest, if it has one)."""
    for name in ("dataset.json", "manifest.json", "meta.json"):
        p = Path(data_dir) / name
        if p.is_file():
            try:
                return json.loads(p.read_text())
            except json.JSONDecodeError:
                return {}
    return {}


def training_record(ckpt: dict[str, Any], data_seed: int | None) -> dict[str, Any]:
    cfg = ckpt["config"]
    rec = data_record(cfg["data"])
    seed = data_seed if data_seed is not None else rec.get("seed")
    hist = ckpt.get("history") or [{}]
    return {
        "config": cfg,
        "data_seed": seed,
        "data_set": cfg["data"],
        "views": ckpt.get("views"),
        "steps": ckpt["step"],
        "wall_time_s": round(float(ckpt["wall_time_s"]), 1),
        "lr_schedule": ckpt.get("lr_history", []),
        "loss": {k: round(v, 5) for k, v in hist[-1].items() if k not in ("step", "wall_time_s")},
        "loss_replacing_elpips": (
            "none needed: Z is trained with a scale-invariant log loss and sky cross-entropy"
            if cfg["stage"] == "depth"
            else "none needed: D is trained with a cross-entropy over sun directions"
            if cfg["stage"] == "sun"
            else "L1 + (1 - SSIM) / 2 (E-LPIPS backbones cannot be downloaded)"
        ),
        "data_record": rec,
        "extra_data": [
            {"data_set": d, "data_record": data_record(d),
             "views_loaded": (ckpt.get("views_by_folder") or {}).get(d)}
            for d in cfg.get("extra_data", [])
        ],
        "command": ckpt.get("command") or f"outcast train <config of run {cfg['run']}>",
        "branched_from": _branch(ckpt.get("branched_from")),
    }


def _branch(rec: dict[str, Any] | None) -> dict[str, Any] | None:
    """Where a ``resume_from`` run branched off: run, step, wall time and that run's command."""
    if not rec:
        return None
    if rec.get("init_onnx"):
        return {k: rec.get(k) for k in ("init_onnx", "sha256", "step", "wall_time_s", "command")}
    out = {k: rec.get(k) for k in ("run", "step", "wall_time_s", "command")}
    out["threads"] = (rec.get("config") or {}).get("threads")
    return out


def export_checkpoint(
    ref: str | Path, out: Path, data_seed: int | None = None,
    kinds: tuple[str, ...] | None = None,
) -> list[Path]:
    """Export every exportable network of a checkpoint into ``out``; returns the ONNX paths.

    A relight-stage run that fed ``L`` the photometric old shadow (``relight_old_shadow =
    "photo"``) never trained ``R``: its ``refine`` is left out, so the shipped one stays."""
    path = resolve_checkpoint(ref)
    nets, ckpt = load_checkpoint_nets(path)
    untrained = {"refine"} if ckpt.get("config", {}).get("relight_old_shadow") == "photo" else set()
    if kinds is not None and untrained & set(kinds):
        raise ValueError(f"expected networks this run trained, got {sorted(untrained & set(kinds))}"
                         f" (not trained: relight_old_shadow = \"photo\")")
    written = []
    for kind, net in nets.items():
        if kind not in SPECS or (kinds is not None and kind not in kinds) or kind in untrained:
            continue
        onnx_path = Path(out) / f"{kind}.onnx"
        parity = export_onnx(net, kind, onnx_path)
        write_manifest(net, kind, onnx_path, training_record(ckpt, data_seed), parity=parity)
        written.append(onnx_path)
    return written
