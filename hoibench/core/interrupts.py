"""Interrupts (Ctrl-C, SIGTERM) and the lifetime of worker processes.

One code path handles both signals: inside :func:`terminate_as_interrupt` SIGTERM raises
``KeyboardInterrupt`` in the main thread, like Ctrl-C. The parent decides what to do; worker
processes of :func:`hoibench.core.parallel.map_units` ignore SIGINT (:func:`ignore_sigint`; a
Ctrl-C in a terminal reaches the whole process group) and die with their parent
(:func:`die_with_parent`), even when it is killed with SIGKILL.

Every output is written atomically (:mod:`hoibench.core.io`), so an interrupted command leaves at
most ``.<name>.*.tmp`` files, removed by :func:`hoibench.core.io.clean_stale_tmp` when it runs
again; rerunning the same command resumes.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from typing import Iterator

EXIT_INTERRUPTED = 130          # 128 + SIGINT, what shells report for a Ctrl-C
PR_SET_PDEATHSIG = 1            # linux/prctl.h


def interrupt_message(what: str) -> str:
    """The one line a command prints when interrupted."""
    return f"interrupted: {what}; rerun the same command to resume"


#: set when an interrupt arrives inside :func:`terminate_as_interrupt`; survives a
#: ``KeyboardInterrupt`` that Python swallowed (raised inside a ``__del__`` or a callback,
#: where it is only printed as "Exception ignored"), so :func:`check_interrupted` at the
#: next unit boundary still stops the command
_INTERRUPTED = threading.Event()


#: depth of :func:`hold_sigint` blocks in the main thread, and the signal that arrived inside one
_HOLD = {"depth": 0, "pending": None}


def _raise_interrupt(signum: int, frame) -> None:
    _INTERRUPTED.set()
    if _HOLD["depth"] and _in_main_thread():     # held: raised when the block ends
        _HOLD["pending"] = signal.Signals(signum).name
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def check_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` when an interrupt arrived (even one that was swallowed)."""
    if _INTERRUPTED.is_set():
        raise KeyboardInterrupt("interrupted")


def was_interrupted() -> bool:
    return _INTERRUPTED.is_set()


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Inside the block SIGTERM (and SIGINT) raise ``KeyboardInterrupt`` in the main thread
    and set the flag :func:`check_interrupted` reads; the previous handlers are restored on
    exit. A no-op outside the main thread (only it may
    set signal handlers) and where SIGTERM does not exist."""
    if not _in_main_thread() or not hasattr(signal, "SIGTERM"):
        yield
        return
    _INTERRUPTED.clear()
    old = signal.signal(signal.SIGTERM, _raise_interrupt)
    old_int = signal.signal(signal.SIGINT, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)
        signal.signal(signal.SIGINT, old_int)
        _INTERRUPTED.clear()        # handled by the caller; later work in this process runs
        _HOLD["pending"] = None


@contextmanager
def hold_sigint() -> Iterator[None]:
    """Block SIGINT in this thread inside the block: a Ctrl-C is held, not lost, and is
    delivered (``KeyboardInterrupt``) on exit. Processes started inside inherit the blocked
    signal through ``exec``, so a spawned worker cannot be hit by Ctrl-C while it imports,
    before :func:`ignore_sigint` runs.

    The mask alone does not hold the interrupt in this process: the kernel hands a signal
    sent to the process group to another thread (a pool's manager thread), and Python runs
    the handler in the main thread anyway, possibly halfway through starting a worker.
    Inside :func:`terminate_as_interrupt` the handler therefore only records a signal that
    arrives in the block; the block raises it when it ends. The mask is a no-op without
    ``pthread_sigmask`` (Windows)."""
    main = _in_main_thread()
    masked = hasattr(signal, "pthread_sigmask")
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if masked else None
    if main:
        _HOLD["depth"] += 1
    try:
        yield
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        if main:
            _HOLD["depth"] -= 1
            if not _HOLD["depth"] and _HOLD["pending"] is not None:
                pending, _HOLD["pending"] = _HOLD["pending"], None
                raise KeyboardInterrupt(pending)


def ignore_sigint() -> None:
    """In a worker: ignore SIGINT (the parent decides) and unblock it (a Ctrl-C held since
    :func:`hold_sigint` is discarded)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def die_with_parent(parent_pid: int, poll_s: float = 0.5) -> str:
    """Make this process exit when ``parent_pid`` (its parent) dies, even by SIGKILL.

    Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``; the kernel sends the signal when the thread
    that started this process ends, so workers must be started from a long-lived thread (the
    one running :func:`hoibench.core.parallel.map_units`). Elsewhere: a daemon thread that exits
    the process when the parent pid changes. Returns the mechanism used."""
    how = "prctl" if _set_pdeathsig() else "watcher"
    if how == "watcher":
        threading.Thread(target=_watch_parent, args=(parent_pid, poll_s), daemon=True,
                         name="hoibench-parent-watch").start()
    if os.getppid() != parent_pid:      # the parent died before the line above took effect
        os._exit(1)
    return how


def _set_pdeathsig() -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(parent_pid: int, poll_s: float) -> None:
    while os.getppid() == parent_pid:
        time.sleep(poll_s)
    os._exit(1)
