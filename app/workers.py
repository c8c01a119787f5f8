"""Background work: one worker thread that owns every call into the relighting session.

* :class:`JobQueue` (Qt-free): one pending job per *channel*; submitting to a channel replaces the
  job waiting there, so while the user drags only the latest request counts. A *background*
  channel's job (the time-lapse dialog's timing of a short export) gives way to any other:
  it starts only when no other job waits and none was submitted for :data:`BACKGROUND_QUIET_S`,
  and one submitted while it runs stops it; it is then queued again behind that job under its
  id, and its second start is not signalled (the GUI still waits for its one result).
* :class:`JobContext`: handed to each job: ``progress(stage, fraction)`` and cancellation.
* :class:`TaskRunner` (a QObject living in the GUI thread): starts the thread, takes submissions,
  and re-emits results, failures and progress as signals in the GUI thread.

The worker thread emits signals of the :class:`_WorkerThread` object; they are connected to *slots
of the TaskRunner* (a GUI-thread QObject), so Qt queues them into the GUI thread. (A cross-thread
signal connected to a plain function would run in the worker thread.)

The session is documented as safe to call from one worker thread at a time, which this design
guarantees: there is exactly one worker thread and jobs run one after another.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal, Slot

#: A background job starts only this long after the user's last job was submitted: stopped by
#: each move of a drag and started again between them, the time-lapse dialog's timing held the
#: worker for a frame each time (a user trial: relight jobs waited up to 0.34 s instead of 0.03,
#: half of the drag's previews dropped).
BACKGROUND_QUIET_S = 1.0


class JobCancelledError(RuntimeError):
    """Raised inside a job (by :meth:`JobContext.check`) when it was cancelled."""


@dataclass
class Job:
    """A unit of work: ``fn(context) -> result``."""

    channel: str
    fn: Callable[[JobContext], Any]
    description: str = ""
    id: int = 0
    cancel_event: threading.Event = field(default_factory=threading.Event)
    #: Stopped to let another job run (a background job): queued again, not cancelled.
    preempted: bool = False
    #: A preempted job queued again (its start was signalled the first time).
    rerun: bool = False


class JobContext:
    """What a running job sees: progress reporting and cancellation."""

    def __init__(self, job: Job, report: Callable[[int, str, str, float], None]):
        self.job = job
        self._report = report

    @property
    def cancel_event(self) -> threading.Event:
        return self.job.cancel_event

    def cancelled(self) -> bool:
        return self.job.cancel_event.is_set()

    def check(self) -> None:
        """Raise :class:`JobCancelledError` when the job was cancelled."""
        if self.cancelled():
            raise JobCancelledError(f"{self.job.description or self.job.channel} cancelled")

    def progress(self, stage: str, fraction: float) -> None:
        """Report progress (thread-safe); also a cancellation point."""
        self._report(self.job.id, self.job.channel, str(stage), float(fraction))
        self.check()


class JobQueue:
    """Thread-safe queue with one pending job per channel (latest wins), FIFO across channels
    except that a background channel's job waits for every other."""

    def __init__(self, background: frozenset[str] = frozenset(),
                 quiet_s: float = BACKGROUND_QUIET_S) -> None:
        self._cond = threading.Condition()
        #: Channels whose jobs give way to any other (see the module docstring).
        self.background = frozenset(background)
        #: How long after the user's last job was submitted a background job may start.
        self.quiet_s = float(quiet_s)
        self._last_foreground = -math.inf
        self._pending: OrderedDict[str, Job] = OrderedDict()
        self._running: Job | None = None
        self._closed = False
        self._ids = itertools.count(1)

    def put(self, job: Job) -> tuple[int, Job | None]:
        """Queue ``job``; returns its id and the pending job it replaced (if any)."""
        with self._cond:
            if self._closed:
                raise RuntimeError("the worker has been shut down")
            job.id = next(self._ids)
            replaced = self._pending.pop(job.channel, None)
            self._pending[job.channel] = job
            if job.channel not in self.background:
                self._last_foreground = time.monotonic()
            run = self._running
            if (run is not None and run.channel in self.background
                    and job.channel not in self.background and not run.cancel_event.is_set()):
                run.preempted = True  # stopped for this one, queued again when it has stopped
                run.cancel_event.set()
            self._cond.notify()
            return job.id, replaced

    def finish(self, job: Job, cancelled: bool) -> bool:
        """The running ``job`` has ended (``cancelled``: by its cancel event). A preempted
        background job is queued again, under its id with a fresh cancel event, unless it was
        cancelled for good since (:meth:`cancel` clears ``preempted`` under the same lock), a
        newer job of its channel waits, or the queue is closed. Returns whether it was queued
        again (then its end is not reported)."""
        with self._cond:
            if self._running is job:
                self._running = None
            again = (cancelled and job.preempted and not self._closed
                     and job.channel not in self._pending)
            if again:
                self._pending[job.channel] = Job(job.channel, job.fn, job.description,
                                                 id=job.id, rerun=True)
            self._cond.notify_all()
            return again

    def _next_channel(self) -> tuple[str | None, float]:
        """The channel to run now (the first job waiting; a background one only when nothing
        else waits and the user's jobs have been quiet :attr:`quiet_s`), and when not, how
        long until a waiting background job may start (inf: none waits)."""
        channel = next((c for c in self._pending if c not in self.background), None)
        if channel is not None or not self._pending:
            return channel, math.inf
        wait = self._last_foreground + self.quiet_s - time.monotonic()
        return (next(iter(self._pending)), 0.0) if wait <= 0 else (None, wait)

    def take(self, timeout: float | None = None) -> Job | None:
        """Wait for the next job; ``None`` when closed (or on timeout)."""
        with self._cond:
            end = None if timeout is None else time.monotonic() + timeout
            while not self._closed:
                channel, wait = self._next_channel()
                if channel is not None:
                    break
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return None
                if math.isfinite(wait):
                    left = wait if left is None else min(left, wait)
                self._cond.wait(left)
            if self._closed:
                return None
            job = self._pending.pop(channel)
            self._running = job
            return job

    def cancel(self, channel: str) -> list[Job]:
        """Cancel the pending and the running job of a channel; returns the dropped pending ones."""
        with self._cond:
            dropped = []
            job = self._pending.pop(channel, None)
            if job is not None:
                job.cancel_event.set()
                dropped.append(job)
            if self._running is not None and self._running.channel == channel:
                self._running.preempted = False  # cancelled for good, not queued again
                self._running.cancel_event.set()
            return dropped

    def busy(self) -> bool:
        with self._cond:
            return self._running is not None or bool(self._pending)

    def running_channel(self) -> str | None:
        with self._cond:
            return None if self._running is None else self._running.channel

    def close(self) -> None:
        with self._cond:
            self._closed = True
            for job in self._pending.values():
                job.cancel_event.set()
            self._pending.clear()
            if self._running is not None:
                self._running.cancel_event.set()
            self._cond.notify_all()


class _WorkerThread(QThread):
    """Runs jobs from a :class:`JobQueue` one after another."""

    job_started = Signal(int, str, str)  # id, channel, description
    job_progress = Signal(int, str, str, float)  # id, channel, stage, fraction
    job_finished = Signal(int, str, object, float)  # id, channel, result, seconds
    job_failed = Signal(int, str, object)  # id, channel, exception
    job_cancelled = Signal(int, str)

    def __init__(self, queue: JobQueue) -> None:
        super().__init__()
        self.queue = queue

    def run(self) -> None:
        while True:
            job = self.queue.take()
            if job is None:
                return
            if not job.rerun:
                self.job_started.emit(job.id, job.channel, job.description)
            ctx = JobContext(job, self.job_progress.emit)
            t0 = time.perf_counter()
            outcome: tuple[str, Any] = ("finished", None)
            try:
                if job.cancel_event.is_set():
                    raise JobCancelledError(job.description)
                outcome = ("finished", job.fn(ctx))
            except JobCancelledError:
                outcome = ("cancelled", None)
            except Exception as exc:  # noqa: BLE001 - every failure goes to the GUI as a dialog
                outcome = ("cancelled", None) if job.cancel_event.is_set() else ("failed", exc)
            seconds = time.perf_counter() - t0
            kind, value = outcome
            if self.queue.finish(job, kind == "cancelled"):
                continue  # it runs again after the job it gave way to
            if kind == "finished":
                self.job_finished.emit(job.id, job.channel, value, seconds)
            elif kind == "failed":
                self.job_failed.emit(job.id, job.channel, value)
            else:
                self.job_cancelled.emit(job.id, job.channel)


class TaskRunner(QObject):
    """GUI-thread front end of the worker thread.

    Signals (all delivered in the GUI thread):
        started(id, channel, description)
        progress(id, channel, stage, fraction)
        finished(id, channel, result, seconds)
        failed(id, channel, exception)
        cancelled(id, channel)
        idle(): nothing is running or pending.
    """

    started = Signal(int, str, str)
    progress = Signal(int, str, str, float)
    finished = Signal(int, str, object, float)
    failed = Signal(int, str, object)
    cancelled = Signal(int, str)
    idle = Signal()

    def __init__(self, parent: QObject | None = None,
                 background: frozenset[str] = frozenset(),
                 quiet_s: float = BACKGROUND_QUIET_S) -> None:
        super().__init__(parent)
        self.queue = JobQueue(background, quiet_s)
        self._latest: dict[str, int] = {}
        # Jobs whose outcome has not reached the GUI thread yet (GUI-thread state only).
        self._outstanding: set[int] = set()
        self._about: dict[int, tuple[str, str]] = {}  # id -> (channel, description), outstanding
        self._thread = _WorkerThread(self.queue)
        self._thread.job_started.connect(self._on_started)
        self._thread.job_progress.connect(self._on_progress)
        self._thread.job_finished.connect(self._on_finished)
        self._thread.job_failed.connect(self._on_failed)
        self._thread.job_cancelled.connect(self._on_cancelled)
        self._thread.start()

    def submit(self, channel: str, fn: Callable[[JobContext], Any], description: str = "") -> int:
        """Queue ``fn(context)`` on ``channel``; a job still waiting on that channel is dropped."""
        job_id, replaced = self.queue.put(Job(channel, fn, description))
        if replaced is not None:
            self._forget(replaced.id)
        self._outstanding.add(job_id)
        self._about[job_id] = (channel, description)
        self._latest[channel] = job_id
        return job_id

    def latest(self, channel: str) -> int | None:
        """Id of the newest job submitted on a channel."""
        return self._latest.get(channel)

    def is_latest(self, job_id: int, channel: str) -> bool:
        return self._latest.get(channel) == job_id

    def cancel(self, channel: str) -> None:
        for job in self.queue.cancel(channel):
            self._forget(job.id)
        self._maybe_idle()

    def busy(self, background: bool = True) -> bool:
        """Whether a job is waiting, running, or its outcome has not reached the GUI yet
        (``background=False``: a job of a channel other than the background ones)."""
        if background:
            return bool(self._outstanding)
        return any(self._about.get(i, ("", ""))[0] not in self.queue.background
                   for i in self._outstanding)

    def active(self) -> list[tuple[int, str, str]]:
        """``(id, channel, description)`` of every job waiting, running or not yet reported."""
        return [(i, *self._about[i]) for i in sorted(self._outstanding) if i in self._about]

    def _forget(self, job_id: int) -> None:
        self._outstanding.discard(job_id)
        self._about.pop(job_id, None)

    def shutdown(self, timeout_ms: int = 10000) -> None:
        """Cancel everything and stop the thread."""
        self.queue.close()
        self._thread.wait(timeout_ms)

    @Slot(int, str, str)
    def _on_started(self, job_id: int, channel: str, description: str) -> None:
        self.started.emit(job_id, channel, description)

    @Slot(int, str, str, float)
    def _on_progress(self, job_id: int, channel: str, stage: str, fraction: float) -> None:
        self.progress.emit(job_id, channel, stage, fraction)

    @Slot(int, str, object, float)
    def _on_finished(self, job_id: int, channel: str, result: Any, seconds: float) -> None:
        self._forget(job_id)
        self.finished.emit(job_id, channel, result, seconds)
        self._maybe_idle()

    @Slot(int, str, object)
    def _on_failed(self, job_id: int, channel: str, exc: Any) -> None:
        self._forget(job_id)
        self.failed.emit(job_id, channel, exc)
        self._maybe_idle()

    @Slot(int, str)
    def _on_cancelled(self, job_id: int, channel: str) -> None:
        self._forget(job_id)
        self.cancelled.emit(job_id, channel)
        self._maybe_idle()

    def _maybe_idle(self) -> None:
        if not self._outstanding:
            self.idle.emit()
