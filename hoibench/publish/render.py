"""Off-screen rendering of human-object interaction clips (pyvista / VTK).

:func:`render_clip` renders a clip of a processed store (:class:`hoibench.datasets.store.Store`);
:func:`render_sequence` renders in-memory arrays (joints, an object, optional body
vertices), so any code can show what it holds.

Scene (metres, y-up): a grey checker floor at ``y = 0`` (0.5 m cells, 3 m beyond the
clip), the body surface (the license-free proxy body posed from the stored SMPL-H
``poses`` / ``trans`` / ``betas``) or a skeleton of tubes between the 22 joints, the
object mesh posed per frame (``v = R v_template + t``), and the joints in contact as red
spheres (with the body part each of them moves tinted red) when contact labels exist. A
label at the top left gives the title, frame index and time, so no two frames of a clip
are identical. The camera is fixed for the whole clip: it looks at the centre of the
clip's bounding box (all rendered frames: joints padded by the body's thickness, the
object, the floor under them) from the front-left of the body's facing at the first
rendered frame (35 degrees off the facing direction, 20 degrees above the horizon), y up,
far enough that the whole box fits the view.

Output format by the suffix of ``out_path``:

* ``.png`` -- one frame of ``size`` pixels: the middle one of the selected frames
  (``frames=[t]`` renders frame ``t``).
* ``.gif`` -- every selected frame; by default every ``k``-th frame of the clip with the
  smallest ``k`` that keeps the GIF at <= 60 frames, played in real time (``clip fps / k``).
* ``.mp4`` -- every selected frame (H.264); by default every frame, in real time. Needs
  ``imageio-ffmpeg`` (``pip install imageio-ffmpeg``). Frames are streamed to the encoder,
  and body and object are posed frame by frame, so long clips need little memory.

Files are written atomically (a temporary file in the target folder, then
``os.replace``). Needs ``pyvista`` and ``imageio`` (``pip install pyvista imageio``),
imported only when something is rendered, so ``import hoibench.publish.render`` stays cheap. No
display is needed: VTK renders off screen through EGL (or OSMesa); without ``DISPLAY``
the EGL window is chosen up front when ``libEGL`` is present (no X server, no Xvfb).
"""
from __future__ import annotations

import math
import os
import tempfile
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["render_clip", "render_sequence", "select_frames", "camera_pose", "MAX_GIF_FRAMES"]

#: Default cap on the number of frames in a GIF (every ``k``-th frame is kept).
MAX_GIF_FRAMES = 60
SUFFIXES = (".png", ".gif", ".mp4")

_BODY_COLOR = (0.62, 0.74, 0.86)
_SKELETON_COLOR = (0.20, 0.33, 0.55)
_OBJECT_COLOR = (0.85, 0.60, 0.30)
_CONTACT_COLOR = (0.90, 0.10, 0.10)
_FLOOR_COLORS = ((0.80, 0.80, 0.80), (0.62, 0.62, 0.62))
_FLOOR_CELL = 0.5
_FLOOR_MARGIN = 3.0
_BONE_RADIUS = 0.018
_JOINT_RADIUS = 0.028
_CONTACT_RADIUS = 0.05
_BODY_PAD = 0.3        # the body surface lies within this distance of its joints (head top, hands)
_CAMERA_AZIMUTH_DEG = 35.0
_CAMERA_ELEVATION_DEG = 20.0
_VIEW_ANGLE_DEG = 30.0
_BODY_CHUNK = 64       # frames posed at a time when body_vertices is a callable
# SMPL-H joints 22-36 are left-hand fingers, 37-51 right-hand fingers: tint with the wrist.
_SMPLH_TO_BODY = np.concatenate([np.arange(22), np.full(15, 20), np.full(15, 21)])


# --------------------------------------------------------------------------- imports
def _import_pyvista():
    if not os.environ.get("DISPLAY") and "VTK_DEFAULT_OPENGL_WINDOW" not in os.environ:
        import ctypes.util
        if ctypes.util.find_library("EGL"):
            # no X server: go straight to EGL instead of VTK's X attempt (and its warning)
            os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
    try:
        import pyvista as pv
    except ImportError as exc:
        raise ImportError("hoibench.publish.render needs pyvista (and imageio): pip install pyvista imageio") from exc
    pv.OFF_SCREEN = True
    return pv


def _import_imageio():
    try:
        import imageio.v2 as iio
    except ImportError as exc:
        raise ImportError("hoibench.publish.render needs imageio to write images: pip install imageio") from exc
    return iio


def _require_ffmpeg() -> None:
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError as exc:
        raise ImportError("writing .mp4 needs the ffmpeg plugin of imageio: pip install imageio-ffmpeg") from exc


# --------------------------------------------------------------------------- helpers
def select_frames(num_frames: int, frames=None, suffix: str = ".gif",
                  max_frames: int = MAX_GIF_FRAMES) -> tuple[np.ndarray, int]:
    """Frame indices to render and the stride they were taken with.

    ``frames``: None (the default for ``suffix``: ``.gif`` every ``k``-th frame with
    ``k = ceil(T / max_frames)``; ``.mp4`` every frame; ``.png`` the middle frame), an int
    stride, a slice, or a sequence of indices (negative ones count from the end). A
    ``.png`` renders the middle one of the selection. Returns ``(indices, stride)``; the
    stride (1 for explicit index lists) sets the default playback rate."""
    T = int(num_frames)
    if T < 1:
        raise ValueError("render: the clip has no frames")
    stride = 1
    if frames is None:
        if suffix == ".gif":
            stride = max(1, math.ceil(T / max_frames))
        idx = np.arange(0, T, stride)
    elif isinstance(frames, (int, np.integer)) and not isinstance(frames, bool):
        if frames < 1:
            raise ValueError(f"frames: a stride must be >= 1, got {frames}")
        stride = int(frames)
        idx = np.arange(0, T, stride)
    elif isinstance(frames, slice):
        idx = np.arange(T)[frames]
        stride = abs(frames.step or 1)
    else:
        idx = np.asarray(frames, dtype=np.int64).reshape(-1)
        if idx.size and (idx.min() < -T or idx.max() >= T):
            raise ValueError(f"frames: indices must lie in [-{T}, {T - 1}], got {idx.min()}..{idx.max()}")
        idx = np.where(idx < 0, idx + T, idx)
    if idx.size == 0:
        raise ValueError("frames: the selection is empty")
    if suffix == ".png":
        idx = idx[[len(idx) // 2]]
    return idx, stride


def _facing(joints0: np.ndarray) -> np.ndarray:
    """Horizontal unit facing direction of one (22, 3) pose (HumanML3D's definition)."""
    across = (joints0[2] - joints0[1]) + (joints0[17] - joints0[16])
    fwd = np.cross(np.array([0.0, 1.0, 0.0]), across)
    fwd[1] = 0.0
    n = np.linalg.norm(fwd)
    return fwd / n if np.isfinite(n) and n > 1e-8 else np.array([0.0, 0.0, 1.0])


def camera_pose(lo, hi, facing, size: tuple[int, int],
                view_angle: float = _VIEW_ANGLE_DEG) -> dict[str, Any]:
    """Fixed camera looking at the box ``[lo, hi]`` from the front-left of ``facing``
    (a horizontal direction), y up, distance chosen so the box's bounding sphere fits
    both the vertical and the horizontal field of view of a ``size = (w, h)`` image.
    Returns ``{"position", "focal_point", "up", "view_angle"}``."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.5)
    az, el = math.radians(_CAMERA_AZIMUTH_DEG), math.radians(_CAMERA_ELEVATION_DEG)
    up = np.array([0.0, 1.0, 0.0])
    f = np.asarray(facing, float)
    side = np.cross(up, f)  # the body's left
    direction = math.cos(el) * (math.cos(az) * f + math.sin(az) * side) + math.sin(el) * up
    w, h = size
    half_v = math.radians(view_angle) / 2
    half_h = math.atan(math.tan(half_v) * w / h)
    dist = 1.05 * radius / math.sin(min(half_v, half_h))
    return {"position": centre + dist * direction, "focal_point": centre, "up": up,
            "view_angle": float(view_angle)}


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (for smooth shading of meshes posed per frame)."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        for c in range(3):
            n[:, c] += np.bincount(f[:, k], weights=fn[:, c], minlength=len(v))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return n


class _Object:
    """Posed object vertices per frame, from (T, V, 3) or (template, rot, trans)."""

    def __init__(self, obj, T: int):
        if isinstance(obj, (tuple, list)):
            if len(obj) != 3:
                raise ValueError("obj: expected (T, V, 3) vertices or (template, rot, trans)")
            self.tmpl, self.rot, self.trans = (np.asarray(a, np.float64) for a in obj)
            if (self.tmpl.ndim != 2 or self.tmpl.shape[1] != 3 or self.rot.shape != (T, 3, 3)
                    or self.trans.shape != (T, 3)):
                raise ValueError(f"obj: expected template (V, 3), rot ({T}, 3, 3), trans ({T}, 3), got "
                                 f"{self.tmpl.shape}, {self.rot.shape}, {self.trans.shape}")
            self.verts = None
        else:
            self.verts = np.asarray(obj, np.float64)
            if self.verts.ndim != 3 or self.verts.shape[0] != T or self.verts.shape[2] != 3:
                raise ValueError(f"obj: expected ({T}, V, 3) vertices, got {self.verts.shape}")

    def at(self, t: int) -> np.ndarray:
        if self.verts is not None:
            return self.verts[t]
        return self.tmpl @ self.rot[t].T + self.trans[t]

    def bounds(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.verts is not None:
            v = self.verts[idx].reshape(-1, 3)
            return v.min(0), v.max(0)
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for s in range(0, len(idx), 64):  # chunks: long clips with big meshes stay small
            sel = idx[s:s + 64]
            v = np.einsum("tij,vj->tvi", self.rot[sel], self.tmpl) + self.trans[sel, None]
            lo, hi = np.minimum(lo, v.min((0, 1))), np.maximum(hi, v.max((0, 1)))
        return lo, hi


def _floor(pv, lo: np.ndarray, hi: np.ndarray):
    """Checker floor at y = 0 covering [lo, hi] in x and z plus 3 m, on a 0.5 m grid."""
    c, m = _FLOOR_CELL, _FLOOR_MARGIN
    x0, x1 = math.floor((lo[0] - m) / c) * c, math.ceil((hi[0] + m) / c) * c
    z0, z1 = math.floor((lo[2] - m) / c) * c, math.ceil((hi[2] + m) / c) * c
    nx, nz = max(1, round((x1 - x0) / c)), max(1, round((z1 - z0) / c))
    X, Z = np.meshgrid(np.linspace(x0, x1, nx + 1), np.linspace(z0, z1, nz + 1), indexing="ij")
    pts = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], 1)
    ij = np.arange(X.size).reshape(nx + 1, nz + 1)
    quads = np.stack([ij[:-1, :-1], ij[:-1, 1:], ij[1:, 1:], ij[1:, :-1]], -1).reshape(-1, 4)  # normal +y
    mesh = pv.PolyData.from_regular_faces(pts, quads)
    ii, kk = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    colors = np.array(_FLOOR_COLORS)[((ii + kk) % 2).ravel()]
    mesh.cell_data["rgb"] = (255 * colors).astype(np.uint8)
    return mesh


def _bones(pv, joints: np.ndarray):
    """Tubes along the 21 bones of a (22, 3) pose."""
    from ..core.skeleton import bone_edges

    edges = np.array(bone_edges())
    lines = pv.PolyData(joints.astype(np.float64))
    lines.lines = np.hstack([np.full((len(edges), 1), 2), edges]).ravel()
    return lines.tube(radius=_BONE_RADIUS, n_sides=10, capping=True)


def _spheres(pv, points: np.ndarray, radius: float, res: int = 14):
    return pv.PolyData(np.asarray(points, np.float64)).glyph(
        geom=pv.Sphere(radius=radius, theta_resolution=res, phi_resolution=res), scale=False, orient=False)


class _Sink:
    """Collects (.png, .gif) or streams (.mp4) frames into a temporary file in the target
    folder; :meth:`commit` moves it onto the target (``os.replace``)."""

    def __init__(self, out: Path, fps: float):
        self.iio = _import_imageio()
        self.out, self.suffix, self.fps = out, out.suffix.lower(), fps
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, self.tmp = tempfile.mkstemp(prefix=f".{out.stem}.", suffix=f".tmp{self.suffix}", dir=out.parent)
        os.close(fd)
        self.images: list[np.ndarray] = []
        self.writer = None
        self.count = 0
        if self.suffix == ".mp4":
            _require_ffmpeg()
            self.writer = self.iio.get_writer(self.tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                              quality=7, macro_block_size=2, pixelformat="yuv420p")

    def add(self, img: np.ndarray) -> None:
        self.count += 1
        if self.writer is not None:
            self.writer.append_data(img)
        else:
            self.images.append(img)

    def commit(self) -> Path:
        if self.suffix == ".png":
            self.iio.imwrite(self.tmp, self.images[0], format="PNG")
        elif self.suffix == ".gif":
            # Pillow's writer: duration in milliseconds per frame, loop forever
            self.iio.mimwrite(self.tmp, self.images, format="GIF", duration=1000.0 / self.fps, loop=0)
        else:
            self.writer.close()
            self.writer = None
        from ..core.io import current_umask
        os.chmod(self.tmp, 0o666 & ~current_umask())  # mkstemp makes 0600; give the usual permissions
        os.replace(self.tmp, self.out)
        return self.out

    def discard(self) -> None:
        if self.writer is not None:
            try:
                self.writer.close()
            except Exception:
                pass
        if os.path.exists(self.tmp):
            os.unlink(self.tmp)


class _Scene:
    """The meshes of one render: added to the plotter on the first frame, updated in place after."""

    def __init__(self, pv, plotter):
        self.pv, self.plotter = pv, plotter
        self.shade = dict(specular=0.2, ambient=0.15)
        self.body_mesh = self.skel_mesh = self.ball_mesh = self.obj_mesh = None
        self.contact_mesh = self.contact_actor = self.text = None

    def body(self, bv: np.ndarray, faces: np.ndarray, normals: np.ndarray, rgb: np.ndarray | None) -> None:
        """The body surface (V, 3) with its vertex normals; ``rgb``: per-vertex colours (contact tint) or None."""
        if self.body_mesh is None:
            self.body_mesh = self.pv.PolyData.from_regular_faces(bv.copy(), faces)
            self.body_mesh.point_data["Normals"] = normals
            self.body_mesh.point_data.active_normals_name = "Normals"
            if rgb is not None:
                self.body_mesh.point_data["rgb"] = rgb
                self.plotter.add_mesh(self.body_mesh, scalars="rgb", rgb=True, show_scalar_bar=False, **self.shade)
            else:
                self.plotter.add_mesh(self.body_mesh, color=_BODY_COLOR, **self.shade)
        else:
            self.body_mesh.points = bv
            self.body_mesh.point_data["Normals"] = normals
            self.body_mesh.point_data.active_normals_name = "Normals"
            if rgb is not None:
                self.body_mesh.point_data["rgb"][:] = rgb

    def skeleton(self, pose: np.ndarray) -> None:
        """Bones and joint spheres of a (22, 3) pose."""
        bones, balls = _bones(self.pv, pose), _spheres(self.pv, pose, _JOINT_RADIUS, res=12)
        if self.skel_mesh is None:
            self.skel_mesh, self.ball_mesh = bones, balls
            self.plotter.add_mesh(self.skel_mesh, color=_SKELETON_COLOR, **self.shade)
            self.plotter.add_mesh(self.ball_mesh, color=_SKELETON_COLOR, **self.shade)
        else:
            self.skel_mesh.copy_from(bones)
            self.ball_mesh.copy_from(balls)

    def object(self, ov: np.ndarray, faces: np.ndarray) -> None:
        """The posed object (V, 3), smooth-shaded."""
        if self.obj_mesh is None:
            self.obj_mesh = self.pv.PolyData.from_regular_faces(ov.copy(), faces)
            self.obj_mesh.point_data["Normals"] = _vertex_normals(ov, faces)
            self.obj_mesh.point_data.active_normals_name = "Normals"
            self.plotter.add_mesh(self.obj_mesh, color=_OBJECT_COLOR, **self.shade)
        else:
            self.obj_mesh.points = ov
            self.obj_mesh.point_data["Normals"] = _vertex_normals(ov, faces)
            self.obj_mesh.point_data.active_normals_name = "Normals"

    def contacts(self, pose: np.ndarray, on: np.ndarray) -> None:
        """Red spheres on the joints ``on`` of a (22, 3) pose (hidden when none)."""
        if self.contact_mesh is None:
            self.contact_mesh = _spheres(self.pv, pose[on[:1]] if len(on) else pose[:1], _CONTACT_RADIUS)
            self.contact_actor = self.plotter.add_mesh(self.contact_mesh, color=_CONTACT_COLOR, ambient=0.3)
        self.contact_actor.SetVisibility(bool(len(on)))
        if len(on):
            self.contact_mesh.copy_from(_spheres(self.pv, pose[on], _CONTACT_RADIUS))

    def label(self, msg: str) -> None:
        if self.text is None:
            self.text = self.plotter.add_text(msg, position="upper_left", font_size=10, color="black")
        elif hasattr(self.text, "SetInput"):
            self.text.SetInput(msg)
        else:  # vtkCornerAnnotation: corner 2 is the upper left
            self.text.SetText(2, msg)


def _check_body(body_vertices, body_faces, body_vertex_joint, contacts, T: int):
    """(frame indices -> (n, V, 3) vertices or None, faces, vertex joints 0-21 for the contact tint or None)."""
    body_fn = None
    if body_vertices is not None:
        if body_faces is None:
            raise ValueError("body_faces: required with body_vertices")
        body_faces = np.asarray(body_faces, np.int64)
        if callable(body_vertices):
            body_fn = body_vertices
        else:
            bv = np.asarray(body_vertices, np.float64)
            if bv.ndim != 3 or bv.shape[0] != T or bv.shape[2] != 3:
                raise ValueError(f"body_vertices: expected shape ({T}, V, 3), got {bv.shape}")
            body_fn = bv.__getitem__
    vjoint = None
    if body_fn is not None and body_vertex_joint is not None and contacts is not None:
        vj = np.asarray(body_vertex_joint, np.int64).reshape(-1)
        vjoint = _SMPLH_TO_BODY[vj] if vj.max() >= 22 else vj
    return body_fn, body_faces, vjoint


def _view_box(J: np.ndarray, idx: np.ndarray, objs: _Object | None, body: bool) -> tuple[np.ndarray, np.ndarray]:
    """The box the camera frames: joints ``J`` of the selected frames (padded by the body's
    thickness), the object, the floor."""
    ok = np.isfinite(J).all(-1)
    if not ok.any():
        raise ValueError("render: no finite joint positions in the selected frames")
    pad = _BODY_PAD if body else 0.05
    lo, hi = J[ok].min(0) - pad, J[ok].max(0) + pad
    if objs is not None:
        olo, ohi = objs.bounds(idx)
        if np.isfinite(olo).all() and np.isfinite(ohi).all():
            lo, hi = np.minimum(lo, olo), np.maximum(hi, ohi)
    lo[1] = min(lo[1], 0.0)
    return lo, hi


def _draw_frames(plotter, scene: _Scene, sink: _Sink, idx: np.ndarray, J: np.ndarray, cam: dict, body_fn,
                 body_faces, vjoint, objs: _Object | None, obj_faces, contacts, label_of) -> None:
    """Pose, draw and screenshot every selected frame into ``sink`` (the body posed
    ``_BODY_CHUNK`` frames at a time; ``label_of(t)``: the label text, or None)."""
    chunk_start, chunk = -1, None
    for k, t in enumerate(idx):
        if body_fn is not None:
            if chunk is None or k >= chunk_start + len(chunk):
                chunk_start = k
                chunk = np.asarray(body_fn(idx[k:k + _BODY_CHUNK]), np.float64)
                if chunk.ndim != 3 or chunk.shape[2] != 3 or len(chunk) != len(idx[k:k + _BODY_CHUNK]):
                    raise ValueError(f"body_vertices: expected ({len(idx[k:k + _BODY_CHUNK])}, V, 3) "
                                     f"vertices, got {chunk.shape}")
            bv = chunk[k - chunk_start]
            normals = _vertex_normals(bv, body_faces)
            rgb = None
            if vjoint is not None:
                if len(vjoint) != len(bv):
                    raise ValueError(f"body_vertex_joint: expected {len(bv)} entries, got {len(vjoint)}")
                hot = contacts[t][vjoint]
                rgb = (255 * np.where(hot[:, None], _CONTACT_COLOR, _BODY_COLOR)).astype(np.uint8)
            scene.body(bv, body_faces, normals, rgb)
        else:
            scene.skeleton(J[k])
        if objs is not None:
            scene.object(objs.at(t), obj_faces)
        if contacts is not None:
            scene.contacts(J[k], np.flatnonzero(contacts[t]))
        msg = label_of(t)
        if msg is not None:
            scene.label(msg)
        if k == 0:
            plotter.camera.position = tuple(cam["position"])
            plotter.camera.focal_point = tuple(cam["focal_point"])
            plotter.camera.up = tuple(cam["up"])
            plotter.camera.view_angle = cam["view_angle"]
        plotter.renderer.ResetCameraClippingRange()
        plotter.render()
        img = plotter.screenshot(return_img=True)
        sink.add(np.ascontiguousarray(img[..., :3]))


# --------------------------------------------------------------------------- rendering
def render_sequence(joints, obj=None, obj_faces=None, contacts=None, out_path="render.gif", *,
                    body_vertices: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None,
                    body_faces=None, body_vertex_joint=None, frames=None,
                    size: tuple[int, int] = (480, 360), fps: float | None = None,
                    clip_fps: float = 20.0, title: str = "", label: bool = True) -> Path:
    """Render in-memory HOI data to ``out_path`` (.png / .gif / .mp4; see the module docstring).

    Args:
        joints: (T, 22, 3) joint positions, metres, y-up (the floor at y = 0). Drawn as a
            skeleton of tubes when ``body_vertices`` is None; always used for the camera,
            the facing direction and the contact spheres.
        obj: None (no object), posed vertices (T, V, 3), or ``(template (V, 3),
            rot (T, 3, 3), trans (T, 3))`` with ``v = R v_template + t`` (posed per frame).
        obj_faces: (F, 3) triangle indices of the object (required with ``obj``).
        contacts: None or (T, 22) bool; joints in contact are drawn as red spheres.
        out_path: target file; its suffix picks the format.
        body_vertices: optional (T, V, 3) body surface (e.g. the proxy body posed from the
            clip's parameters), drawn instead of the skeleton, with ``body_faces`` (F, 3);
            or a callable mapping frame indices (n,) to (n, V, 3), called on chunks of the
            selection, so long clips are posed only where and when they are drawn.
        body_vertex_joint: optional (V,) joint (0-21, or SMPL-H 0-51) each body vertex
            moves with; the parts moved by joints in contact are then tinted red too.
        frames: see :func:`select_frames` (None: the default for the format).
        size: (width, height) in pixels.
        fps: playback rate; None = real time (``clip_fps / stride``).
        clip_fps: frame rate of the data, for the time label and the default ``fps``.
        title: text at the start of the label (e.g. the clip id).
        label: draw the ``title  frame t/T-1  time`` label at the top left.

    Returns:
        ``out_path`` as a :class:`~pathlib.Path`.
    """
    out = Path(out_path)
    suffix = out.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{out}: unsupported output format {out.suffix!r}; use one of {SUFFIXES}")
    if suffix == ".mp4":
        _require_ffmpeg()  # fail before spending time on rendering
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (22, 3):
        raise ValueError(f"joints: expected shape (T, 22, 3), got {joints.shape}")
    T = len(joints)
    w, h = (int(s) for s in size)
    if w < 16 or h < 16:
        raise ValueError(f"size: expected (width, height) of at least 16 pixels, got {size}")
    idx, stride = select_frames(T, frames, suffix)
    play_fps = float(fps) if fps is not None else float(clip_fps) / stride
    if not play_fps > 0:
        raise ValueError(f"fps: must be > 0, got {fps}")

    objs = None
    if obj is not None:
        if obj_faces is None:
            raise ValueError("obj_faces: required when an object is given")
        objs = _Object(obj, T)
        obj_faces = np.asarray(obj_faces, np.int64)
    if contacts is not None:
        contacts = np.asarray(contacts, bool)
        if contacts.shape != (T, 22):
            raise ValueError(f"contacts: expected shape ({T}, 22), got {contacts.shape}")
    body_fn, body_faces, vjoint = _check_body(body_vertices, body_faces, body_vertex_joint, contacts, T)

    J = joints[idx]
    lo, hi = _view_box(J, idx, objs, body_fn is not None)
    cam = camera_pose(lo, hi, _facing(J[0]), (w, h))

    def label_of(t) -> str | None:
        if not label:
            return None
        msg = f"{title}  " if title else ""
        return msg + f"frame {int(t)}/{T - 1}  {t / clip_fps:.2f} s"

    pv = _import_pyvista()
    sink = _Sink(out, play_fps)
    plotter = pv.Plotter(off_screen=True, window_size=[w, h])
    try:
        plotter.set_background("white")
        plotter.add_mesh(_floor(pv, lo, hi), scalars="rgb", rgb=True, show_scalar_bar=False,
                         ambient=0.3, diffuse=0.7)
        _draw_frames(plotter, _Scene(pv, plotter), sink, idx, J, cam, body_fn, body_faces, vjoint, objs, obj_faces,
                     contacts, label_of)
        plotter.close()
        return sink.commit()
    except BaseException:
        plotter.close()
        sink.discard()
        raise


def render_clip(store_root, clip_id: str, out_path, *, body: str = "proxy", frames=None,
                size: tuple[int, int] = (480, 360), fps: float | None = None) -> Path:
    """Render clip ``clip_id`` of the processed store at ``store_root`` (a path or a
    :class:`~hoibench.datasets.store.Store`) to ``out_path`` (.png / .gif / .mp4).

    ``body="proxy"`` draws the proxy body (:class:`hoibench.bodies.ProxyBody`) posed from
    the clip's ``poses`` / ``trans`` / ``betas`` (hands included for SMPL-H ``(T, 156)``
    poses; other layouts use their first 22 joints). It falls back to the skeleton, with a
    warning, when the clip has no body parameters or when the posed proxy's joints lie
    more than 0.15 m (mean over joints and up to 60 frames) from the stored ``joints``.
    ``body="skeleton"`` draws tubes between the stored joints. The object (if any) is the
    store's template posed by ``obj_rot`` / ``obj_trans``; stored ``contacts`` are shown
    as red spheres. ``frames``, ``size``, ``fps``: see :func:`render_sequence`.
    Returns ``out_path`` as a :class:`~pathlib.Path`.
    """
    from ..datasets.store import Store

    if body not in ("proxy", "skeleton"):
        raise ValueError(f"body: expected 'proxy' or 'skeleton', got {body!r}")
    suffix = Path(out_path).suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{out_path}: unsupported output format {Path(out_path).suffix!r}; use one of {SUFFIXES}")
    store = store_root if isinstance(store_root, Store) else Store(store_root)
    clip = store.load(clip_id)
    joints = np.asarray(clip["joints"], np.float64)
    clip_fps = float(clip["fps"]) if "fps" in clip else 20.0

    obj = faces = None
    if "obj_rot" in clip and "obj_trans" in clip and str(clip.get("object_name", "")):
        tmpl, faces = store.object_template(str(clip["object_name"]))
        obj = (tmpl, clip["obj_rot"], clip["obj_trans"])

    body_vertices = body_faces = vertex_joint = None
    if body == "proxy":
        if "poses" in clip and "trans" in clip:
            proxy = _ProxySurface(clip, joints, str(clip_id))
            if proxy.ok:
                body_vertices, body_faces, vertex_joint = proxy, proxy.faces, proxy.part_joint
        else:
            warnings.warn(f"{clip_id}: no body parameters stored; rendering the skeleton", stacklevel=2)
    return render_sequence(joints, obj, faces, clip.get("contacts"), out_path, body_vertices=body_vertices,
                           body_faces=body_faces, body_vertex_joint=vertex_joint, frames=frames,
                           size=size, fps=fps, clip_fps=clip_fps, title=str(clip_id))


class _ProxySurface:
    """Callable ``frame indices -> proxy body vertices`` for a stored clip; ``ok`` is False
    (after a warning) when the parameters do not fit the stored joints."""

    def __init__(self, clip: dict, joints: np.ndarray, clip_id: str):
        from ..bodies.proxy import ProxyBody

        T = len(joints)
        self.ok = False
        poses = np.asarray(clip["poses"], np.float64)
        self.trans = np.asarray(clip["trans"], np.float64)
        if poses.ndim != 2 or len(poses) != T or poses.shape[1] < 66 or self.trans.shape != (T, 3):
            warnings.warn(f"{clip_id}: body parameters (poses {poses.shape}, trans {self.trans.shape}) do not "
                          f"fit {T} frames; rendering the skeleton", stacklevel=4)
            return
        self.poses = poses if poses.shape[1] == 156 else poses[:, :66]
        betas = clip.get("betas")
        self.betas = None if betas is None else np.asarray(betas, np.float64)[..., :16]
        self.body = ProxyBody()
        self.faces, self.part_joint = self.body.faces, self.body.part_joint
        check = np.unique(np.linspace(0, T - 1, min(T, 60)).round().astype(np.int64))
        _, pj = self._forward(check)
        err = float(np.linalg.norm(pj - joints[check], axis=-1).mean())
        if not np.isfinite(err) or err > 0.15:
            warnings.warn(f"{clip_id}: the proxy body posed from the stored parameters is {err:.3f} m (mean per "
                          "joint) from the stored joints; rendering the skeleton", stacklevel=4)
            return
        self.ok = True

    def _forward(self, sel: np.ndarray):
        betas = self.betas
        if betas is not None and betas.ndim == 2 and len(betas) == len(self.poses):
            betas = betas[sel]
        return self.body.forward(self.poses[sel], self.trans[sel], betas)

    def __call__(self, sel: np.ndarray) -> np.ndarray:
        return self._forward(np.asarray(sel, np.int64))[0]


def render_comparison(submission, store_root, clip_id: str, out_path, *, sample: int = 0, frames=None,
                      size: tuple[int, int] = (420, 340), fps: float | None = None) -> Path:
    """A generated sample drawn beside its ground truth: ``out_path`` (.png / .gif) holds two
    panels per frame, the ground truth (left, with the clip's caption) and sample ``sample``
    of ``submission`` for the same id (right, with the submission's method), as skeletons
    with the object. Red spheres mark the joints in contact: stored labels on the left,
    labels computed from the generated joints and object pose (the annotator's signed
    distance thresholds, :func:`hoibench.bodies.contact.joint_contact_labels`) on the right. Frames
    beyond the shorter of the two are not drawn."""
    import tempfile

    from ..evaluator.text import read_captions
    from ..datasets.store import Store
    from ..scoring.submission import Submission
    suffix = Path(out_path).suffix.lower()
    if suffix not in (".png", ".gif"):
        raise ValueError(f"{out_path}: a comparison is written as .png or .gif, got {suffix!r}")
    store = store_root if isinstance(store_root, Store) else Store(store_root)
    gt = store.load(clip_id)
    with Submission(submission) as sub:
        if clip_id not in sub.ids:
            raise ValueError(f"{submission}: no sample for id {clip_id!r}")
        arrays = sub.load(clip_id)
        method = str((sub.meta or {}).get("method", "submission"))
    for key, value in arrays.items():
        bad = np.flatnonzero(~np.isfinite(np.asarray(value, np.float64)).reshape(len(value), -1).all(-1)) \
            if np.asarray(value).dtype.kind in "fc" and len(value) else []
        if len(bad):
            raise ValueError(f"{submission}: samples/{clip_id}.npz: {key}: non-finite values (NaN or inf) in sample "
                             f"{int(bad[0])}: not drawn (hoibench validate lists every problem)")
    joints = np.asarray(arrays["joints"], np.float64)
    if not 0 <= sample < len(joints):
        raise ValueError(f"--sample: {sample} out of range: {submission} has {len(joints)} sample(s) for {clip_id}")
    gen = joints[sample]
    T = min(len(gen), len(gt["joints"]))
    clip_fps = float(gt["fps"]) if "fps" in gt else 20.0
    caps = read_captions(store.root, clip_id) or []
    caption = caps[0].text if caps else ""
    caption = caption if len(caption) <= 58 else caption[:55] + "..."
    obj_gt = obj_gen = faces = None
    gen_contacts = None
    if "obj_rot" in gt and str(gt.get("object_name", "")):
        tmpl, faces = store.object_template(str(gt["object_name"]))
        obj_gt = (tmpl, gt["obj_rot"][:T], gt["obj_trans"][:T])
        if "obj_trans" in arrays:
            rot = arrays.get("obj_rot")
            if rot is None:
                from ..core.geometry import axis_angle_to_matrix
                rot = axis_angle_to_matrix(np.asarray(arrays["obj_rotvec"], np.float64))
            rot, trans = np.asarray(rot, np.float64)[sample][:T], np.asarray(arrays["obj_trans"], np.float64)[sample][:T]
            obj_gen = (tmpl, rot, trans)
            from ..bodies.contact import joint_contact_labels
            gen_contacts = joint_contact_labels(gen[:T], tmpl, faces, rot, trans, str(gt["object_name"]))[0]
    legend = "red: joints in contact"
    with tempfile.TemporaryDirectory() as tmp:
        left = render_sequence(gt["joints"][:T], obj_gt, faces, gt.get("contacts"),
                               Path(tmp) / f"gt{suffix}", frames=frames, size=size, fps=fps, clip_fps=clip_fps,
                               title=f"GT: {caption}")
        right = render_sequence(gen[:T], obj_gen, faces, gen_contacts, Path(tmp) / f"gen{suffix}", frames=frames,
                                size=size, fps=fps, clip_fps=clip_fps, title=f"{method[:40]} ({legend})")
        iio = _import_imageio()
        a, b = iio.mimread(left) if suffix == ".gif" else [iio.imread(left)], \
            iio.mimread(right) if suffix == ".gif" else [iio.imread(right)]
        both = [np.concatenate([x[..., :3], y[..., :3]], 1) for x, y in zip(a, b)]
        out = Path(out_path)
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp_out = Path(tmp) / f"both{suffix}"
        if suffix == ".gif":
            n = len(both)
            duration = 1.0 / (fps or clip_fps * n / max(T, 1))
            iio.mimsave(tmp_out, both, duration=duration, loop=0)
        else:
            iio.imwrite(tmp_out, both[0])
        from ..core.io import atomic_write_bytes
        return atomic_write_bytes(out, tmp_out.read_bytes())  # read-ok: our own file in our own temporary folder
