"""Run configuration: one JSON or TOML file per training run.

A config names the run (checkpoints go to ``~/.cache/outcast/runs/<run>/``), the stage
(``shadow``, ``shadow_2d``, ``relight``, ``relight_pix2pix``, ``depth``), the data and every
hyper-parameter. Unknown keys are an error so a typo never silently trains the default.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

STAGES = ("shadow", "shadow_2d", "relight", "relight_pix2pix", "depth", "sun")


@dataclass
class TrainConfig:
    """Every setting of one training run (see ``configs/*.toml`` in this package for examples).

    Attributes:
        run: run name (checkpoint folder).
        stage: what is trained (one of :data:`STAGES`). ``relight`` trains ``R``, ``L`` and the
            critic ``A`` jointly on top of a frozen ``S`` (``shadow_checkpoint``);
            ``relight_pix2pix`` trains the ablation with the same critic; ``sun`` trains ``D``
            (the sun's direction from the photo, :mod:`outcast_core.nets.sun`).
        data: training data folder (views written by ``outcast data make``).
        extra_data: more data folders whose views are all added to ``data``'s (e.g. a set of
            one-sun views made for ``Z`` only, or of one scene kind); ``max_views`` applies to
            ``data`` alone. Each view is drawn with equal probability, whatever its folder.
        size: working resolution (longer side, pixels) the views are resized to.
        batch: images per step.
        steps: total optimiser steps of the generator(s).
        lr: Adam learning rate for generator(s) and critic (at step 0).
        lr_final: when > 0, the rate follows a cosine from ``lr`` at step 0 to ``lr_final`` at
            ``steps`` (recomputed from the step, so resuming keeps the schedule); 0 = constant.
        seed: seed of torch, numpy and the sampler.
        net: keyword arguments of the trained network (e.g. ``steps``, ``volume_scale``).
        weights: loss weights (paper: shadow 10, refine 2, relight 10, adversarial 0.1; ours adds
            ``change``, default 0: an L1 term of ``L`` on the pixels whose sun visibility differs
            between the two suns, so ``L`` cannot score well by learning only the global light).
        d_every: generator steps per critic step (paper: 5).
        gt_depth_prob: probability that ``S`` sees ground-truth depth rather than ``Z``'s
            estimate (paper: 0.8; 1.0 when no ``depth_checkpoint`` is given).
        depth_checkpoint: trained ``Z`` checkpoint used for estimated depth (a run's
            ``last.pt``, or a shipped ``depth.onnx`` whose checkpoint is gone), or empty.
        shadow_checkpoint: trained ``S`` checkpoint (required by ``relight``).
        new_shadow_gt_depth_prob: ``relight`` stage: probability that the new shadow ``S_n`` fed
            to ``L`` comes from ground-truth depth rather than ``Z``'s (old shadows and normals
            always use ``Z``'s, as in the paper); 0 = always ``Z``'s.
        relight_base: ``relight`` stage: what ``L``'s residual is added to, ``photo`` (the
            paper) or ``physics`` (the shading-ratio relighting, with the light ratio estimated
            from ``C_o`` and ``R``'s ``S_o`` as the app does; see
            :class:`outcast_core.nets.relight.RelightNet`).
        relight_old_shadow: ``relight`` stage: the old shadow ``S_o`` fed to ``L``: ``refine``
            (``R``'s refinement of ``S``, trained jointly: the paper) or ``photo`` (the app's
            photometric stage on the input photo, gated by ``S`` at the original sun:
            :func:`outcast_core.runtime.pipeline.photo_shadows.photo_shadow_probability` and
            :func:`~outcast_core.runtime.pipeline.photo_shadows.original_shadow_from_photo`,
            what the session feeds ``L`` since ``refine="photo"`` became its default; ``R`` is
            then not trained). With ``photo``, ``L`` sees dark materials the photometric stage
            calls shadow, as it does on real photos.
        init_relight_onnx: ``relight`` stage: when this run has no checkpoint yet, start ``L``
            from a shipped ``relight.onnx`` (its training checkpoint gone).
        postprocess_depth: pass ``Z``'s estimates through the app's post-processing
            (:func:`outcast_core.runtime.pipeline.depth_post.postprocess_z`: sky prior, guided
            smoothing)
            before they feed ``S``, ``R`` and ``L``, so training sees what the app computes.
        snap_ground: with ``postprocess_depth``, also snap the estimate's ground to its plane
            (:func:`outcast_core.runtime.pipeline.depth_post.snap_ground`, as the app does since
            2026-11-22); off by default so that earlier configs train as they did.
        resume_from: when this run has no checkpoint yet, continue the named run's checkpoint
            (networks, optimisers, step, wall time) under this config, e.g. to train longer
            with a changed loss; the checkpoint records where it branched.
        init_onnx: when this run has no checkpoint yet, start the stage's network from the
            weights of a shipped ONNX model (e.g. ``models/depth.onnx``: its initialisers carry
            the network's parameter names); optimiser, step and schedule start afresh. For
            continuing a model whose training checkpoint is gone. The ``sun`` stage may name
            ``models/depth.onnx``: ``D``'s encoder then starts from ``Z``'s.
        sun_noise_deg: std of the angular noise added to the original sun (user alignment).
        cloud_prob: probability of painting random clouds into the sky of a training pair (the
            synthetic skies are cloudless; see :func:`outcast_core.train.data.add_clouds`).
        zoom_prob: probability of a random zoom of a training pair (depth stage only; see
            :func:`outcast_core.train.data.zoom_crop`).
        zoom_max: the largest zoom factor (uniform in ``[1, zoom_max]``).
        degrade_prob: probability that a pair's input photo gets a camera's flaws (white
            balance, blur, noise, JPEG: :func:`outcast_core.train.data.degrade_photo`); the
            depth, shadow and sun stages only (a relighting target must stay clean).
        stain_prob: probability that a pair's input photo gets dark stains and fine albedo
            texture that no geometry casts (:func:`outcast_core.train.data.stain_photo`); the
            depth, shadow and sun stages only.
        exposure_stops: range of the random exposure (both images of a pair alike).
        saturation: range of the random saturation factor.
        gamma: range of the random gamma.
        flip: random horizontal flips (sun and normals mirrored).
        threads: torch intra-op threads.
        checkpoint_every: steps between checkpoints.
        time_limit_s: stop (with a checkpoint) after this much wall time in this process; 0 = none.
        max_views: use at most this many views of the data folder (0 = all).
        reload_every: every this many steps, add views that appeared in the data folder since
            the start (training while the data set is still being generated); 0 = never.
        device: ``auto`` (CUDA when available, else the CPU), ``cpu``, ``cuda`` (under
            ``torchrun``: ``cuda:LOCAL_RANK``) or ``cuda:I``. Under ``torchrun`` ``batch`` is
            the global batch, split evenly over the processes (see
            :mod:`outcast_core.train.distributed`).
    """

    run: str
    stage: str
    data: str
    size: int = 128
    batch: int = 4
    steps: int = 10000
    lr: float = 1e-4
    lr_final: float = 0.0
    seed: int = 0
    net: dict[str, Any] = field(default_factory=dict)
    weights: dict[str, float] = field(
        default_factory=lambda: {"shadow": 10.0, "refine": 2.0, "relight": 10.0, "adv": 0.1}
    )
    d_every: int = 5
    gt_depth_prob: float = 0.8
    depth_checkpoint: str = ""
    shadow_checkpoint: str = ""
    new_shadow_gt_depth_prob: float = 0.0
    relight_base: str = "photo"
    relight_old_shadow: str = "refine"
    init_relight_onnx: str = ""
    postprocess_depth: bool = False
    snap_ground: bool = False
    resume_from: str = ""
    init_onnx: str = ""
    sun_noise_deg: float = 3.0
    cloud_prob: float = 0.0
    zoom_prob: float = 0.0
    zoom_max: float = 1.5
    degrade_prob: float = 0.0
    stain_prob: float = 0.0
    exposure_stops: float = 1.0
    saturation: tuple[float, float] = (0.8, 1.2)
    gamma: tuple[float, float] = (0.9, 1.1)
    flip: bool = True
    threads: int = 2
    checkpoint_every: int = 250
    time_limit_s: float = 0.0
    max_views: int = 0
    reload_every: int = 0
    extra_data: list[str] = field(default_factory=list)
    device: str = "auto"

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"expected a stage in {STAGES}, got {self.stage!r}")
        if self.size < 16 or self.batch < 1 or self.steps < 1:
            raise ValueError(
                f"expected size >= 16, batch >= 1, steps >= 1, got {self.size}, {self.batch}, "
                f"{self.steps}"
            )
        if not 0.0 <= self.lr_final <= self.lr:
            raise ValueError(f"expected 0 <= lr_final <= lr, got {self.lr_final} (lr {self.lr})")
        for key in ("gt_depth_prob", "new_shadow_gt_depth_prob", "cloud_prob", "zoom_prob",
                    "degrade_prob", "stain_prob"):
            if not 0.0 <= getattr(self, key) <= 1.0:
                raise ValueError(f"expected {key} in [0, 1], got {getattr(self, key)}")
        if self.zoom_max < 1.0:
            raise ValueError(f"expected zoom_max >= 1, got {self.zoom_max}")
        if self.zoom_prob > 0 and self.stage != "depth":
            raise ValueError(f"expected zoom_prob only for the depth stage (a zoomed view's "
                             f"principal point is off centre), got stage {self.stage!r}")
        for key in ("degrade_prob", "stain_prob"):
            if getattr(self, key) > 0 and self.stage not in ("depth", "shadow", "shadow_2d",
                                                             "sun"):
                raise ValueError(f"expected {key} only for the depth, shadow and sun stages, got "
                                 f"stage {self.stage!r}")
        if self.relight_base not in ("photo", "physics"):
            raise ValueError(f"expected relight_base photo or physics, got {self.relight_base!r}")
        if self.relight_old_shadow not in ("refine", "photo"):
            raise ValueError(f"expected relight_old_shadow refine or photo, got "
                             f"{self.relight_old_shadow!r}")
        for key, default in (("relight_old_shadow", "refine"), ("init_relight_onnx", "")):
            if getattr(self, key) != default and self.stage != "relight":
                raise ValueError(f"expected {key} only for the relight stage, got stage "
                                 f"{self.stage!r}")
        if self.relight_base != "photo" and self.stage != "relight":
            raise ValueError(f"expected relight_base only for the relight stage, got stage "
                             f"{self.stage!r}")
        for key in ("flip", "postprocess_depth", "snap_ground"):
            if not isinstance(getattr(self, key), bool):
                raise ValueError(f"expected {key} true or false, got {getattr(self, key)!r}")
        if self.postprocess_depth and not self.depth_checkpoint:
            raise ValueError("expected a depth_checkpoint for postprocess_depth, got none")
        if self.snap_ground and not self.postprocess_depth:
            raise ValueError("expected postprocess_depth = true for snap_ground, got false")
        if self.init_onnx and self.resume_from:
            raise ValueError("expected either init_onnx or resume_from, got both")
        if self.init_relight_onnx and (self.init_onnx or self.resume_from):
            raise ValueError("expected init_relight_onnx without init_onnx or resume_from (one "
                             "origin per run: the model cards name one)")
        if self.resume_from == self.run:
            raise ValueError(f"expected resume_from to name another run, got {self.run!r}")
        if self.stage == "relight" and not self.shadow_checkpoint:
            raise ValueError("expected a shadow_checkpoint for the relight stage, got none")
        if self.device not in ("auto", "cpu", "cuda") and not (
            self.device.startswith("cuda:") and self.device[5:].isdigit()
        ):
            raise ValueError(f"expected device auto, cpu, cuda or cuda:I, got {self.device!r}")
        self.data = str(Path(self.data).expanduser())
        if isinstance(self.extra_data, str) or not all(
            isinstance(d, str) for d in self.extra_data
        ):
            raise ValueError(
                f"expected extra_data to be a list of folders, got {self.extra_data!r}"
            )
        self.extra_data = [str(Path(d).expanduser()) for d in self.extra_data]
        for key in ("depth_checkpoint", "shadow_checkpoint", "init_onnx", "init_relight_onnx"):
            value = getattr(self, key)
            if value:
                setattr(self, key, str(Path(value).expanduser()))
        self.saturation = tuple(self.saturation)  # type: ignore[assignment]
        self.gamma = tuple(self.gamma)  # type: ignore[assignment]

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["saturation"] = list(self.saturation)
        d["gamma"] = list(self.gamma)
        return d


def load_config(path: str | Path, overrides: dict[str, Any] | None = None) -> TrainConfig:
    """Read a ``.json`` or ``.toml`` config; ``overrides`` replace top-level keys."""
    path = Path(path)
    if path.suffix == ".toml":
        data = tomllib.loads(path.read_text())
    elif path.suffix == ".json":
        data = json.loads(path.read_text())
    else:
        raise ValueError(f"expected a .toml or .json config, got {path.name}")
    data.update(overrides or {})
    known = {f.name for f in fields(TrainConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"expected config keys from {sorted(known)}, got unknown {unknown}")
    return TrainConfig(**data)


def run_dir(run: str) -> Path:
    """Checkpoint folder of a run: ``~/.cache/outcast/runs/<run>/`` (never in git)."""
    if not run or "/" in run or run.startswith("."):
        raise ValueError(f"expected a plain run name, got {run!r}")
    return Path.home() / ".cache" / "outcast" / "runs" / run
