"""Action-recognition feature network for multi-body motion: RA and FID (SyncDiff, paper 004
section 4.2: a network trained on ground-truth motion predicts the action label; RA is its
accuracy on generated motion, FID the Frechet distance of its features).

Input (per clip, :func:`clip_features`): the scene's bodies laid into fixed slots -- two
humans (22 joints), a left and a right hand (21 joints), two objects (translation + 6D
rotation) -- positions relative to the bodies' mean root on the floor plane at frame 0,
plus per-frame velocities and a slot-presence mask, resampled by time to
:data:`WINDOW` frames. Model: three 1D convolutions, mean over time, a 64-D feature layer
(the FID features) and a linear classifier.

``hoibench train-recognizer DATA --out DIR [--split train|all]``: the paper trains on all
splits (train + test); hoibench's protocol names the split (``train`` by default, so test
clips are never fitted) and the recognizer folder records which. Training is seeded and
single-threaded: the same store and seed give byte-identical weights.

Folder: ``recognizer.safetensors`` + ``recognizer.json`` (classes, input statistics, the
split, the store's manifest sha256, accuracy on the train and test ground truth, the
recognizer id = sha256 of both files' canonical content).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..bodies.multibody import MultiBodyClip

__all__ = ["WINDOW", "FEATURE_DIM", "VERSION", "clip_features", "train_recognizer", "load_recognizer", "Recognizer"]

VERSION = "multibody-recognizer-1.0"
WINDOW = 48
FEATURE_DIM = 64
#: a recognizer's weights are read up to this size (the shipped architecture needs about 1 MiB)
MAX_RECOGNIZER_BYTES = 64 * 1024 ** 2
_SLOTS = (("human", 0, 22), ("human", 1, 22), ("hand:left", 0, 21), ("hand:right", 0, 21), ("object", 0, 0),
          ("object", 1, 0))


def _slot_width(kind: str, n_joints: int) -> int:
    return 9 if kind == "object" else 3 * n_joints


IN_POS = sum(_slot_width(k, j) for k, _, j in _SLOTS)
IN_DIM = 2 * IN_POS + len(_SLOTS)


def clip_features(clip: MultiBodyClip) -> np.ndarray:
    """(WINDOW, IN_DIM) float32 input of one clip (see the module docstring)."""
    T = clip.num_frames
    roots = np.stack([b.root() for b in clip.bodies])              # (B, T, 3)
    origin = roots[:, 0].mean(0)
    origin[1] = 0.0
    groups = {"human": clip.of_kind("human"), "object": clip.of_kind("object"),
              "hand:left": [b for b in clip.of_kind("hand") if b.side == "left"],
              "hand:right": [b for b in clip.of_kind("hand") if b.side == "right"]}
    pos = np.zeros((T, IN_POS))
    mask = np.zeros(len(_SLOTS))
    col = 0
    for s, (kind, k, nj) in enumerate(_SLOTS):
        w = _slot_width(kind, nj)
        bodies = groups[kind]
        if k < len(bodies):
            b = bodies[k]
            mask[s] = 1.0
            if kind == "object":
                pos[:, col:col + 3] = b.trans - origin
                pos[:, col + 3:col + 9] = np.asarray(geo.matrix_to_rot6d(b.rot)).reshape(T, 6)
            else:
                pos[:, col:col + w] = (b.joints - origin).reshape(T, -1)
        col += w
    vel = np.gradient(pos, axis=0) * float(clip.fps)
    x = np.concatenate([pos, vel], 1)
    src = np.linspace(0.0, 1.0, T)
    dst = np.linspace(0.0, 1.0, WINDOW)
    out = np.stack([np.interp(dst, src, x[:, c]) for c in range(x.shape[1])], 1)
    return np.concatenate([out, np.repeat(mask[None], WINDOW, 0)], 1).astype(np.float32)


def _model(n_classes: int):
    import torch.nn as nn

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            self.conv = nn.Sequential(nn.Conv1d(IN_DIM, 128, 5, padding=2), nn.GELU(),
                                      nn.Conv1d(128, 128, 5, stride=2, padding=2), nn.GELU(),
                                      nn.Conv1d(128, 128, 5, stride=2, padding=2), nn.GELU())
            self.feature = nn.Linear(128, FEATURE_DIM)
            self.head = nn.Linear(FEATURE_DIM, n_classes)

        def features(self, x):               # x (N, WINDOW, IN_DIM), normalised
            h = self.conv(x.transpose(1, 2)).mean(-1)
            return self.feature(h)

        def forward(self, x):
            import torch
            return self.head(torch.relu(self.features(x)))

    return Net()


def _xz_columns() -> np.ndarray:
    """Column of the x component of every 3-vector of :func:`clip_features`' positions and
    velocities (joints; objects' translation and 6D rotation columns); z is 2 further."""
    starts, col = [], 0
    for kind, _, nj in _SLOTS:
        w = _slot_width(kind, nj)
        starts += list(range(col, col + w, 3))
        col += w
    return np.array(starts + [IN_POS + c for c in starts])


_XZ = _xz_columns()


def _yaw_augment(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Rotate every position/velocity triple of the slots about the vertical axis (objects:
    translation and the 6D rotation's two columns) by one random angle per clip."""
    out = x.copy()
    a = rng.uniform(-np.pi, np.pi, len(x))
    c, s = np.cos(a)[:, None, None], np.sin(a)[:, None, None]
    xs, zs = out[:, :, _XZ].copy(), out[:, :, _XZ + 2].copy()
    out[:, :, _XZ], out[:, :, _XZ + 2] = c * xs + s * zs, -s * xs + c * zs
    return out


class Recognizer:
    """A trained recognizer: :meth:`features` (N, 64) and :meth:`predict` (class names)."""

    def __init__(self, card: dict, state: dict):
        import torch
        self.card = card
        self.classes = list(card["classes"])
        self.mean = np.asarray(card["input_mean"], np.float32)
        self.std = np.asarray(card["input_std"], np.float32)
        self.net = _model(len(self.classes))
        self.net.load_state_dict({k: torch.as_tensor(v) for k, v in state.items()})
        self.net.eval()
        self.id = card.get("recognizer_id", "")

    def _forward(self, clips: list[MultiBodyClip]):
        import torch
        x = np.stack([clip_features(c) for c in clips]) if clips else np.zeros((0, WINDOW, IN_DIM), np.float32)
        x = (x - self.mean) / self.std
        with torch.no_grad():
            f = self.net.features(torch.from_numpy(x.astype(np.float32)))
            return f.numpy().astype(np.float64), self.net.head(torch.relu(f)).numpy()   # = net(x), features once

    def run(self, clips: list[MultiBodyClip]) -> tuple[np.ndarray, list[str]]:
        """Features (N, 64) and predicted action names of ``clips``, from one forward pass."""
        feats, logits = self._forward(clips)
        return feats, [self.classes[i] for i in logits.argmax(1)]

    def features(self, clips: list[MultiBodyClip]) -> np.ndarray:
        return self._forward(clips)[0]

    def embed(self, clips: list[MultiBodyClip]) -> np.ndarray:
        """The recognizer's embedding of ``clips`` (its (N, 64) features: what FID compares)."""
        return self.features(clips)

    def predict(self, clips: list[MultiBodyClip]) -> list[str]:
        return self.run(clips)[1]


def _labelled(store, split: str) -> tuple[list[MultiBodyClip], list[str]]:
    ids = store.clip_ids() if split == "all" else store.clip_ids(split)
    clips = [MultiBodyClip.from_arrays(store.load(c)) for c in ids]
    missing = [c.name for c in clips if not c.action]
    if missing:
        raise ValueError(f"{store.root}: clip {missing[0]}: no action label (the recognizer needs 'action')")
    return clips, [c.action for c in clips]


def train_recognizer(data, out, split: str = "train", steps: int = 400, seed: int = 0, batch: int = 32) -> dict:
    """Train on ``split`` ("train", or "all" = every split as the paper does) of a
    multi-body store; write the folder ``out``; return its card."""
    import torch
    from safetensors.torch import save

    from ..core.io import atomic_write_bytes, atomic_write_text
    from ..datasets.store import Store
    if split not in ("train", "all"):
        raise ValueError(f"--split: expected 'train' or 'all', got {split!r}")
    store = Store(data)
    clips, labels = _labelled(store, split)
    if len(clips) < 2:
        raise ValueError(f"{data}: {len(clips)} labelled clip(s) in split {split!r}: too few to train a recognizer")
    classes = sorted(set(labels))
    y = np.array([classes.index(a) for a in labels])
    X = np.stack([clip_features(c) for c in clips])
    mean = X.reshape(-1, IN_DIM).mean(0)
    std = X.reshape(-1, IN_DIM).std(0) + 1e-3
    saved = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        torch.manual_seed(seed)
        rng = np.random.default_rng(seed)
        net = _model(len(classes))
        opt = torch.optim.Adam(net.parameters(), lr=2e-3)
        lossf = torch.nn.CrossEntropyLoss()
        for _ in range(int(steps)):
            idx = rng.integers(0, len(X), min(batch, len(X)))
            xb = _yaw_augment(X[idx], rng)
            xb = xb + rng.normal(0.0, 0.01, xb.shape).astype(np.float32)
            xb = torch.from_numpy(((xb - mean) / std).astype(np.float32))
            loss = lossf(net(xb), torch.from_numpy(y[idx]))
            opt.zero_grad()
            loss.backward()
            opt.step()
        net.eval()
        state = {k: v.detach().clone().contiguous() for k, v in net.state_dict().items()}
    finally:
        torch.set_num_threads(saved)
    weights = save(state)
    card = {"version": VERSION, "classes": classes, "input_mean": mean.tolist(), "input_std": std.tolist(),
            "window": WINDOW, "feature_dim": FEATURE_DIM, "trained_on_split": split, "steps": int(steps),
            "seed": int(seed), "store": str(store.manifest.get("dataset", "")),
            "store_manifest_sha256": store.manifest_sha256(), "train_clips": len(clips)}
    rec = Recognizer(card, {k: v.numpy() for k, v in state.items()})
    acc = {}
    for s in ("train", "test"):
        ids = store.clip_ids(s)
        if ids:
            cl = [MultiBodyClip.from_arrays(store.load(c)) for c in ids]
            acc[s] = float(np.mean([p == c.action for p, c in zip(rec.predict(cl), cl)]))
    card["gt_accuracy"] = acc
    card["chance_accuracy"] = 1.0 / len(classes)
    card["recognizer_id"] = hashlib.sha256(weights + json.dumps(card, sort_keys=True).encode()).hexdigest()[:12]
    out = Path(out)
    atomic_write_bytes(out / "recognizer.safetensors", weights)
    atomic_write_text(out / "recognizer.json", json.dumps(card, indent=2, sort_keys=True) + "\n")
    return card


def load_recognizer(folder) -> Recognizer:
    """Read a recognizer folder, checking its id against its files."""
    from safetensors.numpy import load
    folder = Path(folder)
    cpath, wpath = folder / "recognizer.json", folder / "recognizer.safetensors"
    for p in (cpath, wpath):
        if not p.is_file():
            raise FileNotFoundError(f"{folder}: not a recognizer folder (missing {p.name}; "
                                    f"make one with `hoibench train-recognizer DATA --out {folder}`)")
    from ..core.io import MAX_SMALL_JSON_BYTES, read_json_file, read_regular_file
    card = read_json_file(cpath, MAX_SMALL_JSON_BYTES, "recognizer card")
    if not isinstance(card, dict):
        raise ValueError(f"{cpath}: expected a JSON object")
    weights = read_regular_file(wpath, MAX_RECOGNIZER_BYTES, "recognizer weights")
    body = {k: v for k, v in card.items() if k != "recognizer_id"}
    want = hashlib.sha256(weights + json.dumps(body, sort_keys=True).encode()).hexdigest()[:12]
    if card.get("recognizer_id") != want:
        raise ValueError(f"{folder}: recognizer_id {card.get('recognizer_id')!r} does not match its files "
                         f"({want}): the weights or the card were changed")
    try:
        state = load(weights)
    except Exception as exc:
        raise ValueError(f"{wpath}: not a readable safetensors file ({type(exc).__name__})") from None
    return Recognizer(card, state)
