"""The audit corruptions (hoibench.audit): every family against an independent expectation,
the identity at the first severity, determinism by seed and independence of clip order."""
from __future__ import annotations

import hashlib
from collections import Counter

import numpy as np
import pytest

from hoibench.audit import FAMILIES, Context, apply, split_context
from hoibench.audit import captions as tx, motion as mo, objects as ob
from hoibench.audit.streams import clip_stream, fraction_count, selection_order, stable_key
from hoibench.core.geometry import rotation_about_y
from hoibench.core.skeleton import JOINT_INDEX, SMPL_REST_JOINTS
from hoibench.evaluator.text import Caption

FPS = 20.0
CTX = Context(fps=FPS)
BOX = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.1, 0.1) for z in (-0.15, 0.15)])   # template


def _clip(T: int = 40, K: int = 2, shift: float = 0.0, name: str = "boxsmall") -> dict[str, np.ndarray]:
    """K samples of T frames: the rest skeleton standing on y = 0, walking along z, swaying,
    with a box 0.4 m in front of the pelvis turning about y."""
    rest = SMPL_REST_JOINTS - [0.0, SMPL_REST_JOINTS[[10, 11], 1].min(), 0.0]
    t = np.arange(T) / FPS
    k = np.arange(K)[:, None]
    root = np.stack([0.05 * np.sin(2 * t + k + shift), 0.0 * t + 0 * k, 0.3 * t + 0 * k], axis=-1)  # (K, T, 3)
    J = rest[None, None] + root[:, :, None, :]
    J[..., JOINT_INDEX["left_wrist"], 1] += 0.1 * np.sin(3 * t)
    obj_trans = J[:, :, 0] + [0.0, 0.1, 0.4]
    obj_rot = np.broadcast_to(rotation_about_y(0.5 * t + 0.1 * k), (K, T, 3, 3))
    return {"joints": J.astype(np.float32), "obj_rot": obj_rot.astype(np.float32),
            "obj_trans": obj_trans.astype(np.float32), "object_name": np.array(name)}


def _split(n: int = 6) -> dict[str, dict[str, np.ndarray]]:
    names = ("boxsmall", "stool", "yogaball")
    return {f"clip{i:02d}": _clip(T=30 + i, K=1, shift=i, name=names[i % 3]) for i in range(n)}


def _captions(clips) -> dict[str, list[Caption]]:
    words = {"boxsmall": ("small box", "small/ADJ box/NOUN"), "stool": ("stool", "stool/NOUN"),
             "yogaball": ("yoga ball", "yoga/NOUN ball/NOUN")}
    verbs = (("lifts", "lift", "lifting"), ("pushes", "push", "pushing"), ("carries", "carry", "carrying"))
    out = {}
    for i, (cid, a) in enumerate(clips.items()):
        text, toks = words[str(a["object_name"])]
        v, lemma, ing = verbs[i % 3]
        tail, tail_toks = (" and then stands still", " and/CCONJ then/ADV stand/VERB still/ADV") if i >= 3 else ("", "")
        out[cid] = [Caption(f"a person {v} the {text}{tail}",
                            tokens=tuple(f"a/DET person/NOUN {lemma}/VERB the/DET {toks}{tail_toks}".split())),
                    Caption(f"someone is {ing} a {text}")]
    return out


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


# ---------------------------------------------------------------- registry and identity
def test_registry_lists_each_family_with_units_and_increasing_severities():
    assert set(FAMILIES) == {"joint_noise", "jitter", "foot_sliding", "freeze", "reverse", "speed", "mirror",
                             "object_float", "object_detach", "grasp_offset", "object_penetrate", "object_swap",
                             "caption_swap", "noun_swap", "verb_swap"}
    for name, spec in FAMILIES.items():
        mags = sorted({spec.magnitude(s) for s in spec.severities})
        assert spec.magnitude(spec.identity) == 0 and len(mags) >= 5, name        # identity + at least 4
        assert [spec.magnitude(s) for s in spec.severities] == sorted(spec.magnitude(s) for s in spec.severities)
        assert spec.unit and spec.corrupts in ("motion", "text") and spec.scope in ("clip", "split")
        assert spec.description and "\n" not in spec.description
    assert FAMILIES["speed"].identity == 1.0 and {0.8, 1.25, 0.5, 2.0} <= set(FAMILIES["speed"].severities)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_the_first_severity_returns_the_ground_truth_exactly(family):
    clips = _split()
    caps = _captions(clips)
    new_clips, new_caps = apply(family, FAMILIES[family].identity, clips, caps, seed=3)
    assert all(_equal(new_clips[c], clips[c]) for c in clips)
    assert new_caps == caps and all(
        [x.tokens for x in new_caps[c]] == [x.tokens for x in caps[c]] for c in caps)
    corrupted, _ = apply(family, FAMILIES[family].severities[-1], clips, caps, seed=3)
    assert all(corrupted[c]["joints"].shape == clips[c]["joints"].shape for c in clips)    # length kept


# ---------------------------------------------------------------- body motion
def test_joint_noise_standard_deviation_matches_sigma():
    a = _clip(T=200, K=4)
    for sigma in (0.01, 0.05):
        out = mo.joint_noise(a, sigma, _rng(), CTX)
        d = (out["joints"].astype(np.float64) - a["joints"])
        assert abs(d.std() / sigma - 1) < 0.02 and abs(d.mean()) < 0.02 * sigma
        assert np.array_equal(out["obj_trans"], a["obj_trans"])


def test_jitter_alternates_with_the_amplitude_per_frame():
    a = _clip()
    out = mo.jitter(a, 0.02, _rng(), CTX)
    d = out["joints"].astype(np.float64) - a["joints"]
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 0.02, atol=1e-5)
    np.testing.assert_allclose(d[:, 1:], -d[:, :-1], atol=1e-5)


def test_foot_sliding_drifts_horizontally_at_the_speed_while_planted():
    a = _clip(T=30, K=1)
    a["joints"][0, :, :, 0] -= a["joints"][0, :, :1, 0]     # feet still on the floor: every frame planted
    a["joints"][0, :, :, 2] -= a["joints"][0, :, :1, 2]
    a["joints"][0, 20:, [10, 11], 1] += 0.2                  # both feet lifted from frame 20 on
    assert mo.planted_frames(a["joints"], FPS)[0].tolist() == [False] + [True] * 19 + [False] * 10
    out = mo.foot_sliding(a, 0.5, _rng(), CTX)
    d = (out["joints"].astype(np.float64) - a["joints"])[0, :, 0]         # pelvis offset (T, 3)
    step = np.linalg.norm(np.diff(d, axis=0), axis=-1)
    np.testing.assert_allclose(step[:19], 0.5 / FPS, atol=1e-5)
    np.testing.assert_allclose(step[19:], 0.0, atol=1e-6)
    np.testing.assert_allclose(d[:, 1], 0.0, atol=1e-6)
    np.testing.assert_allclose(out["obj_trans"] - a["obj_trans"], d[None], atol=1e-5)


def test_freeze_keeps_frame_zero_and_holds_one_frame_from_t0():
    a = _clip(T=41)
    out = mo.freeze(a, 0.25, _rng(), CTX)
    t0 = 30                                                        # floor(0.75 * 40)
    for k, axis in (("joints", 1), ("obj_rot", 1), ("obj_trans", 1)):
        assert np.array_equal(out[k][:, :t0 + 1], a[k][:, :t0 + 1])
        assert np.array_equal(out[k][:, t0:], np.repeat(a[k][:, t0:t0 + 1], 41 - t0, axis=axis))
    whole = mo.freeze(a, 1.0, _rng(), CTX)
    assert np.array_equal(whole["joints"], np.repeat(a["joints"][:, :1], 41, axis=1))
    assert np.array_equal(whole["joints"][:, 0], a["joints"][:, 0])


def test_reverse_of_reverse_is_the_identity():
    a = _clip(T=33)
    for f in FAMILIES["reverse"].severities:
        once = mo.reverse(a, f, _rng(), CTX)
        assert _equal(mo.reverse(once, f, _rng(), CTX), {k: a[k] for k in once})
    full = mo.reverse(a, 1.0, _rng(), CTX)
    assert np.array_equal(full["joints"], a["joints"][:, ::-1])
    assert np.array_equal(full["obj_rot"], a["obj_rot"][:, ::-1])
    half = mo.reverse(a, 0.5, _rng(), CTX)                           # n = floor(16.5 + 0.5) = 17
    assert np.array_equal(half["joints"][:, :16], a["joints"][:, :16])
    assert np.array_equal(half["joints"][:, 16:], a["joints"][:, 16:][:, ::-1])


def test_speed_one_is_the_identity_and_others_resample_to_the_same_length():
    a = _clip(T=41)
    assert _equal(mo.speed(a, 1.0, _rng(), CTX), a)
    fast = mo.speed(a, 2.0, _rng(), CTX)
    slow = mo.speed(a, 0.5, _rng(), CTX)
    assert all(fast[k].shape == a[k].shape == slow[k].shape for k in ("joints", "obj_rot", "obj_trans"))
    np.testing.assert_allclose(fast["joints"][:, :21], a["joints"][:, ::2], atol=1e-6)     # frame t = time 2t
    np.testing.assert_allclose(fast["joints"][:, 21:], np.repeat(a["joints"][:, -1:], 20, axis=1), atol=1e-6)
    np.testing.assert_allclose(slow["joints"][:, ::2], a["joints"][:, :21], atol=1e-6)
    mid = 0.5 * (a["joints"][:, :20] + a["joints"][:, 1:21])
    np.testing.assert_allclose(slow["joints"][:, 1::2], mid, atol=1e-6)
    t = np.arange(41) / FPS                                         # the box turns 0.5 rad/s about y
    np.testing.assert_allclose(slow["obj_rot"][0], rotation_about_y(0.5 * 0.5 * t), atol=1e-5)  # slerp


def test_mirror_twice_is_the_identity_and_swaps_left_and_right():
    a = _clip()
    once = mo.mirror_arrays(a)
    assert _equal(mo.mirror_arrays(once), a)
    lw, rw = JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"]
    assert np.array_equal(once["joints"][..., lw, 0], -a["joints"][..., rw, 0])
    assert np.array_equal(once["joints"][..., lw, 1:], a["joints"][..., rw, 1:])
    np.testing.assert_allclose(np.linalg.det(once["obj_rot"]), 1.0, atol=1e-5)
    M = np.diag([-1.0, 1.0, 1.0])                                   # vertices: the mirror image of M v_template
    v = a["obj_rot"][0, 5] @ BOX.T + a["obj_trans"][0, 5][:, None]
    v2 = once["obj_rot"][0, 5] @ (BOX @ M).T + once["obj_trans"][0, 5][:, None]
    np.testing.assert_allclose(v2, M @ v, atol=1e-5)
    clips = _split(8)
    half = mo.mirror(clips, 0.5, 1, CTX)
    flipped = [c for c in clips if not _equal(half[c], clips[c])]
    assert len(flipped) == 4 and all(_equal(half[c], mo.mirror_arrays(clips[c])) for c in flipped)
    assert set(flipped) <= {c for c in clips if not _equal(mo.mirror(clips, 0.75, 1, CTX)[c], clips[c])}  # nested


# ---------------------------------------------------------------- object
def test_object_float_lifts_the_lowest_point_by_h():
    a = _clip()
    out = ob.object_float(a, 0.1, _rng(), CTX)

    def lowest(x):
        return (x["obj_rot"].astype(np.float64) @ BOX.T)[..., 1, :].min(-1) + x["obj_trans"][..., 1]
    np.testing.assert_allclose(lowest(out) - lowest(a), 0.1, atol=1e-6)
    assert np.array_equal(out["joints"], a["joints"])


def test_object_detach_keeps_the_object_fixed_after_t0():
    a = _clip(T=41)
    out = ob.object_detach(a, 0.5, _rng(), CTX)                      # t0 = 20
    assert np.array_equal(out["obj_trans"][:, :21], a["obj_trans"][:, :21])
    assert (out["obj_trans"][:, 20:] == a["obj_trans"][:, 20:21]).all()
    assert (out["obj_rot"][:, 20:] == a["obj_rot"][:, 20:21]).all()
    assert np.array_equal(out["joints"], a["joints"])


@pytest.mark.parametrize("family,sign", [(ob.grasp_offset, 1.0), (ob.object_penetrate, -1.0)])
def test_grasp_offset_and_penetration_move_the_object_from_or_to_the_body(family, sign):
    a = _clip()
    out = family(a, 0.1, _rng(), CTX)

    def horizontal(x):
        d = x["obj_trans"].astype(np.float64) - x["joints"][..., 0, :]
        return np.linalg.norm(d[..., [0, 2]], axis=-1)
    np.testing.assert_allclose(horizontal(out) - horizontal(a), sign * 0.1, atol=1e-5)
    np.testing.assert_allclose(out["obj_trans"][..., 1], a["obj_trans"][..., 1])


def test_object_swap_names_another_object_of_the_split():
    clips = _split(6)
    ctx = split_context(clips, {})
    out = ob.object_swap(clips, 0.5, 2, ctx)
    swapped = [c for c in clips if str(out[c]["object_name"]) != str(clips[c]["object_name"])]
    assert len(swapped) == 3 and all(str(out[c]["object_name"]) in ctx.objects for c in swapped)
    assert all(np.array_equal(out[c]["obj_trans"], clips[c]["obj_trans"]) for c in clips)


# ---------------------------------------------------------------- text
def test_caption_swap_keeps_the_multiset_of_captions():
    clips = _split(7)
    caps = _captions(clips)
    for f in (0.25, 0.5, 1.0):
        out = tx.caption_swap(caps, f, 5, CTX)
        def multiset(m):
            return Counter(c for lines in m.values() for c in lines)
        assert multiset(out) == multiset(caps)
        moved = [c for c in caps if out[c] != caps[c]]
        assert len(moved) == max(2, fraction_count(f, 7))


def test_noun_swap_replaces_the_object_noun_with_another_objects():
    clips = _split(6)
    caps = _captions(clips)
    ctx = split_context(clips, caps)
    ctx = Context(fps=FPS, objects=ctx.objects, clip_objects=ctx.clip_objects, verbs=ctx.verbs,
                  object_nouns={"boxsmall": (("small/ADJ", "box/NOUN"),), "stool": (("stool/NOUN",),),
                                "yogaball": (("yoga/NOUN", "ball/NOUN"),)})
    out = tx.noun_swap(caps, 1.0, 0, ctx)
    names = {"boxsmall": "small box", "stool": "stool", "yogaball": "yoga ball"}
    for cid, lines in out.items():
        own = names[ctx.clip_objects[cid]]
        for old, new in zip(caps[cid], lines):
            assert own in old.text and own not in new.text and any(n in new.text for n in names.values())
            assert new.text.split()[:3] == old.text.split()[:3]
        assert lines[0].tokens[:4] == caps[cid][0].tokens[:4] and lines[0].tokens != caps[cid][0].tokens
    line = tx._noun_line(Caption("A box is lifted by a person"), (("box/NOUN",),), (), ("exercise/NOUN", "ball/NOUN"))
    assert line.text == "An exercise ball is lifted by a person" and line.tokens[:3] == ("an/DET", "exercise/NOUN",
                                                                                         "ball/NOUN")


def test_verb_swap_replaces_the_main_verb_with_another_verb_of_the_split():
    clips = _split(6)
    caps = _captions(clips)
    ctx = split_context(clips, caps)
    assert ctx.verbs == ("carry", "lift", "push")
    out = tx.verb_swap(caps, 1.0, 0, ctx)
    forms = {"lift": ("lifts", "lifting"), "push": ("pushes", "pushing"), "carry": ("carries", "carrying")}
    for cid in caps:
        old, new = caps[cid][0], out[cid][0]
        lemma = old.tokens[2].split("/")[0]
        verb = new.text.split()[2]
        assert verb != old.text.split()[2] and verb in {f[0] for v, f in forms.items() if v != lemma}
        assert new.tokens[2] == f"{next(v for v, f in forms.items() if f[0] == verb)}/VERB"
        ing = out[cid][1].text.split()[2]
        assert ing != caps[cid][1].text.split()[2] and ing in {f[1] for f in forms.values()}


# ---------------------------------------------------------------- determinism and streams
@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_same_seed_same_result_and_clip_order_does_not_matter(family):
    clips = _split(6)
    caps = _captions(clips)
    sev = FAMILIES[family].severities[3]
    a_clips, a_caps = apply(family, sev, clips, caps, seed=11)
    b_clips, b_caps = apply(family, sev, dict(reversed(list(clips.items()))), dict(reversed(list(caps.items()))),
                            seed=11)
    assert all(_equal(a_clips[c], b_clips[c]) for c in clips) and a_caps == b_caps
    if FAMILIES[family].scope == "clip":                               # a worker's share gives the same clips
        part = {c: clips[c] for c in list(clips)[::2]}
        p_clips, _ = apply(family, sev, part, {c: caps[c] for c in part}, seed=11)
        assert all(_equal(p_clips[c], a_clips[c]) for c in part)


def test_different_seeds_differ_and_streams_are_keyed_by_clip_id():
    clips = _split(4)
    a, _ = apply("joint_noise", 0.01, clips, {}, seed=1)
    b, _ = apply("joint_noise", 0.01, clips, {}, seed=2)
    assert not _equal(a["clip00"], b["clip00"])
    assert stable_key("mirror") == int.from_bytes(hashlib.sha256(b"mirror").digest()[:8], "big")
    x = clip_stream(1, "jitter", 2, "clip03").random(3)
    assert np.array_equal(x, np.random.default_rng(np.random.SeedSequence(
        [1, stable_key("jitter"), 2, stable_key("clip03")])).random(3))
    assert selection_order(4, "mirror", ["b", "a", "c"]) == selection_order(4, "mirror", ["c", "b", "a"])


# ---------------------------------------------------------------- validation
def test_bad_inputs_are_refused_naming_the_argument():
    a = _clip()
    with pytest.raises(ValueError, match=r"arrays\['joints'\]"):
        mo.joint_noise({"joints": np.zeros((5, 3))}, 0.01, _rng(), CTX)
    with pytest.raises(ValueError, match="severity"):
        mo.joint_noise(a, -0.1, _rng(), CTX)
    with pytest.raises(ValueError, match="severity"):
        mo.freeze(a, 1.5, _rng(), CTX)
    with pytest.raises(ValueError, match="rng"):
        mo.jitter(a, 0.01, 0, CTX)
    with pytest.raises(ValueError, match="ctx"):
        mo.foot_sliding(a, 0.1, _rng(), Context(fps=0.0))
    with pytest.raises(ValueError, match="arrays: no object"):
        ob.object_float({"joints": a["joints"]}, 0.1, _rng(), CTX)
    with pytest.raises(ValueError, match=r"arrays\['obj_trans'\]"):
        ob.object_float({**a, "obj_trans": a["obj_trans"][:, :-1]}, 0.1, _rng(), CTX)
    with pytest.raises(ValueError, match="family"):
        apply("blur", 0.1, {"c": a}, {}, seed=0)
    with pytest.raises(ValueError, match="severity"):
        apply("joint_noise", 0.03, {"c": a}, {}, seed=0)
    with pytest.raises(ValueError, match="seed"):
        apply("joint_noise", 0.01, {"c": a}, {}, seed=-1)
    with pytest.raises(ValueError, match=r"clips\['c'\]"):
        apply("mirror", 0.5, {"c": {"joints": np.zeros((4, 3))}}, {}, seed=0)
    with pytest.raises(ValueError, match="captions"):
        tx.caption_swap({"c": "a person walks"}, 0.5, 0, CTX)
    with pytest.raises(ValueError, match="ctx: objects"):
        ob.object_swap({"c": a, "d": a}, 1.0, 0, Context(objects=("boxsmall",)))


# ---------------------------------------------------------------- markers (marker tracks)
def test_markers_follow_the_corrupted_joints():
    """``follow_markers``: equal joints keep the markers; a rigid shift of the whole body shifts
    every marker by it exactly; markers on the proxy body itself become the proxy's markers of
    the corrupted joints (so a frozen tail holds frame t0's markers, to the 0.6 mm by which the
    proxy's body scale, a statistic of the whole clip, moves when half the clip is held)."""
    from hoibench.metrics.body_surface import proxy_markers
    clip = _clip(T=30, K=1)
    J = clip["joints"][0].astype(np.float64)
    rng = _rng(3)
    markers = proxy_markers(J) + rng.normal(scale=0.01, size=(30, 77, 3))     # off the proxy by ~1 cm
    np.testing.assert_array_equal(mo.follow_markers(markers, J, J.copy()), markers)
    shift = np.array([0.3, 0.0, -0.2])
    np.testing.assert_allclose(mo.follow_markers(markers, J, J + shift), markers + shift, atol=1e-12)
    on_proxy = proxy_markers(J)
    frozen = mo.freeze(clip, 0.5, rng, CTX)["joints"][0].astype(np.float64)
    t0 = 14                                               # floor((1 - 0.5) * 29)
    followed = mo.follow_markers(on_proxy, J, frozen)
    np.testing.assert_allclose(followed[t0:], np.broadcast_to(on_proxy[t0], followed[t0:].shape), atol=1e-3)
    np.testing.assert_allclose(followed[:t0], on_proxy[:t0], atol=1e-3)
    assert np.abs(on_proxy[t0 + 1:] - on_proxy[t0]).max() > 0.05          # the tail did move before
    with pytest.raises(ValueError, match="markers: expected shape"):
        mo.follow_markers(markers[:, :10], J, J)
