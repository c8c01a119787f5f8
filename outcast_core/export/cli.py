"""``outcast export CHECKPOINT``: trained networks -> ``models/*.onnx`` + manifests.

:func:`register` adds the sub-command; torch is imported only when it runs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``export`` to an ``argparse`` sub-parser collection; returns the new parser."""
    p = subparsers.add_parser(
        "export", help="export a training run's networks to ONNX with manifests",
        description="Export every network of a checkpoint (except the critic) to "
        "OUT/<name>.onnx, check it against torch with onnxruntime, write OUT/<name>.json and "
        "re-render the model cards OUT/README.md from the manifests.",
    )
    p.add_argument("checkpoint", help="a checkpoint file, or a run name (~/.cache/outcast/runs/)")
    p.add_argument("--out", default="models", help="output folder (default: models)")
    p.add_argument("--data-seed", type=int, help="seed of the data set the run trained on")
    p.set_defaults(func=run_export)
    return p


def run_export(args: argparse.Namespace) -> int:
    from outcast_core.export.cards import update_readme
    from outcast_core.export.checkpoint import export_checkpoint

    written = export_checkpoint(args.checkpoint, Path(args.out), data_seed=args.data_seed)
    written.append(update_readme(args.out))  # the model cards follow the manifests
    print(json.dumps([str(p) for p in written], indent=2))
    return 0
