"""Write what a benchmark prints to a Markdown report as well (``--report PATH``).

The README keeps only what a user needs; measured figures live in the report the benchmark
writes, with the date, the machine and the command that produced them, so every figure can be
traced to one run (compare figures only within one run: the machine is shared and noisy).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import io
import os
import platform
import sys
from collections.abc import Iterator
from pathlib import Path


class _Tee(io.TextIOBase):
    def __init__(self, *streams: io.TextIOBase) -> None:
        self.streams = streams

    def write(self, text: str) -> int:
        for s in self.streams:
            s.write(text)
        return len(text)

    def flush(self) -> None:
        for s in self.streams:
            s.flush()


@contextlib.contextmanager
def report_to(path: str | os.PathLike[str] | None, title: str) -> Iterator[None]:
    """Copy stdout into a Markdown report at ``path`` (nothing when ``path`` is None).

    Args:
        path: the report file (replaced when the run ends; kept as it was if the run fails).
        title: the report's heading, e.g. ``"bench_gui"``.
    """
    if path is None:
        yield
        return
    captured = io.StringIO()
    real = sys.stdout
    sys.stdout = _Tee(real, captured)  # type: ignore[assignment]
    try:
        yield
    finally:
        sys.stdout = real
    now = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    command = " ".join(["python", *sys.argv])
    text = (
        f"# OutCast benchmark report: {title}\n\n"
        f"Written by `{command}` on {now}; {platform.machine()} "
        f"{platform.processor() or platform.system()}, {os.cpu_count()} CPU cores, Python "
        f"{platform.python_version()}. Ratios compare figures of this run only.\n\n"
        f"```\n{captured.getvalue().strip()}\n```\n"
    )
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, out)
    print(f"report written to {out}", file=sys.stderr)
