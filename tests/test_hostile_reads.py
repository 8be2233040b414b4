"""Reads of files a user names or raw data holds: a FIFO, ``/dev/zero`` (through a link) or a
sparse file over the budget of its kind is refused in one line naming the file, fast and
within an address-space limit, by every reader that used to hang or read gigabytes: BEHAVE
``info.json`` and split files, OMOMO's text JSON, RICH's ``multicam2world`` JSON, a
multi-body split file, import mapping and joint files, CHOIS files, a track's ``about.md``,
the annotation files ``submission prompts`` reads, action label files, caption files.

Every case runs in one child process under ``RLIMIT_AS`` (1 GiB) and a timeout; the child
prints one line per case: the exception type, whether it is a ``ValueError`` (the CLI's
one-line path) and its message.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 1024 ** 3

CHILD = r"""
import json, resource, sys
resource.setrlimit(resource.RLIMIT_AS, (%d, %d))
cases = json.loads(sys.argv[1])
for name, path, code in cases:
    try:
        exec(code, {"P": path})
        print(json.dumps([name, "no error", False, ""]))
    except BaseException as e:
        print(json.dumps([name, type(e).__name__, isinstance(e, ValueError), str(e)]))
    sys.stdout.flush()
""" % (LIMIT, LIMIT)

#: (case, statement reading P); each runs for P = a FIFO, /dev/zero and an oversized sparse file
READERS = {
    "split file (BEHAVE, multi-body)": "from hoibench.datasets.splits import read_split_file; read_split_file(P)",
    "OMOMO text json": "from hoibench.datasets.omomo import _texts; _texts(P, 'sub1_box_0')",
    "RICH multicam2world": "from hoibench.datasets.rich import _read_transform; _read_transform(P, 'seq')",
    "import mapping": "from hoibench.scoring.importers import read_mapping; read_mapping(P)",
    "import joint file": "from hoibench.scoring.importers import ReadBudget; ReadBudget(1 << 20, 1 << 22).npy(P, 'joint file')",
    "import CHOIS file": "from hoibench.scoring.importers import ReadBudget; ReadBudget(1 << 20, 1 << 22).npz(P, 'CHOIS file')",
    "prompts annotation": "from hoibench.scoring.prompts import _group_id; _group_id(P)",
    "action labels": "from hoibench.text.annotate import load_action_labels; load_action_labels(P)",
    "protocol file": "from hoibench.tracks.protocol import read_protocol_yaml as f; f(P)",
}
#: the oversized sparse file per case: just over that reader's budget
OVER = {"OMOMO text json": 64 * 1024 ** 2, "split file (BEHAVE, multi-body)": 64 * 1024 ** 2,
        "import mapping": 64 * 1024 ** 2, "import joint file": 1 << 20, "import CHOIS file": 1 << 20,
        "RICH multicam2world": 1024 ** 2, "prompts annotation": 1024 ** 2, "action labels": 64 * 1024 ** 2,
        "protocol file": 1024 ** 2}


def _special_files(tmp: Path) -> dict[str, Path]:
    fifo, zero = tmp / "fifo.json", tmp / "zero.json"
    os.mkfifo(fifo)
    zero.symlink_to("/dev/zero")
    return {"fifo": fifo, "dev-zero": zero}


def _run(cases: list, timeout: float = 120) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps(cases)], capture_output=True, text=True,
                          timeout=timeout, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return {r[0]: r[1:] for r in map(json.loads, proc.stdout.splitlines())}


def test_special_and_oversized_files_are_refused_in_one_line(tmp_path):
    files = _special_files(tmp_path)
    cases = []
    for name, code in READERS.items():
        sparse = tmp_path / f"big_{len(cases)}.json"
        with open(sparse, "wb") as fh:
            fh.truncate(OVER[name] + 1)
        for kind, path in {**files, "oversized": sparse}.items():
            cases.append([f"{name} / {kind}", str(path), code])
    out = _run(cases)
    assert len(out) == len(cases)
    for (case, path, _), (etype, is_value_error, msg) in zip(cases, (out[c[0]] for c in cases)):
        assert is_value_error, f"{case}: {etype}: {msg}"
        assert "\n" not in msg and Path(path).name in msg, f"{case}: {msg!r}"
        kind = case.rsplit(" / ", 1)[1]
        want = {"fifo": "a FIFO", "dev-zero": "a device", "oversized": "limit"}[kind]
        assert want in msg, f"{case}: {msg!r}"


def test_behave_info_json_fifo_neither_hangs_listing_nor_loading(tmp_path):
    seq = tmp_path / "raw" / "sequences" / "Date01_Sub01_boxlarge_hand"
    seq.mkdir(parents=True)
    (tmp_path / "raw" / "objects").mkdir()
    os.mkfifo(seq / "info.json")
    code = ("from hoibench.datasets import behave\nfrom hoibench.datasets.store import PrepareConfig\n"
            "jobs = behave.prepare_jobs(P + '/raw', P + '/none', P + '/out', PrepareConfig('behave'))\n"
            "assert len(jobs) == 1\nimport pathlib; behave.read_info(pathlib.Path(P) / 'raw/sequences/Date01_Sub01_boxlarge_hand/info.json', 'seq', 'box')")
    etype, is_value_error, msg = _run([["behave", str(tmp_path), code]])["behave"]
    assert is_value_error and "info.json" in msg and "FIFO" in msg and "\n" not in msg, (etype, msg)


def test_track_about_md_is_read_through_the_guard(tmp_path):
    from hoibench.publish.pages import MAX_ABOUT_BYTES, read_about
    (tmp_path / "about.md").symlink_to("/dev/zero")
    with pytest.raises(ValueError, match="a device"):
        read_about(tmp_path)
    (tmp_path / "about.md").unlink()
    with open(tmp_path / "about.md", "wb") as fh:
        fh.truncate(MAX_ABOUT_BYTES + 1)
    with pytest.raises(ValueError, match="limit"):
        read_about(tmp_path)
    (tmp_path / "about.md").write_text("# Track\n", encoding="utf-8")
    assert read_about(tmp_path) == "# Track\n"
    assert read_about(tmp_path / "missing") == ""


def test_duplicate_json_keys_are_refused(tmp_path):
    from hoibench.core.io import read_json_file
    p = tmp_path / "submission.json"
    p.write_text('{"fps": 20, "method": "a", "fps": 30}')
    with pytest.raises(ValueError, match="duplicate key 'fps'"):
        read_json_file(p)
    p.write_text('{"a": {"b": 1}, "c": {"b": 2}}')        # the same key in two objects is fine
    assert read_json_file(p) == {"a": {"b": 1}, "c": {"b": 2}}
