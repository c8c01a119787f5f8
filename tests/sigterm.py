"""Shared by the SIGTERM tests (CLI, time-lapse, app): start a child, wait until it says it is
mid-work, send SIGTERM and collect how it ended."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Ended:
    """How a child ended after SIGTERM: exit status, stderr, seconds from the signal."""

    returncode: int
    stderr: str
    seconds: float


def terminate_when_ready(
    args: Sequence[str],
    ready: str,
    *,
    env: dict[str, str] | None = None,
    before: Callable[[], None] | None = None,
    settle: float = 0.0,
) -> Ended:
    """Run ``python args...`` from the repository, wait for the line ``ready`` on its stdout,
    call ``before`` (checks while it works), wait ``settle`` seconds, send SIGTERM and wait.

    Args:
        args: arguments after the Python interpreter (e.g. ``["-c", CODE, ...]``).
        ready: the line the child prints once it is mid-work.
        env: extra environment (``PYTHONPATH`` is set to the repository).
        before: called after ``ready`` and before the signal.
        settle: seconds to wait before the signal.
    """
    full_env = {**os.environ, "PYTHONPATH": str(REPO), **(env or {})}
    proc = subprocess.Popen([sys.executable, *args], cwd=REPO, env=full_env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == ready
        if before is not None:
            before()
        if settle:
            time.sleep(settle)
        t0 = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        return Ended(proc.returncode, err, time.perf_counter() - t0)
    finally:
        proc.kill()
