"""The raw-data loaders ``hoibench prepare`` knows: where each one's format facts come from,
the data's licence note, its default split and what hoibench verified it against
(``hoibench datasets ls``; the same table is in docs/datasets.md, "Every loader")."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Loader", "LOADERS", "loader_names", "main_datasets"]


@dataclass(frozen=True)
class Loader:
    name: str            # hoibench prepare <name>; the module hoibench.datasets.<name>
    source: str          # the public code / release the format facts come from
    licence: str         # the data's licence, as its owners state it
    split: str           # the split a store gets unless --split-file names another
    verified: str        # what the loader's tests check it against


LOADERS: tuple[Loader, ...] = (
    Loader("behave", "BEHAVE release layout", "BEHAVE's licence (registration)",
           "official: Date03 sequences are test", "fixture in its layout, proxy SMPL-H, meshes computed outside the loader"),
    Loader("omomo", "lijiaman/omomo_release, chois_release", "OMOMO's licence",
           "subject split: sub16-17 test", "fixture as the release is, vertices posed as OMOMO's loader poses them"),
    Loader("rich", "paulchhuang/rich_toolkit", "RICH's licence (registration)",
           "the release's resource/meta lists", "fixture with the toolkit's conventions, meshes as smplx2images.py"),
    Loader("multibody", "hoibench's multi-body exchange layout", "yours", "split.json, else all train",
           "synthetic multi-body clips round-trip"),
    Loader("core4d", "leolyliu/CORE4D-Instructions, CORE4D_toolkit", "CC BY 4.0 (README)",
           "released lists: train / test_seen_obj / test_unseen_obj", "CORE4D-layout fixture, proxy SMPL-X; list hashes"),
    Loader("grab", "otaheri/GRAB (+ readers named in grab.py)", "GRAB's licence (registration)",
           "IMoS subject split: s10 test, s1 val", "GRAB-layout fixture, proxy SMPL-X and MANO"),
    Loader("taco", "leolyliu/TACO-Instructions c06f82c", "CC BY 4.0 (README)",
           "V1 lists: train 953 / test_1..4 225, 234, 354, 551",
           "TACO-layout fixture (torch-free pickles), proxy MANO forward + object poses; list hashes"),
    Loader("oakink2", "oakink/OakInk2-PreviewTool 63365c6, OakInk2 README, OakInk2-TaMF 4cb9c46",
           "CC BY-NC-SA 3.0 (Hugging Face card)", "TaMF lists: 431 / 39 / 157 sequences",
           "OAKINK2-layout fixture, proxy MANO forward + object poses; list hashes"),
    Loader("interact", "wzyabcas/InterAct (processing scripts, text2interaction/eval)",
           "each source dataset's licence, plus InterAct's terms", "test_seq.txt (sequence split, as its evaluation "
           "script); --split object: data/test.txt", "InterAct-layout fixture (BEHAVE-, GRAB-, OMOMO-derived), joints "
           "by smplx as InterAct calls it, vertices by trimesh"),
)


def loader_names() -> list[str]:
    return [x.name for x in LOADERS]


def main_datasets(action: str = "ls") -> int:
    """``hoibench datasets ls``: one block per loader."""
    if action != "ls":
        raise ValueError(f"datasets: unknown action {action!r} (expected ls)")
    for x in LOADERS:
        print(f"{x.name}\n  source:   {x.source}\n  licence:  {x.licence}\n  split:    {x.split}\n"
              f"  verified: {x.verified}")
    print("no loader was run on real files in hoibench's tests (the data is licensed); "
          "see docs/datasets.md for what could not be established")
    return 0
