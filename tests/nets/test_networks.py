"""Shapes, ranges and the built-in guarantees of every network."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F  # noqa: N812

from outcast_core.nets import NETWORKS, build
from outcast_core.nets.blocks import count_parameters
from outcast_core.nets.depth import (
    gradient_matching_loss,
    normal_loss,
    scale_invariant_log_loss,
)


def _shadow_inputs(b: int, h: int, w: int, seed: int = 0) -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(seed)
    image = torch.rand(b, 3, h, w, generator=g)
    depth = 1.0 + 3.0 * torch.rand(b, 1, h, w, generator=g)
    depth[:, :, : h // 4] = float("inf")
    normals = F.normalize(torch.randn(b, 3, h, w, generator=g), dim=1)
    normals[:, :, : h // 4] = 0.0
    sun = F.normalize(torch.tensor([[0.3, -0.8, 0.4]]).repeat(b, 1), dim=1)
    focal = torch.full((b, 1), float(w))
    return image, depth, normals, sun, focal


@pytest.mark.parametrize("kind", ["shadow", "shadow_2d"])
@pytest.mark.parametrize("steps", [8, 12])
def test_shadow_nets_give_cosine_weighted_visibility(kind: str, steps: int) -> None:
    kw = {"steps": steps} if kind == "shadow" else {}
    net = build(kind, **kw).eval()
    image, depth, normals, sun, focal = _shadow_inputs(2, 32, 48)
    with torch.no_grad():
        out = net(image, depth, normals, sun, focal)
    assert out.shape == (2, 1, 32, 48)
    cos = (normals * sun[:, :, None, None]).sum(1, keepdim=True).clamp(0, 1)
    assert torch.all(out >= 0) and torch.all(out <= cos + 1e-6)
    assert torch.all(out[:, :, :8] == 0)  # sky: zero normals, zero shadow image


def test_shadow_net_full_resolution_volume_and_gradients() -> None:
    net = build("shadow", steps=8, volume_scale=1.0)
    assert net.pad_multiple == 8
    image, depth, normals, sun, focal = _shadow_inputs(1, 16, 24)
    net(image, depth, normals, sun, focal).mean().backward()
    grads = [p.grad for p in net.enc3d.parameters()]
    assert all(gr is not None and torch.isfinite(gr).all() for gr in grads)
    assert any(float(gr.abs().sum()) > 0 for gr in grads)  # the 3D path is used


def test_shadow_net_depends_on_sun_direction() -> None:
    torch.manual_seed(0)
    net = build("shadow", steps=8).eval()
    image, depth, normals, _, focal = _shadow_inputs(1, 32, 32)
    normals = torch.zeros_like(normals)
    normals[:, 1] = -1.0  # all facing up: the cosine term is the same for both suns below
    a = torch.tensor([[0.6, -0.8, 0.0]])
    b = torch.tensor([[-0.6, -0.8, 0.0]])
    with torch.no_grad():
        sa = net(image, depth, normals, a, focal)
        sb = net(image, depth, normals, b, focal)
    assert float((sa - sb).abs().max()) > 1e-4


def test_shadow_net_rejects_bad_sizes_and_shapes() -> None:
    net = build("shadow", steps=4)
    image, depth, normals, sun, focal = _shadow_inputs(1, 24, 24)  # 24 is not a multiple of 16
    with pytest.raises(ValueError, match="divisible by 16"):
        net(image, depth, normals, sun, focal)
    image, depth, normals, sun, focal = _shadow_inputs(1, 32, 32)
    with pytest.raises(ValueError, match="normals"):
        net(image, depth, normals[:, :2], sun, focal)
    with pytest.raises(ValueError, match="volume_scale"):
        build("shadow", volume_scale=0.3)


def test_refine_and_relight_start_as_identity() -> None:
    image = torch.rand(2, 3, 16, 16) * 0.9 + 0.05
    shadow = torch.rand(2, 1, 16, 16) * 0.9 + 0.05
    sun = F.normalize(torch.randn(2, 3), dim=1)
    normals = F.normalize(torch.randn(2, 3, 16, 16), dim=1)
    with torch.no_grad():
        r = build("refine")(shadow, image, sun)
        relit = build("relight")(image, shadow, shadow, normals, sun, sun, normals)
        p2p = build("relight_pix2pix")(image, normals, sun, sun, normals)
    torch.testing.assert_close(r, shadow, atol=1e-5, rtol=0)
    torch.testing.assert_close(relit, image, atol=1e-5, rtol=0)
    torch.testing.assert_close(p2p, image, atol=1e-5, rtol=0)
    with pytest.raises(ValueError, match="sun_new"):
        build("relight")(image, shadow, shadow, normals, sun, sun[:, :2], normals)


def test_physics_base_is_the_runtimes_shading_ratio_relighting() -> None:
    import numpy as np

    from outcast_core.nets.relight import linear_to_srgb, physics_base, srgb_to_linear
    from outcast_core.runtime.geometry import colour
    from outcast_core.runtime.pipeline.relight import LightEstimate, physics_relight

    g = torch.Generator().manual_seed(3)
    image = torch.rand(1, 3, 24, 32, generator=g)
    s_o, s_n = torch.rand(1, 1, 24, 32, generator=g), torch.rand(1, 1, 24, 32, generator=g)
    normals = F.normalize(torch.randn(1, 3, 24, 32, generator=g), dim=1)
    normals[:, :, :5] = 0.0  # a sky band: no surface
    ratio = torch.tensor([[5.0, 4.0, 2.5]])
    x = image[0].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(srgb_to_linear(image)[0].permute(1, 2, 0).numpy(),
                               colour.srgb_to_linear(x), atol=1e-6)
    np.testing.assert_allclose(linear_to_srgb(image)[0].permute(1, 2, 0).numpy(),
                               colour.linear_to_srgb(x), atol=1e-6)
    with torch.no_grad():
        got = physics_base(image, s_o, s_n, normals, ratio)[0].permute(1, 2, 0).numpy()
    sky = np.zeros((24, 32), bool)
    sky[:5] = True
    want = physics_relight(x, s_o[0, 0].numpy(), s_n[0, 0].numpy(), sky, snap=False,
                           light=LightEstimate(ratio[0].numpy(), True, 0, 0))
    np.testing.assert_allclose(got, want, atol=1e-5)
    np.testing.assert_allclose(got[:5], x[:5], atol=1e-5)  # the sky keeps the photo
    # A pixel that leaves the shadow gets brighter, one that enters it darker.
    assert (got[5:] > x[5:] + 1e-3).any() and (got[5:] < x[5:] - 1e-3).any()


def test_relight_physics_base_starts_as_physics_and_needs_the_ratio() -> None:
    from outcast_core.nets.relight import physics_base

    image = torch.rand(2, 3, 16, 16) * 0.9 + 0.05
    s_o = torch.rand(2, 1, 16, 16)
    s_n = torch.rand(2, 1, 16, 16)
    sun = F.normalize(torch.randn(2, 3), dim=1)
    normals = F.normalize(torch.randn(2, 3, 16, 16), dim=1)
    ratio = torch.tensor([[5.0, 4.0, 2.8], [1.0, 1.0, 1.0]])
    net = build("relight", base="physics")
    photo = build("relight")
    net.load_state_dict(photo.state_dict())  # the base adds no parameters
    with torch.no_grad():
        out = net(image, s_o, s_n, normals, sun, sun, normals, ratio)
        base = physics_base(image, s_o, s_n, normals, ratio).clamp(1e-3, 1 - 1e-3)
        same = net(image, s_o, s_o, normals, sun, sun, normals, ratio)
    torch.testing.assert_close(out, base, atol=1e-5, rtol=0)
    torch.testing.assert_close(same, image, atol=1e-5, rtol=0)  # same sun: the photo
    assert (out - image).abs().max() > 0.05
    with pytest.raises(ValueError, match="light_ratio"):
        net(image, s_o, s_n, normals, sun, sun, normals)
    with pytest.raises(ValueError, match="light_ratio"):
        net(image, s_o, s_n, normals, sun, sun, normals, ratio[:1])
    with pytest.raises(ValueError, match="base"):
        build("relight", base="paint")


def test_critic_receptive_field_and_shape() -> None:
    critic = build("critic")
    x = torch.zeros(1, 3, 128, 128, requires_grad=True)
    out = critic(x, torch.zeros(1, 3, 128, 128), torch.zeros(1, 1, 128, 128))
    assert out.shape == (1, 1, 14, 14)
    out[0, 0, 7, 7].backward()
    rows = torch.nonzero(x.grad.abs().sum(dim=(0, 1, 3)) > 0)
    extent = int(rows.max() - rows.min() + 1)
    assert 60 <= extent <= 70


def test_depth_net_is_scale_free_and_loss_is_scale_invariant() -> None:
    net = build("depth").eval()
    with torch.no_grad():
        depth, sky = net(torch.rand(1, 3, 32, 32))
    assert depth.shape == sky.shape == (1, 1, 32, 32)
    assert torch.all(depth > 0) and torch.all((sky >= 0) & (sky <= 1))
    t = 1.0 + torch.rand(1, 1, 8, 8)
    mask = torch.ones_like(t, dtype=torch.bool)
    assert float(scale_invariant_log_loss(3.7 * t, t, mask)) < 1e-10
    assert float(scale_invariant_log_loss(t**2, t, mask)) > 1e-4


def test_gradient_matching_pays_for_compressed_relief_not_for_scale() -> None:
    # A ramp in log depth (a ground seen at a slant) with a step (an object's edge).
    log_t = torch.linspace(0.0, 2.0, 16).reshape(1, 1, 16, 1).expand(1, 1, 16, 16).clone()
    log_t[..., 4:8, 6:10] -= 0.7
    t = torch.exp(log_t)
    mask = torch.ones_like(t, dtype=torch.bool)
    assert float(gradient_matching_loss(5.0 * t, t, mask)) < 1e-6  # scale is free
    flat = float(gradient_matching_loss(torch.exp(0.3 * log_t), t, mask))
    close = float(gradient_matching_loss(torch.exp(0.9 * log_t), t, mask))
    assert flat > 3 * close > 0  # compressed relief pays, more the flatter
    # Masked-out pixels (sky) neither count nor break it, whatever the depth there.
    t_sky = torch.where(mask & (torch.arange(16).reshape(1, 1, 1, 16) < 12), t,
                        torch.full_like(t, float("inf")))
    sky_mask = torch.isfinite(t_sky)
    assert float(gradient_matching_loss(2.0 * t, t_sky, sky_mask)) < 1e-6
    with pytest.raises(ValueError, match="scales"):
        gradient_matching_loss(t, t, mask, scales=0)


def test_normal_loss_is_one_minus_cosine_on_the_mask() -> None:
    up = torch.zeros(1, 3, 4, 4)
    up[:, 1] = -1.0
    side = torch.zeros(1, 3, 4, 4)
    side[:, 0] = 1.0
    mask = torch.ones(1, 1, 4, 4, dtype=torch.bool)
    assert float(normal_loss(up, up, mask)) == pytest.approx(0.0)
    assert float(normal_loss(side, up, mask)) == pytest.approx(1.0)
    assert float(normal_loss(-up, up, mask)) == pytest.approx(2.0)
    half = mask.clone()
    half[..., 2:] = False
    mixed = torch.where(half, up, side)
    assert float(normal_loss(mixed, up, half)) == pytest.approx(0.0)  # only the mask counts
    assert float(normal_loss(side, torch.zeros_like(up), mask)) == 0.0  # no truth, no cost


def test_parameter_budgets() -> None:
    counts = {k: count_parameters(build(k)) for k in NETWORKS}
    assert 150_000 < counts["shadow"] < 350_000
    assert 350_000 < counts["relight"] < 700_000
    assert 700_000 < counts["depth"] < 1_300_000
    assert 500_000 < counts["sun"] < 1_000_000


def test_sun_net_shapes_targets_and_zs_encoder_names() -> None:
    from outcast_core.nets.sun import BINS, SunNet, expected_angle_deg, soft_target, sun_loss

    net = SunNet().eval()
    logits = net(torch.rand(2, 3, 48, 64))  # any multiple of 16, not square
    assert logits.shape == (2, BINS)
    # The encoder's parameters are named as Z's, so a run can start it from models/depth.onnx.
    z = build("depth").state_dict()
    enc = {k: v for k, v in net.state_dict().items() if k.startswith("unet.enc.")}
    assert enc and all(k in z and z[k].shape == v.shape for k, v in enc.items())
    sun = torch.nn.functional.normalize(torch.tensor([[0.3, -0.8, 0.5], [-0.6, -0.2, -0.7]]),
                                        dim=1)
    t = soft_target(sun, net.bins)
    torch.testing.assert_close(t.sum(dim=1), torch.ones(2))
    nearest = (sun @ net.bins.T).argmax(dim=1)
    assert torch.equal(t.argmax(dim=1), nearest)
    # The loss is lowest for logits that put the target's mass where it is, and the coarse
    # angle of such logits is the bin spacing's, not the far side of the sphere.
    good = torch.log(t + 1e-9)
    assert sun_loss(good, sun, net.bins) < sun_loss(torch.zeros_like(good), sun, net.bins)
    assert float(expected_angle_deg(good, sun, net.bins).max()) < 10.0
    assert float(expected_angle_deg(-good, sun, net.bins).min()) > 90.0
    with pytest.raises(ValueError, match="B x 3 x H x W"):
        net(torch.rand(1, 1, 32, 32))
    # Frozen levels (Z's finest features kept) take no gradient; the rest do.
    frozen = SunNet(freeze=2)
    sun_loss(frozen(torch.rand(1, 3, 32, 32)), sun[:1], frozen.bins).backward()
    grads = {k: p.grad is not None for k, p in frozen.named_parameters()}
    assert not any(v for k, v in grads.items() if k.startswith(("unet.enc.0.", "unet.enc.1.")))
    assert all(v for k, v in grads.items() if not k.startswith(("unet.enc.0.", "unet.enc.1.")))
    with pytest.raises(ValueError, match="freeze"):
        SunNet(freeze=6)


def test_unknown_kind_raises() -> None:
    with pytest.raises(ValueError, match="network kind"):
        build("nope")
