"""Deflate bombs and huge claims where the first pass set no budget: multi-body submissions
(``evaluate``/``validate``) and ``import chois``/``joints``/``features`` get the single-body
budgets derived from the test split; multi-body samples and clips get the single-body
plausibility bounds; ``import mdm`` checks its lengths and dtypes. Crafted in memory; a
fake store object stands in where only the manifest and clip arrays matter."""
from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hoibench.bodies.multibody import Body, MultiBodyClip
from hoibench.scoring.submission_read import FILE_OVERHEAD_BYTES, Submission, max_frames

T, FPS = 12, 20.0


def _clip(name="mb_a", trans_scale=1.0) -> MultiBodyClip:
    t = np.linspace(0, 0.5, T)
    pelvis = np.stack([t, np.full(T, 0.9), np.zeros(T)], -1)
    joints = pelvis[:, None] + np.linspace(-0.8, 0.8, 22)[None, :, None] * np.array([0, 1, 0.1])
    box = Body("box", "object", pelvis + [0.4, -0.3, 0] * np.ones((T, 3)) * trans_scale, np.tile(np.eye(3), (T, 1, 1)),
               template="box")
    return MultiBodyClip(name, "multibody", "s1", FPS, [Body("human", "human", pelvis, None, joints), box],
                         {"box": (np.eye(3), np.array([[0, 1, 2]]))}, {}, "lift")


class FakeStore:
    """The parts of a multi-body Store that budgets and validation read."""

    def __init__(self, clips):
        self.clips = {c.name: c.to_arrays() for c in clips}
        self.manifest = {"dataset": "multibody", "config": {"fps": FPS, "mode": "clean"}, "representations": {},
                         "clips": [{"id": c.name, "split": "test", "frames": T} for c in clips]}
        self.root = Path("fake-store")

    def load(self, cid, keys=None):
        return dict(self.clips[cid])


def _write_sub(out: Path, arrays: dict) -> Path:
    from hoibench.scoring.submission_write import write_submission
    meta = {"method": "m", "version": "1", "representation": "multibody-joints", "fps": FPS,
            "flags": {"samples_per_prompt": 1}}
    return write_submission(out, meta, {"mb_a": arrays})


def _bomb_npz(member: str, claim_bytes: int) -> bytes:
    """An .npz whose one member is a float32 array of ``claim_bytes`` zeros, deflated (a few KiB
    per MiB)."""
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, {"descr": "<f4", "fortran_order": False,
                                               "shape": (claim_bytes // 12, 1, 3)})
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open(f"{member}.npy", "w", force_zip64=True) as f:
            f.write(head.getvalue())
            chunk = bytes(1 << 20)
            for _ in range(claim_bytes // len(chunk)):
                f.write(chunk)
    return buf.getvalue()


def test_multibody_budget_is_the_single_body_rule_over_the_clips_own_arrays():
    from hoibench.scoring.multibody_samples import multibody_limits, sample_values_per_frame
    store = FakeStore([_clip()])
    assert sample_values_per_frame(store.load("mb_a")) == 22 * 3 + 12
    limits = multibody_limits(store, ["mb_a"], 3)
    assert limits.for_id("mb_a") == 3 * max_frames(T, FPS) * 78 * 8 + FILE_OVERHEAD_BYTES


def test_multibody_ground_truth_validates_and_a_bomb_or_1e30_is_refused_by_id(tmp_path):
    from hoibench.scoring.multibody_samples import sample_arrays
    from hoibench.scoring.validate import multibody_report
    store, clip = FakeStore([_clip()]), _clip()
    good = _write_sub(tmp_path / "gt", sample_arrays([clip]))
    rep = multibody_report(good, store)
    assert rep.complete and rep.valid_ids == ["mb_a"], [str(p) for p in rep.problems]

    far = sample_arrays([_clip(trans_scale=1.0)])
    far["box__trans"] = far["box__trans"].copy()
    far["box__trans"][0, 3] = 1e30
    rep = multibody_report(_write_sub(tmp_path / "far", far), store)
    assert not rep.complete and [(p.id, p.field) for p in rep.errors] == [("mb_a", "box__trans")]
    assert "exceeds 1000 m" in rep.errors[0].message

    bomb = tmp_path / "bomb"
    _write_sub(bomb, sample_arrays([clip]))
    (bomb / "samples" / "mb_a.npz").write_bytes(_bomb_npz("human__joints", 64 << 20))
    rep = multibody_report(bomb, store)
    assert not rep.complete and rep.errors[0].id == "mb_a"
    assert "budget" in rep.errors[0].message or "limit" in rep.errors[0].message, rep.errors[0].message


def test_multibody_scorer_opens_submissions_within_the_budget(tmp_path):
    from hoibench.scoring.multibody_samples import multibody_limits, sample_arrays
    store = FakeStore([_clip()])
    bomb = _write_sub(tmp_path / "bomb", sample_arrays([_clip()]))
    (bomb / "samples" / "mb_a.npz").write_bytes(_bomb_npz("human__joints", 64 << 20))
    with Submission(bomb, limits=multibody_limits(store, ["mb_a"], 1)) as sub:
        with pytest.raises(ValueError, match="budget|limit"):
            sub.load("mb_a", keys=None)


def test_prepared_multibody_clips_get_the_plausibility_bounds():
    from hoibench.bodies.multibody import check_clip
    from hoibench.core.plausibility import ImplausibleDataError
    check_clip(_clip())
    with pytest.raises(ImplausibleDataError, match=r"body 'box': trans: \|value\| 1e\+30"):
        bad = _clip()
        bad.bodies[1].trans[3] = 1e30
        check_clip(bad)
    with pytest.raises(ImplausibleDataError, match=r"body 'box': trans: speed"):
        jump = _clip()
        jump.bodies[1].trans[5:] += 10.0
        check_clip(jump)


def test_chois_and_joint_imports_are_read_within_the_budget(tmp_path):
    from hoibench.scoring.importers import ImportProblem, ReadBudget
    p = tmp_path / "a.npz"
    p.write_bytes(_bomb_npz("global_jpos", 64 << 20))
    assert p.stat().st_size < 1 << 20                      # a small file that would inflate to 64 MiB
    with pytest.raises(ImportProblem, match=r"a.npz: its arrays would inflate to \d+ bytes, over the 8388608-byte"):
        ReadBudget(8 << 20, 64 << 20).npz(p, "CHOIS file")
    q = tmp_path / "b.npy"
    np.save(q, np.zeros((1000, 22, 3), np.float32))
    budget = ReadBudget(1 << 20, 300_000)
    assert budget.npy(q, "joint file").shape == (1000, 22, 3)
    with pytest.raises(ImportProblem, match="budget"):    # 264 KB read, 36 KB left for the whole import
        budget.npy(q, "joint file")


def test_import_budget_derives_from_the_test_split():
    from hoibench.scoring.importers import ReadBudget
    from hoibench.scoring.submission_read import VALUES_PER_FRAME
    store = FakeStore([_clip()])
    store.manifest["dataset"] = "synthetic"
    b = ReadBudget.for_store(store)
    cap = b.per_file - 2 * FILE_OVERHEAD_BYTES
    assert cap % (max_frames(T, FPS) * VALUES_PER_FRAME * 8) == 0 and cap > 0


def _mdm(tmp_path, **over) -> Path:
    n = 2
    d = {"motion": np.zeros((n, 22, 3, 30), np.float32), "text": ["a", "b"], "lengths": np.array([30, 20]),
         "num_samples": n, "num_repetitions": 1}
    d.update(over)
    p = tmp_path / "results.npy"
    np.save(p, np.array(d, dtype=object), allow_pickle=True)
    return p


@pytest.mark.parametrize("over,match", [({"lengths": np.array([31, 20])}, r"lengths: entry 0 is 31"),
                                        ({"lengths": np.array([0, 20])}, r"lengths: entry 0 is 0"),
                                        ({"lengths": np.array([-5, 20])}, r"lengths: entry 0 is -5"),
                                        ({"lengths": np.array([2.5, 20])}, r"lengths: entry 0 is 2.5"),
                                        ({"motion": np.zeros((2, 22, 3, 30), np.complex64)}, r"motion: expected real"),
                                        ({"num_samples": 0}, r"num_samples: expected a positive whole number")])
def test_mdm_lengths_and_dtypes_are_checked(tmp_path, over, match):
    from hoibench.scoring.importers import ImportProblem, read_mdm
    with pytest.raises(ImportProblem, match=match):
        read_mdm(_mdm(tmp_path, **over), True, False)
    assert len(read_mdm(_mdm(tmp_path), True, False)) == 2
