"""Executor selection for per-unit work (prepare, contacts, annotation, physical metrics).

``--executor`` accepts:

- ``serial``: in-process ``map``;
- ``processes`` or ``processes:N``: a local process pool (``spawn`` start method, N workers,
  default = CPU count);
- ``dask://ADDRESS``: a running Dask scheduler (``tcp://host:8786`` -> ``dask://host:8786``);
  ``dask://local`` or ``dask://local:N`` starts a local cluster of N worker processes.
  Needs the optional extra ``pip install hoibench[dask]``; a
  ``dask.distributed.Client(...).get_executor()`` is a standard
  ``concurrent.futures.Executor``.

Units must be pure functions of their arguments (seeded from the unit id, never from worker
rank), so results are identical whatever the executor; :func:`map_units` returns results in
input order.

Stopping early: when the consumer of :func:`map_units` stops (``break``/``close()``, e.g.
``--strict``), or an interrupt or a unit's exception ends it, units not started are cancelled
and a process pool's workers are terminated, without waiting for queued work. Pool workers
ignore SIGINT and die with their parent (:mod:`hoibench.core.interrupts`).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import time
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from collections import deque
from typing import Any, Callable, Iterable, Iterator, Sequence

from .interrupts import check_interrupted, die_with_parent, hold_sigint, ignore_sigint


@dataclass(frozen=True)
class ExecutorSpec:
    kind: str                # "serial" | "processes" | "dask"
    workers: int | None = None
    address: str | None = None

    def __str__(self) -> str:
        if self.kind == "processes":
            return f"processes:{self.workers}" if self.workers else "processes"
        if self.kind == "dask":
            return f"dask://{self.address}"
        return "serial"


def parse_executor(spec: str) -> ExecutorSpec:
    """Parse an ``--executor`` value; ``ValueError`` naming the accepted forms otherwise."""
    s = (spec or "serial").strip()
    if s == "serial":
        return ExecutorSpec("serial")
    if s == "processes" or s.startswith("processes:"):
        n = s.partition(":")[2]
        if n and (not n.isdigit() or int(n) < 1):
            raise ValueError(f"--executor: worker count must be a positive integer, got {spec!r}")
        return ExecutorSpec("processes", int(n) if n else None)
    if s.startswith("dask://"):
        addr = s[len("dask://"):]
        if not addr:
            raise ValueError("--executor: dask:// needs an address, e.g. dask://127.0.0.1:8786 or dask://local")
        return ExecutorSpec("dask", address=addr)
    hint = f" (processes:{s} for {s} worker processes?)" if s.isdigit() else ""
    raise ValueError(f"--executor: expected serial, processes[:N] or dask://ADDRESS, got {spec!r}{hint}")


_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Processes started inside this block inherit one-thread settings for OpenMP and BLAS.

    They must be in the environment when a worker starts: a spawned worker may import numpy
    (and BLAS sizes its thread pool) while unpickling its initializer's arguments or its first
    task, before the initializer could change them. N workers x M BLAS threads on N cores spin against each other (2.1x
    slower on the physical metrics here)."""
    saved = {v: os.environ.get(v) for v in _THREAD_VARS}
    os.environ.update({v: "1" for v in _THREAD_VARS})
    try:
        yield
    finally:
        for v, old in saved.items():
            if old is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = old


def _single_threaded_worker() -> None:
    """One compute thread per worker process: N workers x M library threads would
    oversubscribe the cores (torch and BLAS default to one thread per core). torch is not
    imported for this (2 s a worker, and the physical units never use it): it reads
    ``OMP_NUM_THREADS`` when a unit first imports it; if it is already loaded it is told."""
    import sys
    for var in _THREAD_VARS:
        os.environ[var] = "1"
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


def _pool_worker(parent_pid: int, warm: tuple[Callable, tuple] | None = None) -> None:
    """Process-pool initializer: dies with ``parent_pid``, ignores SIGINT (the parent
    decides), one compute thread; then ``warm = (fn, args)`` if given (a failure is ignored:
    it only leaves the worker's caches cold)."""
    die_with_parent(parent_pid)
    ignore_sigint()
    _single_threaded_worker()
    if warm is not None:
        _call_quietly(warm[0], *warm[1])


class _SerialExecutor(cf.Executor):
    def submit(self, fn, /, *args, **kwargs):
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # reported through the future, like a pool would
            fut.set_exception(exc)
        return fut


@contextmanager
def open_executor(spec: str | ExecutorSpec, warm: tuple[Callable, tuple] | None = None) -> Iterator[cf.Executor]:
    """A ``concurrent.futures.Executor`` for ``spec``, shut down on exit; a process pool's
    workers run ``warm = (fn, args)`` when they start (:func:`_pool_worker`)."""
    spec = parse_executor(spec) if isinstance(spec, str) else spec
    if spec.kind == "serial":
        yield _SerialExecutor()
        return
    if spec.kind == "processes":      # its workers start at a submit (:func:`_submit`), not here
        ex = cf.ProcessPoolExecutor(max_workers=spec.workers or os.cpu_count() or 1,
                                    mp_context=mp.get_context("spawn"),
                                    initializer=_pool_worker, initargs=(os.getpid(), warm))
        try:
            yield ex
            ex.shutdown(wait=True)        # an interrupt while waiting for the workers: abandoned below
        except BaseException:
            _abandon(ex, ())
            raise
        return
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise ImportError("--executor dask://...: install the optional extra: "
                          "pip install 'hoibench[dask]'") from exc
    addr = spec.address
    if addr == "local" or addr.startswith("local:"):
        n = int(addr.partition(":")[2] or 2)
        with _single_threaded_children(), LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            yield client.get_executor()
        return
    with Client(addr if "://" in addr else f"tcp://{addr}") as client:
        yield client.get_executor()


@contextmanager
def warm_executor(spec: str | ExecutorSpec, warm: tuple[Callable, tuple] | None = None
                  ) -> Iterator[str | ExecutorSpec | cf.Executor]:
    """What :func:`map_units` can run on, started now: a process pool is opened and its
    workers started at once, each running ``warm = (fn, args)`` (``fn(*args)``, e.g. building
    per-object caches) as it starts, while the caller works on; it is shut down on exit
    (abandoned on an error, like :func:`open_executor`). Serial and Dask specs come back as they are (a
    Dask worker is not chosen by the caller: nothing to warm). Results never depend on the
    warming: a unit computes whatever a cold worker would."""
    parsed = parse_executor(spec) if isinstance(spec, str) else spec
    if parsed.kind != "processes":
        yield spec
        return
    with open_executor(parsed, warm) as ex:
        for _ in range(parsed.workers or os.cpu_count() or 1):
            _submit(ex, _noop)            # each finds no idle worker and starts one
        yield ex


def submit_ahead(executor: cf.Executor, fn: Callable, *args) -> cf.Future:
    """``fn(*args)`` started now on an open pool (e.g. from :func:`warm_executor`: an idle
    worker takes it at once), in the environment every unit of this module runs in. Its
    future may be given to :func:`map_units` as a unit: it is waited for, not run again."""
    return _submit(executor, fn, *args)


def run_early(executor: Any, fn: Callable, *args) -> Callable[[], Any]:
    """Start ``fn(*args)`` now on an open process pool (:func:`submit_ahead`); returns a
    function giving its result. On anything else (a serial or Dask spec) ``fn`` runs when the
    result is asked for."""
    if not isinstance(executor, cf.ProcessPoolExecutor):
        return lambda: fn(*args)
    return submit_ahead(executor, fn, *args).result


def _submit(ex: cf.Executor, fn: Callable, *args) -> cf.Future:
    """``ex.submit(fn, *args)`` with SIGINT held (workers start with it blocked) and in the
    one-thread environment (:func:`_single_threaded_children`): a process pool starts its
    workers at a submit, and a worker may import numpy, sizing BLAS's thread pool, while it
    unpickles its initializer's arguments, before the initializer runs."""
    with hold_sigint(), _single_threaded_children():
        return ex.submit(fn, *args)


def _noop() -> None:
    """A task that only makes the pool start a worker."""


def _call_quietly(fn: Callable, *args) -> None:
    try:
        fn(*args)
    except Exception:                 # noqa: BLE001 - the unit that needs it raises the real error
        pass


def map_units(fn: Callable[[Any], Any], units: Iterable[Any], executor: str | ExecutorSpec | cf.Executor = "serial",
              progress: str | None = None, window: int | None = None) -> Iterator[Any]:
    """Yield ``fn(unit)`` for every unit, in input order, running on ``executor`` (a spec, or
    an executor already open, e.g. from :func:`warm_executor`, which stays open).

    ``serial`` runs each unit when its result is asked for. A pool gets every unit up front
    (a unit that is a future of this pool, from :func:`submit_ahead`, is only waited for),
    or at most ``window`` units ahead of the one being yielded when ``window`` is given
    (then ``units`` may be a generator that is read lazily: streaming keeps memory bounded).
    If the caller stops early (``break``, ``close()``) or an exception or interrupt ends the
    loop, pending units are cancelled and workers terminated (:func:`_abandon`).
    ``progress`` names a progress bar: tqdm when stderr is a terminal (or
    ``HOIBENCH_PROGRESS=1``), else a line every 10 s and one at the end (:class:`LineProgress`);
    ``HOIBENCH_PROGRESS=0`` silences it.
    """
    opened = executor if isinstance(executor, cf.Executor) else None
    spec = ExecutorSpec("pool") if opened is not None else \
        parse_executor(executor) if isinstance(executor, str) else executor
    bar = _progress_bar(progress, len(units) if hasattr(units, "__len__") else None)
    finished = False
    try:
        if spec.kind == "serial" or isinstance(opened, _SerialExecutor):
            for unit in units:
                yield _tick(bar, fn(unit))
        else:
            yield from _map_pool(fn, units, spec, bar, window, opened)
        finished = True
    finally:
        if isinstance(bar, LineProgress):
            if finished:                  # an error or interrupt keeps stderr to its one line
                bar.close()
        elif bar is not None:
            bar.close()


def _tick(bar, result: Any) -> Any:
    check_interrupted()          # an interrupt Python swallowed still stops at a unit boundary
    if bar is not None:
        bar.update(1)
    return result


def _map_pool(fn: Callable[[Any], Any], units: Iterable[Any], spec: ExecutorSpec, bar,
              window: int | None = None, opened: cf.Executor | None = None) -> Iterator[Any]:
    """:func:`map_units` on a process pool or Dask (``opened``: one already open, left open
    unless the loop ends early); abandons the pool on any early exit."""
    with (nullcontext(opened) if opened is not None else open_executor(spec)) as ex:
        futures: deque[cf.Future] = deque()
        todo = iter(units)
        limit = max(1, int(window)) if window is not None else None

        def fill() -> None:
            for unit in todo:             # reading the next unit may be interrupted at once, a submit not
                # a unit already started on this pool (submit_ahead) is waited for, not run again
                futures.append(unit if isinstance(unit, cf.Future) else _submit(ex, fn, unit))
                if limit is not None and len(futures) >= limit:
                    return

        try:
            fill()
            while futures:
                result = futures[0].result()
                futures.popleft()
                yield _tick(bar, result)
                if limit is not None:
                    fill()
        except BaseException:             # KeyboardInterrupt, GeneratorExit, a unit's error
            _abandon(ex, list(futures))
            raise


def _abandon(ex: cf.Executor, futures: Sequence[cf.Future], grace_s: float = 1.0) -> None:
    """Stop ``ex`` now: cancel units not started, shut down without waiting, terminate a
    process pool's workers (SIGTERM, then SIGKILL after ``grace_s``), then wait (at most
    ``grace_s`` more) for the pool's manager thread to close its pipes. Dask's executor
    cancels its futures on ``shutdown(wait=False)``. Safe to call twice."""
    procs = list((getattr(ex, "_processes", None) or {}).values())   # gone after shutdown
    manager = getattr(ex, "_executor_manager_thread", None)
    for fut in futures:
        fut.cancel()
    try:
        ex.shutdown(wait=False, cancel_futures=True)
    except TypeError:                     # executors without cancel_futures (Dask)
        ex.shutdown(wait=False)
    _terminate(procs, grace_s)
    _retire_manager(manager, grace_s)


def _retire_manager(thread: Any, timeout_s: float) -> None:
    """Join a process pool's manager thread, so that nothing of the pool runs when the
    interpreter exits. ``concurrent.futures`` wakes every manager thread it still knows at
    exit by writing to the thread's pipe, without the lock the thread takes to close that
    pipe: a thread still closing it then gets the write on a closed descriptor ("Exception
    ignored in: <module 'threading'> ... OSError: [Errno 9] Bad file descriptor"). A thread
    that does not end in ``timeout_s`` is dropped from that list (it is not written to)."""
    if thread is None:
        return
    try:
        thread.join(timeout_s)
    except RuntimeError:                  # never started
        return
    if thread.is_alive():
        from concurrent.futures import process
        wakeups = getattr(process, "_threads_wakeups", None)
        if wakeups is not None:
            wakeups.pop(thread, None)


def _terminate(procs: Sequence[Any], grace_s: float) -> None:
    """Terminate ``multiprocessing`` processes and reap them (guarded: a process may
    already be gone, or be reaped by the pool's own thread)."""
    for p in procs:
        try:
            p.terminate()
        except (OSError, ValueError, AttributeError):
            pass
    deadline = time.monotonic() + grace_s
    for p in procs:
        try:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(0.5)
        except (OSError, ValueError, AttributeError, AssertionError):
            pass


class LineProgress:
    """Progress for logs and pipes (no terminal): one line on stderr at most every
    ``every_s`` seconds, and a last line with the count and the elapsed time, e.g.
    ``[annotate] 40/120 units, 12.3 s`` ... ``[annotate] done: 120 units in 31.0 s``."""

    def __init__(self, desc: str, total: int | None, every_s: float = 10.0, stream=None):
        import sys
        self.desc, self.total, self.every_s = desc, total, every_s
        self.stream = stream if stream is not None else sys.stderr
        self.n = 0
        self.t0 = self.last = time.monotonic()

    def _write(self, text: str) -> None:
        try:
            print(text, file=self.stream, flush=True)
        except (OSError, ValueError):          # a closed pipe never stops the work
            pass

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.monotonic()
        if now - self.last >= self.every_s:
            self.last = now
            of = f"/{self.total}" if self.total is not None else ""
            self._write(f"[{self.desc}] {self.n}{of} units, {now - self.t0:.1f} s")

    def close(self) -> None:
        self._write(f"[{self.desc}] done: {self.n} units in {time.monotonic() - self.t0:.1f} s")


def _progress_bar(desc: str | None, total: int):
    """A tqdm bar on a terminal, :class:`LineProgress` otherwise (``HOIBENCH_PROGRESS=1``
    forces the bar, ``0`` silences both)."""
    if desc is None:
        return None
    import sys
    setting = os.environ.get("HOIBENCH_PROGRESS")
    if setting == "0":
        return None
    if not (sys.stderr.isatty() or setting == "1"):
        return LineProgress(desc, total)
    try:
        from tqdm import tqdm
    except ImportError:
        return LineProgress(desc, total)
    return tqdm(total=total, desc=desc, unit="unit")
