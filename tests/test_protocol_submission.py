"""Protocols (hoibench.tracks.protocol) and submissions (hoibench.scoring.submission): the claims.

* Every shipped protocol parses, fixes the DESIGN numbers (20 replications, pools of 32,
  300 diversity pairs -- 200 on BEHAVE --, 100 x 30 x 10 MultiModality) and draws the same
  pools whatever the order of the ids; ``hoibench protocols ls/show`` work.
* The ground-truth submission of a store validates cleanly, as a folder and as a zip, and
  its physical metrics can be computed.
* Every kind of broken submission is reported -- all problems at once, with id and field --
  and none crashes the validator: missing and extra ids, wrong shapes and dtypes, NaN,
  centimetres, non-rotations, bad lengths, a pickle inside an .npz, a zip with path
  traversal, a header claiming 10 GB.
"""
from __future__ import annotations

import io
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hoibench.tracks import protocol as P
from hoibench.scoring import submission as S


# ====================================================================== protocols
def test_shipped_protocols_fix_the_design_numbers():
    shipped = P.list_protocols()
    assert {p.id for p in shipped if p.kind == "multibody"} == {"multibody-synthetic"}
    protos = {i: P.get_protocol(i) for i in sorted({p.id for p in shipped if p.kind == "hoi"})}   # defaults
    assert {"behave-legacy", "behave-clean", "omomo-legacy", "omomo-clean", "rich-cat-clean",
            "synthetic-clean", "synthetic-legacy"} <= set(protos)
    t2m = protos["t2m-legacy"]        # text-to-motion's loop, for rows scored with the t2m evaluator
    assert (t2m.replications, t2m.embedding_loop, t2m.diversity_pairs, t2m.track) == (20, "t2m", 300, "behave")
    assert t2m.physical == protos["behave-legacy"].physical
    chois = [protos.pop(i) for i in ("omomo-chois", "omomo-chois-clean")]
    for p in chois:                   # CHOIS's own protocol: its 30 fps evaluator and 120-frame windows
        assert p.fps == 30 and p.dataset == "omomo" and p.clip_window == {"frames": 120, "drop_shorter": True}, p.ref
    assert [p.embedding_loop for p in chois] == ["chois", "hoibench"]       # CHOIS's loop; the clean one ours
    ia = protos.pop("interact-legacy")  # InterAct's released evaluation: its loader and loop, 2 repeats
    assert (ia.replications, ia.embedding_loop, ia.r_precision_pool_size, ia.fps) == (2, "interact-released", 64, 30)
    for p in protos.values():
        if p is t2m:
            continue
        # the other legacy protocols run ChainHOI's released loop: one replication, as its src/eval.py
        assert p.replications == (1 if p.mode == "legacy" else 20) and p.mode in ("legacy", "clean")
        assert p.fps == (30 if p.dataset == "interact" else 20)       # InterAct's evaluator reads 30 fps rows
        assert p.embedding_loop == ("chainhoi" if p.mode == "legacy" else "hoibench")
        assert p.physical_config().mode == p.mode
        assert p.physical_config().shift_to_floor == (p.mode == "legacy")
        if p.dataset != "synthetic":
            assert p.r_precision_pool_size == (64 if p.dataset == "interact" else 32)   # InterAct's batch
            assert (p.mm_texts, p.mm_samples, p.mm_pairs) == (100, 30, 10)
            assert p.diversity_pairs == (100 if p.mode == "legacy" else 200 if p.dataset == "behave" else 300)
    assert protos["behave-clean"].representation == "hml263-clean-1.0"
    assert P.get_protocol("behave-clean@1.1") == protos["behave-clean"]      # the default: 1.2 is a preview
    newer = P.get_protocol("behave-clean@1.2")
    assert newer.preview and "physics" in newer.settings and newer.sha256 != protos["behave-clean"].sha256
    assert len({p.sha256 for p in protos.values()}) == len(protos)


def test_pools_are_seeded_by_protocol_and_replication_not_by_order():
    p = P.get_protocol("behave-clean")
    ids = [f"Date03_Sub{i:03d}" for i in range(100)]
    assert p.pools(ids, 0) == p.pools(list(reversed(ids)), 0)
    assert p.pools(ids, 0) != p.pools(ids, 1)
    assert [len(x) for x in p.pools(ids, 0)] == [32, 32, 32]
    assert p.seed_for("diversity", 3) == P.get_protocol("behave-clean").seed_for("diversity", 3)
    assert p.seed_for("diversity", 3) != p.seed_for("r_precision", 3)
    assert p.multimodality_ids(ids, 0) == p.multimodality_ids(ids[::-1], 0) == sorted(ids)
    assert p.effective_diversity_pairs(50) == 49 and p.effective_diversity_pairs(1000) == 200
    assert [p.sample_index(r, 3) for r in range(5)] == [0, 1, 2, 0, 1]


def test_summaries_use_the_population_std():
    s = P.summarize([1.0, 2.0, 3.0, 4.0])
    assert s["mean"] == 2.5 and s["ci95"] == pytest.approx(1.96 * np.std([1, 2, 3, 4]) / 2)
    rep = P.summarize_replications([{"fid": 1.0, "mm": 2.0}, {"fid": 3.0, "mm": float("nan")}])
    assert rep["fid"]["mean"] == 2.0 and rep["mm"]["n"] == 1
    assert np.std([0.071999] * 20) > 0                      # rounding in the mean ...
    assert P.summarize([0.071999] * 20)["ci95"] == 0.0       # ... is not reported as spread
    assert P.summarize([[0.1, 0.2], [0.1, 0.3]])["ci95"][0] == 0.0


def test_invalid_protocol_names_file_and_field(tmp_path):
    src = (P.PROTOCOLS_DIR / "behave-clean.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(src.replace("mode: clean", "mode: fancy"))
    with pytest.raises(ValueError, match=r"bad.yaml: field 'mode'"):
        P.load_protocol(bad)
    bad.write_text(src.replace("  top_k: 3\n", ""))
    with pytest.raises(ValueError, match="r_precision: missing field 'top_k'"):
        P.load_protocol(bad)
    bad.write_text(src.replace("metrics: [", "metrics: [bogus, "))
    with pytest.raises(ValueError, match="unknown metrics"):
        P.load_protocol(bad)
    with pytest.raises(KeyError, match="known: "):
        P.get_protocol("nope")


def test_protocols_cli(capsys):
    assert P.main_protocols("ls") == 0
    out = capsys.readouterr().out
    assert "behave-clean" in out and "proxy (joint fit)" in out
    assert P.main_protocols("show", "omomo-legacy") == 0
    assert "id: omomo-legacy" in capsys.readouterr().out
    assert P.main_protocols("show", "nope") == 2
    assert P.main_protocols("frobnicate") == 2


# ====================================================================== submissions
@pytest.fixture(scope="module")
def gt_sub(synthetic_store, tmp_path_factory):
    """(store folder, ground-truth submission folder, test ids)."""
    _, data, manifest = synthetic_store
    out = tmp_path_factory.mktemp("sub") / "gt"
    assert S.main_submission_from_store(data, out) == 0
    ids = sorted(c["id"] for c in manifest["clips"] if c["split"] == "test")
    return data, out, ids


def _copy(src: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "sub"
    shutil.copytree(src, dst)
    return dst


def _rewrite(sub: Path, sid: str, **changes):
    with np.load(sub / "samples" / f"{sid}.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v(arrays) if callable(v) else v
    np.savez(sub / "samples" / f"{sid}.npz", **arrays)


def _fields(problems, severity="error"):
    return {(p.id, p.field) for p in problems if p.severity == severity}


def test_ground_truth_submission_is_valid_as_folder_and_zip(gt_sub, tmp_path):
    data, sub, ids = gt_sub
    assert ids and _fields(S.validate(sub, data)) == set()
    meta = json.loads((sub / "submission.json").read_text())
    assert meta["flags"] == {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"}
    z = tmp_path / "gt.zip"
    S.from_store(data, z, as_zip=True)
    rep = S.validation_report(z, data, protocol="synthetic-clean")
    assert rep.complete and rep.valid_ids == ids and rep.samples_per_prompt == 1
    assert [p.field for p in rep.warnings] == ["samples"]          # K = 1: no MultiModality
    with S.Submission(sub) as s:
        arr = s.load(ids[0])
    assert arr["joints"].shape[0] == 1 and arr["joints"].dtype == np.float32 and arr["obj_rot"].shape[-2:] == (3, 3)
    assert S.main_validate(sub, data) == 0


def test_ground_truth_physical_metrics_from_a_submission(gt_sub):
    pytest.importorskip("open3d")
    from hoibench.metrics.physical import clip_inputs, evaluate_physical
    from hoibench.datasets.store import Store
    data, sub, ids = gt_sub
    with S.Submission(sub) as s:
        motions = {i: {k: v[0] for k, v in s.load(i).items()} for i in s.ids}
    proto = P.get_protocol("synthetic-clean")
    res = evaluate_physical(clip_inputs(Store(data), motions, sample=0), proto.physical_config()).compute()
    assert res["clips"] == len(ids) and res["body_surface"] == "proxy (joint fit)"
    assert res["cd"] < 1e-5 and res["contact_iou"] > 0.5          # the real motion touches where GT does
    assert 0 <= res["ps"] < 0.1 and res["fsr"] < 0.1


def test_every_defect_is_reported_at_once(gt_sub, tmp_path):
    data, src, ids = gt_sub
    sub = _copy(src, tmp_path)
    a, b = ids[0], ids[1]
    (sub / "samples" / f"{b}.npz").unlink()                                       # missing id
    shutil.copy(sub / "samples" / f"{a}.npz", sub / "samples" / "Date09_Sub01_box_lift.npz")  # extra id
    T = None

    def cm(arrs):                                                                  # centimetres
        nonlocal T
        T = arrs["joints"].shape[1]
        return arrs["joints"] * 100
    _rewrite(sub, a, joints=cm, obj_trans=lambda z: z["obj_trans"] * 100,
             obj_rot=lambda z: z["obj_rot"] * 2.0, hml263=lambda z: z["hml263"][:, :3])
    meta = json.loads((sub / "submission.json").read_text())
    meta["fps"] = 30
    del meta["method"]
    (sub / "submission.json").write_text(json.dumps(meta))
    probs = S.validate(sub, data)
    got = _fields(probs)
    assert (b, "samples") in got
    assert ("Date09_Sub01_box_lift", "samples") in got
    assert {(a, "joints"), (a, "obj_trans"), (a, "obj_rot"), (a, "hml263"), ("*", "submission.json")} <= got
    text = "\n".join(map(str, probs))
    for needle in ("missing: no samples/", "extra file", "centimetres", "not rotations", "fps 30",
                   "missing field 'method'", "expected T - 1"):
        assert needle in text, needle
    rep = S.validation_report(sub, data)
    assert not rep.complete and b in rep.missing_ids and a in rep.missing_ids
    assert S.main_validate(sub, data) == 1


@pytest.mark.parametrize("defect, field, needle", [
    ("float64", "joints", "expected dtype float32"),
    ("shape", "joints", "expected shape (K, T, 22, 3)"),
    ("nan", "joints", "non-finite"),
    ("reflection", "obj_rot", "reflection"),
    ("one_frame", "joints", "at least 2"),
    ("gt_length", "joints", "uses_gt_length"),
    ("no_object", "obj_trans", "missing"),
    ("both_rotations", "obj_rot", "exactly one"),
    ("k_mismatch", "obj_trans", "samples but joints has"),
])
def test_each_array_defect_is_named(gt_sub, tmp_path, defect, field, needle):
    data, src, ids = gt_sub
    sub = _copy(src, tmp_path)
    sid = ids[0]
    change = {
        "float64": dict(joints=lambda z: z["joints"].astype(np.float64)),
        "shape": dict(joints=lambda z: z["joints"][:, :, :21]),
        "nan": dict(joints=lambda z: np.where(np.arange(22)[None, None, :, None] == 3, np.nan, z["joints"])
                    .astype(np.float32)),
        "reflection": dict(obj_rot=lambda z: z["obj_rot"] * np.array([1, 1, -1], np.float32)),
        "one_frame": dict(joints=lambda z: z["joints"][:, :1], obj_rot=lambda z: z["obj_rot"][:, :1],
                          obj_trans=lambda z: z["obj_trans"][:, :1], hml263=None),
        "gt_length": dict(joints=lambda z: z["joints"][:, :-2], obj_rot=lambda z: z["obj_rot"][:, :-2],
                          obj_trans=lambda z: z["obj_trans"][:, :-2], hml263=None),
        "no_object": dict(obj_trans=None),
        "both_rotations": dict(obj_rotvec=lambda z: np.zeros(z["obj_trans"].shape, np.float32)),
        "k_mismatch": dict(obj_trans=lambda z: np.concatenate([z["obj_trans"]] * 2)),
    }[defect]
    _rewrite(sub, sid, **change)
    probs = S.validate(sub, data)
    hits = [p for p in probs if p.id == sid and p.field == field and p.severity == "error"]
    assert hits and needle in hits[0].message, probs
    assert not S.validation_report(sub, data).complete


def test_a_pickle_inside_an_npz_is_rejected_not_loaded(gt_sub, tmp_path):
    data, src, ids = gt_sub
    sub = _copy(src, tmp_path)
    with np.load(sub / "samples" / f"{ids[0]}.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["joints"] = np.array([{"evil": "payload"}], dtype=object)          # np.savez pickles it
    np.savez(sub / "samples" / f"{ids[0]}.npz", **arrays)
    probs = [p for p in S.validate(sub, data) if p.id == ids[0]]
    assert [p.field for p in probs] == ["file"]
    assert "Python objects" in probs[0].message and "pickle" in probs[0].message


def _npz_with_header(shape, dtype="<f4", payload=b"\0" * 64) -> bytes:
    member = io.BytesIO()
    np.lib.format.write_array_header_1_0(member, {"descr": dtype, "fortran_order": False, "shape": shape})
    member.write(payload)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("joints.npy", member.getvalue())
    return buf.getvalue()


def test_a_10_gb_claimed_shape_is_rejected_from_the_header(gt_sub, tmp_path):
    data, src, ids = gt_sub
    sub = _copy(src, tmp_path)
    shape = (40, 1_000_000, 22, 3)                       # float32: 40 x 1e6 x 66 x 4 B = 10.6 GB
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_npz_with_header(shape))
    probs = [p for p in S.validate(sub, data) if p.id == ids[0]]
    assert len(probs) == 1 and probs[0].field == "file"
    assert "9.8 GiB" in probs[0].message and "limit" in probs[0].message
    # a header claiming more data than the member holds is truncated, not read
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_npz_with_header((1, 70, 22, 3)))
    probs = [p for p in S.validate(sub, data) if p.id == ids[0]]
    assert "truncated" in probs[0].message


def test_a_zip_with_path_traversal_is_rejected(gt_sub, tmp_path):
    data, src, ids = gt_sub
    z = tmp_path / "evil.zip"
    with zipfile.ZipFile(z, "w") as zf:
        for p in sorted(src.rglob("*")):
            if p.is_file():
                zf.write(p, p.relative_to(src).as_posix())
        zf.writestr("../../outside.txt", "gotcha")
        zf.writestr("samples/../../../etc/evil.npz", b"x")
        zf.writestr("/abs/path.npz", b"x")
        zf.writestr("samples\\win.npz", b"x")
    probs = S.validate(z, data)
    zip_probs = [p for p in probs if p.field == "zip"]
    assert len(zip_probs) == 4 and all("rejected, not read" in p.message for p in zip_probs)
    assert any("path traversal" in p.message for p in zip_probs)
    assert not (tmp_path.parent / "outside.txt").exists()
    assert not S.validation_report(z, data).complete


def test_broken_containers_never_crash(gt_sub, tmp_path):
    data, src, ids = gt_sub
    assert _fields(S.validate(tmp_path / "nothing-here", data)) >= {("*", "path")}
    junk = tmp_path / "junk.zip"
    junk.write_bytes(b"this is not a zip")
    assert ("*", "path") in _fields(S.validate(junk, data))
    sub = _copy(src, tmp_path)
    (sub / "submission.json").write_text("{not json")
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(b"garbage")
    got = _fields(S.validate(sub, data))
    assert {("*", "submission.json"), (ids[0], "file")} <= got
    (sub / "submission.json").unlink()
    assert ("*", "submission.json") in _fields(S.validate(sub, data))
    assert S.main_validate(sub, data) == 1
    assert S.main_validate(sub, tmp_path / "no-store") == 2
