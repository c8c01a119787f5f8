"""The worker thread: latest wins per channel, results arrive in the GUI thread, cancel works."""

from __future__ import annotations

import threading
import time

import pytest

from app.workers import Job, JobCancelledError, JobQueue, TaskRunner


def test_queue_latest_wins_per_channel_fifo_across():
    q = JobQueue()
    q.put(Job("shadow", lambda c: 1))
    q.put(Job("export", lambda c: 2))
    _, replaced = q.put(Job("shadow", lambda c: 3))
    assert replaced is not None and replaced.fn(None) == 1
    first, second = q.take(0.1), q.take(0.1)
    assert (first.channel, first.fn(None)) == ("export", 2)
    assert (second.channel, second.fn(None)) == ("shadow", 3)
    assert q.take(0.01) is None


def test_queue_cancel_and_close():
    q = JobQueue()
    job = Job("a", lambda c: 1)
    q.put(job)
    running = q.take(0.1)
    pending = Job("a", lambda c: 2)
    q.put(pending)
    dropped = q.cancel("a")
    assert dropped == [pending] and pending.cancel_event.is_set()
    assert running.cancel_event.is_set()
    q.done(running)
    assert not q.busy()
    q.close()
    with pytest.raises(RuntimeError, match="shut down"):
        q.put(Job("a", lambda c: 3))


@pytest.fixture
def runner(qtbot):
    r = TaskRunner()
    yield r
    r.shutdown()


def test_results_reach_gui_thread_and_work_runs_elsewhere(qtbot, runner):
    gui = threading.get_ident()
    seen = {}

    def job(ctx):
        seen["worker"] = threading.get_ident()
        ctx.progress("half", 0.5)
        return 42

    def on_finished(job_id, channel, result, seconds):
        seen["slot"] = threading.get_ident()
        seen["result"] = (channel, result)

    def on_progress(job_id, channel, stage, fraction):
        seen["progress"] = (stage, fraction)

    runner.finished.connect(on_finished)
    runner.progress.connect(on_progress)
    with qtbot.waitSignal(runner.finished, timeout=5000):
        runner.submit("calc", job)
    assert seen["worker"] != gui
    assert seen["slot"] == gui  # delivered through the runner, a GUI-thread QObject
    assert seen["result"] == ("calc", 42)
    assert seen["progress"] == ("half", 0.5)


def test_only_latest_request_runs_while_busy(qtbot, runner):
    gate = threading.Event()
    ran = []

    def slow(ctx):
        gate.wait(5)
        ran.append("slow")

    runner.submit("other", slow)
    for i in range(20):  # a drag: many requests while the worker is busy
        runner.submit("shadow", lambda ctx, i=i: ran.append(i))
    gate.set()
    qtbot.waitUntil(lambda: not runner.busy(), timeout=5000)
    assert ran == ["slow", 19]


def test_failure_and_cancel_signals(qtbot, runner):
    with qtbot.waitSignal(runner.failed, timeout=5000) as failed:
        runner.submit("x", lambda ctx: 1 / 0)
    assert isinstance(failed.args[2], ZeroDivisionError)

    started = threading.Event()

    def long_job(ctx):
        started.set()
        while True:
            ctx.progress("loop", 0.0)  # a cancellation point
            time.sleep(0.005)

    with qtbot.waitSignal(runner.cancelled, timeout=5000) as cancelled:
        runner.submit("export", long_job)
        assert started.wait(5)
        runner.cancel("export")
    assert cancelled.args[1] == "export"
    assert issubclass(JobCancelledError, RuntimeError)
