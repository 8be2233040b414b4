"""A Ctrl-C while a process pool streams units (what ``hoibench evaluate --executor
processes:2`` does): one line, exit 130, nothing printed at interpreter exit, no pool thread
left; and a Ctrl-C inside :func:`hold_sigint` is raised when the block ends, not inside it."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from hoibench.core.interrupts import hold_sigint, terminate_as_interrupt

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
ROOT = Path(__file__).resolve().parents[1]

#: the evaluate loop in small: units read lazily from a generator, a window of them on a
#: pool of two spawned workers, inside the CLI's interrupt handling
SCRIPT = textwrap.dedent('''
    import sys, threading, time
    import numpy as np
    from concurrent.futures import process
    from hoibench.core.interrupts import terminate_as_interrupt
    from hoibench.core.parallel import map_units

    def unit(x):
        time.sleep(0.05)
        return float(x.sum())

    def units():
        for i in range(2000):
            yield np.random.default_rng(i).normal(size=(64, 263)).astype(np.float32)

    if __name__ == "__main__":
        try:
            with terminate_as_interrupt():
                for n, _ in enumerate(map_units(unit, units(), "processes:2", window=8)):
                    if n == 0:
                        print("first", flush=True)
        except KeyboardInterrupt:
            print("interrupted: rerun to resume", file=sys.stderr)
            left = [t.name for t in threading.enumerate() if t is not threading.main_thread()]
            print(f"threads {left} wakeups {len(process._threads_wakeups)}", file=sys.stderr)
            sys.exit(130)
''')


@pytest.mark.parametrize("delay_s", [0.0, 0.7])
def test_ctrl_c_during_a_streaming_pool_exits_cleanly(tmp_path, delay_s):
    """SIGINT to the process group (a terminal's Ctrl-C) after the first result (and 0.7 s
    later, with units being submitted): exit 130, the one line, no traceback and no
    "Exception ignored" at exit, the pool's manager thread gone before the interpreter exits."""
    script = tmp_path / "stream.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "HOIBENCH_PROGRESS": "0"}
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "first", proc.communicate(timeout=60)
        time.sleep(delay_s)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    lines = err.strip().splitlines()
    assert lines == ["interrupted: rerun to resume", "threads [] wakeups 0"], err


def test_a_signal_inside_hold_sigint_is_raised_when_the_block_ends():
    """Inside :func:`terminate_as_interrupt`, SIGINT sent to this process inside the block
    lets the block run to its end, then raises ``KeyboardInterrupt`` (once)."""
    reached_end = False
    with terminate_as_interrupt():
        with pytest.raises(KeyboardInterrupt):
            with hold_sigint():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)          # the handler has run by now
                reached_end = True
        time.sleep(0.01)                  # nothing further pending
    assert reached_end
