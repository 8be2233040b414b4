"""The raw-data loaders ``hoibench prepare`` knows, registered (``hoibench datasets ls``; the
same table is in docs/datasets.md, "Every loader").

Each :class:`Loader` row states where its format facts come from, the data's licence note,
its default split and what hoibench verified it against, and what ``prepare`` needs to know
to run it without guessing: the module (a :class:`~hoibench.datasets.loader_protocol.DatasetLoader`),
the body model type recorded in the store, whether ``--body-models`` is required, which
extra options ``prepare_jobs`` reads, and its optional hooks as lazy ``"module:attr"``
references (dataset name from the root, prepare warnings, texts written after prepare)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.registry import Registry, load_object

__all__ = ["Loader", "LOADERS", "LOADER_REGISTRY", "register_loader", "get_loader", "loader_names",
           "synthetic_or_behave"]


@dataclass(frozen=True)
class Loader:
    name: str            # hoibench prepare <name>
    source: str          # the public code / release the format facts come from
    licence: str         # the data's licence, as its owners state it
    split: str           # the split a store gets unless --split-file names another
    verified: str        # what the loader's tests check it against
    module: str = ""                     # the loader module (default hoibench.datasets.<name>)
    body_model_type: str = "smplx"       # recorded in the store's config and manifest: smplh or smplx
    needs_body_models: bool = True       # prepare refuses to run without --body-models
    options: tuple[str, ...] = ()        # extra prepare options passed on to prepare_jobs (e.g. sources, split)
    dataset_name: str | None = None      # "module:attr" (root) -> the store's dataset name (default: name)
    warnings: str | None = None          # "module:attr" (root, body_models) -> dataset-level warnings
    texts: str | None = None             # "module:attr" (out, manifest) -> texts written after prepare

    @property
    def module_name(self) -> str:
        return self.module or f"{__package__}.{self.name}"

    def load(self) -> Any:
        """The loader module (imported on use)."""
        from importlib import import_module
        return import_module(self.module_name)

    def name_for(self, root: str | Path) -> str:
        """The store's dataset name for raw data at ``root``."""
        return self.name if self.dataset_name is None else load_object(self.dataset_name)(root)

    def warnings_for(self, root: str | Path, body_models: str | Path | None) -> list[str]:
        """Dataset-level warnings recorded in the manifest (none by default)."""
        return [] if self.warnings is None else list(load_object(self.warnings)(root, body_models))

    def write_texts(self, out: str | Path, manifest: dict) -> None:
        """Texts that come with the data, written after prepare (nothing by default)."""
        if self.texts is not None:
            load_object(self.texts)(out, manifest)


def synthetic_or_behave(root: str | Path) -> str:
    """``synthetic`` for hoibench's own data in the BEHAVE layout (its protocol differs), else ``behave``."""
    return "synthetic" if (Path(root) / "hoibench_synthetic.json").exists() else "behave"


LOADER_REGISTRY: Registry[Loader] = Registry("dataset loader")


def register_loader(loader: Loader) -> Loader:
    """Add a loader (listed after the ones before it); a name registered twice is refused."""
    return LOADER_REGISTRY.add(loader.name, loader)


def get_loader(name: str) -> Loader:
    """The registered loader ``name`` (``KeyError`` naming the known ones otherwise)."""
    return LOADER_REGISTRY.get(name)


def loader_names() -> list[str]:
    """Every registered loader, in registration order (``hoibench prepare`` choices, ``datasets ls``)."""
    return LOADER_REGISTRY.in_order()


_HERE = __package__
for _loader in (
    Loader("behave", "BEHAVE release layout", "BEHAVE's licence (registration)",
           "official: Date03 sequences are test", "fixture in its layout, proxy SMPL-H, meshes computed outside the loader",
           body_model_type="smplh", dataset_name=f"{_HERE}.catalog:synthetic_or_behave"),
    Loader("omomo", "lijiaman/omomo_release, chois_release", "OMOMO's licence",
           "subject split: sub16-17 test", "fixture as the release is, vertices posed as OMOMO's loader poses them"),
    Loader("rich", "paulchhuang/rich_toolkit", "RICH's licence (registration)",
           "the release's resource/meta lists", "fixture with the toolkit's conventions, meshes as smplx2images.py",
           warnings=f"{_HERE}.rich:prepare_warnings"),
    Loader("multibody", "hoibench's multi-body exchange layout", "yours", "split.json, else all train",
           "synthetic multi-body clips round-trip", needs_body_models=False,
           dataset_name=f"{_HERE}.multibody:dataset_name"),
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
           "by smplx as InterAct calls it, vertices by trimesh",
           options=("sources", "split"), texts=f"{_HERE}.interact:write_texts"),
):
    register_loader(_loader)

#: the registered loaders in registration order (``LOADER_REGISTRY`` answers by name)
LOADERS: tuple[Loader, ...] = tuple(LOADER_REGISTRY.get(n) for n in loader_names())
