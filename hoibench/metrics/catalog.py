"""The metric catalogue: the one place that says what every reported number is.

Each :class:`MetricInfo` gives a metric's name, kind, unit, direction, display group,
column title and format, whether it has a per-clip column and which end of that column is
a failure, the paper column it reproduces, its thresholds, a one-line summary and the
implementation (a lazy ``"module:attr"`` reference). Scorers, result files, per-clip
tables, ``format_result``, leaderboard pages and CSV, ``compare`` and the Codabench bundle
read it; no other module defines metric metadata (``tests/test_metric_catalog.py``).

Directions: ``higher`` (higher is better), ``lower``, ``gt`` (best when closest to the
ground truth's value, e.g. Diversity). Adding a metric is one :func:`register` call here
plus its implementation module.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

DIRECTIONS = ("higher", "lower", "gt")
#: display groups, in the order a result prints them
GROUPS = ("semantic", "physical", "extras", "counts", "reported", "clip")
ARROWS = {"higher": "↑", "lower": "↓", "gt": "≈GT"}
#: the scorers that compute a metric of each kind (``scorers`` of an entry overrides it)
_SCORERS_OF_KIND = {"embedding": ("hoi",), "physical": ("hoi",), "multibody": ("multibody",)}


@dataclass(frozen=True)
class MetricInfo:
    """What a reported metric (or a per-clip column) is.

    ``kind``: ``embedding`` | ``physical`` | ``multibody`` | ``task`` (a metric of InterAct's
    object-to-human or human-to-object task, per selected sample) | ``count`` (a count the scorer
    reports beside the metrics) | ``reported`` (only in rows copied from papers) | ``clip``
    (a per-clip column that is no metric of the whole split). ``per_clip``: the metric has a
    column in a result's per-clip table; ``failure_end``: ``high`` or ``low``, the end of that
    column ``render --worst`` shows first (None: not sortable). ``needs_object``: undefined
    ("not applicable") when the scored clips have no object. ``digits``: decimals shown in
    tables (five under 0.01). ``scorers``: the scorers that compute it (a protocol of that
    scorer may list it; default by kind). ``clip_fn``: for a physical metric that is no
    part of :func:`hoibench.metrics.physical.clip_physical_stats`, the ``"module:attr"`` of a
    function ``(ClipInput) -> float`` giving one clip's value (NaN: undefined); the scorer
    computes it per clip when the protocol lists it and reports the mean over clips. A new
    metric of this kind is one entry plus its function: nothing else changes. ``set_level``:
    a value of the whole set of clips (a distance between distributions or pairs), with no
    per-clip values to average.

    A per-clip function is called as ``clip_fn(inp, settings)``: ``settings`` is the
    protocol's mapping named ``settings_key`` (a top-level protocol key such as ``physics``;
    ``{}`` when the entry names none), checked when the protocol is parsed by the
    ``settings_check`` function (``"module:attr"``, ``(mapping, where) -> None``). It returns
    one number, or ``{name: number}`` for several entries that share the function (computed
    once per clip). ``requires``: a module the function needs (an optional extra); when it
    cannot be imported the metric is "not computed: <install_hint>", never zero.
    ``needs_ground_truth``: the function compares the clip with its test clip's ground truth
    (the scorer then fills ClipInput's ``gt_*`` fields). ``multibody_fn``: the same for the
    ``multibody`` scorer, ``(MultiBodyClip, settings) -> number | {name: number}``, called on
    every generated sample and on the ground truth of every test clip."""

    name: str
    kind: str
    direction: str
    unit: str
    group: str
    summary: str
    thresholds: str = ""
    paper_column: str | None = None
    impl: str = ""
    short: str = ""
    digits: int = 3
    per_clip: bool = False
    failure_end: str | None = None
    needs_object: bool = False
    scorers: tuple[str, ...] = ()
    clip_fn: str = ""
    set_level: bool = False
    settings_key: str = ""
    settings_check: str = ""
    requires: str = ""
    install_hint: str = ""
    needs_ground_truth: bool = False
    multibody_fn: str = ""

    def __post_init__(self):
        if not self.scorers and self.kind in _SCORERS_OF_KIND:
            object.__setattr__(self, "scorers", _SCORERS_OF_KIND[self.kind])
        if self.direction not in DIRECTIONS:
            raise ValueError(f"metric {self.name}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if self.group not in GROUPS:
            raise ValueError(f"metric {self.name}: group {self.group!r} is not one of {GROUPS}")
        if self.failure_end not in (None, "high", "low"):
            raise ValueError(f"metric {self.name}: failure_end {self.failure_end!r} is not 'high', 'low' or None")

    @property
    def higher_is_better(self) -> bool | None:
        """True / False, or None when best is the ground truth's value."""
        return {"higher": True, "lower": False, "gt": None}[self.direction]

    @property
    def arrow(self) -> str:
        return ARROWS[self.direction]

    @property
    def title(self) -> str:
        """The column title of tables (``short``, else the name)."""
        return self.short or self.name

    @property
    def units(self) -> str:
        return self.unit

    def load(self):
        """Import and return the implementation named by ``impl``."""
        from ..core.registry import load_object
        return load_object(self.impl)

    def to_dict(self) -> dict:
        return asdict(self)


METRICS: dict[str, MetricInfo] = {}


def register(info: MetricInfo) -> MetricInfo:
    """Add a metric to :data:`METRICS` (``ValueError`` if the name is taken)."""
    if info.name in METRICS:
        raise ValueError(f"metric {info.name!r} is already registered")
    METRICS[info.name] = info
    return info


def get_metric_info(name: str) -> MetricInfo:
    try:
        return METRICS[name]
    except KeyError:
        raise KeyError(f"unknown metric {name!r}; known: {', '.join(sorted(METRICS))}") from None


def metric_names(*kinds: str, group: str | None = None) -> tuple[str, ...]:
    """The registered names of the given kinds (all result metrics when none), in
    registration order, optionally of one display group."""
    want = kinds or ("embedding", "physical", "multibody")
    return tuple(n for n, i in METRICS.items() if i.kind in want and (group is None or i.group == group))


def metrics_for(scorer: str) -> tuple[str, ...]:
    """The metrics a protocol of ``scorer`` (``hoi``, ``multibody``) may list, in
    registration order."""
    return tuple(n for n, i in METRICS.items() if scorer in i.scorers)


def settings_keys() -> tuple[str, ...]:
    """The optional top-level protocol keys that metrics read their settings from."""
    return tuple(sorted({i.settings_key for i in METRICS.values() if i.settings_key}))


def check_settings(key: str, mapping, where: str) -> None:
    """Check a protocol's ``key`` mapping with the check its metrics name (ValueError naming
    ``where`` and the field)."""
    if not isinstance(mapping, dict):
        raise ValueError(f"{where}: field '{key}' must be a mapping, got {type(mapping).__name__}")
    from ..core.registry import load_object
    for check in sorted({i.settings_check for i in METRICS.values() if i.settings_key == key and i.settings_check}):
        load_object(check)(mapping, f"{where}: {key}")


def unavailable(name: str) -> str | None:
    """Why metric ``name`` cannot be computed here ("not computed: ..."), or None."""
    info = METRICS[name]
    if not info.requires:
        return None
    import importlib.util
    if importlib.util.find_spec(info.requires) is None:
        return f"not computed: {info.install_hint or f'install {info.requires}'}"
    return None


def object_metrics() -> tuple[str, ...]:
    """The metrics that need an object ("not applicable" on human-only clips)."""
    return tuple(n for n, i in METRICS.items() if i.needs_object)


#: a negative FID above this is the sqrtm numerics' rounding below zero (FID is a squared
#: distance): shown as 0, the JSON keeps the raw value. One rule for every track.
FID_ROUNDING = 1e-2


def shown_value(name: str, mean: float) -> float:
    """A metric's mean as displayed: a tiny negative FID (:data:`FID_ROUNDING`) shows as 0."""
    return 0.0 if name == "fid" and -FID_ROUNDING < mean < 0 else mean


_E = "hoibench.metrics.embedding"
_C = "hoibench.metrics.contact_metrics"
_M = "hoibench.metrics.motion"
_MB = "hoibench.metrics.multibody"
_EMB = "embedding distance"

for _k in (1, 2, 3):
    register(MetricInfo(f"r_precision_top{_k}", "embedding", "higher", "fraction", "semantic",
                        f"text i retrieves its own motion among the {_k} nearest of its pool",
                        "pools of 32 (protocol), drop the incomplete last pool", f"R Precision Top {_k}",
                        f"{_E}:r_precision", short=f"R@{_k}"))
register(MetricInfo("fid", "embedding", "lower", "squared embedding distance", "semantic",
                    "Frechet distance between real and generated motion embeddings", "sqrtm retried with 1e-6 on the diagonal; |imag| <= 1e-3 dropped", "FID",
                    f"{_E}:fid", short="FID", scorers=("hoi", "multibody"), set_level=True))
register(MetricInfo("mm_dist", "embedding", "lower", _EMB, "semantic", "mean distance between a text and its motion",
                    "pools as R-precision", "MM Dist", f"{_E}:mm_dist", short="MM-Dist", per_clip=True,
                    failure_end="high"))
register(MetricInfo("diversity", "embedding", "gt", _EMB, "semantic", "mean distance between random pairs of motions",
                    "300 pairs (200 on BEHAVE)", "Diversity", f"{_E}:diversity", short="Diversity", set_level=True))
register(MetricInfo("multimodality", "embedding", "higher", _EMB, "semantic",
                    "mean distance between samples of one text", "100 texts x 30 samples x 10 pairs",
                    "MultiModality", f"{_E}:multimodality", short="MModality", set_level=True))
register(MetricInfo("cd", "physical", "lower", "m^2", "physical",
                    "mean squared signed distance of the 22 joints to the object where GT touches",
                    "mask: ground-truth joint contact labels", "CD (ChainHOI)", f"{_C}:contact_distance", short="CD",
                    per_clip=True, failure_end="high", needs_object=True))
register(MetricInfo("ocd", "physical", "lower", "m^2", "physical",
                    "CD minimised over the contact maps of the clip's semantic group",
                    "group members within +-8 frames of the generated length", "OCD (ChainHOI)",
                    f"{_C}:optimal_contact_distance", short="OCD", per_clip=True, failure_end="high",
                    needs_object=True))
register(MetricInfo("ps", "physical", "lower", "fraction", "physical",
                    "penetrating body-surface vertex-frames / all vertex-frames (proxy body by default)",
                    "vertex penetrates when its signed distance < 0", "PS (ChainHOI)", f"{_C}:penetration_counts",
                    short="PS", per_clip=True, failure_end="high", needs_object=True))
register(MetricInfo("fsr", "physical", "lower", "fraction", "physical",
                    "skating foot-frames / ground-contact foot-frames",
                    "feet 10, 11; height < 0.05 m at t+1; step > 0.025 m (legacy: |dx|; clean: xz, 0.5 m/s)",
                    "FSR (ChainHOI)", f"{_M}:foot_skating_counts", short="FSR", per_clip=True, failure_end="high"))
register(MetricInfo("penetration_depth_max_m", "physical", "lower", "m", "extras",
                    "deepest penetration of any frame (max over vertices of -d)", "signed distance < 0",
                    impl=f"{_C}:penetration_depth_stats", per_clip=True, failure_end="high", needs_object=True))
register(MetricInfo("penetration_depth_mean_m", "physical", "lower", "m", "extras",
                    "mean over penetrating frames of the frame's deepest penetration", "signed distance < 0",
                    impl=f"{_C}:penetration_depth_stats", per_clip=True, failure_end="high", needs_object=True))
register(MetricInfo("fsr_gmd", "physical", "lower", "fraction", "extras",
                    "skating frames / (T - 1) per clip, averaged over clips",
                    "feet 10, 11; height < 0.05 m at t and t+1; xz speed and its 5-frame mean > 0.5 m/s",
                    "Foot skating ratio (GMD, HOI-Diff)", f"{_M}:gmd_skating_counts", per_clip=True,
                    failure_end="high"))
register(MetricInfo("contact_iou", "physical", "higher", "fraction", "extras",
                    "IoU of generated vs ground-truth joint contact labels",
                    "predicted label: d < per-object threshold (protocol contact mode)",
                    impl=f"{_C}:contact_iou_counts", per_clip=True, failure_end="low", needs_object=True))
register(MetricInfo("hand_contact_ratio", "physical", "gt", "fraction", "extras", "frames where a hand touches the object",
                    "wrist 20/21 label on (protocol contact mode)", impl=f"{_C}:hand_contact_frames", per_clip=True,
                    needs_object=True))
register(MetricInfo("object_floating_ratio", "physical", "lower", "fraction", "extras",
                    "frames where the object is off the floor and untouched",
                    "lowest object point > 0.02 m, no body vertex within 0.02 m", impl=f"{_C}:floating_frames",
                    per_clip=True, failure_end="high", needs_object=True))
register(MetricInfo("jitter_mps3", "physical", "lower", "m/s^3", "extras", "mean jerk magnitude of the joints",
                    "third finite difference x fps^3", impl=f"{_M}:jitter_sums", per_clip=True, failure_end="high"))
# multi-body tracks (SyncDiff, paper 004 section 4.2; docs/multibody_metrics.md)
register(MetricInfo("csr", "multibody", "gt", "fraction", "physical",
                    "frames where a hand touches an object, mean over hands then clips",
                    "hand surface within 5 mm of an object", "CSR (SyncDiff)", f"{_MB}:CSR", short="CSR"))
register(MetricInfo("crr", "multibody", "gt", "fraction", "physical",
                    "frames where a human holds an object with both hands",
                    "both hand roots within 5 cm of one object", "CRR (SyncDiff)", f"{_MB}:CRR", short="CRR"))
register(MetricInfo("csiou", "multibody", "higher", "fraction", "physical",
                    "IoU of generated vs ground-truth contact frames", "contact frames by the CSR/CRR rules",
                    "CSIoU (SyncDiff)", f"{_MB}:CSIoU", short="CSIoU"))
register(MetricInfo("iv_cm3", "multibody", "lower", "cm^3", "physical",
                    "interpenetration volume per frame, summed over body pairs", "5 mm voxels inside both bodies",
                    "IV (SyncDiff)", f"{_MB}:interpenetration_volume", short="IV"))
register(MetricInfo("id_mm", "multibody", "lower", "mm", "physical",
                    "interpenetration depth per frame, summed over body pairs", "deepest probe inside the other body",
                    "ID (SyncDiff)", f"{_MB}:interpenetration_depth", short="ID"))
register(MetricInfo("sd", "multibody", "higher", "m", "semantic",
                    "wrist-trajectory diversity between the samples of a prompt", "wrists at 15 frames (DiffH2O)",
                    "SD (SyncDiff)", f"{_MB}:SampleDiversity", short="SD", set_level=True))
register(MetricInfo("od", "multibody", "gt", "m", "semantic", "wrist-trajectory diversity across the split",
                    "wrists at 15 frames (DiffH2O)", "OD (SyncDiff)", f"{_MB}:OverallDiversity", short="OD", set_level=True))
register(MetricInfo("ra", "multibody", "higher", "fraction", "semantic",
                    "recognition accuracy of the generated clips' actions", "the track's action recognizer",
                    "RA (SyncDiff)", f"{_MB}:recognition_accuracy", short="RA"))
# physics tier (MuJoCo; hoibench.metrics.physics, docs/metrics.md "Physics")
_PH_FN = "hoibench.metrics.physics:physics_clip_values"
_PH = dict(impl=_PH_FN, clip_fn=_PH_FN, per_clip=True, needs_object=True, scorers=("hoi", "multibody"),
           multibody_fn="hoibench.metrics.physics_multibody:multibody_physics_values", settings_key="physics",
           settings_check="hoibench.metrics.physics:check_settings", requires="mujoco",
           install_hint="install hoibench[physics]")
register(MetricInfo("phys_support_err_m", "physical", "lower", "m", "extras",
                    "object simulated from its generated pose and velocity with body and floor as colliders: "
                    "distance to the generated centre after h, mean over windows",
                    "h = 0.5 s windows every 0.25 s (protocol physics)", failure_end="high", **_PH))
register(MetricInfo("phys_unsupported_ratio", "physical", "lower", "fraction", "extras",
                    "support windows whose simulated object ends farther than 5 cm from the generated one",
                    "error > unsupported_m (protocol physics)", failure_end="high", **_PH))
register(MetricInfo("phys_settle_m", "physical", "lower", "m", "extras",
                    "object released at rest (last frame, frames without body contact): displacement after "
                    "35 frames at 30 fps, mean over releases (HUMOTO)",
                    "contact: capsule surface < 2 cm from the mesh", failure_end="high", **_PH))
register(MetricInfo("phys_balance_ratio", "physical", "higher", "fraction", "extras",
                    "releases after which the object moved < 5 cm and turned < 10 deg (rests stably)",
                    "unsupported_m, balance_turn_deg (protocol physics)", failure_end="low", **_PH))
# counts the single-body scorer reports beside its metrics
register(MetricInfo("clips", "count", "gt", "clips", "counts", "test clips the physical metrics scored"))
register(MetricInfo("clips_with_contact", "count", "gt", "clips", "counts",
                    "test clips whose ground truth has joint-object contact (CD's denominator)"))
# CHOIS (Li et al., ECCV 2024): its released compute_metrics and penetration measures, per clip
# against the test clip's ground truth (hoibench.metrics.chois*, docs/metrics.md "CHOIS")
_CHOIS = "hoibench.metrics.chois_clip:chois_clip_metrics"
for _name, _dir, _unit, _obj, _summary, _paper in (
        ("lhand_jpe", "lower", "mm", False, "left hand joint error (joint 22 of joints24, 20 of 22)", "Hand JPE"),
        ("rhand_jpe", "lower", "mm", False, "right hand joint error (joint 23 of joints24, 21 of 22)", "Hand JPE"),
        ("hand_jpe", "lower", "mm", False, "mean of the two hand joint errors", "Hand JPE"),
        ("mpvpe", "lower", "mm", False, "root-relative vertex error (needs body vertices)", "MPVPE"),
        ("mpjpe", "lower", "mm", False, "root-relative joint error", "MPJPE"),
        ("trans_err", "lower", "mm", False, "root translation error", "Root Err"),
        ("rot_dist", "lower", "Frobenius", False, "root rotation error ||I - R_p R_g^-1||_F", "O (root)"),
        ("foot_sliding", "lower", "m/1000 frames", False,
         "CHOIS's weighted ankle/toe sliding over its DBSCAN floor (0.08 / 0.04 m)", "FS"),
        ("gt_foot_sliding", "gt", "m/1000 frames", False, "the same of the ground truth", "FS (GT)"),
        ("gt_contact_percent", "gt", "fraction", True, "GT frames with a hand joint near the object", "C%"),
        ("pred_contact_percent", "gt", "fraction", True, "generated frames with a hand joint near the object", "C%"),
        ("contact_precision", "higher", "fraction", True, "per-frame contact precision (0 without predicted contact)",
         "Cprec"),
        ("contact_recall", "higher", "fraction", True, "per-frame contact recall (0 without GT contact)", "Crec"),
        ("contact_acc", "higher", "fraction", True, "per-frame contact accuracy", "Acc"),
        ("contact_f1", "higher", "fraction", True, "per-frame contact F1 (0 when precision and recall are 0)", "F1"),
        ("obj_rot_dist", "lower", "Frobenius", True, "object rotation error ||I - R_p R_g^-1||_F", "O"),
        ("obj_com_pos_err", "lower", "mm", True, "object centre (vertex mean) error", "T_obj"),
        ("start_obj_com_pos_err", "lower", "mm", True, "object centre error at the first frame", "Ts"),
        ("end_obj_com_pos_err", "lower", "mm", True, "object centre error at the last frame", "Te"),
        ("waypoints_xy_pos_err", "lower", "mm", True, "object centre xy error at frames 29, 59, 89", "Txy"),
        ("hand_penetration", "lower", "m", True,
         "mean |min(sdf, 0)| of the hand vertices (trainer_chois.py; rest frame per protocol)", "Pen (hand)"),
        ("body_penetration", "lower", "m", True, "the same over all body vertices", "Pen"),
        ("penetration", "lower", "sdf units", True,
         "compute_collision's mean depth beyond 0.04 (normalised SDF units x obj_scale, not metres)", None),
        ("penetration_percent", "lower", "fraction", True, "compute_collision's fraction of penetrating frames",
         None)):
    register(MetricInfo(_name, "physical", _dir, _unit, "physical", _summary, "CHOIS rules", _paper, _CHOIS,
                        per_clip=True, failure_end={"lower": "high", "higher": "low"}.get(_dir),
                        needs_object=_obj, clip_fn=_CHOIS, settings_key="chois", needs_ground_truth=True,
                        settings_check="hoibench.metrics.chois_clip:check_settings",
                        requires="sklearn" if "foot_sliding" in _name else "",
                        install_hint="pip install scikit-learn" if "foot_sliding" in _name else ""))
# InterAct's object-to-human and human-to-object tasks (hoibench.metrics.interact_tasks; the
# interact-o2h and interact-h2o tracks): per test sequence, the sample the protocol's selection
# rule keeps, then the mean over sequences (docs/metrics.md "InterAct's other tasks")
_IT = "hoibench.metrics.interact_tasks"


def _task(direction: str) -> dict:
    """Catalogue fields shared by the task metrics: scored by the interact-task scorer, a column
    of the per-clip table (the selected sample), failing at the end its direction says."""
    return dict(scorers=("interact-task",), per_clip=True,
                failure_end={"lower": "high", "higher": "low"}.get(direction))


_CONTACT = (("contact_precision", "higher", "fraction", "per-frame contact precision (0 without predicted contact)"),
            ("contact_recall", "higher", "fraction", "per-frame contact recall (0 without ground-truth contact)"),
            ("contact_acc", "higher", "fraction", "per-frame contact accuracy"),
            ("contact_f1", "higher", "fraction", "per-frame contact F1 (0 when precision and recall are 0)"),
            ("contact_dist", "gt", "m", "the prediction's nearest distance, mean over the GT's contact frames"),
            ("gt_contact_dist", "gt", "m", "the ground truth's own nearest distance over its contact frames"))
_MARKER_GROUPS = (("full", "all 77 markers"), ("hand", "the 10 hand markers"),
                  ("non_hand", "the 67 markers off the hands"), ("foot", "the 11 toe markers (55 twice)"))
for _name, _dir, _unit, _summary in (
        ("lhand_jpe", "lower", "cm", "left-hand marker error (markers 72-76)"),
        ("rhand_jpe", "lower", "cm", "right-hand marker error (markers 67-71)"),
        ("hand_jpe", "lower", "cm", "mean of the two hand marker errors"),
        ("mpvpe", "lower", "m", "marker error relative to marker 0"),
        ("foot_sliding", "lower", "m x 1000 / (frame x toe marker)",
         "height-weighted xz sliding of the toe markers below 4 cm"),
        ("gt_foot_sliding", "gt", "m x 1000 / (frame x toe marker)", "the same of the ground truth")):
    register(MetricInfo(f"o2h_{_name}", "task", _dir, _unit, "physical" if _dir != "gt" else "extras",
                        f"object-to-human: {_summary}", "InterAct object2human/evaluation_metrics.py",
                        f"{_name} (InterAct o2h)", f"{_IT}:object2human_metrics", **_task(_dir)))
for _group, _what in _MARKER_GROUPS:
    register(MetricInfo(f"o2h_jpe_{_group}", "task", "lower", "cm", "physical" if _group == "full" else "extras",
                        f"object-to-human: marker error of {_what} (markers lowered to y = 0 first)",
                        "InterAct compute_metrics_marker", f"{_group} jpe (InterAct o2h)",
                        f"{_IT}:object2human_metrics", **_task("lower")))
    for _name, _dir, _unit, _summary in _CONTACT:
        register(MetricInfo(f"o2h_{_name}_{_group}", "task", _dir, _unit,
                            "physical" if _group == "full" and _name == "contact_f1" else "extras",
                            f"object-to-human, {_what}: {_summary}", "contact: marker within 0.05 m of the object",
                            f"{_group} {_name} (InterAct o2h)", f"{_IT}:object2human_metrics", **_task(_dir)))
for _name, _dir, _unit, _summary in (
        ("mpvpe", "lower", "m", "object point error relative to point 0"),
        ("mpmpe", "lower", "m", "object point error"),
        ("t_err", "lower", "m", "object translation error (InterAct's object frame)"),
        ("o_err", "lower", "Frobenius", "object rotation error ||I - R_p R_g^-1||_F")) + _CONTACT:
    register(MetricInfo(f"h2o_{_name}", "task", _dir, _unit,
                        "physical" if _name in ("mpvpe", "mpmpe", "t_err", "o_err", "contact_f1") else "extras",
                        f"human-to-object: {_summary}", "contact: a marker within 0.05 m of the object",
                        f"{_name} (InterAct h2o)", f"{_IT}:human2object_metrics", **_task(_dir)))
# only in rows copied from papers
register(MetricInfo("ait_s", "reported", "lower", "s", "reported", "average inference time per sample, as reported"))
# per-clip columns that are no metric of the whole split
register(MetricInfo("gt_mm_dist", "clip", "gt", _EMB, "clip", "the real motion's distance to its own captions",
                    per_clip=True))
register(MetricInfo("text_rank", "clip", "lower", "rank", "clip",
                    "1 + the scored clips whose captions are nearer to the sample than its own", per_clip=True,
                    failure_end="high"))
del _k, _name, _dir, _unit, _summary, _group, _what

__all__ = ["MetricInfo", "METRICS", "DIRECTIONS", "GROUPS", "ARROWS", "FID_ROUNDING", "register", "get_metric_info",
           "metric_names", "metrics_for", "settings_keys", "check_settings", "unavailable", "object_metrics",
           "shown_value"]
