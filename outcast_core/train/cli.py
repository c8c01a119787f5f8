"""``outcast train CONFIG [CONFIG ...]``: the command-line entry of the trainer.

:func:`register` adds the sub-command to the runtime CLI's parser; torch is imported only when
the command runs, so ``outcast`` itself never imports torch. Under ``torchrun`` the same
command trains on every process (see :mod:`outcast_core.train.distributed`); several configs
are trained one after the other in one job (e.g. ``S``, then the ``relight`` stage on it).
"""

from __future__ import annotations

import argparse
import json
import shlex
from typing import Any


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``train`` to an ``argparse`` sub-parser collection; returns the new parser."""
    p = subparsers.add_parser(
        "train", help="train a network from a config file (JSON or TOML)",
        description="Train a network. Checkpoints go to ~/.cache/outcast/runs/<run>/; rerunning "
        "the same config resumes from the last checkpoint. Under torchrun "
        "(torchrun --nproc_per_node=N -m outcast_core.runtime.cli.main train CONFIG) every process "
        "trains its part of each global batch with DistributedDataParallel.",
    )
    p.add_argument("config", nargs="+",
                   help="run config (.toml or .json); several are trained in turn, with the "
                   "same overrides")
    p.add_argument("--steps", type=int, help="override the total number of steps")
    p.add_argument("--time-limit", type=float, help="stop after this many seconds (checkpointed)")
    p.add_argument("--data", help="override the data folder")
    p.add_argument("--threads", type=int, help="override the torch thread count")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any top-level config key (value parsed as JSON, else text)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run_train)
    return p


def run_train(args: argparse.Namespace) -> int:
    """Train each config of ``args.config`` in turn; prints each result (rank 0 only)."""
    from outcast_core.train import distributed
    from outcast_core.train.config import load_config
    from outcast_core.train.trainer import Trainer

    overrides: dict[str, Any] = {}
    if args.steps is not None:
        overrides["steps"] = args.steps
    if args.time_limit is not None:
        overrides["time_limit_s"] = args.time_limit
    if args.data is not None:
        overrides["data"] = args.data
    if args.threads is not None:
        overrides["threads"] = args.threads
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"error: expected --set KEY=VALUE, got {item!r}")
        try:
            overrides[key] = json.loads(value)
        except json.JSONDecodeError:
            overrides[key] = value
    configs = [args.config] if isinstance(args.config, str) else list(args.config)
    cfgs = [load_config(path, overrides) for path in configs]  # every typo before any training
    try:
        for path, cfg in zip(configs, cfgs, strict=True):
            command = " ".join(
                ["outcast train", shlex.quote(path)]
                + [f"--set {shlex.quote(f'{k}={json.dumps(v)}')}" for k, v in overrides.items()]
            )
            result = Trainer(cfg, progress=not args.no_progress, command=command).fit()
            if distributed.is_main_process():
                print(json.dumps(result, indent=2))
    finally:
        distributed.shutdown()
    return 0
