"""The scoring program of a hosted challenge: what an engine's compute worker runs.

Codabench runs ``python3 /app/program/score.py /app/input /app/output`` (the bundle's
``metadata.yaml``) with the participant's upload unzipped in ``/app/input/res`` and the
hidden reference data (:mod:`.reference`) in ``/app/input/ref``. :func:`score_folders`:

1. finds the submission in ``res`` (its ``submission.json`` at the top, in one folder, or a
   single ``.zip``, read in place);
2. validates it against the hidden split with every check and byte budget of
   ``hoibench validate``, and refuses anything short of a complete, valid submission with
   one line (first problem and the count): wrong representation, fps or ids included;
3. scores it with :func:`hoibench.scoring.evaluate.evaluate` (what ``hoibench evaluate``
   runs) under the challenge's protocol and evaluator, and checks the result's evaluator id;
4. writes ``scores.json`` (one number per leaderboard column key, plus the hidden
   ``evaluator_id8`` / ``protocol_sha8`` columns), ``result.json`` (the full result) and
   ``detailed_results.html``.

Errors go to stderr as one line whose paths are relative to ``ref``/``res`` (hidden folder
names and data never printed), exit status 1; no traceback.
"""
from __future__ import annotations

import html
import json
import sys
from pathlib import Path

from ..core.io import atomic_write_text, strict_json_dumps
from .reference import engine_id, read_reference


class ChallengeRefused(ValueError):
    """A submission the challenge does not score (one line)."""


def find_submission(res: Path) -> Path:
    """The submission inside the engine's ``res`` folder."""
    res = Path(res)
    if (res / "submission.json").is_file():
        return res
    entries = [p for p in sorted(res.iterdir()) if not p.name.startswith(".") and p.name != "__MACOSX"]
    dirs = [p for p in entries if p.is_dir() and (p / "submission.json").is_file()]
    zips = [p for p in entries if p.is_file() and p.suffix == ".zip"]
    if len(dirs) == 1:
        return dirs[0]
    if len(zips) == 1 and not dirs:
        return zips[0]
    raise ChallengeRefused("the upload has no submission.json at its top level (zip the submission folder's "
                           "contents: submission.json and samples/)")


def scores_of(result: dict, info: dict) -> dict[str, float]:
    """The engine's scores: each leaderboard column's mean (0/1 for ``complete``), and the
    hidden id columns."""
    out: dict[str, float] = {}
    for col in info["columns"]:
        m = result["metrics"].get(col)
        if isinstance(m, dict) and isinstance(m.get("mean"), (int, float)):
            out[col] = float(m["mean"])
    out["evaluator_id8"] = float(engine_id(result["evaluator_id"]))
    out["protocol_sha8"] = float(engine_id(result["protocol_sha256"]))
    return out


def detailed_html(result: dict, info: dict) -> str:
    """A self-contained page: the result as ``hoibench evaluate`` prints it, and its notes."""
    from ..scoring.report import format_result
    rows = "".join(f"<li>{html.escape(str(n))}</li>" for n in result.get("notes", []))
    title = html.escape(f"{info.get('title', info['track'])}: {result.get('submission', {}).get('method') or ''}")
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{title}</title></head><body>"
            f"<h1>{title}</h1><p>protocol {html.escape(result['protocol'])}@{html.escape(str(result['protocol_version']))}"
            f", evaluator {html.escape(str(result['evaluator_id'])[:12])}, hoibench {html.escape(result['toolkit_version'])}"
            f"</p><pre>{html.escape(format_result(result))}</pre><h2>notes</h2><ul>{rows}</ul></body></html>\n")


def score_folders(input_dir: str | Path, output_dir: str | Path, executor: str = "serial") -> dict:
    """Score ``input_dir/res`` against ``input_dir/ref``; write into ``output_dir``; return the
    scores. :class:`ChallengeRefused` (or ValueError) for a submission that is not scored."""
    from ..scoring.evaluate import evaluate
    from ..scoring.submission import Submission, limits_for, submission_context, validation_report
    from ..datasets.store import Store
    input_dir, output_dir = Path(input_dir), Path(output_dir)
    ref, res = input_dir / "ref", input_dir / "res"
    info = read_reference(ref)
    if not res.is_dir():
        raise ChallengeRefused("no upload (the engine's res folder is missing)")
    sub_path = find_submission(res)
    from ..tracks.protocol import get_protocol
    store = Store(ref / "store")
    proto = get_protocol(info["protocol"])
    rows, fps, cap = submission_context(store, proto)[:3]
    with Submission(sub_path, limits=limits_for(rows, fps, cap)) as sub:
        report = validation_report(sub, store, protocol=proto)
        meta = sub.meta if isinstance(sub.meta, dict) else {}
    want = store.manifest.get("representations", {}).get("hml263", "")
    if meta.get("representation") != want:
        raise ChallengeRefused(f"submission.json: field representation: {meta.get('representation')!r}, the hidden "
                               f"split is {want!r}")
    if not report.complete:
        first = report.errors[0] if report.errors else None
        where = f"{first.id}: {first.field}: {first.message}" if first else "incomplete"
        raise ChallengeRefused(f"not scored: {len(report.errors)} error(s), {len(report.missing_ids)} of "
                               f"{len(report.test_ids)} test ids missing; first: {where} (run hoibench validate "
                               f"on the public prompts' store to see them all)")
    result = evaluate(sub_path, ref / "store", ref / "evaluator", protocol=info["protocol"], executor=executor)
    if result["evaluator_id"] != info["evaluator_id"]:
        raise ChallengeRefused(f"evaluator {result['evaluator_id'][:12]} is not the challenge's "
                               f"{info['evaluator_id'][:12]} (reference data modified?)")
    scores = scores_of(result, info)
    output_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(output_dir / "scores.json", strict_json_dumps(scores, sort_keys=True) + "\n")
    atomic_write_text(output_dir / "result.json", strict_json_dumps(result, indent=1, sort_keys=True) + "\n")
    atomic_write_text(output_dir / "detailed_results.html", detailed_html(result, info))
    return scores


def _hide(text: str, input_dir: Path) -> str:
    """``text`` with the engine's absolute folders replaced by ``ref``/``res``."""
    for name in ("ref", "res"):
        for p in {str(input_dir / name), str((input_dir / name).resolve())}:
            text = text.replace(p + "/", name + "/").replace(p, name)
    return text.replace(str(input_dir.resolve()), "input").replace(str(input_dir), "input")


def main(argv: list[str] | None = None) -> int:
    """``score.py INPUT OUTPUT``: 0 when scored, 1 with one stderr line otherwise."""
    argv = list(sys.argv[1:] if argv is None else argv)
    input_dir = Path(argv[0] if argv else "/app/input")
    output_dir = Path(argv[1] if len(argv) > 1 else "/app/output")
    try:
        scores = score_folders(input_dir, output_dir)
    except KeyboardInterrupt:
        print("hoibench scoring: interrupted", file=sys.stderr)
        return 1
    except Exception as exc:          # never a traceback: it could print hidden paths or data
        msg = " ".join(str(exc).split()) or type(exc).__name__
        print(f"hoibench scoring: error: {_hide(msg, input_dir)}"[:2000], file=sys.stderr)
        return 1
    print(json.dumps(scores, sort_keys=True))
    return 0


__all__ = ["ChallengeRefused", "find_submission", "scores_of", "detailed_html", "score_folders", "main"]
