"""``outcast models``: where each model is found, and whether its checksum holds.

Registered by :data:`outcast_core.runtime.cli.main.OPTIONAL_COMMANDS`. The lookup order is
:mod:`outcast_core.runtime.io.models`' (an explicit ``--dir``, ``$OUTCAST_MODEL_DIR``, the user's
model folder, the shipped models).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from outcast_core.runtime.io.models import (
    KNOWN_MODELS,
    ModelError,
    ModelRegistry,
    check_model_io,
    onnx_session,
    sha256_file,
)


def model_report(registry: ModelRegistry, names: tuple[str, ...] = KNOWN_MODELS,
                 load: bool = False) -> list[dict[str, Any]]:
    """One row per model: its folder, file, version and checksum status.

    Args:
        registry: the registry whose search path is reported.
        names: the models to report.
        load: also load each model with onnxruntime (checks its inputs and outputs too). Each
            file is hashed once either way.

    Returns:
        Dicts with ``name``, ``status`` (``ok``, ``missing``, ``corrupt`` or ``error``),
        ``folder``, ``file``, ``version`` and ``message``.
    """
    rows = []
    for name in names:
        row: dict[str, Any] = {"name": name, "folder": str(registry.directory_for(name)),
                               "file": "", "version": "", "status": "ok", "message": ""}
        if not registry.available(name):
            row.update(status="missing", message=f"no {name}.json in the search path")
            rows.append(row)
            continue
        try:
            manifest = registry.manifest(name)
            path = registry.manifest_path(name).parent / manifest["file"]
            row.update(file=str(path), version=str(manifest.get("version", "")))
            if not path.is_file():
                row.update(status="missing", message=f"{path.name} is missing")
            elif sha256_file(path) != manifest["sha256"]:
                row.update(status="corrupt", message="sha256 does not match the manifest")
            elif load:
                # Its sha256 was just checked: open it and check its inputs and outputs as
                # ModelRegistry.load does, without hashing the file a second time.
                check_model_io(name, manifest, onnx_session(path, registry.threads),
                               path)
        except ModelError as exc:
            row.update(status="error", message=str(exc))
        rows.append(row)
    return rows


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``outcast models`` to an argparse sub-parser set.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers()``.

    Returns:
        The ``models`` parser.
    """
    p = subparsers.add_parser(
        "models", help="list the models found, where, and check their checksums",
        description="Looks each model up in this order: --dir, $OUTCAST_MODEL_DIR, the user's "
        "model folder ($XDG_DATA_HOME/outcast/models), the shipped models; checks each file's "
        "sha256 against its manifest. Exit status 2 when one is missing or corrupt.",
    )
    p.add_argument("--dir", default=None, help="look only in this folder")
    p.add_argument("--load", action="store_true",
                   help="also load each model with onnxruntime (checks inputs and outputs)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run_models_command)
    return p


def run_models_command(args: argparse.Namespace) -> int:
    """Handler of ``outcast models``; returns 0 when every model is there and intact, else 2."""
    registry = ModelRegistry(Path(args.dir).expanduser() if args.dir else None)
    rows = model_report(registry, load=args.load)
    if args.json:
        print(json.dumps({"search_path": [str(p) for p in registry.search_path],
                          "models": rows}, indent=2))
    else:
        print("search path: " + " -> ".join(str(p) for p in registry.search_path))
        if args.dir or os.environ.get("OUTCAST_MODEL_DIR"):  # one folder the user named
            for folder in registry.search_path:
                if not folder.is_dir():
                    print(f"note: {folder} is not a folder", file=sys.stderr)
        for r in rows:
            where = r["file"] or r["folder"]
            extra = f" ({r['message']})" if r["message"] else ""
            print(f"{r['name']:16s} {r['status']:8s} {r['version']:8s} {where}{extra}")
    bad = [r["name"] for r in rows if r["status"] != "ok"]
    if bad:
        print(f"outcast models: error: not usable: {', '.join(bad)}", file=sys.stderr)
        return 2
    return 0
