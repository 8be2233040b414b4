"""Training and sampling inputs of the joint-level diffusion baselines (ChainHOI, EJIM), from a prepared store (numpy only).

- **Rows**: a clip's ``joint_level`` (T-1, 24, 12) (clean mode), normalised per (node,
  channel) with the train split's mean and std (:class:`JointStats`; channels with std
  below 1e-4, such as the zero padding, keep std 1).
- **Windows**: clips longer than ``max_frames`` rows are cropped at a random start ``a`` and
  re-expressed in the window's own canonical frame (:func:`recentre_window`): the heading,
  the global root and the object pose are rotated by ``R_y(yaw_a)`` about the window's
  first root, so a window looks like a clip that starts there (root at x = z = 0, yaw 0).
- **Contacts**: the stored per-joint contact labels (T, 22), rows 0..T-2, gate the contact
  loss on the eight interaction joints; clips without labels contribute no contact term.
- **Object points**: ``object_points`` surface samples of the centred template (area-weighted,
  seeded by the object name), for the point encoder and the contact loss.
- **Text**: captions from ``DATA/texts/<id>.txt``; the ``tokens`` encoder's vocabulary is
  the lower-case words of the train captions (id 0 padding, 1 unknown).
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import skeleton as sk
from ..datasets.store import Store

INTERACTION_JOINTS: tuple[int, ...] = sk.OBJECT_NODE_NEIGHBOURS     # 0, 10, 11, 12, 16, 17, 20, 21
_WORD = re.compile(r"[a-z]+")


@dataclass
class JointStats:
    mean: np.ndarray        # (24, 12) float32
    std: np.ndarray         # (24, 12) float32

    def normalize(self, x: np.ndarray) -> np.ndarray:
        return ((x - self.mean) / self.std).astype(np.float32)

    def denormalize(self, x: np.ndarray) -> np.ndarray:
        return (x * self.std + self.mean).astype(np.float32)

    def sha256(self) -> str:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.mean, np.float32).tobytes())
        h.update(np.ascontiguousarray(self.std, np.float32).tobytes())
        return h.hexdigest()

    def tensors(self) -> dict[str, np.ndarray]:
        return {"stats.mean": self.mean.astype(np.float32), "stats.std": self.std.astype(np.float32)}

    @classmethod
    def from_rows(cls, clips: list[np.ndarray]) -> "JointStats":
        if not clips:
            raise ValueError("no train clips with joint_level rows: cannot compute normalisation statistics")
        x = np.concatenate([c.reshape(-1, 24, 12) for c in clips]).astype(np.float64)
        mean, std = x.mean(0), x.std(0)
        std = np.where(std < 1e-4, 1.0, std)
        return cls(mean.astype(np.float32), std.astype(np.float32))


@dataclass
class ClipItem:
    clip_id: str
    rows: np.ndarray                    # (L, 24, 12) raw joint_level
    contacts: np.ndarray                # (L, 8) bool, interaction joints
    object_name: str
    captions: list[str] = field(default_factory=list)
    joint_contacts: np.ndarray | None = None   # (L, 22) bool, every joint (ChainHOI released's L_h)


def words(text: str) -> list[str]:
    return _WORD.findall(text.lower())


def build_vocab(captions: list[str]) -> list[str]:
    """Sorted word list (entries 0 and 1 are ``<pad>`` and ``<unk>``)."""
    return ["<pad>", "<unk>"] + sorted({w for c in captions for w in words(c)})


def tokenize(texts: list[str], vocab: list[str], max_tokens: int) -> tuple[np.ndarray, np.ndarray]:
    """(ids (B, Lt) int64, pad (B, Lt) bool) with Lt = the longest text (<= max_tokens)."""
    index = {w: i for i, w in enumerate(vocab)}
    seqs = [[index.get(w, 1) for w in words(t)][:max_tokens] or [1] for t in texts]
    Lt = max(len(s) for s in seqs)
    ids = np.zeros((len(seqs), Lt), np.int64)
    for i, s in enumerate(seqs):
        ids[i, :len(s)] = s
    return ids, ids == 0


def surface_points(vertices: np.ndarray, faces: np.ndarray, n: int, seed_text: str) -> np.ndarray:
    """(n, 3) float32 area-weighted surface samples, seeded by ``seed_text`` (deterministic)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not np.isfinite(area).all() or area.sum() <= 0:
        raise ValueError(f"object {seed_text!r}: template has no surface area")
    seed = int.from_bytes(hashlib.sha256(seed_text.encode()).digest()[:8], "little")
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(f), size=n, p=area / area.sum())
    u, w = rng.random(n), rng.random(n)
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    t = tri[pick]
    return (t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + w[:, None] * (t[:, 2] - t[:, 0])).astype(np.float32)


def _rot_y(angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) R_y(angle) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(np.shape(angle) + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 1, 1], R[..., 2, 0], R[..., 2, 2] = c, s, 1.0, -s, c
    return R


def recentre_window(rows: np.ndarray, start: int, length: int) -> np.ndarray:
    """Rows ``[start, start + length)`` of a joint_level clip in the window's own canonical
    frame: yaw - yaw_a; root and object translation ``R_y(yaw_a) (p - root_a)`` in x, z (y
    unchanged); object rotation ``R_y(yaw_a) R``. Relative channels are frame-free."""
    from ..core.geometry import axis_angle_to_matrix, matrix_to_axis_angle

    w = np.array(rows[start:start + length], dtype=np.float64)
    if start == 0:
        return w.astype(np.float32)
    yaw_a = float(rows[start, 0, 7])
    root_a = np.array(rows[start, 0, 8:11], np.float64)
    R = _rot_y(np.array(yaw_a))
    w[:, 0, 7] -= yaw_a
    for sl in (slice(8, 11),):
        p = w[:, 0, sl] - root_a * np.array([1.0, 0.0, 1.0])
        w[:, 0, sl] = p @ R.T
    obj_t = w[:, 23, 3:6] - root_a * np.array([1.0, 0.0, 1.0])
    w[:, 23, 3:6] = obj_t @ R.T
    rot = axis_angle_to_matrix(w[:, 23, 0:3])
    w[:, 23, 0:3] = matrix_to_axis_angle(R[None] @ rot)
    return w.astype(np.float32)


def clip_item(store: Store, cid: str, captions: list[str]) -> ClipItem:
    clip = store.load(cid)
    if "joint_level" not in clip or "obj_rot" not in clip:
        raise ValueError(f"{store.root}: clip {cid}: the joint-level baselines need a human-object clip (field joint_level with "
                         f"an object pose); this clip has no object")
    rows = clip["joint_level"]
    L = rows.shape[0]
    if "contacts" in clip:
        every = np.zeros((L, 22), bool)
        c = np.asarray(clip["contacts"], bool)[:L]
        every[:len(c)] = c
        contacts = every[:, list(INTERACTION_JOINTS[:])]
    else:
        every = np.zeros((L, 22), bool)
        contacts = np.zeros((L, len(INTERACTION_JOINTS)), bool)
    return ClipItem(cid, rows, contacts, str(clip["object_name"]), captions, every)


def captioned_ids(store: Store, split: str) -> tuple[list[tuple[str, list[str]]], list[str]]:
    """([(clip id, its captions)] for the clips of ``split`` with captions, ids without)."""
    from ..evaluator.text import read_captions
    found, missing = [], []
    for cid in store.clip_ids(split):
        caps = read_captions(store.root, cid)
        texts = [c.text for c in caps] if caps else []
        if texts:
            found.append((cid, texts))
        else:
            missing.append(cid)
    return found, missing


def read_split(data: str | Path, split: str) -> tuple[Store, list[ClipItem], list[str]]:
    """(store, items with captions, ids without captions) of a split."""
    store = data if isinstance(data, Store) else Store(data)
    found, missing = captioned_ids(store, split)
    return store, [clip_item(store, cid, texts) for cid, texts in found], missing


def vertex_points(vertices: np.ndarray, n: int, seed_text: str) -> np.ndarray:
    """(n, 3) float32: ``n`` template vertices drawn without replacement (all of them, then
    repeats, when the mesh has fewer), seeded by ``seed_text`` -- ChainHOI released's
    PointNet++ input (its 512 sampled mesh vertices)."""
    v = np.asarray(vertices, np.float32)
    seed = int.from_bytes(hashlib.sha256(("vertices:" + seed_text).encode()).digest()[:8], "little")
    rng = np.random.default_rng(seed)
    if len(v) >= n:
        pick = np.sort(rng.choice(len(v), size=n, replace=False))
    else:
        pick = np.concatenate([np.arange(len(v)), rng.choice(len(v), size=n - len(v))])
    return v[pick]


def input_points(vertices: np.ndarray, faces: np.ndarray, n: int, name: str, source: str = "surface") -> np.ndarray:
    """The point-encoder input of a template: ``surface`` samples or mesh ``vertices``."""
    if source == "vertices":
        return vertex_points(vertices, n, name)
    return surface_points(vertices, faces, n, name)


def object_triangles(store: Store, names: set[str]) -> dict[str, np.ndarray]:
    """object -> (F, 3, 3) float32 triangles of its template (the frame the object pose maps from)."""
    out = {}
    for name in sorted(names):
        v, f = store.object_template(name)
        out[name] = np.asarray(v, np.float32)[np.asarray(f, np.int64)]
    return out


def stack_meshes(meshes: list[np.ndarray]) -> np.ndarray:
    """(B, F_max, 3, 3): triangle sets padded with copies of their first face (a copy never
    changes a nearest-face distance)."""
    F = max(len(m) for m in meshes)
    return np.stack([np.concatenate([m, np.repeat(m[:1], F - len(m), 0)]) for m in meshes])


def object_points(store: Store, names: set[str], n: int, source: str = "surface") -> dict[str, np.ndarray]:
    out = {}
    for name in sorted(names):
        v, f = store.object_template(name)
        out[name] = input_points(v, f, n, name, source)
    return out


def grouped_stats(clips: list[np.ndarray]) -> JointStats:
    """HumanML3D-style grouped statistics in the joint-level layout: the hoi269 rows of the
    clips get :func:`~hoibench.representations.normalization.compute_stats` (per-feature
    mean, std averaged within each feature group); the four global-root values (node 0,
    channels 7..10) and the zero padding keep mean 0, std 1 (left unnormalised)."""
    from ..representations import joint_level, normalization
    if not clips:
        raise ValueError("no train clips with joint_level rows: cannot compute normalisation statistics")
    st = normalization.compute_stats([joint_level.to_hoi269(c.reshape(-1, 24, 12)).astype(np.float64) for c in clips],
                                     "clean")
    mean = joint_level.from_hoi269(st.mean[None].astype(np.float64), global_root=np.zeros((1, 4)))[0]
    std = joint_level.from_hoi269(st.std[None].astype(np.float64), global_root=np.ones((1, 4)))[0]
    std = np.where(std == 0, 1.0, std)
    return JointStats(mean.astype(np.float32), std.astype(np.float32))
