"""Hosted evaluation: the Codabench bundle validates against Codabench's v2 structure; its
scoring program, run as Codabench's compute worker runs it (a fresh process, /app/input/{ref,res}
and /app/output, no network), gives the numbers `hoibench evaluate` gives; hostile uploads
get one line without hidden paths; the EvalAI adapter returns the same numbers; the public
folder holds nothing computed from a test motion; engine exports come back as entries."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("transformers")
pytest.importorskip("open3d")

ROOT = Path(__file__).resolve().parents[1]


def _zip_contents(folder: Path, out: Path) -> Path:
    """What a participant uploads: the submission folder's contents, zipped."""
    with zipfile.ZipFile(out, "w") as z:
        for p in sorted(folder.rglob("*")):
            if p.is_file():
                z.write(p, p.relative_to(folder).as_posix())
    return out


def _engine_run(bundle: Path, upload: Path, where: Path) -> subprocess.CompletedProcess:
    """Unpack like Codabench's worker (program, input/ref, input/res, output) and run the
    scoring program's metadata command in a fresh process with a minimal environment."""
    import yaml
    app = where / "app"
    with zipfile.ZipFile(bundle) as b:
        for member, dest in (("scoring_program.zip", app / "program"), ("reference_data.zip", app / "input" / "ref")):
            import io
            with zipfile.ZipFile(io.BytesIO(b.read(member))) as z:
                z.extractall(dest)
    with zipfile.ZipFile(upload) as z:
        z.extractall(app / "input" / "res")
    (app / "output").mkdir()
    command = yaml.safe_load((app / "program" / "metadata.yaml").read_text())["command"]
    command = command.replace("/app/", f"{app}/")
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(where), "PYTHONPATH": str(ROOT),
           "HOIBENCH_PROGRESS": "0", "no_proxy": "*", "NO_PROXY": "*", "HF_HUB_OFFLINE": "1",
           "TRANSFORMERS_OFFLINE": "1"}
    # the same thread settings as this process: BLAS sums in another order at another thread
    # count, and the ground truth's FID (~1e-7) is all rounding
    env.update({k: v for k, v in os.environ.items() if k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS",
                                                             "OPENBLAS_NUM_THREADS")})
    argv = command.split()
    argv[0] = sys.executable                     # python3 of this environment
    return subprocess.run(argv, cwd=where, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def challenge(annotated_store_with_evaluator, tmp_path_factory):
    from hoibench.challenge.bundle import build_bundle
    from hoibench.scoring.reference_rows import write_reference
    from hoibench.scoring.submission import from_store
    base, data, ev = annotated_store_with_evaluator
    tmp = tmp_path_factory.mktemp("challenge")
    bundle = build_bundle(data, ev, tmp / "bundle.zip", title="test challenge")
    gt = from_store(data, tmp / "gt")
    noisy = write_reference("gt-noise", data, tmp / "noisy", sigma=0.02)
    return tmp, data, ev, bundle, {"gt": Path(gt), "noisy": Path(noisy)}


def test_the_bundle_has_every_file_and_key_codabench_unpacks(challenge):
    import yaml
    from hoibench.challenge.bundle import check_bundle
    tmp, data, ev, bundle, _ = challenge
    assert check_bundle(bundle) == []
    with zipfile.ZipFile(bundle) as z:
        comp = yaml.safe_load(z.read("competition.yaml"))
        info = json.loads(z.read("challenge.json"))
        ref = zipfile.ZipFile(__import__("io").BytesIO(z.read("reference_data.zip")))
    assert comp["version"] == 2 and [p["name"] for p in comp["phases"]] == ["dev", "test"]
    cols = {c["key"]: c for c in comp["leaderboards"][0]["columns"]}
    assert cols["fid"]["sorting"] == "asc" and cols["r_precision_top1"]["sorting"] == "desc"
    assert cols["evaluator_id8"]["hidden"] and info["evaluator_id"] == json.loads((ev / "card.json").read_text())["evaluator_id"]
    # the hidden store carries the test clips only
    from hoibench.datasets.store import Store
    st = Store(data)
    clips = {Path(n).stem for n in ref.namelist() if n.startswith("store/clips/")}
    assert clips == set(st.clip_ids("test"))
    # a broken bundle is named
    bad = tmp / "bad.zip"
    with zipfile.ZipFile(bundle) as z, zipfile.ZipFile(bad, "w") as w:
        for n in z.namelist():
            if n != "scoring_program.zip":
                w.writestr(n, z.read(n))
    assert any("scoring_program.zip" in p for p in check_bundle(bad))


def test_the_scoring_program_run_as_the_worker_runs_it_gives_evaluates_numbers(challenge, tmp_path):
    from hoibench.challenge.scoring import score_folders
    from hoibench.scoring.evaluate import evaluate
    tmp, data, ev, bundle, subs = challenge
    info = json.loads(zipfile.ZipFile(bundle).read("challenge.json"))
    for name in ("gt", "noisy"):
        want = evaluate(subs[name], data, ev, protocol=info["protocol"])["metrics"]
        upload = _zip_contents(subs[name], tmp_path / f"{name}.zip")
        if name == "gt":                            # the worker's way: a fresh process
            r = _engine_run(bundle, upload, tmp_path / "gt-run")
            assert r.returncode == 0, r.stderr
            scores = json.loads((tmp_path / "gt-run" / "app" / "output" / "scores.json").read_text())
            html = (tmp_path / "gt-run" / "app" / "output" / "detailed_results.html").read_text()
            assert "fid" in html.lower() and "<script" not in html
        else:                                       # the same function in this process
            root = tmp_path / "noisy-run" / "input"
            with zipfile.ZipFile(bundle) as b:
                import io
                zipfile.ZipFile(io.BytesIO(b.read("reference_data.zip"))).extractall(root / "ref")
            zipfile.ZipFile(upload).extractall(root / "res")
            scores = score_folders(root, tmp_path / "noisy-run" / "output")
        for key in info["columns"]:             # a metric the protocol does not compute (MModality at K = 1) has no score
            if key not in want:
                assert key not in scores, (name, key)
            elif abs(want[key]["mean"]) < 1e-6:  # the GT's FID (~1e-7) is rounding: equal to 1e-9
                assert scores[key] == pytest.approx(want[key]["mean"], abs=1e-9), (name, key)
            else:
                assert scores[key] == want[key]["mean"], (name, key)
    assert scores["fid"] > 0


def test_a_hostile_upload_is_one_line_without_hidden_paths(challenge, tmp_path):
    tmp, data, ev, bundle, subs = challenge
    bad = tmp_path / "bad"
    import shutil
    shutil.copytree(subs["gt"], bad)
    meta = json.loads((bad / "submission.json").read_text())
    meta["representation"] = "hml263-legacy-1.0"
    (bad / "submission.json").write_text(json.dumps(meta))
    f = sorted((bad / "samples").glob("*.npz"))[0]
    z = dict(np.load(f))
    z["joints"] = np.full_like(z["joints"], np.nan)
    np.savez(f, **z)
    r = _engine_run(bundle, _zip_contents(bad, tmp_path / "bad.zip"), tmp_path / "run")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[0].startswith("hoibench scoring: error: submission.json: field representation")
    assert str(tmp_path) not in lines[0]
    # with the representation right, the NaN sample is refused by validation, named by id and field
    meta["representation"] = "hml263-clean-1.0"
    (bad / "submission.json").write_text(json.dumps(meta))
    r = _engine_run(bundle, _zip_contents(bad, tmp_path / "bad2.zip"), tmp_path / "run2")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and "not scored" in lines[0] and f.stem in lines[0], r.stderr
    assert str(tmp_path) not in lines[0]
    assert not (tmp_path / "run" / "app" / "output" / "scores.json").exists()


def test_the_evalai_adapter_returns_the_same_numbers(challenge, tmp_path):
    from hoibench.challenge import evalai
    from hoibench.challenge.scoring import ChallengeRefused
    tmp, data, ev, bundle, subs = challenge
    ref = tmp_path / "reference_data.zip"
    ref.write_bytes(zipfile.ZipFile(bundle).read("reference_data.zip"))
    out = evalai.evaluate(str(ref), str(_zip_contents(subs["noisy"], tmp_path / "n.zip")), "dev")
    from hoibench.scoring.evaluate import evaluate
    info = json.loads(zipfile.ZipFile(bundle).read("challenge.json"))
    want = evaluate(subs["noisy"], data, ev, protocol=info["protocol"])["metrics"]
    assert list(out["result"][0]) == ["test_split"]
    assert out["submission_result"] == {k: want[k]["mean"] for k in info["columns"] if k in want}
    empty = tmp_path / "empty.zip"
    zipfile.ZipFile(empty, "w").close()
    with pytest.raises(ChallengeRefused, match="not scored|submission.json"):
        evalai.evaluate(str(ref), str(empty), "test")


def test_the_public_folder_holds_nothing_computed_from_a_test_motion(challenge, tmp_path):
    from hoibench.challenge.public import write_public
    from hoibench.datasets.store import Store
    tmp, data, ev, bundle, _ = challenge
    st = Store(data)
    test, train = st.clip_ids("test"), st.clip_ids("train")
    pub = write_public(data, tmp_path / "public")
    files = [p for p in pub.rglob("*") if p.is_file()]
    assert not [p for p in files if p.name.split(".")[0] in set(test)]          # no per-test-clip file
    test_arrays = [st.load(c) for c in test]
    for p in (q for q in files if q.suffix == ".npz"):
        with np.load(p) as z:
            for k in z.files:
                a = z[k]
                for clip in test_arrays:
                    for v in clip.values():               # per-frame arrays (joints, poses, features, contacts)
                        if isinstance(v, np.ndarray) and v.dtype.kind == "f" and v.ndim >= 2 and len(v) > 1 and v.shape == a.shape:
                            assert not np.array_equal(v, a), (p, k)
    text = {p: p.read_text(errors="replace") for p in files if p.suffix in (".json", ".jsonl", ".md", ".txt")}
    for p, t in text.items():
        if p.name != "prompts.jsonl":
            assert not any(c in t for c in test), p
    pub_st = Store(pub / "store")
    assert pub_st.clip_ids("train") == train and pub_st.clip_ids("test") == []
    np.testing.assert_array_equal(pub_st.stats("hml263").mean, st.stats("hml263").mean)   # train-only by construction
    prompts = [json.loads(line) for line in (pub / "prompts.jsonl").read_text().splitlines()]
    assert [p["id"] for p in prompts] == test and all((pub / p["object_mesh"]).is_file() for p in prompts)
    assert all(set(p) >= {"captions", "frames", "fps"} for p in prompts)


def test_engine_exports_come_back_as_entries_and_the_site_lists_every_track(challenge, tmp_path):
    from committed import committed_track
    from hoibench.challenge.engine_results import add_hosted_rows
    from hoibench.challenge.reference import engine_id
    from hoibench.publish.site import build_site
    tmp, data, ev, bundle, _ = challenge
    info = json.loads(zipfile.ZipFile(bundle).read("challenge.json"))
    col = lambda t: f"hidden test(7)-{t}"                                    # noqa: E731
    good = {col("FID"): 0.25, col("R@1"): 0.5, col("evaluator id (8 hex as int)"): engine_id(info["evaluator_id"]),
            col("protocol sha (8 hex as int)"): engine_id(info["protocol_sha256"])}
    other = {**good, col("evaluator id (8 hex as int)"): 12345}
    export = tmp_path / "results.json"
    export.write_text(json.dumps({"Results - test(3)": {"alice-11": good, "bob-12": other}}))
    track = tmp_path / "leaderboards" / "hosted"
    (track / "entries").mkdir(parents=True)
    written, refused = add_hosted_rows(export, info, track)
    assert [p.name for p in written] == ["alice-11.json"] and len(refused) == 1 and "bob-12" in refused[0]
    e = json.loads(written[0].read_text())
    assert e["metrics"]["fid"]["mean"] == 0.25 and e["hosted"]["engine"] == "codabench"
    committed_track("synthetic", tmp_path)                                # as shipped, without a user's rows
    paths = build_site(tmp_path / "leaderboards", tmp_path / "site")
    index = paths["index.html"].read_text()
    assert 'href="synthetic/index.html"' in index and 'href="hosted/index.html"' in index
    assert (tmp_path / "site" / "hosted" / "index.html").read_text().count("alice-11") >= 1
