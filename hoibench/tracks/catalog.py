"""The shipped tracks, one :func:`~hoibench.tracks.registry.register_track` call each
(their protocols are the YAML files in ``hoibench/tracks/protocols/`` that name them)."""
from __future__ import annotations

from .track import Track, register_track

#: the leaderboard columns of single-body tracks (every other metric stays in the CSV)
HOI_COLUMNS = ("r_precision_top1", "r_precision_top3", "fid", "mm_dist", "diversity", "multimodality",
               "cd", "ocd", "ps", "fsr")
#: the leaderboard columns of multi-body tracks
MULTIBODY_COLUMNS = ("csr", "crr", "csiou", "iv_cm3", "id_mm", "sd", "od", "ra", "fid")


def _hoi(name: str, datasets: tuple[str, ...], protocols: tuple[str, ...], description: str,
         store_kind: str = "hoi", **extras) -> Track:
    return Track(name=name, datasets=datasets, store_kind=store_kind, representation="hoi269", submission="hoi",
                 evaluator_kind="contrastive", columns=HOI_COLUMNS, protocols=protocols,
                 scorer="hoi", renderer="hoi", description=description, extras=extras)


register_track(_hoi("synthetic", ("synthetic",), ("synthetic-clean", "synthetic-legacy"),
                    "hoibench's generated HOI data in BEHAVE's layout (the README walk-through and `make demo`).",
                    generic_for="hoi"))
register_track(_hoi("behave", ("behave",), ("behave-clean", "behave-legacy", "t2m-legacy"),
                    "BEHAVE (HOI-Diff's clip split): one person, one object, 20 fps."))
register_track(_hoi("omomo", ("omomo",), ("omomo-clean", "omomo-legacy", "omomo-chois", "omomo-chois-clean"),
                    "OMOMO: one person moving one large object, 20 fps."))
register_track(_hoi("rich-cat", ("rich",), ("rich-cat-clean",),
                    "RICH-CAT (CATMO): a person and a static scene object; object metrics are not applicable.",
                    store_kind="human"))
register_track(Track(
    name="interact", datasets=("interact",), store_kind="hoi", representation="hoi269", submission="hoi",
    evaluator_kind="interact", columns=HOI_COLUMNS, protocols=("interact-clean", "interact-legacy"),
    scorer="hoi", renderer="hoi",
    description="InterAct's unified HOI data (BEHAVE, GRAB, OMOMO, InterCap, NeuralDome, IMHD, CHAIRS; "
                "hoibench prepare interact), 30 fps, scored with InterAct's evaluator (markers + object BPS).",
    extras={"submission_arrays": ("markers",)}))
#: InterAct's conditioned tasks on the interact dataset (chosen by naming their protocol)
O2H_COLUMNS = ("o2h_hand_jpe", "o2h_mpvpe", "o2h_jpe_full", "o2h_contact_f1_full", "o2h_foot_sliding")
H2O_COLUMNS = ("h2o_mpvpe", "h2o_mpmpe", "h2o_t_err", "h2o_o_err", "h2o_contact_f1")


def _interact_task(name: str, task: str, columns: tuple[str, ...], arrays: tuple[str, ...], description: str) -> Track:
    return Track(name=name, datasets=("interact",), store_kind="hoi", representation="hoi269",
                 submission="interact-task", evaluator_kind="none", columns=columns, headline=columns[:4],
                 protocols=(f"{name}-clean",), scorer="interact-task", renderer="hoi", description=description,
                 extras={"protocol_kind": "interact-task", "by_protocol": True, "task": task,
                         "submission_arrays": arrays})


register_track(_interact_task(
    "interact-o2h", "o2h", O2H_COLUMNS, ("markers",),
    "InterAct's object-to-human task: the human's 77 body-surface markers from the object's motion and the text "
    "(best of 10 by marker error); name its protocol: --protocol interact-o2h-clean."))
register_track(_interact_task(
    "interact-h2o", "h2o", H2O_COLUMNS, ("obj_rot", "obj_trans"),
    "InterAct's human-to-object task: the object's motion from the human's markers and the text "
    "(best of 5 by MPVPE); name its protocol: --protocol interact-h2o-clean."))
register_track(Track(
    name="multibody-synthetic", datasets=("multibody-synthetic",), store_kind="multibody",
    representation="multibody-syncdiff", submission="multibody",
    evaluator_kind="recognizer", columns=MULTIBODY_COLUMNS, headline=("csiou", "iv_cm3", "ra", "fid"), protocols=("multibody-synthetic",),
    scorer="multibody", renderer="multibody",
    description="hoibench's generated multi-body data: hands, people and several objects (SyncDiff's metrics).",
    extras={"generic_for": "multibody"}))
