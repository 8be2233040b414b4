"""Thread defaults (:mod:`hoibench.core.threads`): the count chosen from cores and load, and
the order of precedence of ``--threads``, ``HOIBENCH_THREADS`` and ``OMP_NUM_THREADS``."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from hoibench.core import threads as T

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("cores,load,expected", [
    (2, 0.0, 2),      # idle: every core
    (2, 0.4, 2),      # under half a process busy rounds to none
    (2, 0.5, 1),      # half rounds up
    (2, 1.2, 1),
    (2, 2.0, 1),      # every core busy: still one thread
    (2, 7.9, 1),
    (16, 3.4, 13),
    (16, 0.0, 16),
    (1, 0.0, 1),
    (8, -1.0, 8),     # nonsense loads count as idle
    (8, math.nan, 8),
    (8, math.inf, 8),
    (0, 0.0, 1),      # no core reported: one thread
])
def test_choose_threads_is_the_free_cores(cores, load, expected):
    assert T.choose_threads(cores, load) == expected


def test_choose_threads_never_grows_with_load():
    for cores in (1, 2, 4, 16):
        counts = [T.choose_threads(cores, load / 4) for load in range(0, 4 * cores + 8)]
        assert counts == sorted(counts, reverse=True) and min(counts) == 1 and max(counts) == cores


def test_precedence_requested_then_env_then_omp_then_load(monkeypatch):
    monkeypatch.setattr(T, "_CHOSEN", [])
    monkeypatch.setattr(T, "machine_load", lambda: (4, 1.0))
    assert T.default_threads(3, {"HOIBENCH_THREADS": "2"}) == 3
    assert T.default_threads(None, {"HOIBENCH_THREADS": "2", "OMP_NUM_THREADS": "4"}) == 2
    assert T.default_threads(None, {"OMP_NUM_THREADS": "4"}) is None          # torch follows it
    assert T.default_threads(None, {}) == 3
    monkeypatch.setattr(T, "machine_load", lambda: (4, 4.0))
    assert T.default_threads(None, {}) == 3          # decided once per process


@pytest.mark.parametrize("raw", ["0", "-1", "two", "1.5"])
def test_bad_hoibench_threads_is_one_line(raw):
    with pytest.raises(ValueError, match=rf"HOIBENCH_THREADS={raw!r}: expected a positive integer"):
        T.env_threads({"HOIBENCH_THREADS": raw})


def test_wait_policy_is_passive_unless_the_user_set_one():
    env: dict = {}
    assert T.set_wait_policy(env) == "PASSIVE" and env == {"OMP_WAIT_POLICY": "PASSIVE"}
    env = {"OMP_WAIT_POLICY": "ACTIVE"}
    assert T.set_wait_policy(env) == "ACTIVE" and env == {"OMP_WAIT_POLICY": "ACTIVE"}


def test_the_command_sets_passive_before_torch_loads():
    """``hoibench`` sets the policy in its entry point, before any command imports torch."""
    code = ("import os, sys; os.environ.pop('OMP_WAIT_POLICY', None); from hoibench import cli; "
            "cli.main(['version']); print(os.environ.get('OMP_WAIT_POLICY'), 'torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-2:] == ["PASSIVE", "False"], out.stdout
