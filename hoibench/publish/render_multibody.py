"""Draw a multi-body clip: a PNG strip of frames (pyvista, off-screen) with every skeleton as
the capsules the metrics measure (:mod:`hoibench.bodies.capsules`) and every object as its
template; skeletons in contact with an object in that frame (the clip's contact frames) are
drawn red."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..bodies.multibody import MultiBodyClip
from ..bodies.capsules import segments

__all__ = ["render_multibody"]

_SKELETON = (0.35, 0.45, 0.75)
_HOT = (0.85, 0.2, 0.2)
_OBJECT = (0.85, 0.65, 0.3)


def render_multibody(clip: MultiBodyClip, out_path, frames: int = 4, size: tuple[int, int] = (360, 320)) -> Path:
    """``frames`` evenly spaced frames of ``clip`` side by side in ``out_path`` (.png)."""
    from .render import _import_pyvista, camera_pose
    out = Path(out_path)
    if out.suffix.lower() != ".png":
        raise ValueError(f"{out}: the multi-body render writes .png")
    pv = _import_pyvista()
    T = clip.num_frames
    idx = np.unique(np.linspace(0, T - 1, max(1, int(frames))).round().astype(int))
    pts = [b.joints.reshape(-1, 3) if b.joints is not None else b.trans for b in clip.bodies]
    allp = np.concatenate(pts)
    pad = 0.15 if clip.of_kind("human") else 0.03
    lo, hi = allp.min(0) - pad, allp.max(0) + pad
    roots = np.stack([b.root()[0] for b in clip.bodies])
    facing = np.array([0.0, 0.0, 1.0]) if len(roots) < 2 else np.cross(roots[-1] - roots[0], [0.0, 1.0, 0.0])
    if np.linalg.norm(facing) < 1e-6:
        facing = np.array([0.0, 0.0, 1.0])
    cam = camera_pose(lo, hi, facing / np.linalg.norm(facing), size)
    touching = {}
    for (a, _), f in clip.contacts.items():
        touching[a] = touching.get(a, np.zeros(T, bool)) | np.asarray(f, bool)
    plotter = pv.Plotter(off_screen=True, shape=(1, len(idx)), window_size=[size[0] * len(idx), size[1]])
    try:
        for col, t in enumerate(idx):
            plotter.subplot(0, col)
            plotter.set_background("white")
            for b in clip.bodies:
                if b.is_rigid:
                    v, f = clip.templates[b.template]
                    posed = np.asarray(v, np.float64) @ b.rot[t].T + b.trans[t]
                    plotter.add_mesh(pv.PolyData.from_regular_faces(posed, np.asarray(f)), color=_OBJECT,
                                     smooth_shading=False)
                    continue
                a, c, r = segments(b.joints[t:t + 1], b.kind)
                color = _HOT if touching.get(b.name, np.zeros(T, bool))[t] else _SKELETON
                for s in range(len(r)):
                    line = pv.Line(a[0, s], c[0, s])
                    plotter.add_mesh(line.tube(radius=float(r[s]), n_sides=12, capping=True), color=color)
                    plotter.add_mesh(pv.Sphere(radius=float(r[s]), center=c[0, s], theta_resolution=10,
                                               phi_resolution=10), color=color)
            plotter.add_text(f"{clip.name}  frame {int(t)}" if col == 0 else f"frame {int(t)}",
                             position="upper_left", font_size=8, color="black")
            plotter.camera.position = tuple(cam["position"])
            plotter.camera.focal_point = tuple(cam["focal_point"])
            plotter.camera.up = tuple(cam["up"])
        out.parent.mkdir(parents=True, exist_ok=True)
        plotter.screenshot(str(out))
    finally:
        plotter.close()
    return out
