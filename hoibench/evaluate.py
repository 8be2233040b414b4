"""``hoibench evaluate``: score a submission under a versioned protocol.

Steps (docs/protocol.md):

1. validate the submission against the store's test split; only valid ids are scored and
   every missing id is listed in the result, which is marked incomplete;
2. physical metrics (CD, OCD, PS, FSR, extras) per sample index, mapped over clips on the
   executor (identical for every executor);
3. generated joints and object poses are encoded with the store's representation (hoi269
   rows; a ``human`` evaluator reads their first 263 columns) and embedded raw: the
   evaluator normalises with its own statistics;
4. per replication r: sample ``r mod K``, a caption per clip drawn with the protocol's seed,
   R-precision top-1/2/3 and MM-Dist over the protocol's pools, FID against the ground-truth
   embeddings, Diversity, MultiModality (only when K >= the protocol's samples);
5. mean and 95% CI over replications, written with the protocol, evaluator, representation
   and toolkit versions, sample counts, missing ids, flags and timings.
"""
from __future__ import annotations

import platform
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from . import __version__
from .io import atomic_write_json
from .store import Store


def _captions(data: Path, clip_id: str) -> list[str]:
    """Whole-clip captions of a test clip (lines with start = end = 0; timed captions describe
    a segment, not the clip), all captions when there is no whole-clip one."""
    from .evaluator.text import parse_text_file
    path = data / "texts" / f"{clip_id}.txt"
    if not path.exists():
        return []
    caps = parse_text_file(path.read_text())
    whole = [c.text for c in caps if c.whole_clip]
    return whole or [c.text for c in caps]


def _index_pools(pools: Sequence[Sequence[str]], ids: Sequence[str]) -> list[list[int]]:
    where = {cid: i for i, cid in enumerate(ids)}
    return [[where[c] for c in pool] for pool in pools]


def evaluate(submission: str | Path, data: str | Path, evaluator: str | Path, protocol: str | None = None,
             executor: str = "serial") -> dict:
    """Score ``submission`` against the store ``data`` with the evaluator folder ``evaluator``.

    Returns the result dictionary (also what ``--out`` writes). Raises ``ValueError`` when
    nothing can be scored (no valid id, no captions); a partial submission is scored on its
    valid ids and marked ``complete: false``.
    """
    from .evaluator import load_evaluator
    from .metrics import embedding as em
    from .metrics.physical import clip_inputs, evaluate_physical, load_groups
    from .protocol import get_protocol, summarize_replications
    from .representations import hoi269
    from .submission import Submission, validation_report

    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    data = Path(data)
    store = Store(data)
    mode = store.manifest["config"]["mode"]
    proto = get_protocol(protocol or f"{store.manifest['dataset']}-{'legacy' if mode.startswith('legacy') else 'clean'}")
    ev = load_evaluator(evaluator)
    if ev.representation and ev.representation != store.manifest["representations"]["hml263"]:
        raise ValueError(f"evaluator: trained on {ev.representation}, the store holds "
                         f"{store.manifest['representations']['hml263']}")
    with Submission(submission) as sub:
        report = validation_report(sub, store, protocol=proto)
        ids = sorted(report.valid_ids)
        if not ids:
            raise ValueError(f"{submission}: no valid test id to score ({len(report.errors)} error(s)); "
                             f"run hoibench validate for the list")
        samples = {cid: sub.load(cid) for cid in ids}
        meta = dict(sub.meta or {})
    timings["validate_load_s"] = time.perf_counter() - t0
    K = int(report.samples_per_prompt or 1)
    captions = {cid: _captions(data, cid) for cid in ids}
    no_text = [cid for cid, c in captions.items() if not c]
    if no_text:
        raise ValueError(f"{data}: no texts for {len(no_text)} test clip(s) (e.g. {no_text[0]}); "
                         f"run hoibench annotate first")

    # --- physical metrics, once per sample index
    t1 = time.perf_counter()
    groups = load_groups(data)
    physical = {}
    for k in sorted({proto.sample_index(r, K) for r in range(proto.replications)}):
        motions = {cid: {key: np.asarray(v[k]) for key, v in samples[cid].items() if key != "hml263"}
                   for cid in ids}
        inputs = clip_inputs(store, motions, sample=k, groups=groups,
                             contact_mode=proto.physical["contact_thresholds"], fps=store.manifest["config"]["fps"])
        physical[k] = evaluate_physical(inputs, proto.physical_config(), executor=executor).compute()
    timings["physical_s"] = time.perf_counter() - t1

    # --- embeddings
    t2 = time.perf_counter()
    fps = float(store.manifest["config"]["fps"])
    hoi_mode = "legacy" if mode.startswith("legacy") else "clean"
    gen = np.zeros((K, len(ids), ev.embed_dim), np.float32)
    for k in range(K):
        feats = []
        for cid in ids:
            s = samples[cid]
            rot = s["obj_rot"][k] if "obj_rot" in s else s["obj_rotvec"][k]
            feats.append(hoi269.encode(s["joints"][k], rot, s["obj_trans"][k], mode=hoi_mode, fps=fps))
        gen[k] = ev.embed_motion(feats)
    real_feats = []
    for cid in ids:
        clip = store.load(cid)
        real_feats.append(clip["hoi269"] if "hoi269" in clip else clip["hml263"])
    real = ev.embed_motion(real_feats)
    all_caps = sorted({c for caps in captions.values() for c in caps})
    cap_emb = dict(zip(all_caps, ev.embed_text(all_caps)))
    timings["embed_s"] = time.perf_counter() - t2

    # --- replications
    t3 = time.perf_counter()
    per_rep, notes = [], []
    pools_all = proto.pools(ids, 0)
    if not pools_all:
        notes.append(f"fewer valid test ids ({len(ids)}) than the pool size ({proto.r_precision_pool_size}): "
                     f"R-precision and MM-Dist use one pool of all ids (easier than the protocol's pools)")
    mm_ok = K >= proto.mm_samples
    if not mm_ok:
        notes.append(f"MultiModality not computed: {K} sample(s) per prompt, the protocol needs {proto.mm_samples}")
    fid_by_sample: dict[int, float] = {}   # FID depends on the sample index only
    text_sets = [np.stack([cap_emb[c] for c in captions[cid]]) for cid in ids]
    where = {cid: i for i, cid in enumerate(ids)}
    pools_for = lambda r: [[where[c] for c in p] for p in proto.pools(ids, r)]  # noqa: E731
    retrieval = {}
    for k in sorted({proto.sample_index(r, K) for r in range(proto.replications)}):
        retrieval[k] = em.retrieval_replications(text_sets, gen[k], pools_for,
                                                 lambda r: proto.seed_for("caption", r),
                                                 proto.replications, proto.r_precision_top_k)
        fid_by_sample[k] = em.fid(real, gen[k])
    for r in range(proto.replications):
        k = proto.sample_index(r, K)
        tops, mm = retrieval[k]
        row = {f"r_precision_top{i + 1}": float(v) for i, v in enumerate(tops[r])}
        row["mm_dist"] = float(mm[r])
        row["fid"] = fid_by_sample[k]
        pairs = proto.effective_diversity_pairs(len(ids))
        if pairs > 0:
            row["diversity"] = em.diversity(gen[k], pairs, proto.seed_for("diversity", r))
        if mm_ok:
            mm_ids = proto.multimodality_ids(ids, r)
            sel = [ids.index(c) for c in mm_ids]
            row["multimodality"] = em.multimodality(gen[:proto.mm_samples, sel].transpose(1, 0, 2),
                                                    proto.mm_pairs, proto.seed_for("multimodality", r))
        row.update({key: float(v) for key, v in physical[k].items() if isinstance(v, (int, float))})
        per_rep.append(row)
    timings["replications_s"] = time.perf_counter() - t3
    timings["total_s"] = time.perf_counter() - t0
    return {
        **proto.result_header(),
        "complete": bool(report.complete), "evaluator_id": ev.id, "evaluator_variant": ev.variant,
        "representation": store.manifest["representations"], "toolkit": "hoibench", "toolkit_version": __version__,
        "dataset": store.manifest["dataset"], "store_config_sha256": store.manifest.get("config_sha256"),
        "submission": {"path": str(submission), "method": meta.get("method"), "flags": {
            k: meta.get(k) for k in ("uses_gt_length", "samples_per_prompt", "checkpoint_selection") if k in meta}},
        "counts": {"test_ids": len(report.test_ids), "scored_ids": len(ids), "samples_per_prompt": K,
                   "missing_ids": report.missing_ids, "errors": len(report.errors), "warnings": len(report.warnings)},
        "body_surface": proto.physical_config().body_label,
        "metrics": summarize_replications(per_rep, proto.replications),
        "per_replication": per_rep, "notes": notes,
        "timings_s": {k: round(v, 3) for k, v in timings.items()},
        "platform": {"python": platform.python_version(), "numpy": np.__version__},
    }


def format_result(result: dict) -> str:
    lines = [f"{result['protocol']}@{result['protocol_version']}  evaluator {str(result['evaluator_id'])[:12]}  "
             f"{'complete' if result['complete'] else 'INCOMPLETE'}  "
             f"({result['counts']['scored_ids']}/{result['counts']['test_ids']} ids, K={result['counts']['samples_per_prompt']})",
             f"{'metric':28s} {'mean':>12s} {'95% CI':>10s}"]
    for name, s in result["metrics"].items():
        mean, ci = s["mean"], s["ci95"]
        if isinstance(mean, list):
            mean, ci = mean[0], ci[0]
        lines.append(f"{name:28s} {mean:12.5g} {ci:10.3g}")
    lines += [f"note: {n}" for n in result["notes"]]
    return "\n".join(lines)


def main_evaluate(submission, data, evaluator, out=None, protocol=None, executor="serial") -> int:
    result = evaluate(submission, data, evaluator, protocol=protocol, executor=executor)
    if out is not None:
        atomic_write_json(out, result)
    print(format_result(result))
    if out is not None:
        print(f"wrote {out}")
    return 0 if result["complete"] else 1
