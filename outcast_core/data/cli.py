"""``outcast data ...`` commands: make, standard, preview, bench.

``register(subparsers)`` adds the ``data`` command to an argparse sub-parser set; every leaf
parser sets ``func`` (``func(args) -> int`` exit code). Mitsuba is imported only inside the
commands that render. ``python -m outcast_core.data.cli ...`` runs the same commands standalone.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from outcast_core.data.dataset import STANDARD_SETS, DiskFullError, default_set_dir
from outcast_core.data.scene import EXTRA_KINDS, SCENE_KINDS


def _progress_bar(desc: str):  # noqa: ANN202 - a closure
    from tqdm import tqdm

    bar = tqdm(total=0, desc=desc, unit="view")

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return bar, update


def _make(
    out: Path, views: int, suns: int, res: int, spp: int, seed: int, workers: int,
    kind: str | None = None, shard: tuple[int, int] | None = None,
) -> int:
    from outcast_core.data.dataset import make_dataset, shard_range

    bar, update = _progress_bar(out.name)
    try:
        make_dataset(out, views, suns, res, spp, seed, workers, progress=update, kind=kind,
                     shard=shard)
    except DiskFullError as exc:
        bar.close()
        print(
            f"error: {exc.strerror}. Free some space and run the same command again: "
            f"finished views are kept and skipped.",
            file=sys.stderr,
        )
        return 3
    except ValueError as exc:
        bar.close()
        print(f"error: {exc}", file=sys.stderr)
        return 2
    bar.close()
    part = shard_range(views, shard)
    if shard is not None and not part:
        print(f"shard {shard[0]}/{shard[1]}: no views (only {views} for {shard[1]} shards)")
    elif shard is not None:
        print(f"shard {shard[0]}/{shard[1]}: views {part.start}..{part.stop - 1} (seeds "
              f"{seed + part.start}..{seed + part.stop - 1}) of {views} x {suns} suns in {out}")
    else:
        print(f"{views} views x {suns} suns in {out}")
    return 0


def cmd_make(args: argparse.Namespace) -> int:
    return _make(
        Path(args.out), args.views, args.suns, args.res, args.spp, args.seed, args.workers,
        args.kind, args.shard,
    )


def cmd_standard(args: argparse.Namespace) -> int:
    cfg = STANDARD_SETS[args.set]
    out = Path(args.out) if args.out else default_set_dir(args.set)
    views = args.views if args.views else cfg["views"]
    return _make(out, views, cfg["suns"], cfg["res"], cfg["spp"], cfg["seed"], args.workers,
                 shard=args.shard)


def _shard(text: str) -> tuple[int, int]:
    """``I/N`` with ``0 <= I < N``: this machine's part of the views."""
    parts = text.split("/")
    try:
        i, n = (int(p) for p in parts) if len(parts) == 2 else (-1, 0)
    except ValueError:
        i, n = -1, 0
    if not (n >= 1 and 0 <= i < n):
        raise argparse.ArgumentTypeError(f"expected --shard I/N with 0 <= I < N (e.g. 0/4), "
                                         f"got {text!r}")
    return i, n


def cmd_preview(args: argparse.Namespace) -> int:
    from outcast_core.data.preview import contact_sheet

    try:
        path = contact_sheet(args.dir, args.output, args.views, args.tile)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from outcast_core.data.bench import run_bench

    run_bench(args.views, args.suns, args.res, args.spp, args.seed)
    return 0


def _positive(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if val < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {val}")
    return val


def _non_negative(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if val < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {val}")
    return val


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``data make|standard|preview|bench`` to an ``argparse`` sub-parser set.

    Returns:
        The ``data`` parser (each leaf sets ``func``).
    """
    data = subparsers.add_parser("data", help="synthetic training data (Mitsuba 3)")
    sub = data.add_subparsers(dest="data_command", required=True)

    make = sub.add_parser("make", help="render a data set (resumable)")
    make.add_argument("--out", required=True, help="output folder")
    make.add_argument("--views", type=_positive, required=True, help="number of views N")
    make.add_argument("--suns", type=_positive, default=4, help="suns per view K (default 4)")
    make.add_argument(
        "--res", type=_positive, default=128, help="image size in pixels (default 128)"
    )
    make.add_argument("--spp", type=_positive, default=32, help="samples per pixel (default 32)")
    make.add_argument("--seed", type=_non_negative, default=0, help="base seed; view i uses seed+i")
    make.add_argument("--workers", type=_positive, default=1, help="parallel processes (default 1)")
    make.add_argument(
        "--kind", choices=SCENE_KINDS + EXTRA_KINDS, default=None,
        help="only this scene kind (default: the standard street/plaza/close-up mix)",
    )
    make.add_argument(
        "--shard", type=_shard, default=None, metavar="I/N",
        help="render only the I-th of N contiguous seed ranges (0-based), for N machines; "
             "the views keep their global numbers, so the shards' folders together are the set",
    )
    make.set_defaults(func=cmd_make)

    std = sub.add_parser("standard", help="make a standard set (train / test / dev)")
    std.add_argument("--set", choices=sorted(STANDARD_SETS), required=True)
    std.add_argument("--out", default=None, help="folder (default <cache>/data/<set>)")
    std.add_argument(
        "--views",
        type=_positive,
        default=None,
        help="override the number of views (a prefix of the standard set)",
    )
    std.add_argument("--workers", type=_positive, default=1)
    std.add_argument("--shard", type=_shard, default=None, metavar="I/N",
                     help="render only the I-th of N contiguous seed ranges (0-based)")
    std.set_defaults(func=cmd_standard)

    prev = sub.add_parser("preview", help="contact sheet PNG of a data set")
    prev.add_argument("dir", help="data set folder")
    prev.add_argument("-o", "--output", required=True, help="PNG to write")
    prev.add_argument("--views", type=_positive, default=8, help="rows (default 8)")
    prev.add_argument("--tile", type=_positive, default=160, help="tile size (default 160)")
    prev.set_defaults(func=cmd_preview)

    bench = sub.add_parser("bench", help="rendering throughput in views per minute")
    bench.add_argument("--views", type=_positive, default=3)
    bench.add_argument("--suns", type=_positive, default=4)
    bench.add_argument("--res", type=_positive, default=128)
    bench.add_argument("--spp", type=_positive, default=32)
    bench.add_argument("--seed", type=_non_negative, default=900_000)
    bench.set_defaults(func=cmd_bench)
    return data


def main(argv: list[str] | None = None) -> int:
    """Standalone entry point: ``python -m outcast_core.data.cli make ...``."""
    parser = argparse.ArgumentParser(prog="outcast")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["data", *(sys.argv[1:] if argv is None else argv)])
    return int(args.func(args))


if __name__ == "__main__":
    raise SystemExit(main())
