"""Training under torchrun: two CPU processes (gloo) give the one-process result.

The two-process run is a real ``python -m torch.distributed.run --nproc_per_node=2`` of the
``outcast train`` command on a free port of 127.0.0.1, on a tiny data folder written here.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from outcast_core.train.config import TrainConfig, run_dir
from outcast_core.train.distributed import DistContext, param_names_without_grad
from outcast_core.train.trainer import STAGE_NETS, Trainer
from tests.train.conftest import make_view

REPO = Path(__file__).resolve().parents[2]

#: Largest difference allowed between a weight after N steps of the two-process run and of the
#: one-process run (lr 1e-3, Adam). Adam moves every weight by about ``lr`` per step whatever
#: the gradient's size, so a wrong split of the batch, gradients not averaged, or a loss
#: normalised per rank instead of over the global batch show as differences of order ``lr``:
#: measured 2e-3 (shadow) and 5e-3 (relight) with the BCE / change-loss counts taken per rank,
#: 5.5e-3 for one process with half the batch (the control below). When everything is right
#: only float32 rounding in another order of summation remains (two half-batch sums averaged
#: by gloo vs one sum): measured at most 1e-7 on S, 4.3e-7 on the critic after 4 steps (Adam's
#: ``m / sqrt(v)`` amplifies rounding in small gradients, the GAN's most). On another CPU
#: (an AMD EPYC, 2026-12-02) one weight of S's of 5760 came 4e-5 apart (Adam's ``m /
#: sqrt(v)`` on a near-zero gradient), so 1e-4: 2.5x above the largest rounding seen and 20x
#: below the smallest mistake.
TOLERANCE = 1e-4


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _data_folder(root: Path, views: int = 3) -> str:
    from outcast_core.data.dataset import save_view

    for i in range(views):
        v = make_view(i, suns=3)
        v["sun_azel"] = np.zeros((3, 2), np.float32)
        save_view(root / f"view_{i:06d}", v, {"seed": i})
    return str(root)


def _base(run: str, stage: str, data: str, **kw: object) -> dict:
    cfg = {"run": run, "stage": stage, "data": data, "size": 32, "batch": 4, "steps": 3,
           "lr": 1e-3, "checkpoint_every": 2, "threads": 1, "device": "cpu"}
    if stage == "shadow":
        cfg["net"] = {"steps": 4}
    cfg.update(kw)
    return cfg


def _weights(run: str) -> dict:
    return torch.load(run_dir(run) / "last.pt", weights_only=False)


def _assert_same_run(run: str, reference: str) -> None:
    """Same step, same sampler state, every weight within :data:`TOLERANCE`."""
    a, b = _weights(run), _weights(reference)
    assert a["step"] == b["step"] and b["processes"] == 1
    assert a["numpy_rng"] == b["numpy_rng"]  # every rank drew the one-process batches
    assert set(a["nets"]) == set(b["nets"])
    for kind in a["nets"]:
        for name, w in a["nets"][kind].items():
            torch.testing.assert_close(w, b["nets"][kind][name], atol=TOLERANCE, rtol=0,
                                       msg=lambda m, k=kind, n=name: f"{k}.{n}: {m}")


def test_ranks_make_disjoint_parts_of_the_one_process_batch(fake_views) -> None:
    """Each of 4 ranks makes its quarter of every global batch, and the quarters are the
    one-process batch bit for bit, with every augmentation on and views of two sizes (the
    draws of the items a rank skips are those of :meth:`PairSampler.sample`)."""
    from outcast_core.train.data import PairSampler, resize_view

    views = [resize_view(v, 32) for v in fake_views] + [resize_view(make_view(9), 16)]
    kw = {"cloud_prob": 0.5, "zoom_prob": 0.5, "zoom_max": 1.5, "sun_noise_deg": 3.0,
          "degrade_prob": 0.7, "stain_prob": 0.6}
    one = PairSampler(views, np.random.default_rng(7), **kw)
    ranks = [PairSampler(views, np.random.default_rng(7), **kw) for _ in range(4)]
    zoomed = 0
    for _ in range(6):
        full = one.batch(8)
        parts = [s.batch(8, keep=DistContext(rank=r, world=4).part(8))
                 for r, s in enumerate(ranks)]
        for key, value in full.items():
            np.testing.assert_array_equal(np.concatenate([p[key] for p in parts]), value)
        for s in ranks:
            assert s.rng.bit_generator.state == one.rng.bit_generator.state
        zoomed += int((full["focal"][:, 0] > views[0].focal * 1.001).sum())
    assert zoomed > 0
    assert DistContext().part(8) is None  # one process: the whole batch
    with pytest.raises(ValueError, match="divisible by the 3 processes"):
        DistContext(rank=0, world=3).part(8)
    with pytest.raises(ValueError, match="to keep"):
        one.batch(4, keep=slice(4, 8))
    with pytest.raises(ValueError, match="device"):
        TrainConfig(run="r", stage="depth", data="d", device="gpu")


@pytest.mark.parametrize(
    "stage", ["shadow", "shadow_2d", "relight", "relight_physics", "relight_pix2pix", "depth"])
def test_every_trained_parameter_gets_a_gradient(stage: str, fake_views) -> None:
    """DDP runs without find_unused_parameters: every parameter of every wrapped network takes
    part in each step (the critic in its own step; d_every = 1 runs one each step)."""
    from outcast_core.train.data import resize_view

    views = [resize_view(v, 32) for v in fake_views]
    kw: dict = {"d_every": 1, "steps": 1}
    if stage == "relight_physics":
        stage, kw["relight_base"] = "relight", "physics"
    if stage == "relight":
        s = Trainer(TrainConfig(**_base("up", "shadow", "unused", steps=1)), views,
                    progress=False)
        s.fit()
        kw["shadow_checkpoint"] = str(s.checkpoint_path)
        kw["weights"] = {"shadow": 10.0, "refine": 2.0, "relight": 10.0, "adv": 0.1,
                         "change": 10.0}
    tr = Trainer(TrainConfig(**_base(f"g_{stage}", stage, "unused", **kw)), views,
                 progress=False)
    tr.train_step()
    nets = [tr.nets[k] for k in STAGE_NETS[stage]]
    assert param_names_without_grad(nets) == []


def test_two_processes_match_one_with_the_same_global_batch(tmp_path) -> None:
    """``torchrun --nproc_per_node=2`` (gloo) of ``outcast train`` for the shadow stage and the
    GAN relight stage (R, L and the critic, the change loss, one critic step per step), the
    latter stopped after 2 steps and resumed to 4, gives the weights of one process with the
    same global batch of 4, within :data:`TOLERANCE`; resumed in one process for a fifth step
    it still does."""
    data = _data_folder(tmp_path / "data")
    up = Trainer(TrainConfig(**_base("upstream_s", "shadow", data, steps=1)), progress=False)
    up.fit()
    relight = {"shadow_checkpoint": str(up.checkpoint_path), "d_every": 1,
               "weights": {"shadow": 10.0, "refine": 2.0, "relight": 10.0, "adv": 0.1,
                           "change": 10.0}}
    configs = [_base("two_s", "shadow", data),
               _base("two_r", "relight", data, steps=2, **relight),
               _base("two_r", "relight", data, steps=4, **relight)]
    paths = []
    for i, cfg in enumerate(configs):
        paths.append(tmp_path / f"cfg{i}.json")
        paths[-1].write_text(json.dumps(cfg))
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(REPO))
    if Path("/sys/class/net/lo").exists():  # gloo on the loopback, whatever the host name says
        env.setdefault("GLOO_SOCKET_IFNAME", "lo")
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node=2", "--nnodes=1",
           "--master_addr=127.0.0.1", f"--master_port={_free_port()}",
           "-m", "outcast_core.runtime.cli.main", "train", *map(str, paths), "--no-progress"]
    out = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert out.stdout.count('"step"') == 3  # rank 0 alone reports, once per config

    Trainer(TrainConfig(**_base("one_s", "shadow", data)), progress=False).fit()
    Trainer(TrainConfig(**_base("one_r", "relight", data, steps=4, **relight)),
            progress=False).fit()
    for two, one in (("two_s", "one_s"), ("two_r", "one_r")):
        assert _weights(two)["processes"] == 2
        _assert_same_run(two, one)
    # The two-process run resumes in one process and goes on as the one-process run does.
    for run in ("two_r", "one_r"):
        Trainer(TrainConfig(**_base(run, "relight", data, steps=5, **relight)),
                progress=False).fit()
    _assert_same_run("two_r", "one_r")
    # Control: one process with half the batch (what a rank trains on) is far outside it.
    Trainer(TrainConfig(**_base("half_s", "shadow", data, batch=2)), progress=False).fit()
    half, two = _weights("half_s")["nets"]["shadow"], _weights("two_s")["nets"]["shadow"]
    assert max((half[k] - two[k]).abs().max().item() for k in two) > 20 * TOLERANCE


#: Settings a cluster preset may change from the shipped network's config: scale, data,
#: upstream runs, where it runs. Everything else (stage, size, network, losses, augmentations,
#: depth recipe) is the shipped recipe.
_SCALE_KEYS = {"run", "resume_from", "data", "extra_data", "batch", "steps", "lr", "lr_final",
               "threads", "checkpoint_every", "depth_checkpoint", "shadow_checkpoint", "device"}


def test_cluster_presets_are_the_shipped_recipes_at_scale() -> None:
    from outcast_core.train.config import load_config

    configs = REPO / "outcast_core" / "train" / "configs"
    cluster = {load_config(p).stage: load_config(p) for p in configs.glob("cluster_*.toml")}
    assert set(cluster) == {"depth", "shadow", "shadow_2d", "relight", "relight_pix2pix"}
    runs = {c.run for c in cluster.values()}
    for manifest in sorted((REPO / "models").glob("*.json")):
        command = json.loads(manifest.read_text())["training"]["command"]
        shipped = load_config(REPO / command.split()[2])  # outcast train CONFIG ...
        preset = cluster[shipped.stage].to_dict()
        for key, value in shipped.to_dict().items():
            if key not in _SCALE_KEYS:
                assert preset[key] == value, (manifest.name, key)
    for cfg in cluster.values():
        assert cfg.batch % 8 == 0 and not cfg.resume_from
        for upstream in (cfg.depth_checkpoint, cfg.shadow_checkpoint):
            # Each preset trains on the upstream networks of the preset.
            assert not upstream or Path(upstream).parent.name in runs, (cfg.run, upstream)
