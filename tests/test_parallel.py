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
