"""Configs, the pair sampler and the trainer (every stage, resume, checkpoints)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from outcast_core.train.config import TrainConfig, load_config, run_dir
from outcast_core.train.data import (
    PairSampler,
    add_clouds,
    resize_view,
    tonemap_pair,
    zoom_crop,
)
from outcast_core.train.losses import change_loss
from outcast_core.train.trainer import Trainer, light_ratios, load_checkpoint_nets
from tests.train.conftest import make_view


def _cfg(stage: str, **kw) -> TrainConfig:
    base = {"run": f"t_{stage}", "stage": stage, "data": "unused", "size": 32, "batch": 2,
            "steps": 3, "lr": 1e-3, "checkpoint_every": 2, "threads": 1}
    if stage in ("shadow",):
        base["net"] = {"steps": 4}
    base.update(kw)
    return TrainConfig(**base)


def test_config_files_and_errors(tmp_path) -> None:
    (tmp_path / "a.toml").write_text('run = "r"\nstage = "shadow"\ndata = "d"\nbatch = 3\n'
                                     "[net]\nsteps = 16\n")
    cfg = load_config(tmp_path / "a.toml", {"steps": 7})
    assert (cfg.batch, cfg.steps, cfg.net) == (3, 7, {"steps": 16})
    (tmp_path / "b.json").write_text(json.dumps({"run": "r", "stage": "shadow", "data": "d",
                                                 "bacth": 3}))
    with pytest.raises(ValueError, match="unknown"):
        load_config(tmp_path / "b.json")
    with pytest.raises(ValueError, match="stage"):
        TrainConfig(run="r", stage="nope", data="d")
    with pytest.raises(ValueError, match="shadow_checkpoint"):
        TrainConfig(run="r", stage="relight", data="d")
    assert run_dir("abc").parts[-3:] == ("outcast", "runs", "abc")


def test_resize_keeps_nearest_surface_and_fov(fake_views) -> None:
    p = resize_view(fake_views[0], 16)
    assert p.rgb.shape == (3, 16, 16, 3) and p.depth.shape == (16, 16)
    assert np.isclose(p.focal, 16 / (2 * np.tan(np.radians(30))))
    d = fake_views[0]["depth"]
    block = d[:2, :2]
    assert p.depth[0, 0] == (np.min(block) if np.isfinite(block).any() else np.inf)
    with pytest.raises(ValueError, match="divides"):
        resize_view(fake_views[0], 12)


def test_pairs_share_tone_mapping() -> None:
    rng = np.random.default_rng(0)
    x = np.random.default_rng(1).random((8, 8, 3)).astype(np.float32)
    a, b = tonemap_pair(x, x, rng)
    np.testing.assert_array_equal(a, b)
    c, _ = tonemap_pair(x, x, np.random.default_rng(5))
    assert np.abs(a - c).max() > 1e-3  # the settings are random


def test_sampler_flip_mirrors_geometry(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    s = PairSampler(views, np.random.default_rng(0), flip=True, sun_noise_deg=0.0)
    seen_flip = False
    for _ in range(20):
        b = s.sample()
        v = next(v for v in views if np.allclose(np.abs(b["sun_new"]), np.abs(v.sun).max(0))
                 or any(np.allclose(np.abs(b["sun_new"]), np.abs(x)) for x in v.sun))
        flipped = not any(np.allclose(b["sun_new"], x) for x in v.sun)
        if flipped:
            seen_flip = True
            np.testing.assert_array_equal(b["depth"][0], v.depth[:, ::-1])
            np.testing.assert_allclose(b["normals"][0], -v.normals[:, ::-1, 0])
        np.testing.assert_array_equal(b["sun_old"], b["sun_old_noisy"])
    assert seen_flip


@pytest.mark.parametrize("stage", ["shadow", "shadow_2d", "relight_pix2pix", "depth", "sun"])
def test_each_stage_trains_and_resumes(stage: str, fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    tr = Trainer(_cfg(stage), views, progress=False)
    out = tr.fit()
    assert out["step"] == 3 and all(np.isfinite(v) for v in out["losses"].values())
    ckpt = torch.load(tr.checkpoint_path, weights_only=False)
    assert ckpt["step"] == 3
    again = Trainer(_cfg(stage, steps=5), views, progress=False)
    assert again.step == 3
    for k, net in again.nets.items():
        for a, b in zip(net.state_dict().values(), tr.nets[k].state_dict().values(), strict=True):
            torch.testing.assert_close(a, b)
    assert again.fit()["step"] == 5


def test_relight_stage_uses_frozen_shadow_net(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    s = Trainer(_cfg("shadow", steps=1), views, progress=False)
    s.fit()
    before = {k: v.clone() for k, v in s.nets["shadow"].state_dict().items()}
    tr = Trainer(_cfg("relight", shadow_checkpoint=str(s.checkpoint_path), d_every=1), views,
                 progress=False)
    logs = tr.train_step()
    assert {"f_R", "f_L", "f_A", "f_D"} <= set(logs)
    for k, v in tr.shadow_net.state_dict().items():
        torch.testing.assert_close(v, before[k])


def test_same_seed_same_first_losses(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    a = Trainer(_cfg("shadow", run="a"), views, progress=False).train_step()
    b = Trainer(_cfg("shadow", run="b"), views, progress=False).train_step()
    assert a == b


def test_overfitting_one_scene_reduces_the_loss(fake_views) -> None:
    views = [resize_view(make_view(0, suns=1), 32)]
    tr = Trainer(_cfg("shadow_2d", steps=30, flip=False, exposure_stops=0.0, batch=2), views,
                 progress=False)
    first = tr.train_step()["f_S"]
    for _ in range(30):
        last = tr.train_step()["f_S"]
    assert last < 0.8 * first


def test_resume_with_a_lower_learning_rate(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    Trainer(_cfg("shadow_2d", run="lr", steps=2), views, progress=False).fit()
    tr = Trainer(_cfg("shadow_2d", run="lr", steps=3, lr=1e-4), views, progress=False)
    assert tr.step == 2
    assert all(g["lr"] == 1e-4 for g in tr.opt_g.param_groups)
    tr.fit()
    ckpt = torch.load(tr.checkpoint_path, weights_only=False)
    assert [tuple(x) for x in ckpt["lr_history"]] == [(0, 1e-3), (2, 1e-4)]


def test_cosine_schedule_survives_a_resume(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    cfg = _cfg("shadow_2d", run="cos", steps=4, lr=1e-3, lr_final=1e-4)
    tr = Trainer(cfg, views, progress=False)
    assert [tr.lr_at(s) for s in (0, 2, 4, 9)] == pytest.approx([1e-3, 5.5e-4, 1e-4, 1e-4])
    tr.cfg.time_limit_s = 1e-9  # stop after one step
    tr.fit()
    tr = Trainer(_cfg("shadow_2d", run="cos", steps=4, lr=1e-3, lr_final=1e-4), views,
                 progress=False)
    assert tr.step == 1
    tr.train_step()
    assert all(g["lr"] == pytest.approx(tr.lr_at(1)) for g in tr.opt_g.param_groups)
    ckpt = torch.load(tr.checkpoint_path, weights_only=False)
    assert [tuple(x) for x in ckpt["lr_history"]] == [(0, 1e-3)]  # the schedule is the config
    Trainer(_cfg("shadow_2d", run="cos2", steps=1, lr=1e-3), views, progress=False).fit()
    tr = Trainer(_cfg("shadow_2d", run="cos2", steps=3, lr=1e-3, lr_final=1e-4), views,
                 progress=False)
    assert [tuple(x) for x in tr.lr_history] == [(0, 1e-3), (1, pytest.approx(tr.lr_at(1)))]
    with pytest.raises(ValueError, match="lr_final"):
        _cfg("shadow_2d", lr=1e-4, lr_final=1e-3)


def test_change_loss_counts_only_pixels_whose_visibility_changed() -> None:
    pred = torch.zeros(1, 3, 8, 8)
    target = torch.zeros(1, 3, 8, 8)
    target[..., :, :4] = 1.0  # wrong everywhere on the left half
    vis_o = torch.ones(1, 1, 8, 8)
    vis_n = torch.ones(1, 1, 8, 8)
    assert change_loss(pred, target, vis_o, vis_n).item() == 0.0  # nothing moved
    vis_n[..., 6:, 6:] = 0.0  # a shadow appears bottom right, where pred is right
    assert change_loss(pred, target, vis_o, vis_n).item() == 0.0
    vis_n[..., 0:2, 0:2] = 0.0  # and top left, where pred is wrong
    assert change_loss(pred, target, vis_o, vis_n).item() > 0.3
    with pytest.raises(ValueError, match="visibility"):
        change_loss(pred, target, vis_o, vis_n[:, :, :4])


def _views_s_and_z(fake_views: list[dict]) -> tuple[list, Trainer, Trainer]:
    """32 px views and one-step S and Z runs, for relight-stage tests that need checkpoints."""
    views = [resize_view(v, 32) for v in fake_views]
    s = Trainer(_cfg("shadow", steps=1), views, progress=False)
    s.fit()
    z = Trainer(_cfg("depth", run="z", steps=1), views, progress=False)
    z.fit()
    return views, s, z


def test_relight_change_weight_and_gt_new_shadows_reach_the_step(fake_views) -> None:
    views, s, z = _views_s_and_z(fake_views)
    base = {"shadow": 10.0, "refine": 2.0, "relight": 10.0, "adv": 0.1}
    plain = Trainer(_cfg("relight", run="p", shadow_checkpoint=str(s.checkpoint_path),
                         weights=base), views, progress=False).train_step()
    assert "f_change" not in plain
    tr = Trainer(_cfg("relight", run="c", shadow_checkpoint=str(s.checkpoint_path),
                      depth_checkpoint=str(z.checkpoint_path), weights=base | {"change": 10.0},
                      new_shadow_gt_depth_prob=1.0), views, progress=False)
    seen: list[torch.Tensor] = []
    forward = tr.shadow_net.forward
    tr.shadow_net.forward = lambda image, depth, *a: seen.append(depth) or forward(image, depth, *a)
    logs = tr.train_step()
    assert np.isfinite(logs["f_change"]) and logs["loss"] > plain["loss"]
    # S_o on Z's depth (finite, sky 0), S_n on the ground truth (inf on sky).
    assert torch.isfinite(seen[0]).all() and torch.isinf(seen[1]).any()
    tr.cfg.new_shadow_gt_depth_prob = 0.0
    seen.clear()
    tr.train_step()
    assert torch.isfinite(seen[1]).all()
    with pytest.raises(ValueError, match="new_shadow_gt_depth_prob"):
        _cfg("relight", shadow_checkpoint="x", new_shadow_gt_depth_prob=1.5)


def test_relight_on_the_apps_photo_old_shadow_from_a_shipped_l(fake_views, tmp_path) -> None:
    """``relight_old_shadow = "photo"``: L gets the session's photometric S_o (R untouched),
    starting from a shipped relight.onnx."""
    from outcast_core.export.onnx_export import export_onnx
    from outcast_core.nets import build
    from outcast_core.runtime.geometry.camera import cosine_term
    from outcast_core.runtime.pipeline.photo_shadows import (
        original_shadow_from_photo,
        photo_shadow_probability,
    )
    from outcast_core.train.trainer import photo_old_shadow

    views, s, z = _views_s_and_z(fake_views)
    shipped = build("relight")
    export_onnx(shipped, "relight", tmp_path / "relight.onnx", parity_sizes=[(32, 32)])
    tr = Trainer(_cfg("relight", run="photo_so", steps=2, shadow_checkpoint=str(s.checkpoint_path),
                      depth_checkpoint=str(z.checkpoint_path), relight_old_shadow="photo",
                      init_relight_onnx=str(tmp_path / "relight.onnx")), views, progress=False)
    for a, b in zip(tr.nets["relight"].state_dict().values(), shipped.state_dict().values(),
                    strict=True):
        torch.testing.assert_close(a, b)  # L starts as the shipped one
    assert tr.branched_from["init_onnx"] == str(tmp_path / "relight.onnx")
    r_before = [p.detach().clone() for p in tr.nets["refine"].parameters()]
    args: list[tuple] = []
    forward = tr.nets["relight"].forward
    tr.nets["relight"].forward = lambda *a: args.append(a) or forward(*a)
    logs = tr.train_step()
    tr.nets["relight"].forward = forward
    assert np.isfinite(logs["loss"])
    assert all(torch.equal(a, b) for a, b in zip(r_before, tr.nets["refine"].parameters(),
                                                strict=True))  # R is not trained
    image, s_o = args[0][:2]
    assert s_o.shape == (tr.cfg.batch, 1, 32, 32) and not s_o.requires_grad
    # The helper is the session's two steps, item by item.
    prior = torch.rand(1, 1, 16, 16)
    depth = torch.ones(1, 1, 16, 16)
    depth[..., :3, :] = 0.0  # sky
    normals = torch.zeros(1, 3, 16, 16)
    normals[:, 1] = -1.0
    sun = torch.tensor([[0.3, -0.8, 0.5]])
    img = torch.rand(1, 3, 16, 16)
    got = photo_old_shadow(img, prior, depth, normals, sun)[0, 0].numpy()
    sky = depth[0, 0].numpy() <= 0
    prob = photo_shadow_probability(img[0].permute(1, 2, 0).numpy(), sky, prior[0, 0].numpy())
    want = original_shadow_from_photo(prob, cosine_term(normals[0].permute(1, 2, 0).numpy(),
                                                        sun[0].numpy()), sky)
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert (got[:3] == 0).all()  # nothing on the sky
    # Exported: L, not the untrained R (the shipped refine.onnx stays).
    from outcast_core.export.checkpoint import export_checkpoint

    tr.fit()
    written = export_checkpoint(tr.checkpoint_path, tmp_path / "out")
    assert [p.name for p in written] == ["relight.onnx"]
    card = json.loads((tmp_path / "out" / "relight.json").read_text())["training"]
    assert card["branched_from"]["init_onnx"] == str(tmp_path / "relight.onnx")
    assert len(card["branched_from"]["sha256"]) == 64
    with pytest.raises(ValueError, match="not trained"):
        export_checkpoint(tr.checkpoint_path, tmp_path / "out2", kinds=("refine",))


@pytest.mark.parametrize(("stage", "options", "message"), [
    ("relight", {"shadow_checkpoint": "x", "relight_old_shadow": "guess"}, "relight_old_shadow"),
    ("shadow", {"relight_old_shadow": "photo"}, "only for the relight stage"),
    ("depth", {"init_relight_onnx": "relight.onnx"}, "only for the relight stage"),
    ("relight", {"shadow_checkpoint": "x", "init_relight_onnx": "relight.onnx",
                 "init_onnx": "refine.onnx"}, "init_relight_onnx without"),
    ("relight", {"shadow_checkpoint": "x", "init_relight_onnx": "relight.onnx",
                 "resume_from": "relight_v6"}, "init_relight_onnx without"),
    ("relight", {"shadow_checkpoint": "x", "relight_base": "paint"}, "relight_base"),
    ("shadow", {"relight_base": "physics"}, "relight_base only"),
    ("shadow", {"postprocess_depth": "False"}, "postprocess_depth"),
    ("shadow", {"postprocess_depth": True}, "depth_checkpoint"),
])
def test_stage_options_are_checked(stage: str, options: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _cfg(stage, **options)


def test_relight_physics_base_and_postprocessed_depth_reach_the_step(fake_views) -> None:
    views, s, z = _views_s_and_z(fake_views)
    tr = Trainer(_cfg("relight", run="phys", steps=2, shadow_checkpoint=str(s.checkpoint_path),
                      depth_checkpoint=str(z.checkpoint_path), relight_base="physics",
                      postprocess_depth=True), views, progress=False)
    assert tr.nets["relight"].base == "physics" and tr.net_kwargs["relight"] == {"base": "physics"}
    args: list[tuple] = []
    forward = tr.nets["relight"].forward
    tr.nets["relight"].forward = lambda *a: args.append(a) or forward(*a)
    calls: list[int] = []
    import outcast_core.runtime.pipeline.depth_post as dp

    real = dp.postprocess_z
    dp.postprocess_z = lambda *a: calls.append(1) or real(*a)
    try:
        logs = tr.train_step()
    finally:
        dp.postprocess_z = real
    assert np.isfinite(logs["loss"]) and len(calls) == tr.cfg.batch
    image, s_o, _, normals = args[0][:4]
    ratio = args[0][-1]
    assert ratio.shape == (tr.cfg.batch, 3)
    # The ratio is estimated from the photo, R's S_o that L receives and the geometry's sky.
    torch.testing.assert_close(ratio, light_ratios(image, s_o, normals))
    # And light_ratios measures r: lit pixels (S_o = 1) are 1 + r times the shadowed ones.
    r_true = torch.tensor([3.0, 2.0, 1.5])
    shadowed = torch.full((1, 3, 8, 8), 0.1)
    lit_mask = (torch.arange(8) < 4).float().view(1, 1, 1, 8)
    lin = shadowed * (1 + r_true.view(1, 3, 1, 1) * lit_mask)
    srgb = torch.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)
    got = light_ratios(srgb, lit_mask.expand(1, 1, 8, 8), torch.ones(1, 3, 8, 8))
    torch.testing.assert_close(got[0], r_true, atol=1e-3, rtol=1e-3)
    tr.nets["relight"].forward = forward
    tr.fit()
    nets, ckpt = load_checkpoint_nets(tr.checkpoint_path)  # what the exporter rebuilds
    assert nets["relight"].base == "physics" and ckpt["step"] == 2
    with pytest.raises(ValueError, match="built as in its checkpoint"):
        Trainer(_cfg("relight", run="phys", steps=2, shadow_checkpoint=str(s.checkpoint_path)),
                views, progress=False)  # its own checkpoint has a physics-base L


def test_resume_from_branches_off_another_run(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    first = Trainer(_cfg("shadow_2d", run="trunk", steps=2), views, progress=False)
    first.fit()
    br = Trainer(_cfg("shadow_2d", run="branch", steps=4, resume_from="trunk"), views,
                 progress=False)
    assert br.step == 2 and br.branched_from["run"] == "trunk"
    for a, b in zip(br.nets["shadow_2d"].state_dict().values(),
                    first.nets["shadow_2d"].state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)
    br.fit()
    again = Trainer(_cfg("shadow_2d", run="branch", steps=5, resume_from="trunk"), views,
                    progress=False)
    assert again.step == 4 and again.branched_from["step"] == 2  # its own checkpoint wins
    assert torch.load(first.checkpoint_path, weights_only=False)["step"] == 2  # trunk untouched
    with pytest.raises(FileNotFoundError, match="nowhere"):
        Trainer(_cfg("shadow_2d", run="b2", resume_from="nowhere"), views, progress=False)
    with pytest.raises(ValueError, match="another run"):
        _cfg("shadow_2d", run="same", resume_from="same")


def test_clouds_paint_only_the_sky_and_cost_no_draws_when_off(fake_views) -> None:
    views = [resize_view(v, 32) for v in fake_views]
    s = PairSampler(views, np.random.default_rng(4))
    for _ in range(3):
        s.batch(2)
    # The generator's state after the same draws at commit ad1eeb8, before clouds existed: runs
    # without clouds draw exactly what they drew then, so old checkpoints resume identically.
    assert s.rng.bit_generator.state["state"]["state"] == 333745762058983232234985214045603476843
    c = PairSampler(views, np.random.default_rng(4), cloud_prob=0.5)
    for _ in range(3):
        c.batch(2)
    assert c.rng.bit_generator.state != s.rng.bit_generator.state
    rng = np.random.default_rng(0)
    img = np.full((32, 32, 3), 0.3, np.float32)
    sky = np.zeros((32, 32), bool)
    sky[:12] = True
    c1, c2 = add_clouds((img, img * 0.5), sky, rng)
    assert np.array_equal(c1[~sky], img[~sky]) and np.array_equal(c2[~sky], (img * 0.5)[~sky])
    assert np.abs(c1[sky] - img[sky]).max() > 0.1
    assert np.all((c1 >= 0) & (c1 <= 1))
    (same,) = add_clouds((img,), np.zeros((32, 32), bool), rng)
    assert same is img


def test_zoom_crops_one_window_from_every_map_and_scales_the_focal(fake_views) -> None:
    """A zoomed pair is one window of the view, the same for image, depth and sky, brought back
    to the view's size, with the focal scaled by the factor; no zoom costs no draws."""
    ramp = np.arange(32, dtype=np.float32)
    grid = (ramp[:, None] * 100 + ramp[None, :]).astype(np.float32)  # row * 100 + column
    (same,) = zoom_crop((grid,), 1.0, np.random.default_rng(0))
    np.testing.assert_array_equal(same, grid)
    a, b = zoom_crop((grid, grid[..., None].repeat(3, -1)), 2.0, np.random.default_rng(1))
    assert a.shape == (32, 32) and b.shape == (32, 32, 3)
    np.testing.assert_array_equal(b[..., 0], a)
    rows, cols = np.unique(a // 100), np.unique(a % 100)
    assert len(rows) == len(cols) == 16  # a 16 x 16 window, each pixel shown twice
    assert np.all(np.diff(rows) == 1) and np.all(np.diff(cols) == 1)
    with pytest.raises(ValueError, match="zoom factor"):
        zoom_crop((grid,), 0.5, np.random.default_rng(0))

    views = [resize_view(v, 32) for v in fake_views]
    view = views[0]
    z = PairSampler([view], np.random.default_rng(2), flip=False, zoom_prob=1.0, zoom_max=2.0)
    item = z.sample()
    ratio = float(item["focal"][0]) / view.focal
    assert 1.0 < ratio <= 2.0
    depth = item["depth"][0]
    assert depth.shape == (32, 32) and not np.array_equal(depth, view.depth)
    # Every zoomed depth value comes from the view (nearest neighbour: no new values, sky kept).
    assert np.isin(depth, view.depth).all()
    plain = PairSampler(views, np.random.default_rng(4), zoom_prob=0.0)
    for _ in range(3):
        plain.batch(2)
    # Same draws as before zooms existed (see the cloud test above).
    assert plain.rng.bit_generator.state["state"]["state"] == \
        333745762058983232234985214045603476843
    with pytest.raises(ValueError, match="depth stage"):
        TrainConfig(run="r", stage="shadow", data="d", zoom_prob=0.5)
    with pytest.raises(ValueError, match="zoom_max"):
        TrainConfig(run="r", stage="depth", data="d", zoom_max=0.5)


def test_snap_ground_gives_postprocess_z_each_items_camera(fake_views) -> None:
    views, s, z = _views_s_and_z(fake_views)
    views = [dataclasses.replace(v, focal=v.focal * (0.8 + 0.2 * i))  # a focal each
             for i, v in enumerate(views)]
    cams: list = []
    import outcast_core.runtime.pipeline.depth_post as dp

    real = dp.postprocess_z
    dp.postprocess_z = lambda *a: cams.append(a[3] if len(a) > 3 else None) or real(*a)
    try:
        for snap in (False, True):
            tr = Trainer(_cfg("relight", run=f"snap{snap}", steps=1,
                              shadow_checkpoint=str(s.checkpoint_path),
                              depth_checkpoint=str(z.checkpoint_path), postprocess_depth=True,
                              snap_ground=snap), views, progress=False)
            cams.clear()
            batch = tr._tensors()
            tr._estimated_geometry(batch)
            if not snap:
                assert cams == [None] * tr.cfg.batch
            else:
                assert len(cams) == tr.cfg.batch
                h, w = batch["image"].shape[-2:]
                assert len({float(f) for f in batch["focal"].reshape(-1)}) > 1
                for b, cam in enumerate(cams):
                    assert (cam.height, cam.width) == (h, w)
                    assert cam.focal == pytest.approx(float(batch["focal"][b].reshape(-1)[0]))
    finally:
        dp.postprocess_z = real
    with pytest.raises(ValueError, match="postprocess_depth = true for snap_ground"):
        _cfg("shadow", snap_ground=True)
    with pytest.raises(ValueError, match="snap_ground"):
        _cfg("shadow", snap_ground="yes")


def test_extra_data_folders_add_their_views(tmp_path) -> None:
    from outcast_core.data.dataset import save_view

    def folder(name: str, seeds: range, suns: int) -> str:
        root = tmp_path / name
        for i, s in enumerate(seeds):
            v = make_view(s, suns=suns)
            v["sun_azel"] = np.zeros((suns, 2), np.float32)
            save_view(root / f"view_{i:06d}", v, {"seed": s})
        return str(root)

    main = folder("main", range(3), 3)
    extra = folder("one_sun", range(10, 14), 1)
    cfg = _cfg("depth", data=main, max_views=2, extra_data=[extra], steps=2)
    tr = Trainer(cfg, progress=False)
    # max_views limits the main folder only; one-sun views sample pairs of the same sun.
    assert len(tr.sampler.views) == 2 + 4
    assert sorted(v.rgb.shape[0] for v in tr.sampler.views) == [1, 1, 1, 1, 3, 3]
    assert tr.fit()["step"] == 2
    ckpt = torch.load(tr.checkpoint_path, weights_only=False)
    assert ckpt["views_by_folder"] == {main: 2, extra: 4}
    with pytest.raises(ValueError, match="extra_data"):
        _cfg("depth", extra_data=extra)


def test_depth_geometry_terms_and_start_from_a_shipped_onnx(fake_views, tmp_path) -> None:
    from outcast_core.export.onnx_export import export_onnx
    from outcast_core.nets import build

    views = [resize_view(v, 32) for v in fake_views]
    z = build("depth")
    export_onnx(z, "depth", tmp_path / "depth.onnx", parity_sizes=[(32, 32)])
    (tmp_path / "depth.json").write_text(json.dumps(
        {"training": {"steps": 77, "wall_time_s": 12.0, "command": "outcast train z.toml"}}))
    tr = Trainer(_cfg("depth", run="z_geo", steps=2, init_onnx=str(tmp_path / "depth.onnx"),
                      weights={"depth_grad": 0.5, "depth_normal": 0.5}), views, progress=False)
    for a, b in zip(tr.nets["depth"].state_dict().values(), z.state_dict().values(),
                    strict=True):
        torch.testing.assert_close(a, b)  # the ONNX model's weights, not a fresh init
    assert tr.step == 0 and tr.branched_from["step"] == 77
    assert tr.branched_from["command"] == "outcast train z.toml"
    logs = tr.train_step()
    assert {"silog", "sky_bce", "grad", "normal"} <= set(logs)
    assert logs["loss"] == pytest.approx(
        logs["silog"] + logs["sky_bce"] + 0.5 * logs["grad"] + 0.5 * logs["normal"], rel=1e-5)
    tr.fit()
    again = Trainer(_cfg("depth", run="z_geo", steps=3, init_onnx=str(tmp_path / "depth.onnx"),
                         weights={"depth_grad": 0.5, "depth_normal": 0.5}), views,
                    progress=False)
    assert again.step == 2  # its own checkpoint wins over the ONNX start
    plain = Trainer(_cfg("depth", run="z_plain", steps=1), views, progress=False).train_step()
    assert "grad" not in plain and "normal" not in plain  # old configs train as before
    export_onnx(build("shadow_2d"), "shadow_2d", tmp_path / "s2d.onnx", parity_sizes=[(32, 32)])
    with pytest.raises(ValueError, match="missing"):
        Trainer(_cfg("depth", run="z_bad", init_onnx=str(tmp_path / "s2d.onnx")), views,
                progress=False)
    # A shipped Z as the estimated depth of the shadow stage (its checkpoint gone).
    s = Trainer(_cfg("shadow_2d", run="s_on_onnx_z", depth_checkpoint=str(tmp_path / "depth.onnx"),
                     gt_depth_prob=0.0), views, progress=False)
    for a, b in zip(s.depth_net.state_dict().values(), z.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)
    assert not s.depth_net.training
    s.train_step()
    with pytest.raises(ValueError, match="init_onnx or resume_from"):
        _cfg("depth", init_onnx="a.onnx", resume_from="other")


def test_sun_stage_starts_its_encoder_from_z_and_learns_the_sun(fake_views, tmp_path) -> None:
    """D's encoder starts from a shipped Z (its head fresh); the stage's loss is the
    cross-entropy against the true original sun, and overfitting one view lowers it."""
    from outcast_core.export.onnx_export import export_onnx
    from outcast_core.nets import build

    views = [resize_view(make_view(0, suns=1), 32)]
    z = build("depth")
    export_onnx(z, "depth", tmp_path / "depth.onnx", parity_sizes=[(32, 32)])
    tr = Trainer(_cfg("sun", run="d_on_z", steps=40, init_onnx=str(tmp_path / "depth.onnx"),
                      flip=False, exposure_stops=0.0, lr=3e-3, degrade_prob=0.5,
                      stain_prob=0.5), views, progress=False)
    zs = z.state_dict()
    enc = {k: v for k, v in tr.nets["sun"].state_dict().items() if k.startswith("unet.enc.")}
    for k, v in enc.items():
        torch.testing.assert_close(v, zs[k])
    first = tr.train_step()
    assert set(first) == {"loss", "angle"}
    for _ in range(40):
        last = tr.train_step()
    assert last["loss"] < 0.8 * first["loss"]
    assert last["angle"] < 15.0  # the one view's sun, to the bins' spacing


def test_degrade_photo_draws_alike_and_touches_only_the_input(fake_views) -> None:
    from outcast_core.train.data import degrade_photo

    img = np.random.default_rng(0).uniform(0.1, 0.9, (32, 32, 3)).astype(np.float32)
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    out = [degrade_photo(img, a) for _ in range(20)]
    for _ in range(20):
        degrade_photo(np.zeros((1, 1, 3), np.float32), b)  # what PairSampler.skip replays
    assert a.bit_generator.state == b.bit_generator.state
    assert all(o.shape == img.shape and o.dtype == np.float32 for o in out)
    assert all(o.min() >= 0.0 and o.max() <= 1.0 for o in out)
    diffs = [float(np.abs(o - img).mean()) for o in out]
    assert 0.0 < np.median(diffs) < 0.1  # visible flaws, the same picture
    views = [resize_view(v, 32) for v in fake_views]
    clean = PairSampler(views, np.random.default_rng(5)).sample()
    dirty = PairSampler(views, np.random.default_rng(5), degrade_prob=1.0).sample()
    assert not np.array_equal(clean["image"], dirty["image"])
    for key in ("target", "depth", "normals", "shadow_old", "shadow_new"):
        np.testing.assert_array_equal(clean[key], dirty[key])
    with pytest.raises(ValueError, match="degrade_prob"):
        _cfg("relight", shadow_checkpoint="x", degrade_prob=0.5)


def test_stain_photo_darkens_the_surface_only_and_draws_alike(fake_views) -> None:
    from outcast_core.train.data import stain_photo

    img = np.full((48, 48, 3), 0.6, np.float32)
    surface = np.ones((48, 48), bool)
    surface[:12] = False  # sky
    a, b = np.random.default_rng(4), np.random.default_rng(4)
    out = [stain_photo(img, surface, a) for _ in range(30)]
    for _ in range(30):  # what PairSampler.skip replays
        stain_photo(np.zeros((1, 1, 3), np.float32), np.ones((1, 1), bool), b)
    assert a.bit_generator.state == b.bit_generator.state
    assert all(o.shape == img.shape and o.dtype == np.float32 for o in out)
    for o in out:
        np.testing.assert_array_equal(o[:12], img[:12])  # the sky untouched
    changed = [o for o in out if not np.array_equal(o, img)]
    assert len(changed) >= 20  # most calls paint something
    # Stains are dark patches, bluer than the surface around them (shade is sky-lit).
    darkest = min(changed, key=lambda o: float(o[12:].min()))
    px = darkest[12:].reshape(-1, 3)[np.argmin(darkest[12:].sum(-1))]
    assert px.sum() < 0.6 * 3 * 0.8 and px[2] >= px[0]
    views = [resize_view(v, 32) for v in fake_views]
    clean = PairSampler(views, np.random.default_rng(5)).sample()
    stained = PairSampler(views, np.random.default_rng(5), stain_prob=1.0).sample()
    for key in ("target", "depth", "normals", "shadow_old", "shadow_new"):
        np.testing.assert_array_equal(clean[key], stained[key])
    with pytest.raises(ValueError, match="stain_prob"):
        _cfg("relight", shadow_checkpoint="x", stain_prob=0.5)
