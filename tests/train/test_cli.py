"""The train / export / eval commands register on an argparse parser without importing torch."""

from __future__ import annotations

import argparse
import subprocess
import sys

from outcast_core.eval import cli as eval_cli
from outcast_core.export import cli as export_cli
from outcast_core.train import cli as train_cli


def test_commands_register_and_parse() -> None:
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd")
    for mod in (train_cli, export_cli, eval_cli):
        mod.register(sub)
    a = ap.parse_args(["train", "cfg.toml", "--steps", "5", "--threads", "1"])
    assert a.func is train_cli.run_train and a.steps == 5 and a.threads == 1
    a = ap.parse_args(["export", "shadow_v1", "--out", "m"])
    assert a.func is export_cli.run_export and a.out == "m"
    a = ap.parse_args(["eval", "--data", "d", "--max-views", "3"])
    assert a.func is eval_cli.run_eval and a.max_views == 3


def test_registering_does_not_import_torch() -> None:
    code = (
        "import argparse, sys\n"
        "from outcast_core.train import cli as t\n"
        "from outcast_core.export import cli as e\n"
        "from outcast_core.eval import cli as v\n"
        "sub = argparse.ArgumentParser().add_subparsers()\n"
        "[m.register(sub) for m in (t, e, v)]\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_set_overrides_reach_the_config(tmp_path, monkeypatch) -> None:
    seen = {}

    class FakeTrainer:
        def __init__(self, cfg, progress, command):
            seen["cfg"], seen["command"] = cfg, command

        def fit(self):
            return {"step": 0}

    import outcast_core.train.trainer as trainer_mod

    monkeypatch.setattr(trainer_mod, "Trainer", FakeTrainer)
    (tmp_path / "c.toml").write_text('run = "r"\nstage = "shadow"\ndata = "d"\n')
    ap = argparse.ArgumentParser()
    train_cli.register(ap.add_subparsers())
    args = ap.parse_args(["train", str(tmp_path / "c.toml"), "--set", "lr=0.002",
                          "--set", "data=elsewhere", "--threads", "1"])
    assert args.func(args) == 0
    assert seen["cfg"].lr == 0.002 and seen["cfg"].data.endswith("elsewhere")
    assert seen["cfg"].threads == 1 and "--set" in seen["command"]
