"""Physics metrics (hoibench.metrics.physics, MuJoCo) on constructed scenes with known answers:
free fall over h is 0.5 g h^2, a box on the floor or pressed between two palms stays, a box
10 cm from the hands falls, a box on an incline slides exactly when it is steeper than
atan(friction), reruns are identical, and without ``mujoco`` the metrics are "not computed"."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hoibench.core.skeleton import SMPL_REST_JOINTS
from hoibench.metrics import catalog
from hoibench.metrics.physical import ClipInput

mujoco = pytest.importorskip("mujoco")

from hoibench.metrics import physics as P  # noqa: E402
from hoibench.metrics.physics_scene import BodyTrack, object_geometry  # noqa: E402

G, H = 9.81, 0.5
FPS = 20.0
HALF = 0.15                                       # the test box: 30 cm cube


def _box(half: float = HALF) -> tuple[np.ndarray, np.ndarray]:
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * half
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return c, f


def _clip(T: int, centre, body_x: float = 10.0) -> ClipInput:
    """A static box (template centred on its origin) at ``centre``; the body stands far away."""
    v, f = _box()
    joints = np.repeat((np.asarray(SMPL_REST_JOINTS) + [body_x, 1.0, 0.0])[None], T, 0)
    return ClipInput(key="c", joints=joints, fps=FPS, obj_rot=np.repeat(np.eye(3)[None], T, 0),
                     obj_trans=np.repeat(np.asarray(centre, float)[None], T, 0), object_name="box",
                     template_vertices=v, template_faces=f)


def _palms(T: int, gap: float, centre=(0.0, 1.0, 0.0), radius: float = 0.03) -> BodyTrack:
    """Two vertical palm capsules (20 cm) either side of the box along x, their surfaces
    ``gap`` from its faces (negative: pressed in)."""
    x = HALF + radius + gap
    c = np.array([[-x, 0, 0], [x, 0, 0]], float) + centre
    return BodyTrack(np.repeat(c[None], T, 0), np.repeat(np.array([[0, 1.0, 0], [0, 1.0, 0]])[None], T, 0),
                     np.full(2, radius), np.full(2, 0.2))


def _support(track: BodyTrack, centre, T: int = 11, settings=None) -> np.ndarray:
    s = P.resolve_settings(settings)
    v, f = _box()
    scene = P.ClipScene(v, f, track, s)
    R = np.repeat(np.eye(3)[None], T, 0)
    t = np.repeat(np.asarray(centre, float)[None], T, 0)
    return P.support_errors(scene, R, t, FPS)


def test_free_fall_over_a_window_is_half_g_h_squared():
    out = P.physics_clip_values(_clip(21, (0.0, 3.0, 0.0)), {})
    want = 0.5 * G * H ** 2
    assert out["phys_support_err_m"] == pytest.approx(want, rel=0.02)
    assert out["phys_unsupported_ratio"] == 1.0
    assert out["phys_balance_ratio"] == 0.0


def test_a_box_on_the_floor_stays():
    out = P.physics_clip_values(_clip(21, (0.0, HALF, 0.0)), {})
    assert out["phys_support_err_m"] < 0.005 and out["phys_unsupported_ratio"] == 0.0
    assert out["phys_settle_m"] < 0.005 and out["phys_balance_ratio"] == 1.0


def test_a_box_pressed_between_two_palms_stays_and_one_10_cm_from_them_falls():
    held = _support(_palms(11, -0.01), (0.0, 1.0, 0.0))
    assert len(held) == 1 and held.max() < 0.01
    loose = _support(_palms(11, 0.10, centre=(0.0, 2.0, 0.0)), (0.0, 2.0, 0.0))     # 1.85 m above the floor
    assert loose.min() == pytest.approx(0.5 * G * H ** 2, rel=0.02)


def test_a_box_carried_up_between_moving_palms_follows_them():
    T = 11
    lift = np.linspace(0.0, 0.3, T)[:, None] * [0.0, 1.0, 0.0]       # 0.6 m/s upwards
    track = _palms(T, -0.01)
    track = dataclasses.replace(track, centres=track.centres + lift[:, None])
    s = P.resolve_settings({})
    v, f = _box()
    scene = P.ClipScene(v, f, track, s)
    t = np.array([0.0, 1.0, 0.0]) + lift
    err = P.support_errors(scene, np.repeat(np.eye(3)[None], T, 0), t, FPS)
    assert err.max() < 0.02


@pytest.mark.parametrize("deg, slides", [(35.0, True), (18.0, False)])
def test_a_box_on_an_incline_slides_only_when_steeper_than_atan_friction(deg, slides):
    s = P.resolve_settings({"friction": 0.5})                        # atan(0.5) = 26.6 deg
    v, f = _box()
    scene = P.ClipScene(v, f, _palms(2, 5.0), s)
    a = math.radians(deg)                                            # tilting gravity = tilting the floor
    scene.models["mocap"][0].opt.gravity[:] = (G * math.sin(a), -G * math.cos(a), 0.0)
    q0 = np.array([0.0, HALF, 0.0, 1.0, 0.0, 0.0, 0.0])
    end, _ = scene.release(q0, 0, 500)                               # 1 s
    moved = float(np.linalg.norm(end - [0.0, HALF, 0.0]))
    if slides:   # a = g (sin a - mu cos a): 0.5 a t^2 = 0.81 m at 35 deg
        assert moved == pytest.approx(0.5 * G * (math.sin(a) - 0.5 * math.cos(a)), rel=0.1)
    else:
        assert moved < 0.005


def test_reruns_are_identical():
    inp = _clip(25, (0.0, 0.5, 0.0))
    a = P.physics_clip_values(inp, {})
    b = P.physics_clip_values(inp, {})
    assert a == b


def test_human_only_and_short_clips_have_no_value():
    inp = dataclasses.replace(_clip(21, (0, 1, 0)), obj_rot=None, obj_trans=None, template_vertices=None)
    assert all(math.isnan(v) for v in P.physics_clip_values(inp, {}).values())
    out = P.physics_clip_values(_clip(5, (0.0, HALF, 0.0)), {})          # 0.25 s < h
    assert math.isnan(out["phys_support_err_m"]) and out["phys_settle_m"] < 0.005


def test_contact_frames_see_a_hand_on_the_object():
    inp = _clip(3, (0.0, HALF, 0.0))
    assert not P.contact_frames(inp).any()
    J = np.asarray(inp.joints).copy()
    J[1, :, 0] -= 10.0                     # frame 1: the body stands where the box is
    assert P.contact_frames(dataclasses.replace(inp, joints=J)).tolist() == [False, True, False]


def test_hull_notes_a_closed_cavity():
    v, f = _box()
    assert object_geometry(v, f).hull_ratio == pytest.approx(1.0) and not object_geometry(v, f).hull_closes_cavity


def test_settings_are_checked_naming_the_field():
    P.check_settings(dict(P.DEFAULTS), "p.yaml: physics")
    with pytest.raises(ValueError, match="p.yaml: physics: unknown field"):
        P.check_settings({"windows_s": 0.5}, "p.yaml: physics")
    with pytest.raises(ValueError, match="'friction' must be >= 0"):
        P.check_settings({"friction": -1}, "p.yaml: physics")
    with pytest.raises(ValueError, match="'settle_frames' must be a positive integer"):
        P.check_settings({"settle_frames": 3.5}, "p.yaml: physics")
    with pytest.raises(ValueError, match="'timestep_s'"):
        P.check_settings({"timestep_s": 0.1}, "p.yaml: physics")


def test_a_missing_engine_reads_not_computed(monkeypatch):
    for name in P.NAMES:
        info = catalog.METRICS[name]
        assert info.requires == "mujoco" and info.settings_key == "physics"
        monkeypatch.setitem(catalog.METRICS, name, dataclasses.replace(info, requires="hoibench_no_such_engine"))
        assert catalog.unavailable(name) == "not computed: install hoibench[physics]"


def test_clean_protocols_get_a_new_version_and_the_old_ones_still_load():
    from hoibench.tracks.protocol import get_protocol
    for pid, old, new in (("synthetic-clean", "1.1", "1.2"), ("behave-clean", "1.1", "1.2"),
                          ("omomo-clean", "1.1", "1.2"), ("interact-clean", "1.0", "1.1")):
        p, q = get_protocol(f"{pid}@{new}"), get_protocol(f"{pid}@{old}")
        assert get_protocol(pid) == q and p.preview and not q.preview          # a preview is never the default
        assert p.version == new and set(P.NAMES) <= set(p.metrics)
        assert p.settings_for("physics") == P.DEFAULTS
        assert q.version == old and not set(P.NAMES) & set(q.metrics) and q.settings_for("physics") == {}
    for pid in ("behave-legacy", "omomo-legacy", "synthetic-legacy", "t2m-legacy", "rich-cat-clean"):
        assert not set(P.NAMES) & set(get_protocol(pid).metrics)
