"""Physical metrics over a set of clips: per-clip pure units, mapped by an executor, pooled by
a mergeable metric.

Per clip (:func:`clip_physical_stats`, a pure function of one :class:`ClipInput` and the
:class:`PhysicalConfig`, so serial, process-pool and Dask runs agree bit for bit):

========================== ============================================= ======= ==========
output                     definition (module)                           units   better
========================== ============================================= ======= ==========
``cd``                     contact distance (contact_metrics)            m^2     lower
``ocd``                    CD minimised over the semantic group          m^2     lower
``ps``                     penetrating body-surface vertex-frames        frac.   lower
``penetration_depth_max_m`` deepest penetration of a frame (max -d)      m       lower
``penetration_depth_mean_m`` mean over penetrating frames of that depth  m       lower
``fsr``                    ChainHOI foot skating ratio (motion)          frac.   lower
``fsr_gmd``                GMD / HOI-Diff velocity-based skating ratio   frac.   lower
``contact_iou``            joint contact labels vs ground truth          frac.   higher
``hand_contact_ratio``     frames with a wrist in contact                frac.   ~ real
``object_floating_ratio``  object off the floor and untouched            frac.   lower
``jitter_mps3``            mean jerk magnitude                           m/s^3   lower
========================== ============================================= ======= ==========

Pooling (:class:`PhysicalMetrics`): counts are summed over clips (PS, FSR, IoU, ratios,
jitter: ratio of sums, as ChainHOI pools PS and FSR); ``fsr_gmd`` averages per-clip ratios
(GMD); CD and OCD average per-clip values -- ``legacy`` divides by *every* clip, those
without ground-truth contact contributing 0 (ChainHOI's ``contact_distance.mean() /
count_seq``), ``clean`` averages over the clips that have contact.

Body surface for PS, penetration depth and object floating: the proxy body fitted to the
joints (:mod:`hoibench.metrics.body_surface`), labelled ``"proxy (joint fit)"``, or a
user callable named ``"module:function"``. ``legacy`` mode also reproduces ChainHOI's PS
quirk of lowering the body (not the object) so that its lowest joint is at y = 0 before
fitting the surface (``floor_shift``). ChainHOI's other released rules (OCD members, wrists,
GT labels, the FSR frame, evaluated lengths) are settings of :class:`PhysicalConfig`
(:mod:`hoibench.metrics.legacy_rules`); a clip with ``windows`` gives one set of statistics
per replication (:func:`clip_window_stats`, :func:`evaluate_physical_windows`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..core import skeleton as sk
from ..bodies.contact import body_scale, joint_thresholds
from ..bodies.distance import signed_distance_field, to_template_frame
from ..bodies.reference_distance import closest_face_field
from ..core.parallel import map_units
from ..core.registry import load_object
from . import METRICS
from . import contact_metrics as cm
from . import legacy_rules as lr
from . import motion as mo
from .body_surface import PROXY_LABEL, PROXY_VERTICES, proxy_template_points, proxy_vertices_from_joints
from .state import Metric, sorted_items

MODES: tuple[str, ...] = ("legacy", "clean")
#: PS sign rules: hoibench's inside test over all object parts, or ChainHOI's (torchsdf: the
#: closest face's normal, first face on ties; :mod:`hoibench.bodies.reference_distance`)
PS_SIGNS: tuple[str, ...] = ("inside", "closest_face")
#: joint distances of CD/OCD: hoibench's exact ones, or ChainHOI's point-to-triangle functions
#: with the edge quirk (BEHAVE's, OMOMO's numerics)
CD_EDGES: tuple[str, ...] = ("exact", "reference", "reference-omomo")
#: what a legacy result says beside PS: the released evaluation never computes it
LEGACY_PS_NOTE = (
    "ps: ChainHOI's released evaluation does not compute PS -- the PeneMetric calls are commented "
    "out (src/models/chainhoi_behave.py:398 update, :331 compute; chainhoi_omomo.py:440, :363; "
    "commit 4990160), so its published PS came from code not released; hoibench's legacy PS "
    "follows PeneMetric.update as released (compute.py:1141-1198: torchsdf sign of the closest "
    "face, mesh as loaded) on the proxy body instead of SMPLify.")

#: names of the physical metrics (metadata: :data:`hoibench.metrics.METRICS`)
PHYSICAL_OUTPUTS: tuple[str, ...] = tuple(n for n, i in METRICS.items() if i.kind == "physical")


@dataclass(frozen=True)
class PhysicalConfig:
    """Settings of the physical metrics (a protocol fixes them; see docs/metrics.md).

    ``mode``: ``legacy`` (ChainHOI's FSR on x only, its CD/OCD averaging and PS floor shift)
    or ``clean``. ``contact_mode``: thresholds of the predicted contact labels (contact IoU,
    hand contact ratio), :func:`hoibench.bodies.contact.joint_thresholds` modes ``chainhoi`` or
    ``surface``. ``body_surface``: ``"proxy"`` or ``"module:function"`` mapping joints
    (T, 22, 3) to vertices (T, V, 3). ``ocd_members`` ... ``length_crop``: ChainHOI's rules
    (:mod:`hoibench.metrics.legacy_rules`; defaults: hoibench's clean rules);
    ``fsr_canonical_mode``: the hml263 mode of ``fsr_frame="canonical"`` (HOI-Diff's, as ChainHOI).
    ``ps_sign``, ``cd_edge``, ``mesh_repair`` (legacy protocols set the ChainHOI values; the
    defaults are hoibench's): the PS sign rule (:data:`PS_SIGNS`), the joint distances of
    CD/OCD (:data:`CD_EDGES`; contact IoU and the hand ratio keep hoibench's), and whether the
    object mesh is repaired before any distance.
    """

    mode: str = "clean"
    contact_mode: str = "chainhoi"
    body_surface: str = "proxy"
    ocd_length_tolerance: int = cm.OCD_LENGTH_TOLERANCE_FRAMES
    fsr_height_m: float = mo.FSR_HEIGHT_M
    fsr_displacement_m: float = mo.FSR_DISPLACEMENT_M
    gmd_height_m: float = mo.GMD_HEIGHT_M
    gmd_speed_mps: float = mo.GMD_SPEED_MPS
    gmd_window_frames: int = mo.GMD_WINDOW_FRAMES
    vertex_contact_m: float = cm.VERTEX_CONTACT_M
    floor_tolerance_m: float = cm.FLOOR_TOLERANCE_M
    floor_shift: bool | None = None          # None: True in legacy mode, False in clean
    inside_test: str = "auto"
    # ChainHOI's rules (legacy_rules.PHYSICAL_OPTIONS; the defaults are the clean rules)
    ocd_members: str = "tolerance"
    contact_joints: str = "all"
    contact_gt_rule: str = "signed"
    contact_gt_threshold_m: float | None = None
    fsr_frame: str = "world"
    fsr_feet_to_floor: bool = False
    length_crop: str = "none"
    fsr_canonical_mode: str = "legacy-hoidiff"
    ps_sign: str = "inside"                  # PS_SIGNS; "closest_face": ChainHOI (torchsdf)
    cd_edge: str = "exact"                   # CD_EDGES; "reference*": ChainHOI's edge quirk
    mesh_repair: bool = True                 # False: the object mesh as loaded (ChainHOI)

    def __post_init__(self):
        for name in lr.PHYSICAL_OPTIONS:
            lr.check_option(name, getattr(self, name))
        for name, allowed in (("ps_sign", PS_SIGNS), ("cd_edge", CD_EDGES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name}: expected one of {allowed}, got {getattr(self, name)!r}")
        thr = self.contact_gt_threshold_m
        if thr is not None and not thr > 0:
            raise ValueError(f"contact_gt_threshold_m: expected a positive threshold, got {thr!r}")
        if self.fsr_canonical_mode not in lr.CANONICAL_MODES:
            raise ValueError(f"fsr_canonical_mode: expected one of {lr.CANONICAL_MODES}, "
                             f"got {self.fsr_canonical_mode!r}")
        if self.mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {self.mode!r}")
        if self.contact_mode not in ("chainhoi", "surface"):
            raise ValueError(f"contact_mode: expected 'chainhoi' or 'surface', got {self.contact_mode!r}")
        if self.body_surface != "proxy" and ":" not in self.body_surface:
            raise ValueError(f"body_surface: expected 'proxy' or 'module:function', got {self.body_surface!r}")

    @property
    def shift_to_floor(self) -> bool:
        return self.mode == "legacy" if self.floor_shift is None else bool(self.floor_shift)

    @property
    def body_label(self) -> str:
        return PROXY_LABEL if self.body_surface == "proxy" else self.body_surface

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(eq=False)
class ClipInput:
    """One generated clip with what its metrics need (all arrays; picklable).

    ``key``: unique key, e.g. ``(test id, sample index)``; ``joints`` (T, 22, 3) metres,
    y-up; ``obj_rot`` (T, 3, 3), ``obj_trans`` (T, 3) (``v = R v_template + t``); the object
    template (V, 3), (F, 3) and name (for contact thresholds); ``gt_contacts`` (T', 22) the
    ground truth of the test id (None: CD, OCD and IoU undefined); ``group_contacts``: GT maps
    of the other clips of its semantic group (OCD); ``windows``: ``((replication, start,
    length), ...)`` when a legacy length crop applies (:func:`clip_window_stats`).
    ``gt_joints``, ``gt_obj_rot``, ``gt_obj_trans``: the test clip's own ground truth (same
    frames and axes), filled only for metrics that compare with it (catalogue
    ``needs_ground_truth``).
    """

    key: Any
    joints: np.ndarray
    fps: float
    obj_rot: np.ndarray | None = None
    obj_trans: np.ndarray | None = None
    object_name: str = ""
    template_vertices: np.ndarray | None = None
    template_faces: np.ndarray | None = None
    gt_contacts: np.ndarray | None = None
    group_contacts: tuple = field(default_factory=tuple)
    windows: tuple = ()
    gt_joints: np.ndarray | None = None
    gt_obj_rot: np.ndarray | None = None
    gt_obj_trans: np.ndarray | None = None


_SPEC: dict = {}


def _threshold_spec() -> dict | None:
    """The contact-threshold spec, read once per process while the file is unchanged (size and
    mtime); None when it is missing (:func:`joint_thresholds` then names the path)."""
    from ..bodies.contact import CONTACT_THRESHOLDS_FILE, annotators_dir, load_contact_thresholds
    p = annotators_dir() / CONTACT_THRESHOLDS_FILE
    try:
        st = p.stat()
    except OSError:
        return None
    key = (str(p), st.st_mtime_ns, st.st_size)
    if key not in _SPEC:
        _SPEC.clear()
        _SPEC[key] = load_contact_thresholds(p)
    return _SPEC[key]


def _body_fn(config: PhysicalConfig) -> Callable:
    if config.body_surface == "proxy":
        return proxy_vertices_from_joints
    return load_object(config.body_surface)


def clip_physical_stats(inp: ClipInput, config: PhysicalConfig = PhysicalConfig(), extra: Sequence = (),
                        objects: bool = True) -> dict:
    """Sufficient statistics of every physical metric for one clip (pure; see the module);
    ``extra``: ``((name, settings), ...)`` of catalogue metrics with a per-clip function
    (``clip_fn``), each one value (:func:`extra_clip_values`). ``objects=False``: the object
    metrics (CD, OCD, PS, penetration, contact, floating) are not computed (a protocol that
    lists none of them): the clip's statistics are those of a clip without an object."""
    st = _core_stats(inp, config, objects)
    if extra:
        st["extra"] = extra_clip_values(inp, extra)
    return st


def extra_clip_values(inp: ClipInput, extra: Sequence) -> dict[str, float]:
    """``{name: value}`` for catalogue metrics defined by a per-clip function
    (:attr:`hoibench.metrics.catalog.MetricInfo.clip_fn`, called once per function with the
    protocol's settings; ``extra``: ``((name, settings), ...)``); NaN where a clip has no value."""
    from .catalog import get_metric_info
    calls: dict[str, tuple[dict, list[str]]] = {}
    for name, settings in extra:
        info = get_metric_info(name)
        if not info.clip_fn:
            raise ValueError(f"metric {name!r}: the catalogue gives it no per-clip function (clip_fn)")
        calls.setdefault(info.clip_fn, (dict(settings or {}), []))[1].append(name)
    out = {}
    for fn, (settings, names) in sorted(calls.items()):
        got = load_object(fn)(inp, settings)
        for name in names:
            v = got.get(name, float("nan")) if isinstance(got, Mapping) else got
            out[name] = float(v)
    return out


def _core_stats(inp: ClipInput, config: PhysicalConfig, objects: bool = True) -> dict:
    J = np.asarray(inp.joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (sk.NUM_JOINTS, 3):
        raise ValueError(f"{inp.key}: joints: expected shape (T, 22, 3), got {J.shape}")
    fps = float(inp.fps)
    st: dict[str, Any] = {"frames": len(J)}
    st["fsr_skating"], st["fsr_ground"] = mo.foot_skating_counts(
        lr.fsr_joints(J, fps, config.fsr_frame, config.fsr_feet_to_floor, config.fsr_canonical_mode),
        fps, config.mode, config.fsr_height_m, config.fsr_displacement_m)
    st["gmd_skating"], st["gmd_frames"] = mo.gmd_skating_counts(
        J, fps, config.gmd_height_m, config.gmd_speed_mps, config.gmd_window_frames)
    st["jerk_sum"], st["jerk_count"] = mo.jitter_sums(J, fps)
    if not objects or inp.template_vertices is None or inp.obj_rot is None:
        st["has_object"] = False
        return st
    st["has_object"] = True
    R = np.asarray(inp.obj_rot, dtype=np.float64)
    t = np.asarray(inp.obj_trans, dtype=np.float64)
    field_ = signed_distance_field(inp.template_vertices, inp.template_faces, inside_test=config.inside_test,
                                   **({} if config.mesh_repair else {"repair": False}))
    st["inside_test"] = field_.inside_test
    scale = body_scale(J)
    tau = joint_thresholds(inp.object_name, config.contact_mode, scale=scale, thresholds=_threshold_spec())
    own = group = None
    needed = None            # joint-frames whose exact distance CD and OCD read: any GT map's contacts
    if inp.gt_contacts is not None:
        own = lr.select_joints(inp.gt_contacts, config.contact_joints)
        group = tuple(lr.select_joints(g, config.contact_joints) for g in inp.group_contacts)
        if config.cd_edge == "exact":
            needed = np.zeros(J.shape[:2], bool)
            for m in (own, *group):
                n = min(len(J), len(m))
                needed[:n] |= m[:n]
    d, pred = cm.joint_contacts(J, R, t, field_, tau, needed)
    if own is not None:
        d_cd = d if config.cd_edge == "exact" else \
            cm.reference_joint_distances(J, field_.vertices, field_.faces, R, t, config.cd_edge)
        st["cd_sum"], st["cd_count"] = cm.contact_distance_sums(d_cd, own)
        st["ocd"] = cm.optimal_contact_distance(d_cd, own, group, config.ocd_length_tolerance, config.ocd_members)
    if inp.gt_contacts is not None:
        st["iou_inter"], st["iou_union"] = cm.contact_iou_counts(pred, inp.gt_contacts)
    st["hand_frames"], _ = cm.hand_contact_frames(pred)
    # body surface: PS and penetration depth (on the floor-shifted body in legacy mode, as
    # ChainHOI), body contact for object floating (always on the body as given)
    shift = float(J[..., 1].min()) if config.shift_to_floor else 0.0
    body = _body_fn(config)
    neg = total = n_pen = 0
    depth_max = depth_sum = 0.0
    touching = np.zeros(len(J), bool)
    # parts farther than the margin from the object cannot touch it (< vertex_contact_m)
    margin = config.vertex_contact_m + 0.005

    def _vertices(joints, sl):
        n = sl.stop - sl.start
        verts = np.asarray(body(joints[sl]), dtype=np.float64)
        if verts.ndim != 3 or verts.shape[0] != n or verts.shape[2] != 3 or not np.isfinite(verts).all():
            raise ValueError(f"{inp.key}: body_surface {config.body_surface}: expected finite vertices "
                             f"({n}, V, 3) for {n} frames, got shape {verts.shape}")
        return verts

    def surface(joints, sl, **what):
        if config.body_surface == "proxy":
            index, points = proxy_template_points(joints, sl, field_, R, t, margin,
                                                  scale if joints is J else None)
            return cm.surface_frames(field_, points, index, (sl.stop - sl.start, PROXY_VERTICES),
                                     config.vertex_contact_m, **what)
        return cm.surface_frames(field_, to_template_frame(_vertices(joints, sl), R[sl], t[sl]),
                                 contact_m=config.vertex_contact_m, **what)

    closest = None if config.ps_sign == "inside" else closest_face_field(field_.vertices, field_.faces)
    chunk = 256
    for s in range(0, len(J), chunk):
        sl = slice(s, min(len(J), s + chunk))
        if shift or closest is not None:
            touching[sl] = surface(J, sl, penetration=False).touching
            Js = J - np.array([0.0, shift, 0.0])
            sf = surface(Js, sl, touching=False) if closest is None else cm.closest_face_frames(
                closest, to_template_frame(_vertices(Js, sl), R[sl], t[sl]))
        else:
            sf = surface(J, sl)
            touching[sl] = sf.touching
        neg, total = neg + int(sf.penetrating.sum()), total + sf.penetrating.size * sf.vertices
        mx, sm, n = cm.frame_depth_stats(sf.depth, sf.penetrating > 0)
        n_pen, depth_max, depth_sum = n_pen + n, max(depth_max, mx), depth_sum + sm
    st.update(ps_neg=neg, ps_total=total, depth_max=depth_max, depth_sum=depth_sum, depth_count=n_pen)
    low = cm.object_lowest_point(inp.template_vertices, R, t)
    st["float_frames"], _ = cm.floating_frames(low, touching, config.floor_tolerance_m)
    return st


def window_input(inp: ClipInput, start: int, length: int) -> ClipInput:
    """``inp`` seen through the window ``[start, start + length)``: the generated arrays and
    the GT labels are cut to it (a generated clip that ends before ``start + 2`` is read from
    frame 0), group members lose their first ``start`` frames (ChainHOI reads every member
    from the evaluated clip's offset: compute.py:625, ``label[idx:idx + L]``)."""
    T = len(inp.joints)
    s = start if T >= start + 2 else 0
    cut = lambda a, s0=s: None if a is None else np.asarray(a)[s0:s0 + length]  # noqa: E731
    return replace(inp, joints=cut(inp.joints), obj_rot=cut(inp.obj_rot), obj_trans=cut(inp.obj_trans),
                   gt_contacts=cut(inp.gt_contacts, start),
                   group_contacts=tuple(np.asarray(g)[start:] for g in inp.group_contacts), windows=())


def clip_window_stats(inp: ClipInput, config: PhysicalConfig = PhysicalConfig(),
                      extra: Sequence = (), objects: bool = True) -> dict[int, dict]:
    """``{replication: stats}``: :func:`clip_physical_stats` of each window of
    ``inp.windows`` (:func:`window_input`); a window drawn twice is computed once."""
    done: dict[tuple[int, int], dict] = {}
    out = {}
    for r, start, length in inp.windows:
        if (start, length) not in done:
            done[(start, length)] = clip_physical_stats(window_input(inp, start, length), config, extra, objects)
        out[int(r)] = done[(start, length)]
    return out


def warm_fields(root: str, names: Sequence[str], config: PhysicalConfig = PhysicalConfig()) -> int:
    """Build, in this process, the signed-distance fields (mesh checks and bounds grid) the
    physical units will ask for: the templates ``names`` of the store at ``root``, with the
    options :func:`_core_stats` uses (same bytes, so the same cache entries). Run on each pool
    worker while the main process embeds the ground truth and validates the submission
    (:func:`hoibench.core.parallel.warm_executor`); returns how many fields were built."""
    from ..datasets.store import Store
    store = Store(root)
    built = 0
    for name in names:
        v, f = store.object_template(name)
        field_ = signed_distance_field(v, f, inside_test=config.inside_test,
                                       **({} if config.mesh_repair else {"repair": False}))
        field_._grid()
        built += 1
    return built


def _unit(inp: ClipInput, config: PhysicalConfig, extra: Sequence = (), objects: bool = True) -> tuple:
    """``(key, stats)``; with windows ``(key, {"replications": {r: stats}})``."""
    if inp.windows:
        return inp.key, {"replications": clip_window_stats(inp, config, extra, objects)}
    return inp.key, clip_physical_stats(inp, config, extra, objects)


def _ratio(a, b) -> float:
    return float(a / b) if b else float("nan")


class PhysicalMetrics(Metric):
    """Pools per-clip statistics (``reduce="keyed"`` by clip key) into the physical metrics.

    ``update(key, stats)`` adds one clip's :func:`clip_physical_stats`; ``compute()`` returns
    ``{name: value}`` for every name in :data:`PHYSICAL_OUTPUTS` plus ``clips``,
    ``clips_with_contact`` and ``body_surface`` (the label). Sums run in sorted key order.
    """

    name = "physical"

    def __init__(self, mode: str = "clean", body_label: str = PROXY_LABEL):
        super().__init__()
        if mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
        self.mode, self.body_label = mode, body_label
        self.add_state("clips", {}, "keyed")

    def config(self) -> dict:
        return {"mode": self.mode, "body_label": self.body_label}

    def update(self, key, stats: Mapping[str, Any]) -> None:
        if key in self.clips:
            raise ValueError(f"key: clip {key!r} was already added")
        self.clips[key] = dict(stats)

    def per_clip(self) -> dict:
        """Per-clip values ``{key: {cd, ocd, ps, fsr, fsr_gmd, jitter_mps3, ...}}``."""
        out = {}
        for k, s in sorted_items(self.clips):
            row = {"fsr": _ratio(s["fsr_skating"], s["fsr_ground"]),
                   "fsr_gmd": _ratio(s["gmd_skating"], s["gmd_frames"]),
                   "jitter_mps3": _ratio(s["jerk_sum"], s["jerk_count"])}
            if s.get("has_object"):
                row.update(cd=_ratio(s.get("cd_sum", 0.0), s.get("cd_count", 0)),
                           ocd=float(s.get("ocd", float("nan"))),
                           ps=_ratio(s["ps_neg"], s["ps_total"]),
                           penetration_depth_max_m=s["depth_max"],
                           penetration_depth_mean_m=(_ratio(s.get("depth_sum", 0.0), s["depth_count"])
                                                     if s.get("depth_count") else 0.0),
                           contact_iou=_ratio(s.get("iou_inter", 0), s.get("iou_union", 0)),
                           hand_contact_ratio=_ratio(s["hand_frames"], s["frames"]),
                           object_floating_ratio=_ratio(s["float_frames"], s["frames"]))
            row.update(s.get("extra", {}))
            out[k] = row
        return out

    def compute(self) -> dict:
        if not self.clips:
            raise ValueError("PhysicalMetrics: no clips were added")
        items = [s for _, s in sorted_items(self.clips)]
        obj = [s for s in items if s.get("has_object")]
        tot = lambda key, rows=items: sum(s.get(key, 0) for s in rows)  # noqa: E731
        cds = [s["cd_sum"] / s["cd_count"] for s in obj if s.get("cd_count", 0)]
        ocds = [s["ocd"] for s in obj if "ocd" in s and not np.isnan(s["ocd"])]
        n_gt = sum(1 for s in obj if "cd_count" in s)
        if self.mode == "legacy":      # ChainHOI: sum over clips with contact / all clips
            cd = _ratio(sum(cds), n_gt)
            ocd = _ratio(sum(ocds), n_gt)
        else:
            cd = _ratio(sum(cds), len(cds))
            ocd = _ratio(sum(ocds), len(ocds))
        gmd = [_ratio(s["gmd_skating"], s["gmd_frames"]) for s in items if s["gmd_frames"]]
        out = {
            "cd": cd, "ocd": ocd,
            "ps": _ratio(tot("ps_neg", obj), tot("ps_total", obj)),
            "penetration_depth_max_m": max((s["depth_max"] for s in obj), default=float("nan")),
            "penetration_depth_mean_m": (_ratio(tot("depth_sum", obj), tot("depth_count", obj))
                                         if tot("depth_count", obj) else (0.0 if obj else float("nan"))),
            "fsr": _ratio(tot("fsr_skating"), tot("fsr_ground")),
            "fsr_gmd": _ratio(sum(gmd), len(gmd)),
            "contact_iou": _ratio(tot("iou_inter", obj), tot("iou_union", obj)),
            "hand_contact_ratio": _ratio(tot("hand_frames", obj), tot("frames", obj)),
            "object_floating_ratio": _ratio(tot("float_frames", obj), tot("frames", obj)),
            "jitter_mps3": _ratio(tot("jerk_sum"), tot("jerk_count")),
            "clips": len(items), "clips_with_contact": len(cds), "body_surface": self.body_label,
        }
        for name in sorted({n for s in items for n in s.get("extra", {})}):     # mean over clips with a value
            vals = [s["extra"][name] for s in items if np.isfinite(s.get("extra", {}).get(name, np.nan))]
            out[name] = _ratio(sum(vals), len(vals))
        return out


def evaluate_physical(inputs: Sequence[ClipInput], config: PhysicalConfig = PhysicalConfig(),
                      executor: str = "serial", progress: str | None = None) -> PhysicalMetrics:
    """Map :func:`clip_physical_stats` over ``inputs`` on ``executor`` (``serial``,
    ``processes[:N]``, ``dask://...``; :mod:`hoibench.core.parallel`) and pool the results."""
    inputs = list(inputs)
    if any(inp.windows for inp in inputs):
        raise ValueError("inputs: clips with length windows give one value per replication: "
                         "use evaluate_physical_windows")
    metric = PhysicalMetrics(config.mode, config.body_label)
    for key, stats in map_units(partial(_unit, config=config), inputs, executor, progress=progress):
        metric.update(key, stats)
    return metric


def evaluate_physical_windows(inputs: Sequence[ClipInput], config: PhysicalConfig = PhysicalConfig(),
                              executor: str = "serial", progress: str | None = None) -> dict[int, PhysicalMetrics]:
    """``{replication: PhysicalMetrics}`` for clips with length windows (``ClipInput.windows``,
    :func:`hoibench.metrics.legacy_rules.replication_windows`): :func:`clip_window_stats`
    mapped on ``executor``, each replication pooled over the clips."""
    inputs = list(inputs)
    if not all(inp.windows for inp in inputs):
        raise ValueError("inputs: every clip needs its windows (legacy_rules.replication_windows)")
    out: dict[int, PhysicalMetrics] = {}
    for key, stats in map_units(partial(_unit, config=config), inputs, executor, progress=progress):
        for r, st in stats["replications"].items():
            out.setdefault(r, PhysicalMetrics(config.mode, config.body_label)).update(key, st)
    return dict(sorted(out.items()))


# ===================================================================== from a store
def load_groups(data) -> dict[str, list[str]] | None:
    """Semantic groups ``{group id: [clip ids]}`` from ``DATA/annotations/index.json``
    (written by ``hoibench annotate``), or None when the store is not annotated."""
    p = Path(data) / "annotations" / "index.json"
    if not p.is_file():
        return None
    from ..core.io import read_json_file
    index = read_json_file(p, what="annotation index")
    groups = index.get("groups", {}) if isinstance(index, dict) else None
    if not isinstance(groups, dict) or not all(isinstance(v, list) for v in groups.values()):
        raise ValueError(f"{p}: groups: expected an object {{group id: [clip ids]}}")
    return {g: list(ids) for g, ids in groups.items()}


def gt_contact_labels(store, clip: Mapping[str, np.ndarray], mode: str = "chainhoi", rule: str = "signed",
                      threshold_m: float | None = None) -> np.ndarray | None:
    """Ground-truth joint contact labels (T, 22) of a store clip; None without object.

    ``rule="signed"`` without ``threshold_m`` (clean): its stored ``contacts``, else
    :func:`hoibench.bodies.contact.joint_contact_labels` (``d < tau``, ``mode`` thresholds).
    Otherwise (ChainHOI's rule, whose labels always come from distances) from the signed
    distances d of the clip's joints, stored labels ignored: :func:`legacy_rules.gt_labels`
    (``unsigned``: ``|d| <= tau``) with ``tau = threshold_m`` or the ``mode`` thresholds."""
    reference = rule != "signed" or threshold_m is not None
    if "contacts" in clip and not reference:
        return np.asarray(clip["contacts"], dtype=bool)
    if "obj_rot" not in clip:
        return None if "contacts" not in clip else np.asarray(clip["contacts"], dtype=bool)
    from ..bodies.contact import joint_contact_labels, joint_thresholds
    name = str(clip["object_name"])
    v, f = store.object_template(name)
    labels, d = joint_contact_labels(clip["joints"], v, f, clip["obj_rot"], clip["obj_trans"], name, mode=mode)
    if not reference:
        return labels
    tau = threshold_m if threshold_m is not None else joint_thresholds(name, mode, joints=clip["joints"])
    return lr.gt_labels(d, tau, rule)


def _rotation(m: Mapping[str, np.ndarray]) -> np.ndarray | None:
    if "obj_rot" in m:
        return np.asarray(m["obj_rot"])
    if "obj_rotvec" in m:
        from ..core.geometry import axis_angle_to_matrix
        return axis_angle_to_matrix(np.asarray(m["obj_rotvec"], dtype=np.float64))
    return None


#: the arrays of a store clip that its ground-truth labels and object name come from
_GT_KEYS = ("contacts", "joints", "obj_rot", "obj_trans", "object_name")
#: what stored labels alone need (:func:`gt_contact_labels` without a reference rule)
_LABEL_KEYS = ("contacts", "object_name")


def clip_input_factory(store, ids: Sequence[str], groups: Mapping[str, Sequence[str]] | None = None,
                       contact_mode: str = "chainhoi", fps: float | None = None, gt_rule: str = "signed",
                       gt_threshold_m: float | None = None, ground_truth: bool = False,
                       window: int | None = None) -> Callable[..., ClipInput]:
    """A function ``make(cid, motion, sample=None) -> ClipInput`` for generated motions of
    the test ids ``ids``, one at a time (what streaming evaluation needs): the test clip's
    object, GT contacts and its group members' GT contacts (only members among ``ids``
    count: ChainHOI compares within the evaluated set) come from ``store``; GT contacts and
    templates are cached. ``motion``: ``{"joints" (T, 22, 3), "obj_rot" (T, 3, 3) or
    "obj_rotvec" (T, 3), "obj_trans" (T, 3)}``; ``sample`` goes into the key ``(id, sample)``.
    ``gt_rule``, ``gt_threshold_m``: how GT labels are made (:func:`gt_contact_labels`).
    ``ground_truth``: also fill the ``gt_*`` arrays from the test clip; ``window``: keep the
    first ``window`` frames of the motion, its GT labels and GT arrays (a protocol's
    ``clip_window``)."""
    fps = float(store.manifest["config"]["fps"]) if fps is None else float(fps)
    evaluated = set(ids)
    member_of: dict[str, list[str]] = {}
    for members in (groups or {}).values():
        for cid in members:
            member_of[cid] = [m for m in members if m != cid and m in evaluated]
    cache: dict[str, Any] = {}
    templates: dict[str, tuple] = {}
    names: dict[str, str] = {}

    last: dict[str, dict] = {}                     # the last clip read (its K samples and labels share it)
    # only what the labels and ground-truth fields read (not the representations): stored
    # labels alone unless they are measured or the ground truth's arrays are asked for
    keys = _GT_KEYS if ground_truth or gt_rule != "signed" or gt_threshold_m is not None else _LABEL_KEYS

    def load(cid: str) -> dict:
        if cid not in last:
            last.clear()
            got = store.load(cid, keys=keys)
            last[cid] = got if "contacts" in got or keys is _GT_KEYS else store.load(cid, keys=_GT_KEYS)
        return last[cid]

    def gt(cid):
        if cid not in cache:
            clip = load(cid)
            cache[cid] = gt_contact_labels(store, clip, contact_mode, gt_rule, gt_threshold_m)
            names[cid] = str(clip["object_name"]) if "object_name" in clip else ""
        return cache[cid]

    def truth(cid: str) -> dict:
        clip = load(cid)
        return {"gt_joints": clip["joints"], "gt_obj_rot": clip.get("obj_rot"), "gt_obj_trans": clip.get("obj_trans")}

    def cut(a):
        return a if a is None or window is None else a[:window]

    def make(cid: str, motion: Mapping[str, np.ndarray], sample: int | None = None) -> ClipInput:
        own = gt(cid)
        extra = {k: cut(None if a is None else np.asarray(a)) for k, a in truth(cid).items()} if ground_truth else {}
        name = names[cid]
        if name and name not in templates:
            templates[name] = store.object_template(name)
        v, f = templates.get(name, (None, None))
        group = tuple(g for g in (gt(x) for x in member_of.get(cid, [])) if g is not None)
        return ClipInput(
            key=(cid, sample) if sample is not None else cid,
            joints=cut(np.asarray(motion["joints"])), fps=fps,
            obj_rot=cut(_rotation(motion)),
            obj_trans=None if "obj_trans" not in motion else cut(np.asarray(motion["obj_trans"])),
            object_name=name, template_vertices=v, template_faces=f,
            gt_contacts=cut(own), group_contacts=group, **extra)

    return make


def clip_inputs(store, motions: Mapping[str, Mapping[str, np.ndarray]], sample: int | None = None,
                groups: Mapping[str, Sequence[str]] | None = None, contact_mode: str = "chainhoi",
                fps: float | None = None, gt_rule: str = "signed",
                gt_threshold_m: float | None = None) -> list[ClipInput]:
    """:class:`ClipInput` per generated motion (test id -> one sample's arrays), in sorted id
    order: :func:`clip_input_factory` over every id of ``motions``."""
    make = clip_input_factory(store, list(motions), groups, contact_mode, fps, gt_rule, gt_threshold_m)
    return [make(cid, motions[cid], sample) for cid in sorted(motions)]


__all__ = ["PHYSICAL_OUTPUTS", "PS_SIGNS", "CD_EDGES", "LEGACY_PS_NOTE", "PhysicalConfig",
           "ClipInput", "clip_physical_stats", "PhysicalMetrics", "window_input", "clip_window_stats",
           "evaluate_physical_windows",
           "evaluate_physical", "load_groups", "gt_contact_labels", "clip_inputs", "clip_input_factory"]
