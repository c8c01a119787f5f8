"""``outcast eval --data TESTDIR``: Table 1 and the S speed/accuracy sweep into ``models/EVAL.md``.

:func:`register` adds the sub-command; torch is imported only when it runs.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import shlex
from pathlib import Path
from typing import Any

PAPER = {  # Table 1 of the paper (their data), for orientation only
    "Pix2Pix-like": (".165", ".0427", "-"),
    "2D": (".169", ".0515", ".187"),
    "Direct": (".157", ".0409", ".358"),
    "Ours": (".154", ".0399", ".175"),
}
ORDER = ["Input", "Pix2Pix-like", "2D", "Direct", "Physics (Direct shadows)",
         "Physics (Ours shadows)", "Ours", "Direct (Z depth)", "Ours (Z depth)"]


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``eval`` to an ``argparse`` sub-parser collection; returns the new parser."""
    p = subparsers.add_parser(
        "eval", help="evaluate the shipped models on held-out synthetic views",
        description="Paper Table 1 (relighting DSSIM / MSE, shadow MSE, onnxruntime time per "
        "image) and the S speed/accuracy sweep, written to models/EVAL.md.",
    )
    p.add_argument("--data", required=True, help="held-out data folder (outcast data make)")
    p.add_argument("--models", default="models", help="folder of the ONNX models")
    p.add_argument("--max-views", type=int, default=0, help="use the first N views (0 = all)")
    p.add_argument("--sweep-checkpoint", default="",
                   help="S checkpoint (file or run name) for the steps x resolution sweep")
    p.add_argument("--sweep-views", type=int, default=12, help="views used by the sweep")
    p.add_argument("--samples", default="",
                   help="JSON of sample photos and suns (e.g. samples/suns.json): relight them "
                   "with the shipped models into samples_sheet.png")
    p.add_argument("--depth-data", default="",
                   help="a second held-out folder on which only Z is scored (e.g. one-sun "
                   "landscape views, a scene kind the Table 1 views do not have)")
    p.add_argument("--threads", type=int, default=2, help="onnxruntime threads")
    p.add_argument("--out", default="", help="report file (default: MODELS/EVAL.md)")
    p.add_argument("--no-manifest-update", action="store_true",
                   help="do not write the measured metrics into the manifests")
    p.set_defaults(func=run_eval)
    return p


def _fmt(v: float | None, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def render_table(res: dict[str, Any]) -> str:
    lines = [
        "| Method | DSSIM | MSE | Shadow MSE | Time / image (s) | Paper DSSIM / MSE / shadow MSE |",
        "|---|---|---|---|---|---|",
    ]
    rows = res["rows"]
    for method in ORDER + sorted(set(rows) - set(ORDER)):
        if method not in rows:
            continue
        r = rows[method]
        paper = " / ".join(PAPER.get(method, ("", "", ""))).strip(" /") or "-"
        lines.append(
            f"| {method} | {_fmt(r.get('dssim'))} | {_fmt(r.get('mse'))} | "
            f"{_fmt(r.get('shadow_mse'))} | {_fmt(r.get('time_s'), 3)} | {paper} |"
        )
    return "\n".join(lines)


def render_depth(depth: dict[str, Any]) -> str:
    lines = ["| Depth source | silog | AbsRel | delta < 1.25 | sky IoU | Time / image (s) |",
             "|---|---|---|---|---|---|"]
    for src, r in depth.items():
        lines.append(f"| {src} | {_fmt(r['silog'])} | {_fmt(r['abs_rel'])} | "
                     f"{_fmt(r['delta1'], 3)} | {_fmt(r.get('sky_iou'), 3)} | "
                     f"{_fmt(r['time_s'], 3)} |")
    return "\n".join(lines)


def render_sweep(results: list[dict[str, Any]]) -> str:
    sizes = sorted({r["size"] for r in results})
    steps = sorted({r["steps"] for r in results})
    by = {(r["steps"], r["size"]): r for r in results}
    head = "| z \\ size | " + " | ".join(f"{s} px" for s in sizes) + " |"
    lines = [head, "|---" * (len(sizes) + 1) + "|"]
    for z in steps:
        cells = [f"{by[(z, s)]['shadow_mse']:.4f} / {by[(z, s)]['latency_ms']:.0f} ms"
                 for s in sizes]
        lines.append(f"| {z} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run_eval(args: argparse.Namespace) -> int:
    from outcast_core.eval.table import (
        evaluate_depth,
        evaluate_table,
        plot_speed_accuracy,
        save_sheet,
        speed_accuracy,
    )
    from outcast_core.export.checkpoint import data_record, resolve_checkpoint
    models = Path(args.models)
    out = Path(args.out) if args.out else models / "EVAL.md"
    command = "outcast eval " + " ".join(
        shlex.quote(a) for a in _argv_of(args)
    )
    if args.depth_data and not (models / "depth.onnx").is_file():
        # Before the long table run, not after it.
        raise ValueError(f"expected {models / 'depth.onnx'} for --depth-data, got no such file")
    res = evaluate_table(args.data, models, args.max_views, args.threads)
    sheet = save_sheet(res["sheet"], out.parent / "eval_sheet.png") if res["sheet"] else None
    rec = data_record(args.data)
    md = [
        "# Evaluation on held-out synthetic views",
        "",
        f"Produced by `{command}` on {dt.datetime.now(dt.UTC).isoformat(timespec='minutes')} "
        "on this 2-core CPU (onnxruntime, "
        f"{args.threads} threads; the machine was shared with other jobs, so times are noisy).",
        "",
        f"Test data: `{args.data}` (data set record: {json.dumps(rec, sort_keys=True)}), "
        f"{res['views']} views, {res['pairs']} relighting pairs (every ordered pair of "
        "different suns of a view). Geometry inputs of the shadow methods: ground-truth depth "
        "(sky = no surface) and normals from it, as the runtime computes them; L and "
        "Pix2Pix-like get normals from Z's post-processed depth, as the app runs them (their "
        "model cards say which depth they were trained on); Z's time is counted only in "
        "`Ours (Z depth)` and `Direct (Z depth)`. `Ours (Z depth)` runs the "
        "photo-only pipeline of the app: Z's depth and sky of the input photo, post-processed "
        "as the app does (sky prior, guided filter and ground plane, "
        "`runtime/pipeline/depth_post.py`), "
        "normals from "
        "them; `Direct (Z depth)` is the app's Direct shadow mode on the same depth. "
        "Relighting metrics are on sRGB [0, 1] images tone-mapped with the view's "
        "exposure; DSSIM = (1 - SSIM) / 2 with an 11x11 Gaussian window.",
        "",
        "## Table 1",
        "",
        render_table(res),
        "",
        "Rows: `2D` and `Direct` feed their shadows to our trained R and L; `Physics` is the "
        "runtime's non-learned shading-ratio relighting; `Input` is the unchanged photo. "
        "Paper numbers are from their data set and are listed for orientation only.",
    ]
    if res.get("depth"):
        md += ["", "## Z: depth and sky", "",
               "Per photo of the same views; depth errors on the ground truth's non-sky pixels "
               "after scaling the prediction by the median ratio (Z has no metric scale); silog = "
               "std of the log error (scale-free); sky IoU against the ground truth's sky. The "
               "ground-plane prior is what the app uses when no depth model is installed. "
               "`Z + post-processing (app)` is what the app uses: Z's sky combined with the "
               "classical sky prior, and Z's depth smoothed by a guided filter with its ground "
               "snapped to a fitted plane (`runtime/pipeline/depth_post.py`). These are for real "
               "photos "
               "(clouds Z takes for surfaces, photo texture and ground bumps read as relief); "
               "this row shows what they cost or gain on synthetic views.",
               "",
               render_depth(res["depth"])]
    depth_extra = None
    if args.depth_data:
        depth_extra = evaluate_depth(args.depth_data, models, 0, args.threads)
        md += ["", f"### Z on `{args.depth_data}`", "",
               f"Data set record: {json.dumps(data_record(args.depth_data), sort_keys=True)}; "
               f"{depth_extra['views']} views, {depth_extra['photos']} photos, scored as above.",
               "", render_depth(depth_extra["depth"])]
    if res["missing"]:
        md += ["", "Not evaluated (model not shipped / not trained): "
               + ", ".join(f"`{n}.onnx`" for n in res["missing"]) + "."]
    if sheet is not None:
        md += ["", "Side-by-side sheet, one pair from each of the first test views: "
               f"`{sheet.name}`."]
    if args.sweep_checkpoint:
        ckpt = resolve_checkpoint(args.sweep_checkpoint)
        sweep = speed_accuracy(args.data, ckpt, max_views=args.sweep_views,
                               threads=args.threads)
        plot = plot_speed_accuracy(sweep, out.parent / "eval_speed_accuracy.png")
        md += [
            "", "## S: speed / accuracy (shadow MSE / median onnxruntime latency per frame)", "",
            f"First {args.sweep_views} test views, every ordered sun pair; inputs resized to each "
            "working size, output resized back to the ground truth's size; march step fixed at "
            "1/64 of the longer side, so z sets the reach (z = 64: the whole frame).", "",
            render_sweep(sweep), "", f"Plot: `{plot.name}`.",
        ]
    else:
        md += ["", "## S: speed / accuracy", "", "Not run (no `--sweep-checkpoint` given)."]
    if args.samples:
        from outcast_core.eval.samples import relight_samples, save_samples_sheet

        rows, records = relight_samples(args.samples, models)
        png = save_samples_sheet(rows, out.parent / "samples_sheet.png")
        md += ["", "## Sample photographs", "",
               f"`{png.name}`: the photos of `{args.samples}` relit by the app's photo-only "
               "pipeline (learned mode, balanced preset, Z's depth). Columns: input, Z depth "
               "(near = bright), refined old shadow, then per new sun its S_n and the relit "
               "photo. Suns (azimuth, elevation relative to the camera):", ""]
        md += [f"- `{r['file']}`: original {r['from']}, sun 1..n = {r['to']}; depth: "
               f"{r['depth_source']}, shadows: {r['shadows']}, relighting: {r['relight']}, "
               f"{r['seconds']} s" for r in records]
        md += ["", "New shadows in the relit photos (`eval.samples.shadow_contrast`): the "
               "fraction of the surface that is lit under the original sun and that S_n puts "
               "in shadow, and the relit photo's mean sRGB there over its mean where both suns "
               "light the surface; the photo contrast is the same ratio for the input's own "
               "shadows (S_o), i.e. how dark a real shadow is in that photo.", "",
               "| Photo | Sun | New shadow (fraction of surface) | Relit contrast | Photo "
               "contrast |", "|---|---|---|---|---|"]
        for r in records:
            for k, c in enumerate(r["contrast"]):
                md.append(f"| `{r['file']}` | {k + 1} {r['to'][k]} | {c['new_shadow_frac']} | "
                          f"{c['relit_contrast']} | {c['photo_contrast']} |")
    from outcast_core.runtime.pipeline.real_eval import real_section

    # The real-photo section (``outcast eval real --report``) is measured by another command.
    kept = real_section(out.read_text(encoding="utf-8")) if out.exists() else ""
    out.write_text("\n".join(md) + "\n" + (f"\n{kept}\n" if kept else ""))
    if not args.no_manifest_update:
        from outcast_core.export.cards import update_readme

        _update_manifests(models, res, depth_extra)
        update_readme(models)
    print(out)
    return 0


def _argv_of(args: argparse.Namespace) -> list[str]:
    parts = ["--data", args.data]
    if args.models != "models":
        parts += ["--models", args.models]
    if args.max_views:
        parts += ["--max-views", str(args.max_views)]
    if args.sweep_checkpoint:
        parts += ["--sweep-checkpoint", args.sweep_checkpoint, "--sweep-views",
                  str(args.sweep_views)]
    if args.samples:
        parts += ["--samples", args.samples]
    if args.depth_data:
        parts += ["--depth-data", args.depth_data]
    return parts


def _update_manifests(
    models: Path, res: dict[str, Any], depth_extra: dict[str, Any] | None = None
) -> None:
    from outcast_core.export.onnx_export import update_metrics

    rows = res["rows"]
    where = {"test_views": res["views"], "test_pairs": res["pairs"]}
    pick = {
        "shadow": ("Ours", ("shadow_mse",)),
        "shadow_2d": ("2D", ("shadow_mse",)),
        "relight": ("Ours", ("dssim", "mse", "time_s")),
        "refine": ("Ours", ("dssim", "mse")),
        "relight_pix2pix": ("Pix2Pix-like", ("dssim", "mse", "time_s")),
    }
    depth = res.get("depth", {}).get("Z")
    if depth and (models / "depth.json").is_file():
        vals = {f"heldout_{k}": round(depth[k], 5)
                for k in ("silog", "abs_rel", "delta1", "sky_iou", "time_s")}
        if "Ours (Z depth)" in rows:
            vals |= {f"heldout_pipeline_{k}": round(rows["Ours (Z depth)"][k], 5)
                     for k in ("dssim", "mse", "shadow_mse") if k in rows["Ours (Z depth)"]}
        if depth_extra:
            z = depth_extra["depth"]["Z"]
            vals |= {f"heldout_extra_{k}": round(z[k], 5) for k in ("silog", "abs_rel", "delta1")}
            vals["heldout_extra_photos"] = depth_extra["photos"]
            vals["heldout_extra_data"] = depth_extra["data"]
        update_metrics(models / "depth.json", vals | where)
    for name, (row, keys) in pick.items():
        man = models / f"{name}.json"
        if man.is_file() and row in rows:
            vals = {f"heldout_{k}": round(rows[row][k], 5) for k in keys if k in rows[row]}
            update_metrics(man, vals | where)
