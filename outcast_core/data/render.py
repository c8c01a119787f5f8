"""Render a :class:`~outcast_core.data.scene.SceneSpec` with Mitsuba 3 (``scalar_rgb``).

Per view the renderer builds two Mitsuba scenes from the *same culled* triangles:

* the RGB scene: textured materials, Mitsuba's ``sunsky`` model (Hosek-Wilkie sky + sun) baked
  per sun into an ``envmap`` + ``directional`` emitter (:mod:`outcast_core.data.sky`; 1.5-1.6x
  faster than the ``sunsky`` emitter and within 3 % of it, see the tests), path tracing;
* the white scene: every surface white twosided Lambertian, one ``directional`` emitter of
  irradiance pi, direct lighting only, one ray through each pixel centre. Its radiance is exactly
  ``max(0, N.w) * visibility`` (the shadow image), and its AOVs give the position and geometric
  normal of the surface seen through each pixel centre (depth and normals).

Off-screen casters: every triangle wholly outside the view frustum (all three corners beyond one
frustum plane, with a 2-pixel margin) is dropped before either scene is built, so neither the RGB
nor the shadow image sees shadows of off-screen geometry.

Mitsuba is imported lazily (only this module needs it). Mitsuba's camera looks down its local +z
with +x to the left and +y up; OutCast's camera has x right, y down, z forward, so the sensor's
``to_world`` is ``[-x_cam, -y_cam, z_cam, origin]`` in world coordinates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from outcast_core.data.meshes import Mesh, concat
from outcast_core.data.scene import SceneSpec
from outcast_core.data.sky import (
    ENV_HEIGHT,
    ENV_WIDTH,
    SunSky,
    env_to_world_matrix,
    sun_disc_coverage,
)
from outcast_core.runtime.geometry.camera import Camera

VARIANT = "scalar_rgb"
MAX_DEPTH = 5  # path length: up to 4 bounces
CULL_MARGIN_PX = 2.0
NEAR_CLIP = 0.01
HALF_FLOAT_MAX = 60000.0


def _mi() -> Any:
    import mitsuba as mi

    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    return mi


def cull_to_frustum(
    spec: SceneSpec, height: int, width: int, margin_px: float = CULL_MARGIN_PX
) -> list[tuple[Mesh, int]]:
    """Drop every triangle that lies wholly outside the camera's view frustum.

    Args:
        spec: the scene.
        height: image height in pixels. width: image width in pixels.
        margin_px: the frustum is widened by this many pixels on each side.

    Returns:
        ``(mesh, material)`` pairs holding only the kept triangles (parts with none are dropped).
    """
    cam = Camera.from_fov(height, width, spec.camera.fov_deg)
    tx = (width / 2 + margin_px) / cam.focal
    ty = (height / 2 + margin_px) / cam.focal
    kept = []
    for mesh, mat in spec.parts:
        if len(mesh.faces) == 0:
            continue
        p = spec.camera.world_to_camera(mesh.vertices)  # V x 3
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        outside = np.stack(
            [x + tx * z < 0, tx * z - x < 0, y + ty * z < 0, ty * z - y < 0, z < NEAR_CLIP], axis=1
        )  # V x 5
        tri_out = outside[mesh.faces]  # F x 3 x 5
        culled = np.any(np.all(tri_out, axis=1), axis=1)  # F
        if culled.all():
            continue
        faces = mesh.faces[~culled]
        used, inverse = np.unique(faces, return_inverse=True)
        kept.append((Mesh(mesh.vertices[used], inverse.reshape(-1, 3), mesh.uv[used]), mat))
    return kept


def _mesh(mi: Any, name: str, mesh: Mesh, uv_scale: tuple[float, float], bsdf: Any) -> Any:
    props = mi.Properties()
    props["bsdf"] = bsdf
    m = mi.Mesh(
        name,
        len(mesh.vertices),
        len(mesh.faces),
        props=props,
        has_vertex_normals=False,
        has_vertex_texcoords=True,
    )
    params = mi.traverse(m)
    params["vertex_positions"] = mesh.vertices.astype(np.float32).ravel()
    params["faces"] = mesh.faces.astype(np.uint32).ravel()
    uv = mesh.uv / np.asarray(uv_scale, np.float64)
    params["vertex_texcoords"] = uv.astype(np.float32).ravel()
    params.update()
    return m


def _sensor(mi: Any, spec: SceneSpec, height: int, width: int, sampler: dict) -> dict:
    C = spec.camera.rotation
    o = spec.camera.origin
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = -C[:, 0], -C[:, 1], C[:, 2], o
    return {
        "type": "perspective",
        "fov": float(spec.camera.fov_deg),
        "fov_axis": "x",
        "near_clip": NEAR_CLIP,
        "far_clip": 1e5,
        "to_world": mi.ScalarTransform4f(m.tolist()),
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": sampler,
    }


def _subpixel_rays(spec: SceneSpec, height: int, width: int, n: int = 4) -> np.ndarray:
    """World directions of ``n x n`` stratified rays per pixel, ``n*n x H x W x 3``."""
    cam = Camera.from_fov(height, width, spec.camera.fov_deg)
    offsets = (np.arange(n) + 0.5) / n
    out = []
    for oy in offsets:
        for ox in offsets:
            u = np.arange(width)[None, :] + ox
            v = np.arange(height)[:, None] + oy
            d = np.stack(
                np.broadcast_arrays(
                    (u - cam.cx) / cam.focal, (v - cam.cy) / cam.focal, np.ones((1, 1))
                ),
                axis=-1,
            )  # H x W x 3
            d = d / np.linalg.norm(d, axis=-1, keepdims=True)
            out.append(d @ spec.camera.rotation.T)
    return np.stack(out)


def _envmap_data(env: np.ndarray, current: Any) -> np.ndarray:
    """Mitsuba's internal envmap tensor for a lat-long image: one wrapped column on each side."""
    shape = tuple(np.array(current).shape)
    padded = np.concatenate([env[:, -1:], env, env[:, :1]], axis=1)
    if shape != padded.shape:
        raise RuntimeError(f"expected Mitsuba's envmap data of shape {padded.shape}, got {shape}")
    return np.ascontiguousarray(padded)


def _directional_to_world(mi: Any, direction: np.ndarray) -> Any:
    """``to_world`` of a directional emitter shining along ``direction`` (its local +z)."""
    d = np.asarray(direction, np.float64)
    up = [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0]
    return mi.ScalarTransform4f().look_at(origin=[0.0, 0.0, 0.0], target=d.tolist(), up=up)


def _bsdf(mi: Any, material: Any) -> Any:
    tex = {
        "type": "bitmap",
        "bitmap": mi.Bitmap(np.ascontiguousarray(material.texture.image)),
        "raw": True,
    }
    if material.kind == "plastic":
        inner = {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": float(material.roughness),
            "diffuse_reflectance": tex,
        }
    else:
        inner = {"type": "diffuse", "reflectance": tex}
    return mi.load_dict({"type": "twosided", "bsdf": inner})


def build_scenes(
    spec: SceneSpec, height: int, width: int, spp: int, seed: int, cull: bool = True
) -> tuple[Any, Any]:
    """The RGB scene and the white (shadow / G-buffer) scene of one view.

    Both are built from the same triangles: those left by :func:`cull_to_frustum` (or all of them
    with ``cull=False``, which only tests use to show that culling matters).
    """
    mi = _mi()
    parts = cull_to_frustum(spec, height, width) if cull else list(spec.parts)
    by_mat: dict[int, list[Mesh]] = {}
    for mesh, mat in parts:
        by_mat.setdefault(mat, []).append(mesh)

    rgb: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH},
        "sensor": _sensor(
            mi,
            spec,
            height,
            width,
            {"type": "independent", "sample_count": int(spp), "seed": int(seed)},
        ),
        # Placeholders: render_view bakes the sunsky of every sun into these two emitters.
        "sky": {
            "type": "envmap",
            "bitmap": mi.Bitmap(np.full((ENV_HEIGHT, ENV_WIDTH, 3), 0.1, np.float32)),
            "to_world": mi.ScalarTransform4f(env_to_world_matrix()),
        },
        "sun": {
            "type": "directional",
            "direction": [0.0, 0.0, -1.0],
            "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
        },
    }
    white_bsdf = mi.load_dict(
        {
            "type": "twosided",
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}},
        }
    )
    white: dict[str, Any] = {
        "type": "scene",
        "integrator": {
            "type": "aov",
            "aovs": "pp:position,nn:geo_normal",
            "shade": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        },
        "sensor": _sensor(
            mi, spec, height, width, {"type": "stratified", "sample_count": 1, "jitter": False}
        ),
        "sun": {
            "type": "directional",
            "direction": [0.0, 0.0, -1.0],
            "irradiance": {"type": "rgb", "value": math.pi},
        },
    }
    all_meshes = []
    for mat, meshes in sorted(by_mat.items()):
        merged = concat(meshes)
        material = spec.materials[mat]
        rgb[f"m{mat}"] = _mesh(mi, f"m{mat}", merged, material.texture.period, _bsdf(mi, material))
        all_meshes.append(merged)
    if all_meshes:
        white["geometry"] = _mesh(mi, "white", concat(all_meshes), (1.0, 1.0), white_bsdf)
    return mi.load_dict(rgb), mi.load_dict(white)


def render_view(
    spec: SceneSpec, res: int | tuple[int, int], spp: int, seed: int, cull: bool = True
) -> dict[str, Any]:
    """Render every sun of one view.

    Args:
        spec: scene from :func:`~outcast_core.data.scene.generate_scene`.
        res: image size (square) or ``(height, width)``.
        spp: samples per pixel of the path-traced RGB images.
        seed: sampler seed (the same seed gives bit-identical images).
        cull: drop geometry outside the view frustum first (always, except in tests).

    Returns:
        Dict with ``rgb`` (K x H x W x 3 float32 linear radiance), ``shadow`` (K x H x W float32),
        ``depth`` (H x W float32, +inf on sky), ``normals`` (H x W x 3 float32, camera space,
        facing the camera, 0 on sky), ``sky`` (H x W bool), ``sun`` (K x 3 float32 camera-space
        unit vectors), ``sun_azel`` (K x 2 float32 degrees), ``fov_deg`` (float).
    """
    height, width = (res, res) if isinstance(res, int) else res
    if height < 1 or width < 1:
        raise ValueError(f"expected a positive resolution, got {res}")
    if spp < 1:
        raise ValueError(f"expected spp >= 1, got {spp}")
    mi = _mi()
    rgb_scene, white_scene = build_scenes(spec, height, width, spp, seed, cull)
    rgb_params = mi.traverse(rgb_scene)
    white_params = mi.traverse(white_scene)
    sunsky = SunSky(spec.turbidity, spec.sky_albedo)
    C = spec.camera.rotation
    rays = _subpixel_rays(spec, height, width)  # S x H x W x 3, world
    K = len(spec.suns)
    rgb = np.zeros((K, height, width, 3), np.float32)
    shadow = np.zeros((K, height, width), np.float32)
    suns_cam = np.zeros((K, 3), np.float32)
    azel = np.zeros((K, 2), np.float32)
    depth = normals = sky = None
    for k, sun in enumerate(spec.suns):
        w_world = sun.world_direction(spec.camera)
        baked = sunsky.bake(w_world)
        rgb_params["sky.data"] = mi.TensorXf(_envmap_data(baked["envmap"], rgb_params["sky.data"]))
        rgb_params["sun.irradiance.value"] = mi.Color3f(*baked["sun_irradiance"].tolist())
        rgb_params["sun.to_world"] = _directional_to_world(mi, -w_world)
        rgb_params.update()
        white_params["sun.to_world"] = _directional_to_world(mi, -w_world)
        white_params.update()
        img = np.array(mi.render(rgb_scene, seed=int(seed)), dtype=np.float32)  # H x W x 3
        g = np.array(mi.render(white_scene), dtype=np.float32)  # H x W x 9
        sky_k = np.linalg.norm(g[..., 6:9], axis=-1) < 0.5
        disc = sun_disc_coverage(rays, w_world, baked["sun_radius"]) * sky_k  # H x W
        img = img[..., :3] + disc[..., None] * baked["sun_radiance"].astype(np.float32)
        rgb[k] = np.clip(np.nan_to_num(img, nan=0.0, posinf=HALF_FLOAT_MAX), 0.0, HALF_FLOAT_MAX)
        shadow[k] = np.clip(g[..., :3].mean(axis=-1), 0.0, 1.0)
        suns_cam[k] = sun.camera_direction(spec.camera)
        azel[k] = (sun.azimuth_deg % 360.0, sun.elevation_deg)
        if depth is None:
            pos, nrm = g[..., 3:6].astype(np.float64), g[..., 6:9].astype(np.float64)
            sky = np.linalg.norm(nrm, axis=-1) < 0.5
            p_cam = (pos - spec.camera.origin) @ C  # H x W x 3
            n_cam = nrm @ C
            n_cam /= np.maximum(np.linalg.norm(n_cam, axis=-1, keepdims=True), 1e-12)
            flip = np.sum(n_cam * p_cam, axis=-1, keepdims=True) > 0
            n_cam = np.where(flip, -n_cam, n_cam)
            sky |= p_cam[..., 2] <= 0
            depth = np.where(sky, np.inf, p_cam[..., 2]).astype(np.float32)
            normals = np.where(sky[..., None], 0.0, n_cam).astype(np.float32)
    if depth is None or normals is None or sky is None:
        raise ValueError(f"expected at least one sun, got {K}")
    shadow[:, sky] = 0.0
    return {
        "rgb": rgb,
        "shadow": shadow,
        "depth": depth,
        "normals": normals,
        "sky": sky,
        "sun": suns_cam,
        "sun_azel": azel,
        "fov_deg": float(spec.camera.fov_deg),
    }


def suggest_exposure(rgb: np.ndarray, sky: np.ndarray, key: float = 0.14) -> float:
    """One exposure for all suns of a view, like a camera's averaging meter.

    Maps the log-average luminance of the whole frame (sky included, highlights above the 98th
    percentile clipped so that a visible sun does not dominate) to ``key``.

    Args:
        rgb: ``K x H x W x 3`` linear radiance. sky: ``H x W`` sky mask (unused pixels none).

    Returns:
        A multiplier for ``rgb`` before :func:`~outcast_core.runtime.geometry.colour.tonemap_aces`.
    """
    lum = (rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)).reshape(-1)  # K*H*W
    lum = lum[np.isfinite(lum)]
    if lum.size == 0:
        return 1.0
    hi = max(float(np.percentile(lum, 98)), 1e-6)
    logavg = float(np.exp(np.mean(np.log(np.clip(lum, hi * 1e-3, hi)))))
    return float(np.clip(key / max(logavg, 1e-6), 0.5, 2000.0))
