"""``hoibench submission prompts``: one JSON line per test clip, and the documented ten-line
loop turns it into a submission that validates complete."""
from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np

from hoibench.scoring.prompts import prompts, write_prompts


def test_prompts_carry_what_a_generator_needs(template_store, tmp_path):
    from hoibench.datasets.store import Store
    st = Store(template_store)
    ps = prompts(template_store)
    assert [p["id"] for p in ps] == st.clip_ids("test")
    for p in ps[:4]:
        clip = st.load(p["id"])
        assert p["frames"] == len(clip["joints"]) and p["fps"] == float(st.manifest["config"]["fps"])
        assert p["object"] == str(clip["object_name"]) and p["captions"]
        with np.load(p["object_mesh"]) as z:
            assert z["vertices"].shape[1] == 3
    text = write_prompts(template_store, tmp_path / "p.jsonl")
    assert (tmp_path / "p.jsonl").read_text() == text and len(text.splitlines()) == len(ps)


def test_the_documented_loop_makes_a_valid_submission(template_store, tmp_path):
    from hoibench.scoring import prompts as mod
    from hoibench.datasets.store import Store
    from hoibench.scoring.submission import validation_report
    write_prompts(template_store, tmp_path / "prompts.jsonl")
    loop = re.search(r"A ten-line generation loop.*?::\n\n(.*?)\n\"\"\"", mod.__doc__ + '\n"""', re.S).group(1)
    code = "\n".join(line[4:] for line in loop.splitlines())
    st = Store(template_store)

    def my_model(caption, mesh, frames):        # the ground truth stands in for a generator
        clip = next(st.load(c) for c in st.clip_ids("test") if len(st.load(c)["joints"]) == frames)
        return clip["joints"], clip["obj_rot"], clip["obj_trans"]
    import os
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(code, {"my_model": my_model})
    finally:
        os.chdir(here)
    rep = validation_report(tmp_path / "my_sub", template_store)
    assert rep.complete, [str(p) for p in rep.problems][:3]


def test_cli_prints_or_writes_and_refuses_a_store_without_texts(template_store, tmp_path):
    exe = [sys.executable, "-m", "hoibench.cli", "submission", "prompts"]
    r = subprocess.run(exe + [str(template_store)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and json.loads(r.stdout.splitlines()[0])["id"]
    import shutil
    bare = tmp_path / "bare"
    shutil.copytree(template_store, bare)
    shutil.rmtree(bare / "texts")
    r = subprocess.run(exe + [str(bare)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "texts/" in r.stderr
