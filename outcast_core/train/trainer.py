"""The trainer: one loop for every stage, seeded, resumable, with a progress bar of losses.

Stages (``TrainConfig.stage``):

* ``shadow`` / ``shadow_2d``: ``S`` (or the 2D ablation) alone, ``f = w_shadow * f_S``; ``S``
  sees ground-truth depth with probability ``gt_depth_prob`` and ``Z``'s estimate otherwise
  (only when a ``depth_checkpoint`` is given; without one every step uses ground truth).
* ``relight``: ``R``, ``L`` and the critic ``A`` jointly on a frozen ``S`` (no gradient from
  ``R`` into ``S``, as in the paper): ``f = w_refine f_R + w_relight f_L + w_adv f_A``, one
  critic step per ``d_every`` generator steps. The original sun fed to ``S``/``R``/``L`` carries
  noise (``sun_noise_deg``); old shadows and normals use ``Z``'s depth when one is given, the new
  shadow ground-truth depth with probability ``new_shadow_gt_depth_prob``. With a ``change``
  weight, ``L`` also pays :func:`~outcast_core.train.losses.change_loss` on the pixels whose
  sun visibility differs between the two suns.
* ``relight_pix2pix``: the ablation, ``L`` without shadow inputs, same critic (conditioned on
  ``C_o`` and an empty shadow channel).
* ``depth``: ``Z`` with the scale-invariant log loss plus binary cross-entropy on the sky mask.
* ``sun``: ``D`` (:mod:`outcast_core.nets.sun`), the original sun's direction from the photo,
  with the cross-entropy against a von Mises-Fisher kernel about the true sun; ``init_onnx`` may
  name ``models/depth.onnx`` to start its encoder from ``Z``'s.

``f_S``, ``f_R``, ``f_L`` are ``L1 + DSSIM`` (:func:`outcast_core.train.losses.structural_loss`),
our stand-in for the paper's E-LPIPS. Checkpoints (``last.pt``: networks, optimisers, RNG states,
step, wall time) live in ``~/.cache/outcast/runs/<run>/``; a rerun with the same config resumes,
and a new run with ``resume_from`` continues another run's checkpoint (recorded as
``branched_from``).

Under ``torchrun`` the same loop runs on every process with DistributedDataParallel and gives
the result of one process with the same global batch (:mod:`outcast_core.train.distributed`).
"""

from __future__ import annotations

import json
import math
import pickle
import random
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812  (the universal torch idiom)
from torch import nn

from outcast_core.nets import build
from outcast_core.nets.depth import gradient_matching_loss, normal_loss, scale_invariant_log_loss
from outcast_core.nets.geometry_torch import normals_from_depth
from outcast_core.nets.sun import expected_angle_deg, sun_loss
from outcast_core.train import distributed
from outcast_core.train.config import TrainConfig, run_dir
from outcast_core.train.data import PairSampler, Prepared, find_views, load_prepared
from outcast_core.train.losses import (
    change_loss,
    change_weight,
    lsgan_d_loss,
    lsgan_g_loss,
    structural_loss,
)

#: Networks trained by each stage (``critic`` included where there is a GAN term).
STAGE_NETS: dict[str, tuple[str, ...]] = {
    "shadow": ("shadow",),
    "shadow_2d": ("shadow_2d",),
    "relight": ("refine", "relight", "critic"),
    "relight_pix2pix": ("relight_pix2pix", "critic"),
    "depth": ("depth",),
    "sun": ("sun",),
}


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % (2**32))
    torch.manual_seed(seed)


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """Read a checkpoint as tensors and plain data only (``torch.load(weights_only=True)``).

    A checkpoint is a pickle: loaded with ``weights_only=False``, one from elsewhere could run
    any code. Ours hold only state dicts, numbers, strings, lists and dicts.

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is not a checkpoint, is corrupt, or holds other objects.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} not found")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        raise ValueError(
            f"refusing to load checkpoint {path}: it holds objects other than tensors and "
            "plain data (loading them could run code)"
        ) from exc
    except (RuntimeError, EOFError, OSError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"cannot read checkpoint {path}: not a checkpoint, or corrupt "
                         f"({first})") from exc
    if not isinstance(ckpt, dict) or not isinstance(ckpt.get("nets"), dict):
        raise ValueError(f"expected a training checkpoint with 'nets' in {path}, got "
                         f"{type(ckpt).__name__}")
    return ckpt


def load_checkpoint_nets(path: str | Path) -> tuple[dict[str, nn.Module], dict[str, Any]]:
    """Rebuild the networks of a checkpoint (eval mode) and return them with its record."""
    ckpt = load_checkpoint(path)
    nets: dict[str, nn.Module] = {}
    for kind, state in ckpt["nets"].items():
        net = build(kind, **ckpt["net_kwargs"].get(kind, {}))
        net.load_state_dict(state)
        nets[kind] = net.eval()
    return nets, ckpt


def onnx_origin(path: str | Path) -> dict[str, Any]:
    """What a run started from a shipped ONNX model records: its path, SHA-256 and, from the
    model card beside it (``NAME.json``), the steps, wall time and command that trained it."""
    from outcast_core.runtime.io.models import sha256_file

    path = Path(path)
    rec: dict[str, Any] = {"init_onnx": str(path), "sha256": sha256_file(path)}
    card = path.with_suffix(".json")
    if card.exists():
        tr = json.loads(card.read_text()).get("training", {})
        rec.update(step=tr.get("steps"), wall_time_s=tr.get("wall_time_s"),
                   command=tr.get("command", ""))
    return rec


def load_onnx_weights(net: nn.Module, path: str | Path, prefix: str = "") -> None:
    """Copy an exported ONNX model's initialisers into ``net`` by parameter name.

    ``torch.onnx.export`` keeps the state-dict names of parameters it does not fold, so a model
    exported from this network type holds every entry of its state dict. With ``prefix`` only
    the entries whose names start with it are copied (``D``'s encoder from ``Z``'s model:
    ``"unet.enc."``); the rest keep their values. Raises ``ValueError`` when one is missing or
    has another shape (a model of another network or width).
    """
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(path))
    weights = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    full = net.state_dict()
    state = {k: v for k, v in full.items() if k.startswith(prefix)}
    missing = [k for k in state if k not in weights]
    wrong = [k for k in state if k in weights and tuple(weights[k].shape) != tuple(state[k].shape)]
    if missing or wrong:
        raise ValueError(
            f"expected {path} to hold the network's {len(state)} tensors, got "
            f"{len(missing)} missing ({missing[:3]}) and {len(wrong)} of another shape "
            f"({wrong[:3]})"
        )
    full.update({k: torch.from_numpy(weights[k].copy()) for k in state})
    net.load_state_dict(full)


def _is_depth_model(path: str | Path) -> bool:
    """Whether an ONNX file is ``Z`` (its card says so, else its outputs do)."""
    import onnx

    card = Path(path).with_suffix(".json")
    if card.exists():
        return json.loads(card.read_text()).get("name") == "depth"
    return [o.name for o in onnx.load(str(path)).graph.output] == ["depth", "sky"]


def _postprocessed(
    depth: torch.Tensor, sky: torch.Tensor, image: torch.Tensor,
    focal: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`~outcast_core.runtime.pipeline.depth_post.postprocess_z` on each item of a batch;
    given the
    focal lengths (``B x 1``, pixels), with the ground snapped to its plane as the app does."""
    from outcast_core.runtime.geometry.camera import Camera
    from outcast_core.runtime.pipeline.depth_post import postprocess_z

    ds, ss = [], []
    h, w = depth.shape[-2:]
    dev = depth.device
    depth, sky, image = depth.cpu(), sky.cpu(), image.cpu()
    for b in range(depth.shape[0]):
        cam = None if focal is None else Camera(h, w, float(focal[b].reshape(-1)[0]))
        d, s = postprocess_z(depth[b, 0].numpy(), sky[b, 0].numpy(),
                             image[b].permute(1, 2, 0).numpy(), cam)
        ds.append(torch.from_numpy(np.where(s, 0.0, d).astype(np.float32)))
        ss.append(torch.from_numpy(s.astype(np.float32)))
    return torch.stack(ds)[:, None].to(dev), torch.stack(ss)[:, None].to(dev)


def light_ratios(
    image: torch.Tensor, shadow_old: torch.Tensor, normals: torch.Tensor
) -> torch.Tensor:
    """Per-item sun/ambient ratio ``B x 3`` as the app estimates it (no gradient).

    :func:`~outcast_core.runtime.pipeline.relight.estimate_light` on the photo, the refined original
    shadow and the sky of the geometry (pixels with zero normals).
    """
    from outcast_core.runtime.pipeline.relight import estimate_light_on_surfaces

    out = [
        estimate_light_on_surfaces(image[b].detach().cpu().permute(1, 2, 0).numpy(),
                                   shadow_old[b, 0].detach().cpu().numpy(),
                                   normals[b].detach().cpu().permute(1, 2, 0).numpy()).ratio
        for b in range(image.shape[0])
    ]
    return torch.from_numpy(np.stack(out).astype(np.float32)).to(image.device)


def photo_old_shadow(image: torch.Tensor, prior: torch.Tensor, depth: torch.Tensor,
                     normals: torch.Tensor, sun: torch.Tensor) -> torch.Tensor:
    """``B x 1 x H x W`` old shadow as the app's session makes it with ``refine="photo"``
    (no gradient): the photo's shadow probability gated by ``S`` at the original sun
    (``prior``), visibility times the lit level; the sky is where ``depth`` is 0."""
    from outcast_core.runtime.geometry.camera import cosine_term
    from outcast_core.runtime.pipeline.photo_shadows import (
        original_shadow_from_photo,
        photo_shadow_probability,
    )

    out = []
    for b in range(image.shape[0]):
        img = image[b].detach().cpu().permute(1, 2, 0).numpy()
        sky = depth[b, 0].detach().cpu().numpy() <= 0
        prob = photo_shadow_probability(img, sky, prior[b, 0].detach().cpu().numpy())
        cos = cosine_term(normals[b].detach().cpu().permute(1, 2, 0).numpy(),
                          sun[b].detach().cpu().numpy())
        out.append(original_shadow_from_photo(prob, cos, sky))
    return torch.from_numpy(np.stack(out)[:, None].astype(np.float32)).to(image.device)


class _ShadowLogits(nn.Module):
    """``S``'s :meth:`logits` as ``forward``, so DistributedDataParallel (which hooks
    ``forward``) can wrap it; its parameters are the wrapped network's."""

    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, *args: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.net.logits(*args)


class Trainer:
    """Runs one :class:`TrainConfig` to completion (or to its time limit), resuming if possible.

    Under ``torchrun`` every process builds one (same config, same seed): ``cfg.batch`` is the
    global batch, of which each rank trains on its part; rank 0 writes checkpoints and logs.

    Args:
        cfg: the run's configuration.
        views: prepared views (loaded from ``cfg.data`` when omitted; tests pass tiny ones).
        progress: show a tqdm bar (rank 0 only).
        command: the command line, recorded in checkpoints.
        dist: the process's place in a distributed run (default: :func:`distributed.setup`,
            which joins ``torchrun``'s process group, or is one process without it).
    """

    def __init__(
        self, cfg: TrainConfig, views: list[Prepared] | None = None, progress: bool = True,
        command: str = "", dist: distributed.DistContext | None = None,
    ) -> None:
        self.cfg = cfg
        self.command = command
        torch.set_num_threads(max(1, cfg.threads))
        self.dist = dist if dist is not None else distributed.setup(cfg.device)
        self.dist.check_batch(cfg.batch)
        self.device = self.dist.device
        self.progress = progress and self.dist.is_main
        seed_everything(cfg.seed)
        self.dir = run_dir(cfg.run)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._loaded: set[Path] = set()
        self._reload = views is None and cfg.reload_every > 0
        # Views loaded from each data folder (recorded in checkpoints and model cards).
        self.views_by_folder: dict[str, int] = {}
        if views is None:
            views = self._load_new_views(first=True)
        self.sampler = PairSampler(
            views, np.random.default_rng(cfg.seed), cfg.exposure_stops, cfg.saturation,
            cfg.gamma, cfg.flip, cfg.sun_noise_deg, cfg.cloud_prob, cfg.zoom_prob,
            cfg.zoom_max, cfg.degrade_prob, cfg.stain_prob,
        )
        self.net_kwargs: dict[str, dict[str, Any]] = {}
        self.nets: dict[str, nn.Module] = {}
        for kind in STAGE_NETS[cfg.stage]:
            kw = dict(cfg.net) if kind == STAGE_NETS[cfg.stage][0] else {}
            if kind == "relight" and cfg.relight_base != "photo":
                kw["base"] = cfg.relight_base
            self.net_kwargs[kind] = kw
            self.nets[kind] = build(kind, **kw).to(self.device).train()
        gen = [p for k, n in self.nets.items() if k != "critic" for p in n.parameters()]
        betas = (0.5, 0.999) if "critic" in self.nets else (0.9, 0.999)  # GAN: pix2pix's beta1
        self.opt_g = torch.optim.Adam(gen, lr=cfg.lr, betas=betas)
        self.opt_d = (
            torch.optim.Adam(self.nets["critic"].parameters(), lr=cfg.lr, betas=(0.5, 0.999))
            if "critic" in self.nets else None
        )
        self.depth_net = None
        if cfg.depth_checkpoint and cfg.depth_checkpoint.endswith(".onnx"):
            # A shipped Z whose training checkpoint is gone: its ONNX weights, default widths.
            self.depth_net = build("depth")
            load_onnx_weights(self.depth_net, cfg.depth_checkpoint)
            self.depth_net = self.depth_net.eval().to(self.device)
        elif cfg.depth_checkpoint:
            self.depth_net = load_checkpoint_nets(cfg.depth_checkpoint)[0]["depth"].to(
                self.device)
        self.shadow_net = None
        if cfg.shadow_checkpoint:
            nets, _ = load_checkpoint_nets(cfg.shadow_checkpoint)
            self.shadow_net = nets.get("shadow") or nets.get("shadow_2d")
            if self.shadow_net is None:
                raise ValueError(f"expected a shadow network in {cfg.shadow_checkpoint}, got none")
            self.shadow_net.to(self.device)
            for p in self.shadow_net.parameters():
                p.requires_grad_(False)
        self.step = 0
        self.lr_history: list[tuple[int, float]] = []
        self.wall_time_s = 0.0
        self.history: list[dict[str, float]] = []
        self._stop = False
        self._resume()
        if not self.lr_history or (not cfg.lr_final and self.lr_history[-1][1] != cfg.lr):
            self.lr_history.append((self.step, cfg.lr))
        # What the steps call: the networks themselves in one process; under torchrun the same
        # networks wrapped in DistributedDataParallel (after the resume: DDP's start-up
        # broadcast then copies nothing new). The critic's wrapper serves its own step only;
        # the generator's adversarial term calls the bare critic with its parameters frozen.
        self._ddp: dict[str, nn.Module] = {}
        if self.dist.enabled:
            for kind, net in self.nets.items():
                self._ddp[kind] = self.dist.wrap(
                    _ShadowLogits(net) if kind in ("shadow", "shadow_2d") else net)

    # -- checkpoints -------------------------------------------------------------------------
    def _load_new_views(self, first: bool = False) -> list[Prepared]:
        """The views of ``data`` (at most ``max_views``) and ``extra_data`` not loaded yet,
        counted per folder. ``data`` must hold some on the ``first`` call."""
        out: list[Prepared] = []
        folders = [(self.cfg.data, self.cfg.max_views)] + [(d, 0) for d in self.cfg.extra_data]
        # Under torchrun rank 0 lists the folders, so every rank loads the same views even
        # while a data set is still being written.
        listings: list[list[Path] | None] = [None] * len(folders)
        if self.dist.enabled:
            listings = self.dist.on_main(lambda: [find_views(f) for f, _ in folders])
        for (folder, most), paths in zip(folders, listings, strict=True):
            got = load_prepared(folder, self.cfg.size, most, skip=self._loaded,
                                allow_empty=not first or folder != self.cfg.data, paths=paths)
            self.views_by_folder[folder] = self.views_by_folder.get(folder, 0) + len(got)
            out += got
        return out

    @property
    def checkpoint_path(self) -> Path:
        return self.dir / "last.pt"

    def _resume_checkpoint(self) -> tuple[Path, dict[str, Any] | None]:
        """The checkpoint to resume from (this run's, else ``resume_from``'s) and its content,
        or ``None`` when the run starts afresh."""
        path = self.checkpoint_path
        if not path.exists() and self.cfg.resume_from:
            path = run_dir(self.cfg.resume_from) / "last.pt"
            if not path.exists():
                raise FileNotFoundError(
                    f"expected a checkpoint of run {self.cfg.resume_from!r} to resume from at "
                    f"{path}, found none"
                )
        return path, load_checkpoint(path) if path.exists() else None

    def _resume(self) -> None:
        self.branched_from: dict[str, Any] | None = None
        # Under torchrun rank 0 reads the checkpoint it wrote and hands it to every rank (the
        # other machines of a multi-node run need no shared run folder).
        path, ckpt = (self.dist.on_main(self._resume_checkpoint) if self.dist.enabled
                      else self._resume_checkpoint())
        if ckpt is None:
            if self.cfg.init_onnx:
                first = STAGE_NETS[self.cfg.stage][0]
                # D starts from a shipped D, or its encoder from Z's (``unet.enc.*``).
                prefix = ("unet.enc." if self.cfg.stage == "sun"
                          and _is_depth_model(self.cfg.init_onnx) else "")
                load_onnx_weights(self.nets[first], self.cfg.init_onnx, prefix)
                self.branched_from = onnx_origin(self.cfg.init_onnx)
            if self.cfg.init_relight_onnx:  # never with init_onnx (TrainConfig)
                load_onnx_weights(self.nets["relight"], self.cfg.init_relight_onnx)
                self.branched_from = onnx_origin(self.cfg.init_relight_onnx)
            return
        if path != self.checkpoint_path:
            self.branched_from = {"run": self.cfg.resume_from, "step": int(ckpt["step"]),
                                  "wall_time_s": round(float(ckpt["wall_time_s"]), 1),
                                  "config": ckpt["config"], "command": ckpt.get("command", "")}
        else:
            self.branched_from = ckpt.get("branched_from")
        if ckpt["config"]["stage"] != self.cfg.stage:
            raise ValueError(
                f"expected a checkpoint of stage {self.cfg.stage}, got {ckpt['config']['stage']}"
            )
        for k in self.nets:
            saved = ckpt.get("net_kwargs", {}).get(k, {})
            if saved != self.net_kwargs[k] and path == self.checkpoint_path:
                raise ValueError(
                    f"expected {k} built as in its checkpoint {path} ({saved}), got "
                    f"{self.net_kwargs[k]}; start a new run with resume_from to change it"
                )
        for k, net in self.nets.items():
            net.load_state_dict(ckpt["nets"][k])
        self.opt_g.load_state_dict(ckpt["opt_g"])
        if self.opt_d is not None:
            self.opt_d.load_state_dict(ckpt["opt_d"])
        # The config's learning rate wins over the saved one, so a run can be resumed with a
        # lower rate (a manual step decay; recorded in the checkpoint's lr_history).
        for opt in (self.opt_g, self.opt_d):
            for group in opt.param_groups if opt is not None else ():
                group["lr"] = self.cfg.lr
        self.lr_history = ckpt.get("lr_history") or [(0, float(ckpt["config"]["lr"]))]
        old = ckpt["config"]
        if (old.get("lr_final", 0.0), old["steps"]) != (self.cfg.lr_final, self.cfg.steps) \
                and self.cfg.lr_final:
            # A schedule set or changed on resume: record where it took over.
            self.lr_history.append((int(ckpt["step"]), self.lr_at(int(ckpt["step"]))))
        self.sampler.rng.bit_generator.state = ckpt["numpy_rng"]
        torch.set_rng_state(ckpt["torch_rng"])
        self.step = int(ckpt["step"])
        self.wall_time_s = float(ckpt["wall_time_s"])
        self.history = ckpt.get("history", [])

    def save(self) -> Path:
        """Write ``last.pt`` atomically (rank 0 only; the others return its path)."""
        if not self.dist.is_main:
            return self.checkpoint_path
        ckpt = {
            "config": self.cfg.to_dict(),
            "stage": self.cfg.stage,
            "nets": {k: n.state_dict() for k, n in self.nets.items()},
            "net_kwargs": self.net_kwargs,
            "opt_g": self.opt_g.state_dict(),
            "opt_d": self.opt_d.state_dict() if self.opt_d is not None else None,
            "numpy_rng": self.sampler.rng.bit_generator.state,
            "torch_rng": torch.get_rng_state(),
            "step": self.step,
            "wall_time_s": self.wall_time_s,
            "history": self.history,
            "views": len(self.sampler.views),
            "views_by_folder": self.views_by_folder,
            "command": self.command,
            "lr_history": self.lr_history,
            "branched_from": self.branched_from,
            "processes": self.dist.world,
        }
        tmp = self.checkpoint_path.with_suffix(".tmp")
        torch.save(ckpt, tmp)
        tmp.replace(self.checkpoint_path)
        return self.checkpoint_path

    # -- one step ----------------------------------------------------------------------------
    def _tensors(self) -> dict[str, torch.Tensor]:
        """This process's part of the step's global batch, as tensors on its device.

        Every rank draws the whole global batch from the same generator (the draws of one
        process) and makes its own slice of it.
        """
        part = self.dist.part(self.cfg.batch)
        b = self.sampler.batch(self.cfg.batch) if part is None else \
            self.sampler.batch(self.cfg.batch, keep=part)
        return {k: torch.from_numpy(v).to(self.device) for k, v in b.items()}

    def _forward(self, kind: str) -> Any:
        """What a step calls to run net ``kind``: the network (``S``: its ``logits``), or under
        torchrun its DistributedDataParallel wrapper, whose backward averages the gradients."""
        if kind in self._ddp:
            return self._ddp[kind]
        net = self.nets[kind]
        return net.logits if kind in ("shadow", "shadow_2d") else net

    def _global_count(self, count: torch.Tensor) -> torch.Tensor:
        """The normaliser of a loss divided by a count over the batch: the count over the whole
        global batch (at least 1) over the number of ranks, so that the ranks' mean loss and
        their averaged gradients are the single-process ones."""
        return self.dist.global_sum(count).clamp_min(1.0) / self.dist.world

    def _estimated_geometry(
        self, t: dict[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``Z``'s depth (sky -> 0) and the normals from it, or the ground truth without ``Z``.

        With ``postprocess_depth`` the estimate goes through the app's post-processing first
        (with ``snap_ground``, including the ground plane).
        """
        if self.depth_net is None:
            return t["depth"], t["normals"]
        with torch.no_grad():
            depth, sky = self.depth_net(t["image"])
            if self.cfg.postprocess_depth:
                depth, sky = _postprocessed(depth, sky, t["image"],
                                            t["focal"] if self.cfg.snap_ground else None)
            depth = torch.where(sky > 0.5, torch.zeros_like(depth), depth)
            return depth, normals_from_depth(depth, t["focal"])

    def _step_shadow(self, t: dict[str, torch.Tensor]) -> dict[str, float]:
        logits = self._forward(STAGE_NETS[self.cfg.stage][0])
        depth, normals = t["depth"], t["normals"]
        if self.depth_net is not None and self.sampler.rng.random() >= self.cfg.gt_depth_prob:
            depth, normals = self._estimated_geometry(t)
        logit, cos = logits(t["image"], depth, normals, t["sun_new"], t["focal"])
        pred = torch.sigmoid(logit) * cos
        vis = t["visibility_new"]
        # The target is reachable: the network's own cosine times the true visibility.
        f_s = structural_loss(pred, cos * vis)
        # Cross-entropy on visibility where the surface faces the sun: a gradient that does not
        # vanish when the sigmoid saturates on the wrong side.
        wgt = (cos > 0.02).to(logit.dtype)
        bce = (F.binary_cross_entropy_with_logits(logit, vis, reduction="none") * wgt).sum() \
            / self._global_count(wgt.sum())
        loss = self.cfg.weights["shadow"] * (f_s + 0.1 * bce)
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        mse = F.mse_loss(pred, t["shadow_new"])
        return {"loss": loss.item(), "f_S": f_s.item(), "bce": bce.item(), "mse": mse.item()}

    def _critic_step(self, real: torch.Tensor, fake: torch.Tensor, t: dict[str, torch.Tensor],
                     s_n: torch.Tensor) -> float:
        if self.opt_d is None:
            raise RuntimeError("this stage has no critic")
        critic = self._forward("critic")
        d_loss = lsgan_d_loss(critic(real, t["image"], s_n), critic(fake.detach(), t["image"], s_n))
        self.opt_d.zero_grad(set_to_none=True)
        d_loss.backward()
        self.opt_d.step()
        return d_loss.item()

    def _step_relight(self, t: dict[str, torch.Tensor]) -> dict[str, float]:
        w = self.cfg.weights
        critic = self.nets["critic"]
        sun_o = t["sun_old_noisy"]
        depth_o, normals_o = self._estimated_geometry(t)
        logs: dict[str, float] = {}
        if self.cfg.stage == "relight":
            if self.shadow_net is None:
                raise RuntimeError("the relight stage needs a shadow_checkpoint")
            depth_n, normals_n = depth_o, normals_o
            p_gt = self.cfg.new_shadow_gt_depth_prob
            if p_gt > 0 and self.sampler.rng.random() < p_gt:
                depth_n, normals_n = t["depth"], t["normals"]
            with torch.no_grad():  # no gradient from R into S
                s_o_raw = self.shadow_net(t["image"], depth_o, normals_o, sun_o, t["focal"])
                s_n = self.shadow_net(t["image"], depth_n, normals_n, t["sun_new"], t["focal"])
            if self.cfg.relight_old_shadow == "photo":
                s_o = photo_old_shadow(t["image"], s_o_raw, depth_o, normals_o, sun_o)
            else:
                s_o = self._forward("refine")(s_o_raw, t["image"], sun_o)
            extra = ()
            if self.cfg.relight_base == "physics":
                extra = (light_ratios(t["image"], s_o.detach(), normals_o),)
            c_n = self._forward("relight")(
                t["image"], s_o, s_n, normals_o, sun_o, t["sun_new"], t["view_dirs"], *extra
            )
            f_r = structural_loss(s_o, t["shadow_old"])
            logs["f_R"] = f_r.item()
            # R is not trained when L sees the photometric S_o (nothing of R reaches it).
            loss_r = w["refine"] * f_r if self.cfg.relight_old_shadow == "refine" else 0.0
        else:
            s_n = torch.zeros_like(t["shadow_new"])
            c_n = self._forward("relight_pix2pix")(
                t["image"], normals_o, sun_o, t["sun_new"], t["view_dirs"]
            )
            loss_r = torch.zeros((), device=self.device)
        f_l = structural_loss(c_n, t["target"])
        w_change = w.get("change", 0.0)
        if w_change:
            vis_o, vis_n = t["visibility_old"], t["visibility_new"]
            f_c = change_loss(c_n, t["target"], vis_o, vis_n, weight_sum=self._global_count(
                change_weight(vis_o, vis_n).sum()) if self.dist.enabled else None)
            logs["f_change"] = f_c.item()
            loss_r = loss_r + w_change * f_c
        for p in critic.parameters():
            p.requires_grad_(False)
        f_a = lsgan_g_loss(critic(c_n, t["image"], s_n))
        for p in critic.parameters():
            p.requires_grad_(True)
        loss = loss_r + w["relight"] * f_l + w["adv"] * f_a
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        logs.update({"loss": loss.item(), "f_L": f_l.item(), "f_A": f_a.item(),
                     "mse": F.mse_loss(c_n, t["target"]).item()})
        if self.step % max(1, self.cfg.d_every) == 0:
            logs["f_D"] = self._critic_step(t["target"], c_n, t, s_n)
        return logs

    def _step_depth(self, t: dict[str, torch.Tensor]) -> dict[str, float]:
        depth, sky = self._forward("depth")(t["image"])
        valid = torch.isfinite(t["depth"]) & (t["depth"] > 0)
        f_z = scale_invariant_log_loss(depth, t["depth"], valid)
        f_sky = F.binary_cross_entropy(sky.clamp(1e-6, 1 - 1e-6), (~valid).to(sky.dtype))
        loss = f_z + f_sky
        logs: dict[str, float] = {"silog": f_z.item(), "sky_bce": f_sky.item()}
        w_grad = self.cfg.weights.get("depth_grad", 0.0)
        if w_grad > 0:
            f_grad = gradient_matching_loss(depth, t["depth"], valid)
            loss = loss + w_grad * f_grad
            logs["grad"] = f_grad.item()
        w_normal = self.cfg.weights.get("depth_normal", 0.0)
        if w_normal > 0:
            # Both sides through the same function (the runtime's), so a zoomed crop's off-centre
            # rays bend both alike; the prediction only where the truth has a surface.
            true_n = normals_from_depth(t["depth"], t["focal"])
            pred_n = normals_from_depth(torch.where(valid, depth, torch.zeros_like(depth)),
                                        t["focal"])
            f_normal = normal_loss(pred_n, true_n, valid)
            loss = loss + w_normal * f_normal
            logs["normal"] = f_normal.item()
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        return {"loss": loss.item(), **logs}

    def _step_sun(self, t: dict[str, torch.Tensor]) -> dict[str, float]:
        net = self.nets["sun"]
        logits = self._forward("sun")(t["image"])
        loss = sun_loss(logits, t["sun_old"], net.bins)
        self.opt_g.zero_grad(set_to_none=True)
        loss.backward()
        self.opt_g.step()
        angle = expected_angle_deg(logits.detach(), t["sun_old"], net.bins)
        return {"loss": loss.item(), "angle": float(angle.median())}

    def lr_at(self, step: int) -> float:
        """The learning rate of optimiser step ``step`` (constant, or cosine to ``lr_final``)."""
        cfg = self.cfg
        if not cfg.lr_final:
            return cfg.lr
        t = min(step / cfg.steps, 1.0)
        return cfg.lr_final + 0.5 * (cfg.lr - cfg.lr_final) * (1.0 + math.cos(math.pi * t))

    def train_step(self) -> dict[str, float]:
        """Draw one batch and take one optimiser step; returns the step's losses (under
        torchrun averaged over the ranks: the global batch's)."""
        return self.dist.mean_logs(self._train_step())

    def _train_step(self) -> dict[str, float]:
        if self.cfg.lr_final:
            lr = self.lr_at(self.step)
            for opt in (self.opt_g, self.opt_d):
                for group in opt.param_groups if opt is not None else ():
                    group["lr"] = lr
        t = self._tensors()
        if self.cfg.stage in ("shadow", "shadow_2d"):
            return self._step_shadow(t)
        if self.cfg.stage == "depth":
            return self._step_depth(t)
        if self.cfg.stage == "sun":
            return self._step_sun(t)
        return self._step_relight(t)

    # -- the loop ----------------------------------------------------------------------------
    def fit(self) -> dict[str, Any]:
        """Train until ``cfg.steps`` (or the time limit / SIGTERM); checkpoint on the way out."""
        from tqdm import tqdm

        old = signal.getsignal(signal.SIGTERM)

        def _on_term(signum: int, frame: Any) -> None:
            self._stop = True

        try:
            signal.signal(signal.SIGTERM, _on_term)
        except ValueError:  # not the main thread
            old = None
        start = time.monotonic()
        base_wall = self.wall_time_s
        bar = tqdm(total=self.cfg.steps, initial=self.step, disable=not self.progress,
                   dynamic_ncols=True, mininterval=5.0)
        ema: dict[str, float] = {}
        log = open(self.dir / "log.jsonl", "a") if self.dist.is_main else None  # noqa: SIM115
        out_of_time = False
        try:
            # Under torchrun every rank stops at the same step (SIGTERM or the time limit on
            # any of them), so none is left waiting in a collective.
            while self.step < self.cfg.steps and not self.dist.any(self._stop or out_of_time):
                for net in self.nets.values():
                    net.train()
                logs = self.train_step()
                self.step += 1
                self.wall_time_s = base_wall + time.monotonic() - start
                for k, v in logs.items():
                    ema[k] = v if k not in ema else 0.98 * ema[k] + 0.02 * v
                if not all(math.isfinite(v) for v in logs.values()):
                    raise RuntimeError(f"non-finite loss at step {self.step}: {logs}")
                bar.update(1)
                if self.step % 25 == 0:
                    bar.set_postfix({k: f"{v:.4f}" for k, v in ema.items()})
                    rec = {"step": self.step, "wall_time_s": round(self.wall_time_s, 1), **ema}
                    self.history.append(rec)
                    if log is not None:
                        log.write(json.dumps(rec) + "\n")
                        log.flush()
                if self.step % self.cfg.checkpoint_every == 0:
                    self.save()
                if self._reload and self.step % self.cfg.reload_every == 0:
                    self.sampler.views += self._load_new_views()
                limit = self.cfg.time_limit_s
                out_of_time = bool(limit) and time.monotonic() - start >= limit
        finally:
            bar.close()
            if log is not None:
                log.close()
            self.save()
            if old is not None:
                signal.signal(signal.SIGTERM, old)
        self.dist.barrier()  # the checkpoint is written before any rank goes on
        return {"step": self.step, "wall_time_s": self.wall_time_s, "losses": ema,
                "checkpoint": str(self.checkpoint_path)}
