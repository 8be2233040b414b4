"""Old import paths (before 0.7.0) kept working for one version, with a
:class:`DeprecationWarning` naming the new path (docs/changelog.md, 0.7.0).

``import hoibench.store`` gives a module that forwards every attribute to
:mod:`hoibench.datasets.store`; the old ``hoibench.multibody`` package forwards its
submodules. Installed by ``hoibench/__init__.py``; removed in 0.8.0.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

#: old module path -> new module path
MOVED: dict[str, str] = {
    "hoibench.errors": "hoibench.core.errors",
    "hoibench.ids": "hoibench.core.ids",
    "hoibench.io": "hoibench.core.io",
    "hoibench.interrupts": "hoibench.core.interrupts",
    "hoibench.parallel": "hoibench.core.parallel",
    "hoibench.plausibility": "hoibench.core.plausibility",
    "hoibench.geometry": "hoibench.core.geometry",
    "hoibench.skeleton": "hoibench.core.skeleton",
    "hoibench.contact": "hoibench.bodies.contact",
    "hoibench.multibody.clip": "hoibench.bodies.multibody",
    "hoibench.multibody.surfaces": "hoibench.bodies.capsules",
    "hoibench.multibody.representation": "hoibench.representations.multibody",
    "hoibench.store": "hoibench.datasets.store",
    "hoibench.splits": "hoibench.datasets.splits",
    "hoibench.export": "hoibench.datasets.export",
    "hoibench.multibody.synthetic": "hoibench.datasets.synthetic_multibody",
    "hoibench.annotate": "hoibench.text.annotate",
    "hoibench.text_tokens": "hoibench.text.tokens",
    "hoibench.multibody.metrics": "hoibench.metrics.multibody",
    "hoibench.protocol": "hoibench.tracks.protocol",
    "hoibench.multibody.recognizer": "hoibench.evaluator.recognizer",
    "hoibench.submission": "hoibench.scoring.submission",
    "hoibench.evaluate": "hoibench.scoring.evaluate",
    "hoibench.multibody.evaluate": "hoibench.scoring.multibody",
    "hoibench.compare": "hoibench.scoring.compare",
    "hoibench.importers": "hoibench.scoring.importers",
    "hoibench.prompts": "hoibench.scoring.prompts",
    "hoibench.reference_rows": "hoibench.scoring.reference_rows",
    "hoibench.leaderboard": "hoibench.publish.leaderboard",
    "hoibench.leaderboard_render": "hoibench.publish.pages",
    "hoibench.render": "hoibench.publish.render",
    "hoibench.multibody.render": "hoibench.publish.render_multibody",
}
#: old packages that now only forward their submodules
OLD_PACKAGES = ("hoibench.multibody",)


class _Forward(types.ModuleType):
    """A module standing for ``target`` under its old name."""

    def __init__(self, name: str, target: str | None):
        super().__init__(name)
        self.__dict__["_target"] = target
        if target is None:
            self.__path__ = []           # a package: its submodules are found by the finder

    def __getattr__(self, attr: str):
        target = self.__dict__["_target"]
        if target is None:
            raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r}")
        return getattr(importlib.import_module(target), attr)

    def __dir__(self):
        target = self.__dict__["_target"]
        return dir(importlib.import_module(target)) if target else []


class _Loader(importlib.abc.Loader):
    def create_module(self, spec):
        return _Forward(spec.name, MOVED.get(spec.name))

    def exec_module(self, module):
        target = MOVED.get(module.__name__)
        new = f"import {target}" if target else "the modules listed in docs/architecture.md"
        warnings.warn(f"{module.__name__} moved in hoibench 0.7.0: use {new} (the old path goes in 0.8.0)",
                      DeprecationWarning, stacklevel=3)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname in MOVED or fullname in OLD_PACKAGES:
            return importlib.util.spec_from_loader(fullname, _Loader(), is_package=fullname in OLD_PACKAGES)
        return None


def install() -> None:
    """Put the forwarding finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
