"""An EvalAI adapter: the challenge's scoring as EvalAI's ``evaluate`` entry point.

EvalAI calls ``evaluate(test_annotation_file, user_submission_file, phase_codename,
**kwargs)`` from the challenge's ``evaluation_script/__init__.py``; here
``test_annotation_file`` is the bundle's ``reference_data.zip`` (or its unzipped folder) and
``user_submission_file`` the participant's upload (a submission ``.zip``). The return value is
EvalAI's result structure::

    {"result": [{"<split codename>": {"<metric>": value, ...}}],
     "submission_result": {"<metric>": value, ...}}

with the same numbers as the Codabench scoring program and ``hoibench evaluate``
(:func:`hoibench.challenge.scoring.score_folders`). The split codename is the phase's split
(``challenge.json``'s ``phases``) with ``_split`` appended, or ``split_codename=`` given by
the caller. A refused submission raises :class:`~hoibench.challenge.scoring.ChallengeRefused`
(EvalAI shows the message as the submission's error).
"""
from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path

from .reference import read_reference
from .scoring import score_folders

#: most bytes a reference zip may expand to (the organiser's own file, still bounded)
MAX_REFERENCE_BYTES = 64 << 30


def _extract_reference(path: Path, dest: Path) -> Path:
    with zipfile.ZipFile(path) as z:  # read-ok: member paths and the expanded size are checked before extracting
        total = 0
        for m in z.infolist():
            name = m.filename
            if name.startswith("/") or ".." in Path(name).parts or "\\" in name:
                raise ValueError(f"{path.name}: member {name!r}: unsafe path")
            total += m.file_size
        if total > MAX_REFERENCE_BYTES:
            raise ValueError(f"{path.name}: expands to {total} bytes (limit {MAX_REFERENCE_BYTES})")
        z.extractall(dest)
    return dest


def evaluate(test_annotation_file, user_submission_file, phase_codename, **kwargs) -> dict:
    """EvalAI's entry point (module docstring)."""
    ref_src = Path(test_annotation_file)
    sub = Path(user_submission_file)
    with tempfile.TemporaryDirectory(prefix="hoibench-evalai-") as tmp:
        inp = Path(tmp) / "input"
        (inp / "res").mkdir(parents=True)
        if ref_src.is_dir():
            (inp / "ref").symlink_to(ref_src.resolve(), target_is_directory=True)
        else:
            _extract_reference(ref_src, inp / "ref")
        if sub.is_dir():
            shutil.copytree(sub, inp / "res" / "submission")
        else:
            shutil.copy2(sub, inp / "res" / (sub.name if sub.suffix == ".zip" else "submission.zip"))
        info = read_reference(inp / "ref")
        split = kwargs.get("split_codename") or f"{info.get('phases', {}).get(phase_codename, 'test')}_split"
        scores = score_folders(inp, Path(tmp) / "output", executor=kwargs.get("executor", "serial"))
    metrics = {k: v for k, v in scores.items() if k in info["columns"]}
    return {"result": [{split: metrics}], "submission_result": metrics,
            "submission_metadata": {"evaluator_id8": scores["evaluator_id8"], "protocol_sha8": scores["protocol_sha8"]}}


__all__ = ["evaluate", "MAX_REFERENCE_BYTES"]
