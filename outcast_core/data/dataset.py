"""The synthetic data set on disk: one folder per view, written atomically, resumable.

Layout (see ``outcast_core/data/README.md``)::

    DIR/dataset.json            generation arguments (checked on resume)
    DIR/view_000000/view.npz    arrays of one view
    DIR/view_000000/meta.json   scene kind, camera, sky, seeds

This module imports no Mitsuba: :func:`load_view` works anywhere numpy does.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

FORMAT_VERSION = 2  # bump whenever the generator's output for a seed changes
VIEW_PREFIX = "view_"
STANDARD_SETS: dict[str, dict[str, int]] = {
    # 4 800 training pairs / 400 test pairs; seeds never overlap (train 0..1199, test 1e6..).
    "train": {"views": 1200, "suns": 4, "res": 128, "spp": 32, "seed": 0},
    "test": {"views": 100, "suns": 4, "res": 128, "spp": 32, "seed": 1_000_000},
    "dev": {"views": 60, "suns": 4, "res": 128, "spp": 32, "seed": 500_000},
}
_ARG_KEYS = ("suns", "res", "spp", "seed", "version", "kind")


class DiskFullError(OSError):
    """Raised when the disk fills up while writing a view (finished views are kept)."""


def cache_dir() -> Path:
    """OutCast's cache root: ``$OUTCAST_CACHE`` or ``~/.cache/outcast``."""
    env = os.environ.get("OUTCAST_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "outcast"


def default_set_dir(name: str) -> Path:
    """Where the named data set lives: ``<cache>/data/<name>``."""
    return cache_dir() / "data" / name


def view_dir(root: Path, index: int) -> Path:
    return Path(root) / f"{VIEW_PREFIX}{index:06d}"


def list_views(root: str | Path) -> list[Path]:
    """Finished view folders under ``root``, sorted."""
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"expected a data set folder, got {str(root)!r} (not a directory)")
    return sorted(
        p
        for p in root.iterdir()
        if p.is_dir()
        and p.name.startswith(VIEW_PREFIX)
        and "." not in p.name
        and (p / "view.npz").is_file()
    )


def save_view(folder: str | Path, data: dict[str, Any], meta: dict[str, Any]) -> None:
    """Write one view atomically: into ``<folder>.tmp`` first, then rename.

    Raises:
        DiskFullError: when the disk is full (the partial folder is removed).
    """
    folder = Path(folder)
    tmp = folder.with_name(folder.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        tmp.mkdir(parents=True)
        arrays = {
            "rgb": np.asarray(data["rgb"], np.float16),
            "shadow": np.asarray(data["shadow"], np.float16),
            "depth": np.asarray(data["depth"], np.float32),
            "normals": np.asarray(data["normals"], np.float16),
            "sky": np.asarray(data["sky"], bool),
            "sun": np.asarray(data["sun"], np.float32),
            "sun_azel": np.asarray(data["sun_azel"], np.float32),
            "fov_deg": np.float32(data["fov_deg"]),
            "exposure": np.float32(data.get("exposure", 1.0)),
        }
        np.savez(tmp / "view.npz", **arrays)
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True))
        if folder.exists():
            shutil.rmtree(folder)
        os.replace(tmp, folder)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if exc.errno == errno.ENOSPC:
            raise DiskFullError(errno.ENOSPC, f"disk full while writing {folder}") from exc
        raise


def load_view(path: str | Path) -> dict[str, Any]:
    """Load one view folder (or its ``view.npz``).

    Args:
        path: a ``view_<6-digit index>`` folder.

    Returns:
        Dict with ``rgb`` (K x H x W x 3 float32 linear radiance), ``shadow`` (K x H x W float32,
        cosine-weighted sun visibility in [0, 1]), ``depth`` (H x W float32 z depth, +inf on sky),
        ``normals`` (H x W x 3 float32 camera-space unit normals facing the camera, 0 on sky),
        ``sky`` (H x W bool), ``sun`` (K x 3 float32 camera-space unit vectors toward the sun),
        ``sun_azel`` (K x 2 float32 azimuth/elevation in degrees relative to the level camera),
        ``fov_deg`` (float, horizontal), ``exposure`` (float, suggested multiplier of ``rgb``
        before tone mapping), ``meta`` (dict from meta.json).
    """
    path = Path(path)
    npz = path / "view.npz" if path.is_dir() else path
    if not npz.is_file():
        raise ValueError(f"expected a view folder holding view.npz, got {str(path)!r}")
    with np.load(npz) as z:
        out: dict[str, Any] = {
            "rgb": z["rgb"].astype(np.float32),
            "shadow": z["shadow"].astype(np.float32),
            "depth": z["depth"].astype(np.float32),
            "normals": z["normals"].astype(np.float32),
            "sky": z["sky"].astype(bool),
            "sun": z["sun"].astype(np.float32),
            "sun_azel": z["sun_azel"].astype(np.float32),
            "fov_deg": float(z["fov_deg"]),
            "exposure": float(z["exposure"]),
        }
    meta_path = npz.parent / "meta.json"
    out["meta"] = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    return out


def iter_views(root: str | Path) -> Iterator[dict[str, Any]]:
    """Load every finished view of a data set in order."""
    for p in list_views(root):
        yield load_view(p)


def bytes_per_view(suns: int, res: int) -> int:
    """Approximate size of one view on disk."""
    px = res * res
    return suns * px * (3 * 2 + 2) + px * (4 + 3 * 2 + 1) + 4096


def render_one(
    index: int, suns: int, res: int, spp: int, base_seed: int, kind: str | None = None
) -> tuple[dict, dict]:
    """Generate and render view ``index`` of a data set (seed = base seed + index).

    ``kind`` forces a scene kind (``generate_scene``); ``None`` draws the standard mix.
    """
    from outcast_core.data.render import render_view, suggest_exposure
    from outcast_core.data.scene import generate_scene

    seed = int(base_seed) + int(index)
    spec = generate_scene(seed, suns, kind)
    data = render_view(spec, res, spp, seed)
    data["exposure"] = suggest_exposure(data["rgb"], data["sky"])
    cam = spec.camera
    meta = {
        "version": FORMAT_VERSION,
        "index": int(index),
        "seed": seed,
        "kind": spec.kind,
        "target": spec.target,
        "res": int(res),
        "spp": int(spp),
        "camera": {
            "height_above_ground_m": float(spec.info["camera_height_m"]),
            "pitch_deg": float(cam.pitch_deg),
            "roll_deg": float(cam.roll_deg),
            "fov_deg": float(cam.fov_deg),
        },
        "sky": {"turbidity": spec.turbidity, "ground_albedo": spec.sky_albedo},
        "suns_azel_deg": [[s.azimuth_deg, s.elevation_deg] for s in spec.suns],
        "exposure": data["exposure"],
    }
    return data, meta


def _worker(job: tuple[str, int, int, int, int, int, str | None]) -> int:
    root, index, suns, res, spp, seed, kind = job
    data, meta = render_one(index, suns, res, spp, seed, kind)
    save_view(view_dir(Path(root), index), data, meta)
    return index


def check_args(views: int, suns: int, res: int, spp: int, seed: int, workers: int) -> None:
    """Raise ``ValueError`` for arguments ``make_dataset`` cannot use."""
    for name, val, lo in (
        ("views", views, 1),
        ("suns", suns, 1),
        ("res", res, 8),
        ("spp", spp, 1),
        ("seed", seed, 0),
        ("workers", workers, 1),
    ):
        if not isinstance(val, int | np.integer) or val < lo:
            raise ValueError(f"expected --{name} to be an integer >= {lo}, got {val!r}")
    if res > 4096:
        raise ValueError(f"expected --res <= 4096, got {res}")


def shard_range(views: int, shard: tuple[int, int] | None) -> range:
    """The view indices of shard ``(i, n)``: the ``i``-th of ``n`` contiguous, near-equal ranges
    of ``0 .. views-1`` (so of seeds ``seed .. seed+views-1``); all of them for ``None``.

    Example:
        >>> [list(shard_range(10, (i, 3))) for i in range(3)]
        [[0, 1, 2], [3, 4, 5, 6], [7, 8, 9]]
    """
    if shard is None:
        return range(views)
    i, n = shard
    if not (isinstance(n, int) and isinstance(i, int) and n >= 1 and 0 <= i < n):
        raise ValueError(f"expected a shard I/N with 0 <= I < N, got {i}/{n}")
    return range(i * views // n, (i + 1) * views // n)


def _write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write JSON via a unique temporary file and a rename (shards may share the folder)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
    os.replace(tmp, path)


def make_dataset(
    root: str | Path,
    views: int,
    suns: int,
    res: int,
    spp: int,
    seed: int,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    kind: str | None = None,
    shard: tuple[int, int] | None = None,
) -> list[int]:
    """Render views ``0 .. views-1`` into ``root``, skipping finished ones.

    Args:
        root: output folder (created).
        views: number of views N. suns: suns per view K. res: square image size.
        spp: path-tracing samples per pixel. seed: base seed (view i uses seed + i).
        workers: parallel processes.
        progress: called as ``progress(done, total)`` after each view (of this shard).
        kind: render only this scene kind (recorded in ``dataset.json``); ``None``: the
            standard mix of street, plaza and close-up.
        shard: ``(i, n)``: render only the ``i``-th of ``n`` contiguous ranges of views
            (:func:`shard_range`). The views keep their global indices and seeds and
            ``dataset.json`` is the same for every shard, so ``n`` machines writing into one
            shared folder, or folders copied together, make the unsharded set: no merge step.

    Returns:
        The indices rendered by this call.

    Raises:
        ValueError: bad arguments, or ``root`` holds a set made with other arguments.
        DiskFullError: the disk filled up (finished views stay; re-run to resume).
    """
    check_args(views, suns, res, spp, seed, workers)
    from outcast_core.data.scene import EXTRA_KINDS, SCENE_KINDS

    if kind is not None and kind not in SCENE_KINDS + EXTRA_KINDS:
        raise ValueError(f"expected --kind in {SCENE_KINDS + EXTRA_KINDS}, got {kind!r}")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    args = {"suns": suns, "res": res, "spp": spp, "seed": seed, "version": FORMAT_VERSION}
    if kind is not None:
        args["kind"] = kind
    info_path = root / "dataset.json"
    if info_path.is_file():
        old = json.loads(info_path.read_text())
        diff = {k: (old.get(k), args.get(k)) for k in _ARG_KEYS if old.get(k) != args.get(k)}
        if diff:
            raise ValueError(
                f"expected {root} to hold a set made with the same arguments, got "
                f"differences (existing, requested): {diff}"
            )
    mine = shard_range(views, shard)
    todo = [i for i in mine if not (view_dir(root, i) / "view.npz").is_file()]
    free = shutil.disk_usage(root).free
    need = len(todo) * bytes_per_view(suns, res)
    if need > free:
        raise DiskFullError(
            errno.ENOSPC,
            f"need about {need / 1e6:.0f} MB for {len(todo)} views in "
            f"{root}, only {free / 1e6:.0f} MB free",
        )
    info = dict(
        args,
        views=max(
            views,
            json.loads(info_path.read_text()).get("views", 0) if info_path.is_file() else views,
        ),
    )
    _write_json_atomic(info_path, info)
    total = len(mine)
    done = total - len(todo)
    if progress:
        progress(done, total)
    jobs = [(str(root), i, suns, res, spp, seed, kind) for i in todo]
    finished: list[int] = []
    if workers == 1:
        for job in jobs:
            finished.append(_worker(job))
            done += 1
            if progress:
                progress(done, total)
    else:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(workers) as pool:
            for idx in pool.imap_unordered(_worker, jobs):
                finished.append(idx)
                done += 1
                if progress:
                    progress(done, total)
    return finished
