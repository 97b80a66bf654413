"""Where the runs of a sweep execute: in threads here, or as tasks on a Dask cluster.

A run (one lockstep closed loop: its node processes, its bag, its analysis) is a task: a
picklable top-level function and its arguments. :class:`RunPool` executes tasks

- on a ``dask.distributed.LocalCluster`` on this machine (the default): ``jobs`` worker
  processes of one thread each;
- on an existing Dask scheduler, ``"tcp://HOST:PORT"`` (workers started with ``dask worker``
  or, on a SLURM/PBS cluster, by dask-jobqueue; README "Sweeps on a cluster");
- or in ``jobs`` threads of this process (``"threads"``: no Dask at all),

and hands back plain :class:`concurrent.futures.Future` objects, so callers wait on them
the same way (``as_completed``, ``result()``) whatever the pool.

The pool dispatches tasks itself, never more at a time than the cluster has threads: Dask
would otherwise hand a worker more tasks than it runs at once, and a worker's death would
fail the ones queued behind its running task too. A task that fails (it raised, or its
worker died: ``KilledWorker``) is logged, ``<label>: failed on <worker>: <reason>; retrying
once``, and submitted once more; a second failure is the future's exception. Dask itself
must not retry a task whose worker died behind our back: the LocalCluster's scheduler has
``distributed.scheduler.allowed-failures`` 0; a remote scheduler should too (the pool says
so when it does not).

Cancellation (Ctrl-C, :meth:`RunPool.cancel`): queued tasks are dropped and running ones
stopped. A flag (a ``distributed.Event`` named per pool on a cluster, a ``threading.Event``
here) is watched by each task from a thread beside it on its worker; once it is set, that
thread calls what the task registered with :func:`on_cancel` (a run: closing its
:class:`~joint_space_control.processes.loop.ClosedLoop`, which stops its node processes),
and the task ends.
"""

from __future__ import annotations

import concurrent.futures
import logging
import os
import signal
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

#: How long [s] a task's watcher waits on the cancel flag per turn.
WATCH_PERIOD = 0.5
#: How long [s] cancel() waits for the running tasks to stop before Dask drops them.
CANCEL_TIMEOUT = 60.0
#: How long [s] connecting to a remote scheduler may take.
CONNECT_TIMEOUT = 10.0
#: Tasks run at most this many times (the first attempt and one retry).
ATTEMPTS = 2


# -- on the worker: cancellation of the task running in a thread --------------------------


class _Scope:
    """The task running in one thread: cancelled or not."""

    def __init__(self) -> None:
        self.cancelled = False


_local = threading.local()
_registry_lock = threading.Lock()
#: What running tasks registered to be called on cancellation, each with its task's scope.
_closers: dict[object, tuple[_Scope | None, Callable[[], None]]] = {}


@contextmanager
def on_cancel(close: Callable[[], None]) -> Iterator[None]:
    """While inside: ``close`` is called, from another thread, when the pool task running in
    this thread is cancelled (at once if it already is), or by :func:`stop_all`. It must be
    safe to call from any thread and more than once (``ClosedLoop.close`` is)."""
    scope = getattr(_local, "scope", None)
    token = object()
    with _registry_lock:
        _closers[token] = (scope, close)
        cancelled = scope is not None and scope.cancelled
    if cancelled:
        close()
    try:
        yield
    finally:
        with _registry_lock:
            _closers.pop(token, None)


def stop_all() -> None:
    """Call everything registered with :func:`on_cancel` in this process (of every task)."""
    with _registry_lock:
        closers = [close for _, close in _closers.values()]
    for close in closers:
        close()


def _cancel_scope(scope: _Scope) -> None:
    with _registry_lock:
        scope.cancelled = True
        closers = [close for s, close in _closers.values() if s is scope]
    for close in closers:
        close()


def _watched(
    fn: Callable[..., T], args: tuple, cancelled: Callable[[float], bool], where: str | None
) -> T:
    """``fn(*args)`` in this thread, with a watcher thread beside it that cancels its scope
    once ``cancelled(timeout)`` (wait up to timeout [s] for the flag, say whether it is set)
    returns True. A failure carries ``jsc_worker`` (where it ran) to the client."""
    where = where or threading.current_thread().name
    if cancelled(0):
        raise CancelledError("the run pool was cancelled")
    scope = _Scope()
    done = threading.Event()

    def watch() -> None:
        try:
            while not done.is_set():
                if cancelled(WATCH_PERIOD):
                    if not done.is_set():
                        _cancel_scope(scope)
                    return
        except Exception:  # noqa: BLE001 - the worker is going away: nothing to stop
            return

    threading.Thread(target=watch, name="jsc-cancel-watch", daemon=True).start()
    _local.scope = scope
    try:
        return fn(*args)
    except BaseException as err:
        err.jsc_worker = where  # type: ignore[attr-defined]
        raise
    finally:
        _local.scope = None
        done.set()


def dask_setup(worker: Any) -> None:
    """Dask preload of the LocalCluster's workers (this module is named as their preload):
    Ctrl-C in a terminal is SIGINT to the whole foreground process group, the workers
    included, and a worker would die of it mid-task with a traceback. They do nothing on
    SIGINT and leave the stopping to the pool: it cancels the runs (their nodes stopped)
    and then closes the cluster. A Python handler rather than SIG_IGN: handlers are reset
    on exec, so the node processes a worker starts keep the default (SIG_IGN would be
    inherited)."""
    signal.signal(signal.SIGINT, lambda signum, frame: None)


def _dask_task(event_name: str, fn: Callable[..., T], *args: Any) -> T:
    """A pool task on a Dask worker: ``fn(*args)``, cancelled by the pool's Event."""
    from distributed import Event, get_worker

    event = Event(event_name)

    def cancelled(timeout: float) -> bool:
        return bool(event.wait(timeout)) if timeout > 0 else bool(event.is_set())

    return _watched(fn, args, cancelled, get_worker().address)


# -- where the tasks run -------------------------------------------------------------------


@dataclass(eq=False)
class _Task:
    label: str
    fn: Callable[..., Any]
    args: tuple
    future: Future
    attempts: int = 0
    handle: Any = field(default=None, repr=False)
    """The backend's handle of the running attempt (a Dask future must be kept referenced,
    or Dask forgets the task)."""


Done = Callable[[_Task, Any, BaseException | None, str], None]


class _Threads:
    """Tasks in a ThreadPoolExecutor of this process."""

    def __init__(self, jobs: int) -> None:
        self.jobs = jobs
        self.flag = threading.Event()
        self.executor = ThreadPoolExecutor(jobs, thread_name_prefix="jsc-run")

    @property
    def description(self) -> str:
        return f"threads, {self.jobs}"

    def capacity(self) -> int:
        return self.jobs

    def start(self, task: _Task, done: Done) -> None:
        def finished(f: Future) -> None:
            if f.cancelled():  # dropped by the executor's shutdown
                done(task, None, CancelledError("the run pool was closed"), "")
                return
            err = f.exception()
            where = getattr(err, "jsc_worker", "a thread") if err is not None else ""
            done(task, None if err is not None else f.result(), err, where)

        task.handle = self.executor.submit(_watched, task.fn, task.args, self.flag.wait, None)
        task.handle.add_done_callback(finished)

    def cancel(self) -> None:
        self.flag.set()

    def drop(self, tasks: list[_Task]) -> None:
        """Nothing stops a thread from outside: the tasks were asked to and must."""

    def missing(self, path: Path) -> list[str]:
        return [] if path.is_dir() else ["this process"]

    def close(self) -> None:
        self.executor.shutdown(wait=True, cancel_futures=True)


class _Dask:
    """Tasks on a Dask cluster: a LocalCluster of ``jobs`` one-thread workers, or the
    cluster behind ``address``."""

    def __init__(self, jobs: int, address: str | None) -> None:
        try:
            import dask
            from distributed import Client, Event, LocalCluster
        except ImportError as err:  # a ROS workspace without the venv's extras
            raise ValueError(
                f"runs on Dask need dask[distributed] ({err}): pip install "
                "'dask[distributed]', or run them in threads (--scheduler threads)"
            ) from None

        self.cluster = None
        self.address = address
        if address is None:
            # A task whose worker dies fails at once (KilledWorker): our retry, logged, is
            # the only one. Nothing is queued on a worker behind its running task (the
            # pool dispatches no more than the workers' threads), so nothing else fails.
            with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
                self.cluster = LocalCluster(
                    n_workers=jobs,
                    threads_per_worker=1,
                    processes=True,
                    # its HTTP server on a free port: 8787 taken by another cluster
                    # printed a warning
                    dashboard_address=":0",
                    silence_logs=logging.CRITICAL,
                    preload=[__name__],  # dask_setup: Ctrl-C is the pool's to handle
                )
            try:
                self.client = Client(self.cluster)
            except BaseException:
                self.cluster.close()
                raise
        else:
            try:
                self.client = Client(address, timeout=CONNECT_TIMEOUT)
            except Exception as err:  # noqa: BLE001 - any failure to connect is the address's
                raise ValueError(
                    f"cannot connect to the Dask scheduler {address!r} (is `dask scheduler` "
                    "running there?): " + (" ".join(str(err).split()) or type(err).__name__)
                ) from None
        self.event = Event(f"jsc-cancel-{uuid.uuid4().hex}", client=self.client)

    def allowed_failures(self) -> int | None:
        """How often the scheduler itself reruns a task whose worker died (None: unknown)."""
        try:
            return int(
                self.client.run_on_scheduler(
                    lambda dask_scheduler: dask_scheduler.allowed_failures
                )
            )
        except Exception:  # noqa: BLE001 - an old or locked-down scheduler: just unknown
            return None

    @property
    def description(self) -> str:
        workers = self.client.nthreads()
        n, threads = len(workers), sum(workers.values())
        where = "LocalCluster" if self.cluster is not None else f"scheduler {self.address}"
        text = f"{where}, {n} worker{'s' if n != 1 else ''}"
        return text if threads == n else f"{text} ({threads} threads)"

    def capacity(self) -> int:
        return sum(self.client.nthreads().values())

    def start(self, task: _Task, done: Done) -> None:
        from distributed import KilledWorker

        def finished(f: Any) -> None:
            try:
                if f.status == "finished":
                    done(task, f.result(), None, "")
                    return
                err = f.exception() if f.status == "error" else CancelledError(f.status)
            except BaseException as fetch:  # noqa: BLE001 - the result could not be fetched
                err = fetch
            if isinstance(err, KilledWorker):
                where = getattr(err.last_worker, "address", str(err.last_worker))
            else:
                where = getattr(err, "jsc_worker", "an unknown worker")
            done(task, None, err, where)

        key = "".join(c if c.isalnum() or c in "-_." else "_" for c in task.label)
        task.handle = self.client.submit(
            _dask_task,
            self.event.name,
            task.fn,
            *task.args,
            key=f"{key}-{uuid.uuid4().hex[:8]}",
            pure=False,
        )
        task.handle.add_done_callback(finished)

    def cancel(self) -> None:
        self.event.set()

    def drop(self, tasks: list[_Task]) -> None:
        self.client.cancel([t.handle for t in tasks if t.handle is not None])

    def missing(self, path: Path) -> list[str]:
        seen = self.client.run(os.path.isdir, str(path))
        return sorted(worker for worker, ok in seen.items() if not ok)

    def close(self) -> None:
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()


def _reason(err: BaseException) -> str:
    """The failure in one line."""
    if type(err).__name__ == "KilledWorker":  # by name: the threads pool has no Dask
        return "its worker died (KilledWorker)"
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def _end(future: Future, value: Any = None, err: BaseException | None = None) -> None:
    """Resolve ``future`` unless it already is (cancelled by its owner or by the pool)."""
    try:
        if err is None:
            future.set_result(value)
        else:
            future.set_exception(err)
    except concurrent.futures.InvalidStateError:
        pass


def _drop(future: Future) -> None:
    """A task that will not run: its future cancelled (waiters told), or, once running,
    failed with CancelledError."""
    if future.cancel():
        future.set_running_or_notify_cancel()  # wakes as_completed / wait
    else:
        _end(future, err=CancelledError("the run pool was cancelled"))


class RunPool:
    """Where runs execute: a Dask LocalCluster (``scheduler`` None: ``jobs`` worker
    processes of one thread), an existing Dask scheduler (``"tcp://HOST:PORT"``), or
    ``jobs`` threads of this process (``"threads"``). ``log`` gets one line per failure and
    retry. Close it (or use it as a context manager): that closes the client and the
    cluster. A bad ``jobs`` or an unreachable scheduler is a ValueError."""

    def __init__(
        self, jobs: int = 2, scheduler: str | None = None, log: Callable[[str], None] = print
    ) -> None:
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
        self._log = log
        self._lock = threading.Condition()
        self._queue: deque[_Task] = deque()
        self._running: set[_Task] = set()
        self._cancelled = False
        self._closed = False
        self._backend: _Threads | _Dask = (
            _Threads(jobs) if scheduler == "threads" else _Dask(jobs, scheduler)
        )
        if isinstance(self._backend, _Dask) and self._backend.cluster is None:
            retries = self._backend.allowed_failures()
            if retries:
                log(
                    f"note: the scheduler reruns a task whose worker died up to {retries} "
                    "times itself before this pool sees it (its "
                    "distributed.scheduler.allowed-failures; 0 makes every death logged)"
                )
        self._dispatcher = threading.Thread(target=self._dispatch, name="jsc-pool", daemon=True)
        self._dispatcher.start()

    # -- the API -------------------------------------------------------------------------
    def submit(self, label: str, fn: Callable[..., T], *args: Any) -> Future[T]:
        """Run ``fn(*args)`` (a picklable top-level function) on a worker; ``label`` names
        it in the log. A failure is logged and the task run once more; a second failure is
        the future's exception."""
        future: Future[T] = Future()
        with self._lock:
            if self._closed or self._cancelled:
                raise RuntimeError("the run pool is closed")
            self._queue.append(_Task(label, fn, args, future))
            self._lock.notify_all()
        return future

    def cancel(self) -> None:
        """Ctrl-C: drop the queued tasks, stop the running ones (each closes what it
        registered with :func:`on_cancel`: a run's node processes) and return when they are
        gone. No task is retried after this; the pool takes no more tasks."""
        with self._lock:
            self._cancelled = True
            queued = list(self._queue)
            self._queue.clear()
            self._lock.notify_all()
        for task in queued:
            _drop(task.future)
        self._backend.cancel()
        deadline = time.monotonic() + CANCEL_TIMEOUT
        with self._lock:
            while self._running and time.monotonic() < deadline:
                self._lock.wait(0.2)
            left = list(self._running)
        if left:  # still running after CANCEL_TIMEOUT: dropped; closing the pool ends them
            self._backend.drop(left)
            for task in left:
                _drop(task.future)

    def close(self) -> None:
        """Stop what still runs (as :meth:`cancel`), close the client and the cluster
        (idempotent)."""
        with self._lock:
            if self._closed:
                return
            busy = bool(self._queue or self._running)
        if busy:
            self.cancel()
        with self._lock:
            self._closed = True
            self._lock.notify_all()
        self._dispatcher.join()
        self._backend.close()

    @property
    def workers(self) -> int:
        """How many runs execute at once (the cluster's worker threads, now)."""
        return self._backend.capacity()

    @property
    def description(self) -> str:
        """Where the runs execute: ``LocalCluster, 2 workers``, ``scheduler tcp://…, 4
        workers`` or ``threads, 2``."""
        return self._backend.description

    def missing(self, directory: Path) -> list[str]:
        """The workers on which ``directory`` is not a directory (at this path): where the
        runs could not write their files for this process to read."""
        return self._backend.missing(directory)

    def __enter__(self) -> RunPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- dispatching ---------------------------------------------------------------------
    def _dispatch(self) -> None:
        """Start queued tasks while fewer run than the cluster has threads (the capacity is
        asked again every half second: workers come and go)."""
        while True:
            with self._lock:
                while not self._closed and not self._queue:
                    self._lock.wait()
                if self._closed:
                    return
            try:
                capacity = self._backend.capacity()
            except Exception:  # noqa: BLE001 - the scheduler is unreachable now: try later
                capacity = 0
            with self._lock:
                if self._closed:
                    return
                if not self._queue or len(self._running) >= capacity:
                    self._lock.wait(0.5)
                    continue
                task = self._queue.popleft()
                if task.attempts == 0 and not task.future.set_running_or_notify_cancel():
                    continue  # cancelled by its owner while queued
                task.attempts += 1
                self._running.add(task)
            try:
                self._backend.start(task, self._finished)
            except Exception as err:  # noqa: BLE001 - could not be submitted: a failure too
                self._finished(task, None, err, "the client")

    def _finished(self, task: _Task, value: Any, err: BaseException | None, where: str) -> None:
        with self._lock:
            self._running.discard(task)
            task.handle = None
            retry = (
                err is not None
                and not self._cancelled
                and not self._closed
                and task.attempts < ATTEMPTS
            )
            if retry:
                self._log(f"{task.label}: failed on {where}: {_reason(err)}; retrying once")
                self._queue.appendleft(task)
            elif err is not None and not self._cancelled and task.attempts >= ATTEMPTS:
                self._log(f"{task.label}: failed again on {where}: {_reason(err)}")
            self._lock.notify_all()
        if not retry:
            _end(task.future, value, err)
