"""Data set on disk: round trip, resumable generation, argument and disk-full errors, CLI."""

from __future__ import annotations

import argparse
import errno
import json
import subprocess
import sys

import numpy as np
import pytest

from outcast_core.data import dataset as ds
from outcast_core.data.dataset import DiskFullError, load_view, make_dataset, save_view


def _fake_view(rng: np.random.Generator, k: int = 2, h: int = 6, w: int = 8) -> dict:
    sky = np.zeros((h, w), bool)
    sky[0] = True
    depth = rng.uniform(1, 50, (h, w)).astype(np.float32)
    depth[sky] = np.inf
    n = rng.normal(size=(h, w, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[sky] = 0
    return {
        "rgb": rng.uniform(0, 3, (k, h, w, 3)).astype(np.float32),
        "shadow": rng.uniform(0, 1, (k, h, w)).astype(np.float32),
        "depth": depth,
        "normals": n.astype(np.float32),
        "sky": sky,
        "sun": rng.normal(size=(k, 3)).astype(np.float32),
        "sun_azel": rng.uniform(0, 90, (k, 2)).astype(np.float32),
        "fov_deg": 55.5,
        "exposure": 7.25,
    }


def test_save_load_round_trip(tmp_path) -> None:
    view = _fake_view(np.random.default_rng(0))
    save_view(tmp_path / "view_000000", view, {"kind": "street"})
    got = load_view(tmp_path / "view_000000")
    assert got["meta"] == {"kind": "street"}
    for key in ("rgb", "shadow", "normals"):  # float16 on disk
        assert got[key].dtype == np.float32 and got[key].shape == view[key].shape
        np.testing.assert_allclose(got[key], view[key], rtol=1e-3, atol=1e-3)
    np.testing.assert_array_equal(got["depth"], view["depth"])  # float32 on disk: exact
    np.testing.assert_array_equal(got["sky"], view["sky"])
    np.testing.assert_array_equal(got["sun"], view["sun"])
    np.testing.assert_array_equal(got["sun_azel"], view["sun_azel"])
    assert got["fov_deg"] == pytest.approx(55.5) and got["exposure"] == pytest.approx(7.25)
    assert not (tmp_path / "view_000000.tmp").exists()
    with pytest.raises(ValueError, match="expected a view folder"):
        load_view(tmp_path / "missing")


def test_disk_full_leaves_no_partial_view(tmp_path, monkeypatch) -> None:
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(ds.np, "savez", full)
    with pytest.raises(DiskFullError):
        save_view(tmp_path / "view_000000", _fake_view(np.random.default_rng(1)), {})
    assert list(tmp_path.iterdir()) == []


def test_bad_arguments_are_rejected(tmp_path) -> None:
    for kwargs, word in (
        ({"views": 0}, "--views"),
        ({"suns": 0}, "--suns"),
        ({"res": 4}, "--res"),
        ({"spp": 0}, "--spp"),
        ({"seed": -1}, "--seed"),
        ({"workers": 0}, "--workers"),
    ):
        args = {"views": 1, "suns": 1, "res": 16, "spp": 1, "seed": 0, "workers": 1} | kwargs
        with pytest.raises(ValueError, match=word):
            make_dataset(tmp_path / "x", **args)


@pytest.mark.slow
def test_make_is_resumable_and_deterministic(tmp_path) -> None:
    pytest.importorskip("mitsuba")
    root = tmp_path / "set"
    calls = []
    done = make_dataset(
        root, views=2, suns=1, res=16, spp=1, seed=7, progress=lambda d, t: calls.append((d, t))
    )
    assert sorted(done) == [0, 1] and calls[-1] == (2, 2)
    first = load_view(root / "view_000001")
    assert first["meta"]["seed"] == 8
    # A second run skips finished views; a third with more views renders only the new one.
    assert make_dataset(root, views=2, suns=1, res=16, spp=1, seed=7) == []
    assert make_dataset(root, views=3, suns=1, res=16, spp=1, seed=7) == [2]
    assert json.loads((root / "dataset.json").read_text())["views"] == 3
    # Other arguments on the same folder are refused.
    with pytest.raises(ValueError, match="same arguments"):
        make_dataset(root, views=3, suns=1, res=16, spp=2, seed=7)
    # Re-rendering a view from scratch gives the same arrays, bit for bit.
    other = tmp_path / "again"
    make_dataset(other, views=2, suns=1, res=16, spp=1, seed=7)
    again = load_view(other / "view_000001")
    for key in ("rgb", "shadow", "depth", "normals", "sky", "sun"):
        np.testing.assert_array_equal(first[key], again[key])


def test_cli_registers_and_reports_errors(tmp_path, capsys) -> None:
    from outcast_core.data.cli import main, register

    parser = argparse.ArgumentParser(prog="outcast")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(
        ["data", "make", "--out", str(tmp_path), "--views", "3", "--res", "32"]
    )
    assert callable(args.func) and args.views == 3 and args.suns == 4
    with pytest.raises(SystemExit):
        parser.parse_args(["data", "make", "--out", str(tmp_path), "--views", "0"])
    assert "expected an integer >= 1" in capsys.readouterr().err
    assert main(["preview", str(tmp_path / "nothing"), "-o", str(tmp_path / "s.png")]) == 2
    assert "expected a data set folder" in capsys.readouterr().err


def test_cli_import_does_not_load_mitsuba() -> None:
    code = "import sys, outcast_core.data, outcast_core.data.cli; print('mitsuba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_contact_sheet_of_fake_views(tmp_path) -> None:
    from PIL import Image

    from outcast_core.data.preview import COLUMNS, contact_sheet

    rng = np.random.default_rng(2)
    for i in range(3):
        save_view(tmp_path / f"view_{i:06d}", _fake_view(rng, h=8, w=8), {"kind": "closeup"})
    out = contact_sheet(tmp_path, tmp_path / "sheet.png", max_views=2, tile=32)
    img = np.asarray(Image.open(out))
    assert img.shape == (16 + 2 * 32, len(COLUMNS) * 32, 3)
    assert img[16:].std() > 10  # real content, not a blank canvas


def test_scene_kind_is_checked_and_recorded(tmp_path, monkeypatch) -> None:
    args = {"views": 2, "suns": 1, "res": 8, "spp": 1, "seed": 5}
    with pytest.raises(ValueError, match="--kind"):
        make_dataset(tmp_path / "x", **args, kind="moonscape")
    # The kind reaches every view's render and is recorded in dataset.json.
    seen = []

    def fake_render(index, suns, res, spp, base_seed, kind=None):
        seen.append((index, kind))
        return _fake_view(np.random.default_rng(index), k=suns, h=res, w=res), {"kind": kind}

    monkeypatch.setattr(ds, "render_one", fake_render)
    land = tmp_path / "land"
    assert sorted(make_dataset(land, **args, kind="landscape")) == [0, 1]
    assert sorted(seen) == [(0, "landscape"), (1, "landscape")]
    assert json.loads((land / "dataset.json").read_text())["kind"] == "landscape"
    # A landscape folder refuses the standard mix, and a standard folder (no "kind" recorded,
    # as every set made before the landscape kind) refuses landscapes.
    with pytest.raises(ValueError, match="'kind'"):
        make_dataset(land, **args)
    mixed = tmp_path / "mixed"
    make_dataset(mixed, **args)
    assert "kind" not in json.loads((mixed / "dataset.json").read_text())
    assert seen[-1] == (1, None)
    with pytest.raises(ValueError, match="'kind'"):
        make_dataset(mixed, **args, kind="landscape")
