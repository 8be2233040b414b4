"""Compute threads that degrade gracefully on a shared machine.

torch and OpenMP default to one compute thread per core, and OpenMP threads spin (busy-wait)
for a while after each parallel region. On a machine whose cores are already busy, those
threads compete with the other processes for the same cores and with each other: ChainHOI
tiny sampling on 2 cores next to 2 busy processes ran many times slower with 2 spinning
threads than with 1 (figures: docs/benchmarks.md, "Threads on a busy machine").

The rules here, in order of precedence:

* an explicit count (a command's ``--threads``) wins;
* ``HOIBENCH_THREADS=N`` (a positive integer) next;
* ``OMP_NUM_THREADS`` set by the user: torch already follows it, nothing is changed;
* otherwise :func:`choose_threads`: the cores not already busy, from the 1-minute load
  average, ``max(1, min(cores, cores - floor(load + 0.5)))``, decided once per process.

Float32 results on CPU can depend on the thread count (the order of parallel sums), so a
run that must reproduce bit for bit on another day fixes it: ``--threads N`` or
``HOIBENCH_THREADS=N``.

:func:`set_wait_policy` sets ``OMP_WAIT_POLICY=PASSIVE`` (idle OpenMP threads sleep instead
of spinning) unless the user set it; OpenMP reads it when torch loads, so the ``hoibench``
command sets it before importing anything that loads torch.
"""
from __future__ import annotations

import math
import os
from typing import Mapping

#: environment variable naming the compute threads hoibench uses (a positive integer)
ENV_THREADS = "HOIBENCH_THREADS"


def choose_threads(cores: int, load: float) -> int:
    """Intra-op threads for ``cores`` cores whose 1-minute load average is ``load``
    (runnable processes): the cores not busy, ``cores - floor(load + 0.5)``, at least 1 and
    at most ``cores``. A negative or non-finite load counts as 0."""
    cores = max(1, int(cores))
    busy = math.floor(load + 0.5) if math.isfinite(load) and load > 0 else 0
    return max(1, min(cores, cores - busy))


def env_threads(environ: Mapping[str, str] | None = None) -> int | None:
    """``HOIBENCH_THREADS`` as a positive integer, None when unset; ``ValueError`` (one line)
    when set to anything else."""
    env = os.environ if environ is None else environ
    raw = env.get(ENV_THREADS)
    if raw is None or raw.strip() == "":
        return None
    if not raw.strip().isdigit() or int(raw) < 1:
        raise ValueError(f"{ENV_THREADS}={raw!r}: expected a positive integer (compute threads)")
    return int(raw)


def machine_load() -> tuple[int, float]:
    """(usable cores, 1-minute load average); the load is 0 where the platform has none."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        load = 0.0
    return cores, load


#: the count :func:`default_threads` chose from the load, kept for the rest of the process
_CHOSEN: list[int] = []


def default_threads(requested: int | None = None, environ: Mapping[str, str] | None = None) -> int | None:
    """The thread count to set: ``requested``, else ``HOIBENCH_THREADS``, else None when the
    user set ``OMP_NUM_THREADS`` (torch follows it), else :func:`choose_threads` of this
    machine, measured once per process (two trainings or samplings in one process use the
    same count, so they give the same numbers)."""
    env = os.environ if environ is None else environ
    if requested:
        return int(requested)
    fixed = env_threads(env)
    if fixed is not None:
        return fixed
    if env.get("OMP_NUM_THREADS"):
        return None
    if not _CHOSEN:
        _CHOSEN.append(choose_threads(*machine_load()))
    return _CHOSEN[0]


def set_torch_threads(requested: int | None = None) -> int:
    """Set torch's intra-op threads by :func:`default_threads` and return the count in use."""
    import torch
    n = default_threads(requested)
    if n is not None and n != torch.get_num_threads():
        torch.set_num_threads(n)
    return torch.get_num_threads()


def set_wait_policy(environ: dict | None = None) -> str:
    """Set ``OMP_WAIT_POLICY=PASSIVE`` unless already set (before torch loads); return the
    policy in force."""
    env = os.environ if environ is None else environ
    return env.setdefault("OMP_WAIT_POLICY", "PASSIVE")


__all__ = ["ENV_THREADS", "choose_threads", "env_threads", "machine_load", "default_threads",
           "set_torch_threads", "set_wait_policy"]
