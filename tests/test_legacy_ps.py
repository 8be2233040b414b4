"""Legacy protocols measure PS and CD with ChainHOI's released rules; clean ones with hoibench's.

Each rule gets a constructed case where the two differ, the legacy value checked against a
hand computation of the reference's rule and the clean value against hoibench's:

* PS sign (torchsdf ``compute_sdf`` as ``PeneMetric.update`` calls it, ChainHOI 4990160
  compute.py:1186-1198): the side of the closest face's plane, the first face winning ties --
  overlapping boxes, stacked (touching) boxes in both face orders;
* CD's point-to-edge quirk (compute.py:418/422): a joint whose nearest feature is an edge that
  is ``v0 -> v2`` in both faces holding it; values of the reference's own torch functions on
  the same input are recorded below;
* no repair: a mesh with an inverted part.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("open3d")

from hoibench.bodies import reference_distance as rd  # noqa: E402
from hoibench.metrics import physical as ph  # noqa: E402
from hoibench.tracks import protocol as pr  # noqa: E402

# trimesh.creation.box's faces (outward): vertex i has coordinates lo/hi by its bits (x: 4, y: 2, z: 1)
BOX_F = np.array([[1, 3, 0], [4, 1, 0], [0, 3, 2], [2, 4, 0], [1, 7, 3], [5, 1, 4],
                  [5, 7, 1], [3, 7, 2], [6, 4, 2], [2, 7, 6], [6, 5, 4], [7, 5, 6]])


def box(lo, hi, inverted: bool = False) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[(hi if i & 4 else lo)[0], (hi if i & 2 else lo)[1], (hi if i & 1 else lo)[2]] for i in range(8)])
    return v, (BOX_F[:, ::-1] if inverted else BOX_F).copy()


def union(*meshes) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, n = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.vstack(vs), np.vstack(fs)


# ------------------------------------------------------------------ PS through the clip path
_BODY: np.ndarray = np.zeros((1, 3))


def fixed_body(joints) -> np.ndarray:
    """``body_surface`` callable: the points ``_BODY`` on every frame."""
    return np.broadcast_to(_BODY, (len(joints),) + _BODY.shape).copy()


CLEAN = ph.PhysicalConfig("clean", body_surface=f"{__name__}:fixed_body")
LEGACY = replace(CLEAN, ps_sign="closest_face", mesh_repair=False)


def ps_counts(points, mesh, config, frames: int = 2) -> tuple[int, int]:
    """(penetrating vertex-frames, vertex-frames) of ``points`` held still for ``frames``."""
    global _BODY
    _BODY = np.asarray(points, float)
    v, f = mesh
    inp = ph.ClipInput("c", np.full((frames, 22, 3), 10.0), 20.0, np.tile(np.eye(3), (frames, 1, 1)),
                       np.zeros((frames, 3)), "box", v, f)
    st = ph.clip_physical_stats(inp, config)
    return st["ps_neg"], st["ps_total"]


def both_paths(points, mesh) -> rd.ClosestFace:
    """The closest-face rule by brute force; the fast path must give the same signs."""
    brute = rd.closest_face_brute(points, *mesh)
    fast = rd.ClosestFaceField(*mesh)(points)
    np.testing.assert_array_equal(fast.sign, brute.sign)
    np.testing.assert_allclose(fast.distance, brute.distance, atol=1e-9)
    return brute


def test_kernel_sign_is_the_side_of_the_face_normal_v1v2_x_v1v3():
    """torchsdf .cu:211/236: ``n = (v1 - v2) x (v1 - v3)``, outside iff ``(p - c).n >= 0``: a
    CCW triangle seen from +z has n = +z; a point in its plane counts as outside."""
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    p = np.array([[0.2, 0.2, 0.5], [0.2, 0.2, -0.5], [2.0, 2.0, 0.0], [-1.0, 0.3, -1e-3]])
    sq, sign = rd.kernel_pairs(p, np.broadcast_to(tri, (4, 3, 3)))
    np.testing.assert_array_equal(sign, [1, -1, 1, -1])
    np.testing.assert_allclose(sq, [0.25, 0.25, 4.5, 1.0 + 1e-6], rtol=1e-12)


def test_kernel_distance_is_the_exact_point_triangle_distance():
    """Only the sign rule is a quirk: the kernel's region tests give the exact distance
    (Ericson's closest point) on random and sliver triangles."""
    rng = np.random.default_rng(0)
    p, t = rng.normal(size=(20000, 3)), rng.normal(size=(20000, 3, 3))
    t[10000:, 2] = t[10000:, 0] + 0.5 * (t[10000:, 1] - t[10000:, 0]) + 1e-3 * rng.normal(size=(10000, 3))
    sq, _ = rd.kernel_pairs(p, t)
    c = rd.exact_closest_point(p, t[:, 0], t[:, 1], t[:, 2])
    np.testing.assert_allclose(np.sqrt(sq), np.linalg.norm(p - c, axis=1), atol=1e-12)


def test_overlapping_parts_sign_by_the_nearest_face_not_by_inside_any_part():
    """Box A = [-1, 1]^3, box B = [0.5, 3] x [-0.5, 0.5]^2 overlapping it. p1 = (0.4, 0, 0) is
    inside A; its nearest face is B's x = 0.5 face (0.1 away, normal -x), and p1 is on its +
    side: ((0.4 - 0.5) * -1 = 0.1 >= 0) -> outside by the reference, inside by hoibench."""
    mesh = union(box((-1, -1, -1), (1, 1, 1)), box((0.5, -0.5, -0.5), (3, 0.5, 0.5)))
    pts = np.array([[0.4, 0, 0], [0.6, 0, 0], [0, 0, 0.9], [2, 0, 0.8]])
    ref = both_paths(pts, mesh)
    np.testing.assert_array_equal(ref.sign, [1, -1, -1, 1])                       # hand: see above
    np.testing.assert_allclose(ref.distance, [0.1, 0.1, 0.1, 0.3], atol=1e-12)
    assert ps_counts(pts, mesh, LEGACY) == (2 * 2, 4 * 2)                        # p2, p3
    assert ps_counts(pts, mesh, CLEAN) == (3 * 2, 4 * 2)                         # p1, p2, p3


@pytest.mark.parametrize("lower_first", [True, False])
def test_touching_parts_tie_goes_to_the_first_face(lower_first):
    """Stacked boxes L = [-1, 1]^2 x [-1, 0], U = [-1, 1]^2 x [0, 1] share the plane z = 0. q =
    (0.25, 0.125, 0.0625) in U is 0.0625 from L's top (normal +z: q on its + side, outside)
    and U's bottom (normal -z: inside) -- an exact tie, won by whichever part comes first
    (.cu:238/245 replace only on a strictly smaller distance). hoibench: inside U."""
    lower, upper = box((-1, -1, -1), (1, 1, 0)), box((-1, -1, 0), (1, 1, 1))
    mesh = union(lower, upper) if lower_first else union(upper, lower)
    pts = np.array([[0.25, 0.125, 0.0625], [0.25, 0.125, 0.75]])
    ref = both_paths(pts, mesh)
    expected_face = rd.closest_face_brute(pts[:1], *(lower if lower_first else upper)).face[0]
    assert ref.face[0] == expected_face
    np.testing.assert_array_equal(ref.sign, [1 if lower_first else -1, -1])
    assert ps_counts(pts, mesh, LEGACY) == ((1 if lower_first else 2) * 2, 4)
    assert ps_counts(pts, mesh, CLEAN) == (2 * 2, 4)


def test_first_face_of_a_kernel_block_that_is_nan_hides_the_block():
    """.cu:188-249: faces in blocks of 512, each block's best starts at its first face and is
    replaced only by a strictly smaller value, so a NaN first face (all three vertices equal)
    keeps its block out; the brute force follows it, the fast path defers to the brute force
    on meshes with degenerate faces."""
    far = np.array([[0.0, 0, 5], [1, 0, 5], [0, 1, 5]])
    near = np.array([[0.0, 0, 1], [1, 0, 1], [0, 1, 1]])
    point = np.array([[0.2, 0.2, 0.0]])
    for first_of_block_1, winner in ((near, 512), (np.zeros((3, 3)), 0)):
        tris = np.concatenate([np.tile(far, (512, 1, 1)), first_of_block_1[None], near[None]])
        v, f = tris.reshape(-1, 3), np.arange(len(tris) * 3).reshape(-1, 3)
        assert rd.closest_face_brute(point, v, f).face[0] == winner
        assert rd.ClosestFaceField(v, f).brute == (winner == 0)


def test_no_repair_inverted_part():
    """Box A outward, box B = [2, 3] x [-0.5, 0.5]^2 with inward faces. As loaded (legacy), q1
    inside B is on the + side of its nearest face (y = 0.5, normal -y: (0.1 - 0.5) * -1 > 0):
    outside; q2, q3 just outside B are on the - side of theirs: inside. hoibench flips B before
    measuring (clean), and ChainHOI's rule on the repaired mesh agrees with it."""
    mesh = union(box((-1, -1, -1), (1, 1, 1)), box((2, -0.5, -0.5), (3, 0.5, 0.5), inverted=True))
    pts = np.array([[2.5, 0.1, 0.05], [3.1, 0.1, 0.05], [2.5, 0.6, 0.05], [0, 0, 0.5]])
    np.testing.assert_array_equal(both_paths(pts, mesh).sign, [1, -1, -1, -1])
    assert ps_counts(pts, mesh, LEGACY) == (3 * 2, 8)                            # q2, q3, q4
    assert ps_counts(pts, mesh, CLEAN) == (2 * 2, 8)                             # q1, q4
    assert ps_counts(pts, mesh, replace(LEGACY, mesh_repair=True)) == (2 * 2, 8)
    assert ps_counts(pts, mesh, replace(CLEAN, mesh_repair=False)) == (2 * 2, 8)  # |winding| >= 0.5


def test_fast_closest_face_equals_brute_force_on_the_synthetic_objects():
    from hoibench.datasets import synthetic as syn
    rng = np.random.default_rng(3)
    for name in syn.OBJECTS:
        obj = syn.build_object(name)
        v, f = obj.vertices, obj.faces
        i = rng.integers(0, len(f), 300)
        near = np.einsum("nk,nkd->nd", rng.dirichlet([1, 1, 1], 300), v[f[i]]) + rng.normal(scale=0.01, size=(300, 3))
        pts = np.concatenate([near, rng.uniform(v.min(0) - 0.5, v.max(0) + 0.5, (300, 3))])
        both_paths(pts, (v, f))


# ------------------------------------------------------------------ CD: the edge quirk
# A closed tetrahedron whose edge a-b is v0 -> v2 in both faces holding it: (b, x, a) and (a, y, b)
TET_V = np.array([[0.0, 0, 0], [0, 2, 0], [2, 1, 0], [0.5, 1, 2]])          # a, b, x, y
TET_F = np.array([[1, 2, 0], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
TET_P = np.array([[-1.0, 1.5, 0.0], [-1.0, 0.5, 0.0], [-0.5, 1.0, 0.25], [3.0, 3.0, 3.0]])
# ChainHOI 4990160 compute.py point_to_triangle_distance (BEHAVE, :428) and
# point_to_triangle_distance3 (OMOMO, :722), run with torch 2.13 (CPU, float64) on TET_P
# (joints 4..21 at (3, 3, 3), two frames) in a scratch folder outside the repository:
TORCH_BEHAVE = [1.118033988749895, 1.118033988749895, 0.5457051563317492, -3.280243893371345]
TORCH_OMOMO = [1.118033988749895, 1.118033988749895, 0.5457051550082198]


def test_contact_distance_reproduces_the_reference_functions():
    np.testing.assert_allclose(rd.contact_distance_brute(TET_P, TET_V, TET_F, "reference"), TORCH_BEHAVE, atol=1e-6)
    np.testing.assert_allclose(rd.contact_distance_brute(TET_P[:3], TET_V, TET_F, "reference-omomo"), TORCH_OMOMO,
                               atol=1e-6)
    for variant in ("reference", "reference-omomo"):                              # fast = |brute|
        np.testing.assert_allclose(rd.ContactDistanceField(TET_V, TET_F, variant)(TET_P),
                                   np.abs(rd.contact_distance_brute(TET_P, TET_V, TET_F, variant)), atol=1e-12)
    np.testing.assert_allclose(rd.contact_distance_brute(TET_P, TET_V, TET_F, "exact-edges"),
                               np.sign(TORCH_BEHAVE) * rd.exact_triangle_distance(TET_P, TET_V, TET_F), atol=1e-12)


def test_cd_edge_quirk():
    """p = (-1, 1.5, 0): exact distance 1 (to (0, 1.5, 0) on edge a-b). The reference, face
    (b, x, a) = (v0, v1, v2): edge v0 -> v2 = b -> a measured from x: t = (p - x).(a - b) /
    |a - b|^2 = (-3, 0.5, 0).(0, -2, 0) / 4 = -0.25 -> 0 -> b; edge b -> x: t = (p - b).(x - b)
    / 5 = -0.3 -> 0 -> b; edge x -> a: t = (p - x).(a - x) / 5 = 1.1 -> 1 -> a, |p - a| =
    sqrt(3.25); so sqrt(1.25) = |p - b|. Face (a, y, b): edge a -> b measured from y: t =
    (p - y).(b - a) / 4 = 0.25 -> (0, 0.5, 0), sqrt(2); edge y -> b: t = 1 -> b, sqrt(1.25).
    The plane projections fall outside both faces. So CD = 1.25 m^2 for that joint (legacy),
    1.0 (clean)."""
    a, b, x, y = TET_V
    p = TET_P[0]
    assert np.dot(p - x, a - b) / 4 == -0.25 and np.dot(p - b, x - b) / 5 == -0.3
    assert np.dot(p - x, a - x) / 5 == pytest.approx(1.1) and np.dot(p - y, b - a) / 4 == 0.25
    assert np.square(p - b).sum() == 1.25
    joints = np.full((2, 22, 3), 3.0)
    joints[:, 0] = p
    joints[:, 1] = TET_P[2]                                                       # a control: no quirk
    gt = np.zeros((2, 22), bool)
    gt[:, :2] = True
    inp = ph.ClipInput("c", joints, 20.0, np.tile(np.eye(3), (2, 1, 1)), np.zeros((2, 3)), "tet", TET_V, TET_F, gt)
    control = TORCH_BEHAVE[2] ** 2
    clean = ph.clip_physical_stats(inp, CLEAN)
    legacy = ph.clip_physical_stats(inp, replace(LEGACY, cd_edge="reference"))
    assert clean["cd_sum"] / clean["cd_count"] == pytest.approx((1.0 + control) / 2, abs=1e-6)
    assert legacy["cd_sum"] / legacy["cd_count"] == pytest.approx((1.25 + control) / 2, abs=1e-12)
    assert legacy["ocd"] == pytest.approx((1.25 + control) / 2, abs=1e-12)


# ------------------------------------------------------------------ protocols
def test_legacy_protocols_carry_the_reference_rules_and_clean_ones_are_unchanged():
    for pid, edge in (("behave-legacy", "reference"), ("omomo-legacy", "reference-omomo"),
                      ("synthetic-legacy", "reference")):
        p = pr.get_protocol(pid)
        c = p.physical_config()
        assert p.version == "1.3" and p.changelog[-2].startswith("1.2:") and p.changelog[-1].startswith("1.3:")
        assert (c.ps_sign, c.cd_edge, c.mesh_repair) == ("closest_face", edge, False)
    clean = {"behave-clean": "3d9bb579152fb66826fe300d8bce23bc2f87bfd034d48ff3c53b2a94b2561036",
             "omomo-clean": "4465b4d470fc1febec277d71905a6241494b5b93362fbcc0fbeb91c6d586e8c4",
             "synthetic-clean": "60ab40d0520112bd7c35c966b8e434a37b45f8aaf0b8684a769b5fdd34dae45a",
             "rich-cat-clean": "0392868ea393481257bde4cf03d56379051344932ee634faf9319de070a9f5bd"}
    for pid, sha in clean.items():
        p = pr.get_protocol(pid)
        c = p.physical_config()
        assert p.sha256 == sha and (c.ps_sign, c.cd_edge, c.mesh_repair) == ("inside", "exact", True)
        assert not {"ps_sign", "cd_edge", "mesh_repair"} & set(p.physical)


@pytest.mark.parametrize("key, value", [("ps_sign", "nearest"), ("cd_edge", "quirk"), ("mesh_repair", "no")])
def test_bad_physical_settings_name_the_file_and_field(key, value):
    path = pr.PROTOCOLS_DIR / "synthetic-legacy.yaml"
    d = pr.read_protocol_yaml(path)
    d["physical"][key] = value
    with pytest.raises(ValueError, match=rf"synthetic-legacy.yaml: physical: field '{key}'"):
        pr.protocol_from_dict(d, str(path))


def test_legacy_ps_note_cites_the_commented_out_call():
    for ref in ("chainhoi_behave.py:398", "chainhoi_omomo.py:440", "compute.py:1141-1198", "4990160"):
        assert ref in ph.LEGACY_PS_NOTE
    assert ph.LEGACY_PS_NOTE.startswith("ps: ")
