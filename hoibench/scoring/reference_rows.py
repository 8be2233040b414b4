"""Reference rows: submissions that bracket the scale of every metric (``hoibench submission
reference KIND``), scored by the same code path as any model.

==================  ===========================================================================
kind                each test clip's sample (K = 1, the ground truth's length)
==================  ===========================================================================
gt                  the clip itself (:func:`hoibench.scoring.submission.from_store`)
gt-noise            the clip's joints and object translation plus i.i.d. Gaussian noise of
                    ``sigma`` metres per coordinate and frame (seeded by ``(seed, clip id)``);
                    the object rotation unchanged. 1 cm and 3 cm are the documented rows.
static-first-pose   the clip's first frame held for every frame: body and object still
mean-pose           the mean train pose and a static object (:mod:`hoibench.scoring.mean_pose`)
mismatched-texts    another test clip's motion (ground truth, its own length) under this
                    clip's id and caption: a derangement of the sorted test ids seeded by
                    ``seed``, so no clip keeps its own motion; R-precision falls to chance while
                    FID stays near the ground truth's (the same motions, reassigned)
==================  ===========================================================================

The ground truth is the best row on every metric but R-precision's ceiling; noise and a
static pose are worse on FID at least; mismatched texts sit at chance R-precision.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .. import __version__
from ..datasets.store import Store
from .submission import from_store, write_submission

KINDS = ("gt", "gt-noise", "static-first-pose", "mean-pose", "mismatched-texts")


def _rng(seed: int, cid: str) -> np.random.Generator:
    h = int.from_bytes(hashlib.sha256(f"{seed}:{cid}".encode()).digest()[:8], "little")
    return np.random.default_rng(h)


def derangement(n: int, seed: int) -> np.ndarray:
    """A seeded permutation of ``range(n)`` with no fixed point (n >= 2): a random cyclic
    order, each element mapped to the next one in it."""
    if n < 2:
        raise ValueError(f"mismatched-texts: needs at least 2 test clips, got {n}")
    order = np.random.default_rng(seed).permutation(n)
    out = np.empty(n, np.int64)
    out[order] = np.roll(order, -1)
    return out


def _arrays(clip: dict, joints: np.ndarray, rot: np.ndarray | None, trans: np.ndarray | None) -> dict:
    out = {"joints": joints[None].astype(np.float32)}
    if rot is not None and "obj_rot" in clip:
        out["obj_rot"] = rot[None].astype(np.float32)
        out["obj_trans"] = trans[None].astype(np.float32)
    return out


def write_reference(kind: str, data: str | Path, out: str | Path, *, sigma: float = 0.01, seed: int = 0,
                    as_zip: bool = False) -> Path:
    """Write the ``kind`` reference submission for ``data``'s test split to ``out``."""
    if kind not in KINDS:
        raise ValueError(f"reference kind {kind!r}: choose one of {', '.join(KINDS)}")
    if kind == "gt":
        return from_store(data, out, as_zip=as_zip)
    if kind == "mean-pose":
        from .mean_pose import write_mean_pose_submission
        return write_mean_pose_submission(data, out, as_zip=as_zip)
    if kind == "gt-noise" and not (np.isfinite(sigma) and 0 < sigma <= 1.0):
        raise ValueError(f"--sigma: expected metres in (0, 1], got {sigma!r}")
    st = Store(data)
    ids = st.clip_ids("test")
    if not ids:
        raise ValueError(f"{data}: the test split has no clips")
    label = {"gt-noise": f"ground truth + {sigma * 100:g} cm Gaussian noise",
             "static-first-pose": "static first pose (body and object)",
             "mismatched-texts": "ground truth under mismatched texts"}[kind]
    m = st.manifest
    meta = {"method": label, "version": __version__, "url": "",
            "representation": m.get("representations", {}).get("hml263", ""), "fps": float(m["config"]["fps"]),
            "flags": {"uses_gt_length": kind != "mismatched-texts", "samples_per_prompt": 1,
                      "checkpoint_selection": "n/a"},
            "source": {"reference": kind, "store": m.get("dataset", ""), "split": "test", "seed": seed,
                       **({"sigma_m": sigma} if kind == "gt-noise" else {}), "toolkit_version": __version__}}
    partner = derangement(len(ids), seed) if kind == "mismatched-texts" else None

    def samples():
        for i, cid in enumerate(ids):
            clip = st.load(cid, keys=("joints", "obj_rot", "obj_trans"))
            rot, trans = clip.get("obj_rot"), clip.get("obj_trans")
            if kind == "gt-noise":
                rng = _rng(seed, cid)
                j = clip["joints"] + rng.normal(scale=sigma, size=clip["joints"].shape)
                t = None if trans is None else trans + rng.normal(scale=sigma, size=trans.shape)
                yield cid, _arrays(clip, j, rot, t)
            elif kind == "static-first-pose":
                T = len(clip["joints"])
                hold = lambda a: None if a is None else np.repeat(a[:1], T, 0)  # noqa: E731
                yield cid, _arrays(clip, hold(clip["joints"]), hold(rot), hold(trans))
            else:
                other = st.load(ids[partner[i]], keys=("joints", "obj_rot", "obj_trans"))
                if ("obj_rot" in clip) != ("obj_rot" in other):
                    raise ValueError(f"{data}: clips {cid} and {ids[partner[i]]} differ in having an object")
                yield cid, _arrays(clip, other["joints"], other.get("obj_rot"), other.get("obj_trans"))

    return write_submission(out, meta, samples(), as_zip=as_zip)


# ---------------------------------------------------------------------- by track
def _main_hoi(action: str, data, out, kind: str | None, *, as_zip: bool, samples: int, sigma: float,
              seed: int) -> int:
    if action == "reference":
        if kind is None:
            raise ValueError("submission reference: --kind is required (gt, gt-noise, static-first-pose, mean-pose, "
                             "mismatched-texts)")
        path = write_reference(kind, data, out, sigma=sigma, seed=seed, as_zip=as_zip)
        print(f"wrote {path} ({kind})")
        return 0
    from .submission import main_submission_from_store
    return main_submission_from_store(data, out, as_zip=as_zip)


def _main_multibody(action: str, data, out, kind: str | None, *, as_zip: bool, samples: int, sigma: float,
                    seed: int) -> int:
    from .multibody import write_multibody_submission
    kind = "gt" if action == "from-store" else (kind or "gt")
    path = write_multibody_submission(data, out, kind=kind, as_zip=as_zip, samples=samples, sigma=sigma, seed=seed)
    print(f"wrote {path} ({kind}, multi-body)")
    return 0


def _main_interact_task(action: str, data, out, kind: str | None, *, as_zip: bool, samples: int, sigma: float,
                        seed: int, task: str = "") -> int:
    from .interact_task_files import write_task_reference
    kind = "gt" if action == "from-store" else (kind or "gt")
    path = write_task_reference(kind, data, out, task, as_zip=as_zip)
    print(f"wrote {path} ({kind}, InterAct {task})")
    return 0


#: the reference-submission writers, by a track's submission schema
REFERENCE_WRITERS = {"hoi": _main_hoi, "multibody": _main_multibody, "interact-task": _main_interact_task}


def main_reference(action: str, data, out, kind: str | None = None, *, as_zip: bool = False, samples: int = 1,
                   sigma: float = 0.01, seed: int = 0, protocol=None) -> int:
    """``hoibench submission from-store|reference DATA --out OUT``: the ground truth or a
    reference row of the store's test split, written in its track's submission schema (the
    track a given ``protocol`` selects, :func:`hoibench.tracks.registry.fitting_track`)."""
    from ..tracks.protocol import get_protocol
    from ..tracks.registry import fitting_track
    track = fitting_track(Store(data), get_protocol(protocol) if protocol is not None else None)
    task = {"task": track.extras["task"]} if track.extras.get("task") else {}
    return REFERENCE_WRITERS[track.submission](action, data, out, kind, as_zip=as_zip, samples=samples,
                                               sigma=sigma, seed=seed, **task)
