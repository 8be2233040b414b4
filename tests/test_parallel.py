"""Progress reporting of hoibench.core.parallel.map_units without a terminal."""
from __future__ import annotations


def test_line_progress_for_logs_and_silence_on_error(monkeypatch, capsys):
    import io
    from hoibench.core import parallel
    buf = io.StringIO()
    bar = parallel.LineProgress("stage", 3, every_s=0.0, stream=buf)
    for _ in range(3):
        bar.update()
    bar.close()
    lines = buf.getvalue().splitlines()
    assert lines[:3] == ["[stage] 1/3 units, " + lines[0].split(", ")[1], lines[1], lines[2]]
    assert lines[2].startswith("[stage] 3/3 units") and lines[-1].startswith("[stage] done: 3 units in ")
    # without a terminal, map_units logs a last line when it finishes, and none when a unit fails
    monkeypatch.delenv("HOIBENCH_PROGRESS", raising=False)
    assert list(parallel.map_units(abs, [-1, -2], progress="demo")) == [1, 2]
    assert "[demo] done: 2 units" in capsys.readouterr().err

    def boom(x):
        raise ValueError("bad unit")
    try:
        list(parallel.map_units(boom, [1], progress="demo"))
    except ValueError:
        pass
    assert capsys.readouterr().err == ""
    monkeypatch.setenv("HOIBENCH_PROGRESS", "0")
    list(parallel.map_units(abs, [-1], progress="demo"))
    assert capsys.readouterr().err == ""


def _threads_and_warm(_unit):
    """In a pool worker: torch's thread count once a unit imports it, and whether the warm-up ran."""
    import os
    import torch
    return torch.get_num_threads(), os.environ.get("HOIBENCH_TEST_WARMED")


def _mark_warm(value):
    import os
    os.environ["HOIBENCH_TEST_WARMED"] = value


def _fail_warm(_value):
    raise RuntimeError("a warm-up that fails leaves the worker cold, nothing else")


def test_warm_executor_runs_the_warm_up_on_each_worker_and_units_get_one_thread():
    """A warmed pool: every worker ran the warm-up before its units; torch, imported by a unit,
    gets one thread (the worker set OMP_NUM_THREADS instead of importing it); the pool stays
    open across map_units calls; a failing warm-up changes nothing; serial specs pass through."""
    from hoibench.core.parallel import map_units, warm_executor
    with warm_executor("processes:2", (_mark_warm, ("yes",))) as pool:
        first = list(map_units(_threads_and_warm, range(6), pool))
        second = list(map_units(_threads_and_warm, range(2), pool))
    assert {t for t, _ in first + second} == {1}
    assert {w for _, w in first + second} == {"yes"}
    with warm_executor("processes:1", (_fail_warm, ("x",))) as pool:
        assert [t for t, _ in map_units(_threads_and_warm, range(2), pool)] == [1, 1]
    with warm_executor("serial", (_mark_warm, ("no",))) as spec:
        assert spec == "serial" and list(map_units(abs, [-3], spec)) == [3]
