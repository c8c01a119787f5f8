"""Sharded data generation: N machines each render a seed range; together they are the set."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from outcast_core.data import dataset as ds
from outcast_core.data.dataset import list_views, load_view, make_dataset, shard_range


def test_shard_ranges_cover_the_views_once() -> None:
    for views in (1, 2, 7, 10, 1200):
        for n in (1, 2, 3, 4, 16):
            parts = [shard_range(views, (i, n)) for i in range(n)]
            assert [v for p in parts for v in p] == list(range(views))  # contiguous, in order
            assert max(map(len, parts)) - min(map(len, parts)) <= 1
    assert shard_range(5, None) == range(5)
    for bad in ((1, 1), (-1, 2), (0, 0), (3, 2)):
        with pytest.raises(ValueError, match="expected a shard"):
            shard_range(10, bad)


def _fake_render(index, suns, res, spp, base_seed, kind=None):
    rng = np.random.default_rng(base_seed + index)  # a view is a function of its seed only
    sky = np.zeros((res, res), bool)
    sky[0] = True
    depth = rng.uniform(1, 50, (res, res)).astype(np.float32)
    depth[sky] = np.inf
    data = {
        "rgb": rng.uniform(0, 3, (suns, res, res, 3)),
        "shadow": rng.uniform(0, 1, (suns, res, res)),
        "depth": depth, "normals": np.zeros((res, res, 3)), "sky": sky,
        "sun": rng.normal(size=(suns, 3)), "sun_azel": rng.uniform(0, 90, (suns, 2)),
        "fov_deg": 60.0, "exposure": 1.0,
    }
    return data, {"seed": base_seed + index, "index": index}


def _same_sets(a: Path, b: Path) -> None:
    names = [p.name for p in list_views(a)]
    assert names == [p.name for p in list_views(b)]
    assert json.loads((a / "dataset.json").read_text()) == json.loads(
        (b / "dataset.json").read_text())
    for name in names:
        va, vb = load_view(a / name), load_view(b / name)
        assert va["meta"] == vb["meta"]
        for key in ("rgb", "shadow", "depth", "normals", "sky", "sun", "sun_azel"):
            np.testing.assert_array_equal(va[key], vb[key])


def test_shards_make_the_unsharded_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ds, "render_one", _fake_render)
    args = {"views": 7, "suns": 2, "res": 8, "spp": 1, "seed": 40}
    whole = tmp_path / "whole"
    assert sorted(make_dataset(whole, **args)) == list(range(7))
    shared = tmp_path / "shared"  # three machines on one shared folder
    got = [sorted(make_dataset(shared, **args, shard=(i, 3))) for i in range(3)]
    assert got == [[0, 1], [2, 3], [4, 5, 6]]
    _same_sets(whole, shared)
    merged = tmp_path / "merged"  # three machines on local folders, copied together
    for i in range(3):
        part = tmp_path / f"part{i}"
        progress: list[tuple[int, int]] = []
        make_dataset(part, **args, shard=(i, 3), progress=lambda d, t, seen=progress:
                     seen.append((d, t)))
        assert progress[-1] == (len(shard_range(7, (i, 3))),) * 2
        shutil.copytree(part, merged, dirs_exist_ok=True)
    _same_sets(whole, merged)
    assert make_dataset(shared, **args, shard=(1, 3)) == []  # resumable per shard


def test_cli_shard_option(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          monkeypatch: pytest.MonkeyPatch) -> None:
    from outcast_core.data.cli import register

    parser = argparse.ArgumentParser(prog="outcast")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["data", "make", "--out", str(tmp_path / "s"), "--views", "5",
                              "--res", "8", "--spp", "1", "--suns", "1", "--shard", "1/2"])
    assert args.shard == (1, 2)
    monkeypatch.setattr(ds, "render_one", _fake_render)
    assert args.func(args) == 0
    assert "shard 1/2: views 2..4 (seeds 2..4) of 5" in capsys.readouterr().out
    assert [p.name for p in list_views(tmp_path / "s")] == [f"view_00000{i}" for i in (2, 3, 4)]
    for bad in ("2/2", "1", "a/b", "-1/3"):
        with pytest.raises(SystemExit):
            parser.parse_args(["data", "make", "--out", "x", "--views", "2", f"--shard={bad}"])
        assert "expected --shard I/N" in capsys.readouterr().err


@pytest.mark.slow
def test_sharded_renders_equal_the_unsharded_ones(tmp_path: Path) -> None:
    pytest.importorskip("mitsuba")
    args = {"views": 3, "suns": 1, "res": 16, "spp": 1, "seed": 11}
    make_dataset(tmp_path / "whole", **args)
    for i in range(2):
        make_dataset(tmp_path / "shared", **args, shard=(i, 2))
    _same_sets(tmp_path / "whole", tmp_path / "shared")
