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
    assert q.finish(running, cancelled=True) is False  # cancelled, not preempted
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


def test_queue_takes_a_background_job_only_when_nothing_else_waits():
    q = JobQueue(background=frozenset({"estimate"}), quiet_s=0.0)
    q.put(Job("estimate", lambda c: "e"))
    q.put(Job("shadow", lambda c: "s"))
    assert [q.take(0.1).channel, q.take(0.1).channel] == ["shadow", "estimate"]


def test_a_background_job_waits_until_the_users_jobs_have_been_quiet():
    """A user trial: stopped by each move of a drag and started again between moves, the
    timing held the worker a frame each time. It now starts only ``quiet_s`` after the last
    submission of another channel, each new one putting it off again."""
    q = JobQueue(background=frozenset({"estimate"}), quiet_s=0.3)
    q.put(Job("estimate", lambda c: "e"))
    assert q.take(0.01).channel == "estimate"  # nothing submitted before: at once
    q.put(Job("estimate", lambda c: "e"))
    q.put(Job("relight", lambda c: "r"))
    assert q.take(0.01).channel == "relight"
    t0 = time.monotonic()
    assert q.take(0.1) is None  # too soon after the relight
    q.put(Job("relight", lambda c: "r"))  # a drag's next move puts it off again
    assert q.take(0.01).channel == "relight"
    job = q.take(2.0)
    assert job.channel == "estimate" and time.monotonic() - t0 >= 0.3


def test_a_cancel_between_a_preempted_jobs_end_and_its_requeue_is_kept():
    """A review's race: the worker ended a preempted job and queued it again in two steps, so
    a cancel in between was lost and the job ran again. ``finish`` does both under one lock."""
    q = JobQueue(background=frozenset({"bg"}), quiet_s=0.0)
    q.put(Job("bg", lambda c: 1))
    job = q.take(0.1)
    q.put(Job("relight", lambda c: 2))
    assert job.preempted and job.cancel_event.is_set()
    assert q.cancel("bg") == [] and not job.preempted  # cancelled for good while stopping
    assert q.finish(job, cancelled=True) is False
    assert [q.take(0.1).channel, q.take(0.01)] == ["relight", None]
    # Preempted and not cancelled: queued again under its id, its start not to be signalled.
    q.put(Job("bg", lambda c: 3))
    job = q.take(0.1)
    q.put(Job("relight", lambda c: 4))
    assert q.finish(job, cancelled=True) is True
    assert q.take(0.1).channel == "relight"
    again = q.take(0.1)
    assert (again.id, again.rerun, again.cancel_event.is_set()) == (job.id, True, False)
    # A job that finished before it noticed the preemption is reported, not run again.
    q.finish(again, cancelled=False)
    assert q.take(0.01) is None


def test_a_background_job_gives_way_and_runs_again_unseen(qtbot):
    """The time-lapse estimate used the only worker thread, so a relighting waited behind it (a
    review): a job submitted while a background job runs stops it, runs first, and the
    background job runs again from the start under its id, its second start not signalled; the
    GUI sees one start and one result, and ``busy(background=False)`` ignores it. A background
    job cancelled by its own channel, running or queued again, is not run again."""
    runner = TaskRunner(background=frozenset({"estimate"}), quiet_s=0.0)
    try:
        runs: list[str] = []
        started = threading.Event()
        hold = threading.Event()

        def estimate(ctx):
            runs.append("estimate")
            started.set()
            if runs.count("estimate") > 1 and hold.is_set():
                return "timed"
            while not ctx.cancelled():  # until stopped
                time.sleep(0.002)
            ctx.check()

        starts: list[str] = []
        cancelled: list[int] = []
        runner.started.connect(lambda i, channel, d: starts.append(channel))
        runner.cancelled.connect(lambda job_id, channel: cancelled.append(job_id))
        hold.set()
        with qtbot.waitSignal(runner.finished, timeout=5000,
                              check_params_cb=lambda i, c, r, s: c == "estimate") as done:
            job_id = runner.submit("estimate", estimate)
            assert started.wait(5)
            runner.submit("relight", lambda ctx: runs.append("relight"))
            assert runner.busy() and runner.busy(background=False)
        assert runs == ["estimate", "relight", "estimate"]
        assert done.args[0] == job_id and done.args[2] == "timed" and cancelled == []
        assert starts == ["estimate", "relight"]
        qtbot.waitUntil(lambda: not runner.busy(), timeout=5000)

        # Cancelled while it runs: stopped for good.
        runs.clear()
        started.clear()
        hold.clear()
        with qtbot.waitSignal(runner.cancelled, timeout=5000) as stopped:
            job_id = runner.submit("estimate", estimate)
            assert started.wait(5)
            assert runner.busy() and not runner.busy(background=False)
            runner.cancel("estimate")
        assert stopped.args[0] == job_id and runs == ["estimate"]
        qtbot.waitUntil(lambda: not runner.busy(), timeout=5000)

        # Cancelled once queued again behind the job it gave way to: dropped, never rerun.
        runs.clear()
        started.clear()
        gate = threading.Event()
        runner.submit("estimate", estimate)
        assert started.wait(5)
        runner.submit("relight", lambda ctx: gate.wait(5))
        qtbot.waitUntil(lambda: runner.queue.running_channel() == "relight", timeout=5000)
        runner.cancel("estimate")
        gate.set()
        qtbot.waitUntil(lambda: not runner.busy(), timeout=5000)
        assert runs == ["estimate"]
    finally:
        runner.shutdown()
