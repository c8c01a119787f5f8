"""How well a depth model's geometry serves shadows, on synthetic views with true depth.

``outcast eval`` reports Z's scale-invariant log error; shadows need more than that: the
relief (a compressed depth map turns a flat ground toward the camera) and the normals that the
cosine term and the ray marcher consume. For each view this runs Z as the app does
(:func:`run_depth_model`, then :func:`postprocess_z` with the view's camera) and prints, on the
true surface pixels both call surface:

* ``silog``: the standard deviation of the log depth error (scale-free), raw and post-processed;
* ``slope``: the slope of log(estimate) against log(truth); 1 = the right relief, < 1 compressed;
* ``normal``: the median angle between the estimate's and the truth's normals (both from
  ``normals_from_depth``, as the runtime computes them);
* ``n_z low``: the median camera-space z component of the normals in the lower half (the
  ground, mostly): more negative = turned toward the camera;
* ``false away``: over the view's suns, the fraction of surface where the estimate's cosine is
  below 0.15 but the truth's is not (the overlay's "facing away" shadow that is not there).

Run (the models folder holds ``depth.onnx`` and its card)::

    python3 scripts/eval_depth_geometry.py ~/.cache/outcast/data/test --max-views 40 \
        --models models
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from outcast_core.data.dataset import list_views, load_view  # noqa: E402
from outcast_core.runtime.geometry.camera import (  # noqa: E402
    Camera,
    focal_from_fov,
    normals_from_depth,
)
from outcast_core.runtime.io.models import ModelRegistry  # noqa: E402
from outcast_core.runtime.pipeline.depth_post import postprocess_z, run_depth_model  # noqa: E402
from outcast_core.train.data import auto_exposure, tonemap  # noqa: E402

#: Cosine below which a surface counts as facing away from the sun (the overlay's threshold).
AWAY = 0.15


def view_scores(model: object, view: dict) -> dict[str, float]:
    """The figures above for one view (keys as printed)."""
    e = view["exposure"] if view["exposure"] > 0 else auto_exposure(view["rgb"][0])
    img = tonemap(view["rgb"][0], e)
    true_d, true_sky = view["depth"], view["sky"]
    h, w = true_d.shape
    cam = Camera(h, w, focal_from_fov(w, view["fov_deg"]))
    raw, sky_p = run_depth_model(model, img)
    post, sky = postprocess_z(raw, sky_p, img, cam)
    surf = ~true_sky & np.isfinite(true_d) & (true_d > 0) & ~sky
    out: dict[str, float] = {}
    lt = np.log(true_d[surf])
    for key, arr in (("raw", raw), ("post", post)):
        le = np.log(np.maximum(arr[surf], 1e-8))
        out[f"silog {key}"] = float(np.std(le - lt))
        out[f"slope {key}"] = float(np.polyfit(lt, le, 1)[0])
    n_est = normals_from_depth(np.where(sky, np.inf, post).astype(np.float32), cam)
    n_true = normals_from_depth(np.where(true_sky, np.inf, true_d).astype(np.float32), cam)
    cos = np.clip((n_est * n_true).sum(-1), -1.0, 1.0)
    out["normal"] = float(np.median(np.degrees(np.arccos(cos[surf]))))
    low = surf.copy()
    low[: h // 2] = False
    out["n_z low"] = float(np.median(n_est[..., 2][low])) if low.any() else float("nan")
    out["n_z low true"] = float(np.median(n_true[..., 2][low])) if low.any() else float("nan")
    away = [((n_est @ s < AWAY) & (n_true @ s >= AWAY))[surf].mean() for s in view["sun"]]
    out["false away"] = float(np.mean(away))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="a folder made by `outcast data make`")
    ap.add_argument("--max-views", type=int, default=40, help="first N views (default 40)")
    ap.add_argument("--models", default=str(ROOT / "models"),
                    help="folder holding depth.onnx (default: the shipped models)")
    args = ap.parse_args(argv)
    model = ModelRegistry(args.models).load("depth")
    rows = [view_scores(model, load_view(p)) for p in list_views(args.data)[: args.max_views]]
    if not rows:
        print(f"no views in {args.data}", file=sys.stderr)
        return 1
    print(f"{len(rows)} views of {args.data}, depth model from {args.models}")
    for key in rows[0]:
        vals = np.array([r[key] for r in rows])
        print(f"  {key:14s} mean {np.nanmean(vals):8.4f}   median {np.nanmedian(vals):8.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
