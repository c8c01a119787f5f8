"""The paper's Table 1 on held-out synthetic views, and S's speed/accuracy sweep.

Table 1 (relighting DSSIM and MSE, shadow MSE, onnxruntime time per image) compares:

* ``Pix2Pix-like``: ``relight_pix2pix.onnx`` (no shadow inputs);
* ``2D``: ``shadow_2d.onnx`` shadows fed to our ``R`` and ``L``;
* ``Direct``: the runtime's Direct shadows
(:func:`outcast_core.runtime.geometry.shadows.direct_shadow`)
  fed to our ``R`` and ``L``;
* ``Physics``: the runtime's non-learned relighting (shading ratios) on Direct shadows, and on
  our ``S`` shadows;
* ``Ours``: ``shadow.onnx`` + ``refine.onnx`` + ``relight.onnx``;
* ``Input``: the unchanged photo (what every method must beat).

Every pair ``(i, j)``, ``i != j``, of a view is one test image: the photo under sun ``i`` is
relit to sun ``j`` and compared with the render under sun ``j``; both are tone-mapped with the
view's exposure (no augmentation). Shadow networks and Direct get the ground-truth depth (sky =
no surface) and normals computed from it as the runtime does; ``L`` and Pix2Pix-like get normals
from ``Z``'s post-processed depth when ``Z`` is installed, as the app runs them (they were trained
on normals from ``Z``'s raw depth). ``Ours (Z depth)`` is the whole photo-only pipeline, where
``Z``'s depth and sky of the photo replace the ground truth for the shadows too (what the app does
on a photo without a depth map); ``Direct (Z depth)`` is the app's Direct shadow mode on that same
depth, fed to ``R`` and ``L`` like the rest. Shadow MSE is ``S(C_i, w_j)`` against the
ground-truth shadow image ``j`` over the whole frame.

When ``depth.onnx`` is present, ``Z`` is also scored on its own (:func:`evaluate_table`'s
``depth`` entry): scale-free depth errors and sky IoU against the ground truth, next to the
runtime's ground-plane prior (what the app falls back to without ``Z``).
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from outcast_core.eval.metrics import depth_errors, dssim, iou, mse
from outcast_core.eval.onnx_models import TimedModel
from outcast_core.runtime.geometry.camera import (
    Camera,
    network_depth,
    normals_from_depth,
    view_directions,
)
from outcast_core.runtime.geometry.shadows import direct_shadow
from outcast_core.runtime.pipeline.depth_post import postprocess_z
from outcast_core.runtime.pipeline.relight import estimate_light_on_surfaces, physics_relight
from outcast_core.runtime.pipeline.session import ground_plane_depth
from outcast_core.train.data import Prepared, auto_exposure, load_prepared, tonemap


@dataclass
class TestView:
    """One held-out view ready for the networks (batch-1 NCHW float32 arrays)."""

    prep: Prepared
    images: list[np.ndarray]  # K x (H x W x 3) sRGB
    sky: np.ndarray

    @property
    def camera(self) -> Camera:
        return self.prep.camera

    def chw(self, k: int) -> np.ndarray:
        return np.moveaxis(self.images[k], -1, 0)[None]

    def depth_in(self) -> np.ndarray:
        d = np.where(self.sky, 0.0, self.prep.depth)
        return d[None, None].astype(np.float32)

    def normals_in(self) -> np.ndarray:
        return np.moveaxis(self.prep.normals, -1, 0)[None].astype(np.float32)

    def psi_in(self) -> np.ndarray:
        return np.moveaxis(view_directions(self.camera), -1, 0)[None].astype(np.float32)

    def focal_in(self) -> np.ndarray:
        return np.array([[self.prep.focal]], np.float32)

    def sun_in(self, k: int) -> np.ndarray:
        return self.prep.sun[k][None].astype(np.float32)


def load_test_views(data: str | Path, size: int = 128, max_views: int = 0) -> list[TestView]:
    out = []
    for p in load_prepared(data, size, max_views):
        e = p.exposure if p.exposure > 0 else auto_exposure(p.rgb[0])
        imgs = [tonemap(p.rgb[k], e) for k in range(p.rgb.shape[0])]
        out.append(TestView(p, imgs, ~np.isfinite(p.depth)))
    return out


def pairs(view: TestView) -> Iterator[tuple[int, int]]:
    k = view.prep.rgb.shape[0]
    for i in range(k):
        for j in range(k):
            if i != j:
                yield i, j


def _load(models: Path, name: str, threads: int) -> TimedModel | None:
    p = models / f"{name}.onnx"
    return TimedModel(p, threads) if p.is_file() else None


def _hw(a: np.ndarray) -> np.ndarray:
    return np.moveaxis(a[0], 0, -1) if a.shape[1] == 3 else a[0, 0]


def evaluate_table(
    data: str | Path, models: str | Path = "models", max_views: int = 0, threads: int = 2,
    sheet_pairs: int = 6,
) -> dict[str, Any]:
    """Run every available method on every test pair; returns per-method means and a sheet.

    Returns:
        ``{"rows": {method: {"dssim", "mse", "shadow_mse", "time_s", "n"}}, "missing": [...],
        "views": n, "pairs": n, "sheet": list of image rows, "depth": {source: {"silog",
        "abs_rel", "delta1", "sky_iou", "time_s", "n"}}}`` (``depth`` empty without ``Z``).
    """
    models = Path(models)
    m = {n: _load(models, n, threads)
         for n in ("depth", "shadow", "shadow_2d", "refine", "relight", "relight_pix2pix")}
    missing = sorted(n for n, v in m.items() if v is None)
    views = load_test_views(data, max_views=max_views)
    acc: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    dacc: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    sheet: list[list[np.ndarray]] = []
    n_pairs = 0
    for v_idx, view in enumerate(views):
        depth, normals, psi, focal = view.depth_in(), view.normals_in(), view.psi_in(), \
            view.focal_in()
        k = view.prep.rgb.shape[0]
        direct, t_direct = [], []
        for s in range(k):
            t = time.perf_counter()
            direct.append(direct_shadow(view.prep.depth, view.camera, view.prep.sun[s],
                                        normals=view.prep.normals, sky=view.sky))
            t_direct.append(time.perf_counter() - t)
        z_geo = _depth_from_z(m["depth"], view, dacc) if m["depth"] is not None else None
        z_direct: dict[tuple[int, int], tuple[np.ndarray, float]] = {}  # (photo, sun)
        view_pairs = list(pairs(view))
        show = view_pairs[v_idx % len(view_pairs)]  # the sheet: one pair of each of the first views
        for i, j in view_pairs:
            n_pairs += 1
            c_o, c_o_in = view.images[i], view.chw(i)
            gt, gt_s = view.images[j], view.prep.shadow[j]
            w_o, w_n = view.sun_in(i), view.sun_in(j)
            shadows: dict[str, tuple[np.ndarray, np.ndarray, float]] = {
                "Direct": (direct[i], direct[j], t_direct[i] + t_direct[j]),
            }
            for label, name in (("Ours", "shadow"), ("2D", "shadow_2d")):
                net = m[name]
                if net is None:
                    continue
                (so,), t1 = net.run(image=c_o_in, depth=depth, normals=normals, sun=w_o,
                                    focal=focal)
                (sn,), t2 = net.run(image=c_o_in, depth=depth, normals=normals, sun=w_n,
                                    focal=focal)
                shadows[label] = (so[0, 0], sn[0, 0], t1 + t2)
            if z_geo is not None and m["shadow"] is not None:
                zd, zn, tz, z_depth, z_sky = z_geo[i]
                (so,), t1 = m["shadow"].run(image=c_o_in, depth=zd, normals=zn, sun=w_o,
                                            focal=focal)
                (sn,), t2 = m["shadow"].run(image=c_o_in, depth=zd, normals=zn, sun=w_n,
                                            focal=focal)
                shadows["Ours (Z depth)"] = (so[0, 0], sn[0, 0], tz + t1 + t2)
                # Direct on the same estimated depth: the photo pipeline's other shadow mode
                # (each photo's shadow per sun computed once, its time counted in every pair).
                for k in (i, j):
                    if (i, k) not in z_direct:
                        t = time.perf_counter()
                        d = direct_shadow(z_depth, view.camera, view.prep.sun[k],
                                          normals=np.moveaxis(zn[0], 0, -1), sky=z_sky)
                        z_direct[i, k] = (d, time.perf_counter() - t)
                (d_o, t_o), (d_n, t_n) = z_direct[i, i], z_direct[i, j]
                shadows["Direct (Z depth)"] = (d_o, d_n, tz + t_o + t_n)
            row = {"Input": c_o}
            acc["Input"]["dssim"].append(dssim(c_o, gt))
            acc["Input"]["mse"].append(mse(c_o, gt))
            acc["Input"]["time_s"].append(0.0)
            for label, (so, sn, ts) in shadows.items():
                acc[label]["shadow_mse"].append(mse(sn, gt_s))
                if m["refine"] is not None and m["relight"] is not None:
                    # L (and Pix2Pix-like) were trained on normals from Z's depth (the paper's
                    # recipe); every row feeds them normals from Z's post-processed depth, as the
                    # app does. Z's time is counted only in "Ours (Z depth)".
                    nrm = z_geo[i][1] if z_geo else normals
                    (so_r,), t_r = m["refine"].run(shadow=so[None, None], image=c_o_in, sun=w_o)
                    ratio = np.ones(3, np.float32)
                    if "light_ratio" in m["relight"].inputs:
                        # L with the physics base takes the light ratio, estimated as the app
                        # does (the sky: pixels without normals).
                        t = time.perf_counter()
                        ratio = estimate_light_on_surfaces(
                            c_o, so_r[0, 0], np.moveaxis(nrm[0], 0, -1)).ratio
                        t_r += time.perf_counter() - t
                    (c_n,), t_l = m["relight"].run(
                        image=c_o_in, shadow_old=so_r, shadow_new=sn[None, None],
                        normals=nrm, sun_old=w_o, sun_new=w_n, view_dirs=psi,
                        light_ratio=ratio[None],
                    )
                    out = _hw(c_n)
                    acc[label]["dssim"].append(dssim(out, gt))
                    acc[label]["mse"].append(mse(out, gt))
                    acc[label]["time_s"].append(ts + t_r + t_l)
                    row[label] = out
                elif label != "Direct":
                    acc[label]["time_s"].append(ts)
                if label in ("Direct", "Ours"):
                    t = time.perf_counter()
                    phys = physics_relight(c_o, so, sn, view.sky)
                    tp = time.perf_counter() - t
                    key = f"Physics ({label} shadows)"
                    acc[key]["dssim"].append(dssim(phys, gt))
                    acc[key]["mse"].append(mse(phys, gt))
                    acc[key]["time_s"].append(ts + tp)
                    row[key] = phys
            if m["relight_pix2pix"] is not None:
                (c_n,), t_p = m["relight_pix2pix"].run(
                    image=c_o_in, normals=z_geo[i][1] if z_geo else normals, sun_old=w_o,
                    sun_new=w_n, view_dirs=psi,
                )
                out = _hw(c_n)
                acc["Pix2Pix-like"]["dssim"].append(dssim(out, gt))
                acc["Pix2Pix-like"]["mse"].append(mse(out, gt))
                acc["Pix2Pix-like"]["time_s"].append(t_p)
                row["Pix2Pix-like"] = out
            if len(sheet) < sheet_pairs and (i, j) == show:
                row["Target"] = gt
                row["S_n ground truth"] = gt_s
                for label, (_, sn, _) in shadows.items():
                    row[f"S_n {label}"] = sn
                sheet.append(row)
    rows = {
        method: {k: float(np.mean(v)) for k, v in d.items()} | {"n": len(next(iter(d.values())))}
        for method, d in acc.items()
    }
    depth_rows = _depth_rows(dacc)
    return {"rows": rows, "missing": missing, "views": len(views), "pairs": n_pairs,
            "sheet": sheet, "depth": depth_rows}


def _depth_rows(dacc: dict[str, dict[str, list[float]]]) -> dict[str, dict[str, float]]:
    """Per depth source: the mean of each score over the photos, and their number."""
    return {
        src: {k: float(np.nanmean(v)) for k, v in d.items()} | {"n": len(d["silog"])}
        for src, d in dacc.items()
    }


def evaluate_depth(
    data: str | Path, models: str | Path = "models", max_views: int = 0, threads: int = 2,
) -> dict[str, Any]:
    """``Z`` alone on every photo of ``data`` (views of any number of suns, e.g. one-sun
    landscapes): ``{"data": folder, "views": n, "photos": n, "depth": {source: {"silog", ...}}}``
    as in :func:`evaluate_table`.

    Raises:
        ValueError: no ``depth.onnx`` in ``models``, or no views in ``data``.
    """
    model = _load(Path(models), "depth", threads)
    if model is None:
        raise ValueError(f"expected {Path(models) / 'depth.onnx'}, got no such file")
    views = load_test_views(data, max_views=max_views)
    dacc: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for view in views:
        _depth_from_z(model, view, dacc)
        _depth_at_scales(model, view, dacc)
    depth_rows = _depth_rows(dacc)
    return {"data": str(data), "views": len(views), "photos": depth_rows["Z"]["n"],
            "depth": depth_rows}


#: Scales of :func:`_depth_at_scales`: how much larger than at training the views are shown.
DEPTH_SCALES = (1.5, 2.0, 3.0)


def _depth_at_scales(
    model: TimedModel, view: TestView, dacc: dict[str, dict[str, list[float]]]
) -> None:
    """Raw ``Z`` on each photo of ``view`` upsampled (bicubic) by each of :data:`DEPTH_SCALES`,
    its log depth shrunk back (area) and scored against the ground truth: how much worse ``Z``
    gets on an image larger than the views it was trained on, which is why the app runs it at
    its training scale (:func:`outcast_core.runtime.pipeline.depth_post.run_depth_model`)."""
    gt, valid = view.prep.depth, ~view.sky
    h, w = gt.shape
    for s in range(view.prep.rgb.shape[0]):
        for f in DEPTH_SCALES:
            big = cv2.resize(view.images[s], (round(w * f), round(h * f)),
                             interpolation=cv2.INTER_CUBIC).clip(0.0, 1.0)
            (d, _), t = model.run(image=big.transpose(2, 0, 1)[None])
            log_d = np.log(np.maximum(d[0, 0, : big.shape[0], : big.shape[1]], 1e-6))
            depth = np.exp(cv2.resize(log_d, (w, h), interpolation=cv2.INTER_AREA))
            for k, v in (depth_errors(depth, gt, valid) | {"time_s": t}).items():
                dacc[f"Z, view shown {f:g}x larger"][k].append(v)


def _depth_from_z(
    model: TimedModel, view: TestView, dacc: dict[str, dict[str, list[float]]]
) -> list[tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]]:
    """``Z`` on each photo of ``view``: network inputs (depth with sky 0, normals), time, and
    the post-processed ``H x W`` depth and sky; scores ``Z`` and the ground-plane prior into
    ``dacc``."""
    gt, gt_sky = view.prep.depth, view.sky
    out = []
    for s in range(view.prep.rgb.shape[0]):
        (d, sky_prob), t = model.run(image=view.chw(s))
        depth, z_sky = np.maximum(d[0, 0], 1e-6), sky_prob[0, 0] > 0.5
        scores = depth_errors(depth, gt, ~gt_sky) | {"sky_iou": iou(z_sky, gt_sky), "time_s": t}
        for k, v in scores.items():
            dacc["Z"][k].append(v)
        # What the app uses: sky prior, smoothing, ground plane
        # (runtime.pipeline.depth_post.postprocess_z).
        t0 = time.perf_counter()
        depth, sky = postprocess_z(d[0, 0], sky_prob[0, 0], view.images[s], view.camera)
        t += time.perf_counter() - t0
        app = depth_errors(depth, gt, ~gt_sky)
        for k, v in (app | {"sky_iou": iou(sky, gt_sky), "time_s": t}).items():
            dacc["Z + post-processing (app)"][k].append(v)
        # The network inputs as the session makes them (sky: inf for normals, 0 for S).
        depth_sky = np.where(sky, np.inf, depth).astype(np.float32)
        normals = normals_from_depth(depth_sky, view.camera)
        out.append((network_depth(depth_sky)[None, None],
                    np.moveaxis(normals, -1, 0)[None].astype(np.float32), t, depth, sky))
    t = time.perf_counter()
    prior, prior_sky = ground_plane_depth(view.camera)
    t = time.perf_counter() - t
    scores = depth_errors(prior, gt, ~gt_sky) | {"sky_iou": iou(prior_sky, gt_sky), "time_s": t}
    for k, v in scores.items():
        dacc["Ground-plane prior"][k].append(v)
    return out


def save_sheet(rows: list[dict[str, np.ndarray]], path: str | Path, tile: int = 128) -> Path:
    """A PNG contact sheet: one test pair (or photo) per row, one method per column, labelled.

    Tiles are ``tile`` wide; each row is as tall as its first image's aspect ratio asks, so
    photos are not squashed.
    """
    if not rows:
        raise ValueError("expected at least one sheet row, got none")
    cols = list(rows[0])
    for r in rows[1:]:
        cols += [c for c in r if c not in cols]
    head = 18
    heights = []
    for row in rows:
        h0, w0 = np.asarray(next(iter(row.values()))).shape[:2]
        heights.append(max(8, round(tile * h0 / w0)))
    canvas = np.full((head + sum(heights), tile * len(cols), 3), 255, np.uint8)
    for c, name in enumerate(cols):
        cv2.putText(canvas, name[:22], (c * tile + 2, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.33,
                    (0, 0, 0), 1, cv2.LINE_AA)
        y = head
        for row, th in zip(rows, heights, strict=True):
            if name in row:
                img = np.asarray(row[name], np.float32)
                if img.ndim == 2:
                    img = np.repeat(img[..., None], 3, axis=2)
                img = cv2.resize(img, (tile, th), interpolation=cv2.INTER_AREA)
                canvas[y : y + th, c * tile : (c + 1) * tile] = np.clip(img * 255 + 0.5, 0, 255)
            y += th
    path = Path(path)
    cv2.imwrite(str(path), cv2.cvtColor(canvas, cv2.COLOR_RGB2BGR))
    return path


def _resize_inputs(view: TestView, k: int, size: int) -> dict[str, np.ndarray]:
    h0, w0 = view.prep.depth.shape
    h, w = (size, round(w0 * size / h0)) if h0 >= w0 else (round(h0 * size / w0), size)
    interp = cv2.INTER_AREA if size < max(h0, w0) else cv2.INTER_LINEAR
    img = cv2.resize(view.images[k], (w, h), interpolation=interp)
    depth = cv2.resize(view.prep.depth, (w, h), interpolation=cv2.INTER_NEAREST)
    cam = view.camera.resized(h, w)
    normals = normals_from_depth(depth, cam)
    depth = np.where(np.isfinite(depth), depth, 0.0)
    return {"image": np.moveaxis(img, -1, 0)[None], "depth": depth[None, None],
            "normals": np.moveaxis(normals, -1, 0)[None], "focal": np.array([[cam.focal]])}


def speed_accuracy(
    data: str | Path, checkpoint: str | Path, steps: tuple[int, ...] = (8, 16, 32, 64),
    sizes: tuple[int, ...] = (96, 128, 192, 256), max_views: int = 12, threads: int = 2,
    workdir: str | Path | None = None,
) -> list[dict[str, Any]]:
    """Shadow MSE (at the data's resolution) and onnxruntime latency of ``S`` per (z, size).

    The trained weights are re-exported with each march length ``z`` (the march step is kept,
    so ``z`` sets the reach); inputs are resized to each working size and the output resized back
    to the ground truth's size before the MSE.
    """
    import tempfile

    import torch

    from outcast_core.export.onnx_export import export_onnx
    from outcast_core.train.trainer import load_checkpoint_nets

    nets, _ = load_checkpoint_nets(checkpoint)
    net = nets["shadow"]
    views = load_test_views(data, max_views=max_views)
    results = []
    tmp = Path(workdir) if workdir else Path(tempfile.mkdtemp(prefix="outcast_sweep_"))
    for z in steps:
        net.steps = int(z)
        path = tmp / f"shadow_z{z}.onnx"
        with torch.no_grad():
            export_onnx(net, "shadow", path, [(64, 64), (48, 80)])
        model = TimedModel(path, threads)
        for size in sizes:
            errs, times = [], []
            for view in views:
                h0, w0 = view.prep.depth.shape
                for i, j in pairs(view):
                    inp = _resize_inputs(view, i, size)
                    (out,), t = model.run(sun=view.sun_in(j), **inp)
                    s = cv2.resize(out[0, 0], (w0, h0), interpolation=cv2.INTER_AREA
                                   if size > max(h0, w0) else cv2.INTER_LINEAR)
                    errs.append(mse(s, view.prep.shadow[j]))
                    times.append(t)
            results.append({"steps": int(z), "size": int(size), "shadow_mse": float(np.mean(errs)),
                            "latency_ms": float(np.median(times) * 1000), "n": len(errs)})
    return results


def plot_speed_accuracy(results: list[dict[str, Any]], path: str | Path) -> Path:
    """A PNG plot (OpenCV drawing): latency (x, log) against shadow MSE (y), one line per size."""
    w, h, m = 640, 420, 60
    img = np.full((h, w, 3), 255, np.uint8)
    xs = np.log10([r["latency_ms"] for r in results])
    ys = np.array([r["shadow_mse"] for r in results])
    x0, x1 = xs.min() - 0.05, xs.max() + 0.05
    y0, y1 = ys.min() * 0.95, ys.max() * 1.05

    def px(x: float, y: float) -> tuple[int, int]:
        return (int(m + (x - x0) / (x1 - x0) * (w - 2 * m)),
                int(h - m - (y - y0) / (y1 - y0) * (h - 2 * m)))

    cv2.rectangle(img, (m, m), (w - m, h - m), (0, 0, 0), 1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    cv2.putText(img, "S: shadow MSE vs onnxruntime latency (labels: march steps z)", (m, 25),
                font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, "latency per frame, ms (log)", (w // 2 - 90, h - 15), font, 0.45, (0, 0, 0),
                1, cv2.LINE_AA)
    cv2.putText(img, f"{y1:.4f}", (2, m + 5), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, f"{y0:.4f}", (2, h - m), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    for t in range(int(np.floor(x0)), int(np.ceil(x1)) + 1):
        for sub in (1, 2, 5):
            v = np.log10(sub) + t
            if x0 <= v <= x1:
                x, _ = px(v, y0)
                cv2.line(img, (x, h - m), (x, h - m + 4), (0, 0, 0), 1)
                cv2.putText(img, f"{10 ** v:g}", (x - 8, h - m + 16), font, 0.35, (0, 0, 0), 1)
    colours = [(200, 60, 40), (40, 150, 40), (40, 60, 220), (150, 40, 160), (0, 140, 200)]
    sizes = sorted({r["size"] for r in results})
    series = []
    for n, size in enumerate(sizes):
        pts = sorted((r for r in results if r["size"] == size), key=lambda r: r["steps"])
        col = colours[n % len(colours)]
        coords = [px(np.log10(r["latency_ms"]), r["shadow_mse"]) for r in pts]
        for a, b in zip(coords[:-1], coords[1:], strict=True):
            cv2.line(img, a, b, col, 2, cv2.LINE_AA)
        for c in coords:
            cv2.circle(img, c, 4, col, -1)
        series.append((pts, coords, col))
    # Labels after all points, each at the first of four corners where it overlaps no point, no
    # legend entry and no label placed before it (else the least-overlapping corner).
    placed = [(c[0] - 5, c[1] - 5, c[0] + 5, c[1] + 5) for _, coords, _ in series for c in coords]
    placed += [(w - m - 62, m + 4 + 16 * n, w - m, m + 22 + 16 * n) for n in range(len(sizes))]
    for pts, coords, col in series:
        for r, c in zip(pts, coords, strict=True):
            text = str(r["steps"])
            (tw, th), _ = cv2.getTextSize(text, font, 0.35, 1)
            corners = [(c[0] + 5, c[1] - 5), (c[0] + 5, c[1] + th + 5),
                       (c[0] - tw - 5, c[1] - 5), (c[0] - tw - 5, c[1] + th + 5)]

            def overlap(o: tuple[int, int], tw: int = tw, th: int = th) -> int:
                box = (o[0], o[1] - th, o[0] + tw, o[1])
                return sum(max(0, min(box[2], b[2]) - max(box[0], b[0]))
                           * max(0, min(box[3], b[3]) - max(box[1], b[1])) for b in placed)

            org = min(corners, key=overlap)  # min keeps the first of equal overlaps
            placed.append((org[0], org[1] - th, org[0] + tw, org[1]))
            cv2.putText(img, text, org, font, 0.35, col, 1)
    for n, (size, (_, _, col)) in enumerate(zip(sizes, series, strict=True)):
        cv2.putText(img, f"{size} px", (w - m - 60, m + 18 + 16 * n), font, 0.45, col, 1,
                    cv2.LINE_AA)
    path = Path(path)
    cv2.imwrite(str(path), img)
    return path
