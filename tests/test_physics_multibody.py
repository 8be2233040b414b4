"""The physics tier of multi-body clips (hoibench.metrics.physics_multibody): every object
simulated in turn with the skeletons and the other objects kinematic. Constructed scenes
with known answers: one human and one object give the single-body tier's numbers exactly;
an object resting on another object, or on two flat hands, stays, and falls 0.5 g h^2
without them; a moving support carries what rests on it; the other objects' kinematic
states interpolate their poses."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hoibench.bodies.multibody import Body, MultiBodyClip
from hoibench.core.geometry import axis_angle_to_matrix, matrix_to_quaternion
from hoibench.core.skeleton import SMPL_REST_JOINTS
from hoibench.metrics.physical import ClipInput

pytest.importorskip("mujoco")

from hoibench.metrics import physics as P  # noqa: E402
from hoibench.metrics.physics_multibody import multibody_physics_values, object_values  # noqa: E402
from hoibench.metrics.physics_scene import rigid_states  # noqa: E402

G, H, FPS = 9.81, 0.5, 20.0
FREE_FALL = 0.5 * G * H ** 2


def _box(hx: float, hy: float | None = None, hz: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    half = np.array([hx, hx if hy is None else hy, hx if hz is None else hz])
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * half
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return c, f


def _object(name: str, centres, T: int) -> Body:
    t = np.broadcast_to(np.asarray(centres, float), (T, 3)).copy()
    return Body(name, "object", t, np.repeat(np.eye(3)[None], T, 0), None, name)


TEMPLATES = {"cube": _box(0.05), "slab": _box(0.2, 0.01, 0.2)}


def test_one_human_and_one_object_give_the_single_body_numbers_exactly():
    T = 21
    lift = np.linspace(0.0, 0.2, T)[:, None] * [0.0, 1.0, 0.0]
    joints = np.repeat((np.asarray(SMPL_REST_JOINTS) + [0.25, 0.95, 0.0])[None], T, 0) + lift[:, None]
    R = np.repeat(np.eye(3)[None], T, 0)
    t = np.array([0.0, 1.0, 0.0]) + lift
    v, f = TEMPLATES["cube"]
    single = P.physics_clip_values(ClipInput(key="c", joints=joints, fps=FPS, obj_rot=R, obj_trans=t,
                                             object_name="cube", template_vertices=v, template_faces=f), {})
    clip = MultiBodyClip("c", "t", "s", FPS, [Body("person", "human", joints[:, 0], None, joints),
                                              Body("cube", "object", t, R, None, "cube")], TEMPLATES)
    assert multibody_physics_values(clip, {}) == single
    assert not any(math.isnan(x) for x in single.values())


def test_an_object_on_another_stays_and_the_unsupported_one_falls():
    T = 21
    slab = _object("slab", (0.0, 2.0, 0.0), T)
    cube = _object("cube", (0.0, 2.0 + 0.01 + 0.05, 0.0), T)          # resting on the slab's top
    clip = MultiBodyClip("stack", "t", "s", FPS, [slab, cube], TEMPLATES)
    err, disp, turn = object_values(clip, 1, {})
    assert err.max() < 0.005 and disp.max() < 0.005 and turn.max() < 1.0
    assert len(disp) == T                         # no skeleton touches it: released at every frame
    slab_err, _, _ = object_values(clip, 0, {})                       # nothing under the slab
    assert slab_err.min() == pytest.approx(FREE_FALL, rel=0.02)
    pooled = multibody_physics_values(clip, {})
    assert pooled["phys_support_err_m"] == pytest.approx(np.concatenate([slab_err, err]).mean())
    assert pooled["phys_unsupported_ratio"] == pytest.approx(0.5)
    away = MultiBodyClip("apart", "t", "s", FPS, [_object("slab", (5.0, 2.0, 0.0), T), cube], TEMPLATES)
    alone, _, _ = object_values(away, 1, {})
    assert alone.min() == pytest.approx(FREE_FALL, rel=0.02)


def test_a_moving_support_carries_the_object_on_it():
    T = 21
    slide = np.linspace(0.0, 0.3, T)[:, None] * [1.0, 0.0, 0.0]       # 0.3 m/s along x
    slab = _object("slab", np.array([0.0, 2.0, 0.0]) + slide, T)
    cube = _object("cube", np.array([0.0, 2.06, 0.0]) + slide, T)
    err, _, _ = object_values(MultiBodyClip("tray", "t", "s", FPS, [slab, cube], TEMPLATES), 1, {})
    assert err.max() < 0.01
    still = _object("slab", (0.0, 2.0, 0.0), T)           # the support stays: friction cannot push the cube
    err, _, _ = object_values(MultiBodyClip("tray", "t", "s", FPS, [still, cube], TEMPLATES), 1, {})
    assert err.min() > 0.05


def _flat_hand(name: str, z: float, top: float, T: int, x: float = 0.0) -> Body:
    """A straight hand lying flat along x (centred at ``x``), its capsules' tops at height ``top``."""
    from hoibench.bodies.capsules import bones
    J = np.zeros((T, 21, 3))
    J[:, :, 0] = x + np.linspace(-0.06, 0.06, 21)
    J[:, :, 1] = top - bones("hand")[2].max()
    J[:, :, 2] = z
    return Body(name, "hand", J[:, 0], None, J, None, "left" if z < 0 else "right")


def test_a_box_on_two_flat_hands_stays_and_counts_as_held():
    T = 21
    hands = [_flat_hand("left_hand", -0.03, 1.5, T), _flat_hand("right_hand", 0.03, 1.5, T)]
    cube = _object("cube", (0.0, 1.55, 0.0), T)
    clip = MultiBodyClip("palms", "t", "s", FPS, hands + [cube], TEMPLATES)
    err, disp, _ = object_values(clip, 2, {})
    assert err.max() < 0.01
    assert len(disp) == 1                          # touched at every frame: released at the last only
    dropped = MultiBodyClip("palms", "t", "s", FPS, [_flat_hand("left_hand", -0.03, 1.5, T, x=0.3), cube], TEMPLATES)
    err, disp, _ = object_values(dropped, 1, {})
    assert err.min() == pytest.approx(FREE_FALL, rel=0.02) and len(disp) == T


def test_a_clip_without_objects_has_no_value():
    T = 21
    clip = MultiBodyClip("hands", "t", "s", FPS, [_flat_hand("left_hand", 0.0, 1.0, T)], {})
    assert all(math.isnan(v) for v in multibody_physics_values(clip, {}).values())
    with pytest.raises(ValueError, match="body 'left_hand' is a hand, not an object"):
        object_values(clip, 0, {})


def test_rigid_states_interpolate_poses_and_give_their_velocity():
    T, w = 5, 0.4                                  # 0.4 rad per frame about y, 0.1 m per frame along x
    R = np.stack([axis_angle_to_matrix(np.array([0.0, w * k, 0.0])) for k in range(T)])
    t = np.arange(T)[:, None] * [0.1, 0.0, 0.0]
    q, v = rigid_states(R, t, np.array([0.0, 2.0, 2.5, 4.0]), FPS)
    np.testing.assert_allclose(q[[0, 1, 3], :3], t[[0, 2, 4]], atol=1e-12)
    np.testing.assert_allclose(q[[0, 1, 3], 3:], matrix_to_quaternion(R[[0, 2, 4]]), atol=1e-12)
    np.testing.assert_allclose(q[2, 3:], matrix_to_quaternion(axis_angle_to_matrix(np.array([0.0, 2.5 * w, 0.0]))),
                               atol=1e-12)
    np.testing.assert_allclose(v[:, :3], np.repeat([[0.1 * FPS, 0.0, 0.0]], 4, 0), atol=1e-12)
    np.testing.assert_allclose(v[:, 3:], np.repeat([[0.0, w * FPS, 0.0]], 4, 0), atol=1e-9)
