"""InterAct's object-to-human and human-to-object metrics (hoibench.metrics.interact_tasks).

The recorded values were computed by InterAct's own functions on the arrays of
:func:`_arrays` (a scratch harness outside the repository, not committed):
``compute_metrics_marker`` of ``object2human/evaluation_metrics.py`` (called with copies of
the arrays, since it lowers them in place) and ``compute_metrics_obj_marker`` /
``get_frobenious_norm_rot_only`` of ``human2object/evaluation_metrics.py`` (GitHub
wzyabcas/InterAct @ daa7945178e4b2fa0e14bddc3661f723ade50597; numpy 2.4.6, scipy 1.17.1).
hoibench matched them to 4e-16 relative; the tests allow 1e-12.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hoibench.metrics import interact_tasks as IT

REL = 1e-12


def _arrays(seed=7, T=50, M=60):
    """Markers walking (T, 77, 3), a noisy prediction 2 cm high, an object of M points near
    the left hand, and a predicted object (rotated, shifted), metres."""
    rng = np.random.default_rng(seed)
    base = np.concatenate([rng.uniform(-0.3, 0.3, (77, 1)), rng.uniform(0.0, 1.7, (77, 1)), rng.uniform(-0.2, 0.2, (77, 1))], 1)
    walk = np.cumsum(rng.normal(0, 0.01, (T, 1, 3)), axis=0)
    gt = base[None] + walk + rng.normal(0, 0.005, (T, 77, 3))
    pred = gt + rng.normal(0, 0.03, (T, 77, 3))
    pred[..., 1] += 0.02
    tmpl = rng.normal(0, 0.12, (M, 3))
    obj_t = gt[:, 72] + np.array([0.05, 0.0, 0.0]) + rng.normal(0, 0.02, (T, 3))
    obj_verts = tmpl[None] + obj_t[:, None]
    pred_obj_t = obj_t + rng.normal(0, 0.03, (T, 3))
    aa = rng.normal(0, 0.2, (T, 3))
    R = Rotation.from_rotvec(aa).as_matrix()
    pred_verts = np.einsum("tij,mj->tmi", R, tmpl) + pred_obj_t[:, None]
    return dict(gt=gt, pred=pred, obj_verts=obj_verts, pred_verts=pred_verts, gt_trans=obj_t, pred_trans=pred_obj_t,
                pred_rotvec=aa, gt_rotvec=np.zeros((T, 3)))


# InterAct's functions on _arrays(seed): object2human at the contact threshold given, human2object at 0.05 m
REFERENCE = {
 "o2h_7": {
  "lhand_jpe": 5.160117596188562,
  "rhand_jpe": 5.051926810430146,
  "hand_jpe": 5.1060222033093545,
  "mpvpe": 0.06628253285758617,
  "gt_foot_sliding": 0.0,
  "foot_sliding": 0.029441566006014847,
  "hand": {
   "jpe": 6.748824107259546,
   "contact_precision": 0.918918918918919,
   "contact_recall": 0.7391304347826086,
   "contact_acc": 0.7,
   "contact_f1_score": 0.8192771084337348,
   "contact_dist": 0.04059836403002291,
   "gt_contact_dist": 0.03375800217120891
  },
  "non_hand": {
   "jpe": 6.722407076092169,
   "contact_precision": 0.5208333333333334,
   "contact_recall": 0.9259259259259259,
   "contact_acc": 0.5,
   "contact_f1_score": 0.6666666666666667,
   "contact_dist": 0.033325645011062964,
   "gt_contact_dist": 0.03885099937787441
  },
  "foot": {
   "jpe": 6.864573030187908,
   "contact_precision": 0.0,
   "contact_recall": 0.0,
   "contact_acc": 0.98,
   "contact_f1_score": 0.0,
   "contact_dist": 0.1262244160418221,
   "gt_contact_dist": 0.047858983941606065
  },
  "full": {
   "jpe": 6.725837859360658,
   "contact_precision": 0.94,
   "contact_recall": 1.0,
   "contact_acc": 0.94,
   "contact_f1_score": 0.9690721649484536,
   "contact_dist": 0.029935093847824563,
   "gt_contact_dist": 0.032256135455426924
  }
 },
 "h2o_7": {
  "mpmpe": 0.07422899258985795,
  "mpvpe": 0.08117898452950219,
  "gt_contact_dist": 0.026618119191026718,
  "contact_dist": 0.02900593017071965,
  "contact_precision": 1.0,
  "contact_recall": 1.0,
  "contact_acc": 1.0,
  "contact_f1_score": 1.0,
  "t_err": 0.04813420369069132,
  "o_err": 0.45276547441837683
 },
 "o2h_8": {
  "lhand_jpe": 5.181788308226862,
  "rhand_jpe": 5.051450612014706,
  "hand_jpe": 5.116619460120784,
  "mpvpe": 0.06689603793994023,
  "gt_foot_sliding": 0.3093825017595173,
  "foot_sliding": 0.07327132810345373,
  "hand": {
   "jpe": 7.922116471586925,
   "contact_precision": 0.5,
   "contact_recall": 0.16666666666666666,
   "contact_acc": 0.88,
   "contact_f1_score": 0.25,
   "contact_dist": 0.12555683744506008,
   "gt_contact_dist": 0.0911396899852841
  },
  "non_hand": {
   "jpe": 7.970283133769305,
   "contact_precision": 1.0,
   "contact_recall": 1.0,
   "contact_acc": 1.0,
   "contact_f1_score": 1.0,
   "contact_dist": 0.02855231696302845,
   "gt_contact_dist": 0.029112428439289947
  },
  "foot": {
   "jpe": 7.72793798355533,
   "contact_precision": 0.3,
   "contact_recall": 1.0,
   "contact_acc": 0.44,
   "contact_f1_score": 0.4615384615384615,
   "contact_dist": 0.07569786648390439,
   "gt_contact_dist": 0.08741472753131302
  },
  "full": {
   "jpe": 7.964027723096269,
   "contact_precision": 1.0,
   "contact_recall": 1.0,
   "contact_acc": 1.0,
   "contact_f1_score": 1.0,
   "contact_dist": 0.02855231696302845,
   "gt_contact_dist": 0.029112428439289947
  }
 },
 "h2o_8": {
  "mpmpe": 0.06360514081710349,
  "mpvpe": 0.05508590568746096,
  "gt_contact_dist": 0.02614624643454593,
  "contact_dist": 0.026085628011460558,
  "contact_precision": 1.0,
  "contact_recall": 0.98,
  "contact_acc": 0.98,
  "contact_f1_score": 0.98989898989899,
  "t_err": 0.04614011607006827,
  "o_err": 0.43529990094762366
 }
}
THRESHOLDS = {7: 0.05, 8: 0.1}


def _close(got, want, what):
    assert got == pytest.approx(want, rel=REL, abs=1e-15), what


@pytest.mark.parametrize("seed", [7, 8])
def test_object2human_equals_interact_code(seed):
    a = _arrays(seed)
    got = IT.object2human_metrics(a["pred"], a["gt"], a["obj_verts"], THRESHOLDS[seed])
    for k, v in REFERENCE[f"o2h_{seed}"].items():
        if isinstance(v, dict):
            for kk, vv in v.items():
                _close(got[k][kk], vv, f"{k}.{kk}")
        else:
            _close(got[k], v, k)


@pytest.mark.parametrize("seed", [7, 8])
def test_human2object_equals_interact_code(seed):
    a = _arrays(seed)
    rp, rg = (Rotation.from_rotvec(a[k]).as_matrix() for k in ("pred_rotvec", "gt_rotvec"))
    got = IT.human2object_metrics(a["pred_verts"], a["obj_verts"], a["gt"], 0.05, a["pred_trans"], a["gt_trans"],
                                  rp, rg)
    for k, v in REFERENCE[f"h2o_{seed}"].items():
        _close(got[k], v, k)


def test_identical_prediction_is_perfect_and_the_floor_quirk_shows():
    a = _arrays(7)
    got = IT.object2human_metrics(a["gt"], a["gt"], a["obj_verts"])
    assert got["hand_jpe"] == 0 and got["mpvpe"] == 0 and got["foot_sliding"] == got["gt_foot_sliding"]
    assert got["full"]["jpe"] == 0 and got["full"]["contact_dist"] == got["full"]["gt_contact_dist"]
    # lifting the prediction 5 cm moves no hand marker relative to marker 0 (MPVPE 0) but the
    # hand JPE by 5 cm; the groups' JPE sees the markers after each is lowered to y = 0: 0
    lifted = a["gt"] + np.array([0.0, 0.05, 0.0])
    got = IT.object2human_metrics(lifted, a["gt"], a["obj_verts"])
    assert got["mpvpe"] == pytest.approx(0, abs=1e-12) and got["hand_jpe"] == pytest.approx(5.0)
    assert got["full"]["jpe"] == pytest.approx(0, abs=1e-9)


def test_contact_scores_analytic():
    gt = np.array([0.01, 0.01, 0.2, 0.2])
    pred = np.array([0.01, 0.3, 0.01, 0.3])
    s = IT.contact_scores(pred, gt, 0.05)        # TP 1, FN 1, FP 1, TN 1
    assert (s["contact_precision"], s["contact_recall"], s["contact_acc"], s["contact_f1_score"]) == (0.5, 0.5, 0.5, 0.5)
    assert s["contact_dist"] == pytest.approx((0.01 + 0.3) / 2) and s["gt_contact_dist"] == pytest.approx(0.01)
    none = IT.contact_scores(np.ones(3), np.ones(3), 0.05)
    assert none["contact_f1_score"] == 0 and none["contact_dist"] == 0 and none["contact_acc"] == 1


def test_rotation_error_and_best_sample():
    r = Rotation.from_rotvec([[0, 0, np.pi / 2]]).as_matrix()
    # ||I - Rz(90)||_F = sqrt(1 + 1 + 1 + 1) = 2
    assert IT.rotation_error(r, np.eye(3)[None]) == pytest.approx(2.0)
    assert IT.best_sample([3.0, 1.0, 1.0]) == 1 and IT.best_sample([0.2, 0.9, 0.9], higher_is_better=True) == 1


def test_bad_input_is_one_line():
    with pytest.raises(ValueError, match="pred: expected a finite \\(T, 77, 3\\) array"):
        IT.object2human_metrics(np.zeros((4, 22, 3)), np.zeros((4, 77, 3)), np.zeros((4, 5, 3)))
    with pytest.raises(ValueError, match="frame counts differ"):
        IT.object2human_metrics(np.zeros((4, 77, 3)), np.zeros((5, 77, 3)), np.zeros((4, 5, 3)))
