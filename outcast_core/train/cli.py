"""``outcast train CONFIG``: the command-line entry of the trainer.

:func:`register` adds the sub-command to the runtime CLI's parser; torch is imported only when
the command runs, so ``outcast`` itself never imports torch.
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
        "the same config resumes from the last checkpoint.",
    )
    p.add_argument("config", help="run config (.toml or .json)")
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
    cfg = load_config(args.config, overrides)
    command = " ".join(
        ["outcast train", shlex.quote(args.config)]
        + [f"--set {shlex.quote(f'{k}={json.dumps(v)}')}" for k, v in overrides.items()]
    )
    result = Trainer(cfg, progress=not args.no_progress, command=command).fit()
    print(json.dumps(result, indent=2))
    return 0
