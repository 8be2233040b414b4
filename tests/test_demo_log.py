"""The demo's log: training lines shown once each, never with a doubled prefix or cut
mid-word; one line when a run ends; sampling progress throttled but every 'wrote' line kept."""
from __future__ import annotations

from hoibench.demo import LogWatch, ThrottledLog, shorten


def test_shorten_cuts_at_a_word_boundary():
    text = "[catmo] step 1200/3000 loss 0.1234 (mse 0.1 vel 0.02) 6.60 steps/s " * 3
    out = shorten(text, 60)
    assert len(out) <= 60 and out.endswith(" ...")
    kept = out[:-4].split()
    assert kept == " ".join(text.split()).split()[:len(kept)]            # whole words only
    assert shorten("short line", 60) == "short line"


def test_log_watch_prints_each_new_line_once_without_a_doubled_prefix(tmp_path, capsys):
    log = tmp_path / "chainhoi.log"
    log.write_text("[chainhoi] step 10/100 loss 1.0\n")
    w = LogWatch("chainhoi", log, every_s=0.0)
    w.poll(None, 1.0)
    w.poll(None, 2.0)                                    # unchanged: nothing new
    log.write_text(log.read_text() + "[chainhoi] wrote runs/chainhoi-tiny in 12 s\n")
    w.poll(None, 3.0)
    w.poll(0, 4.0)
    w.poll(0, 5.0)                                       # ended: silent from now on
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["  [chainhoi] step 10/100 loss 1.0", "  [chainhoi] wrote runs/chainhoi-tiny in 12 s",
                     "  [chainhoi] finished after 4 s"]


def test_log_watch_waits_between_lines_and_names_a_failure(tmp_path, capsys):
    log = tmp_path / "catmo.log"
    log.write_text("step 1\n")
    w = LogWatch("catmo", log, every_s=3600.0)
    w.poll(None, 1.0)
    log.write_text("step 1\nstep 2\n")
    w.poll(None, 2.0)                                    # within every_s: not shown yet
    w.poll(1, 3.0)                                       # the end shows the newest line and the failure
    assert capsys.readouterr().out.splitlines() == ["  [catmo] step 1", "  [catmo] step 2",
                                                    "  [catmo] FAILED (exit 1) after 3 s"]


def test_throttled_log_keeps_written_lines(capsys):
    log = ThrottledLog(every_s=3600.0)
    for i in range(5):
        log(f"[catmo] sampled {i + 1}/5 clip{i}")
    log("[catmo] wrote subs/catmo: 5 clips x 1 samples in 3.0 s")
    assert capsys.readouterr().out.splitlines() == ["  [catmo] sampled 1/5 clip0",
                                                    "  [catmo] wrote subs/catmo: 5 clips x 1 samples in 3.0 s"]
