"""Every registered scorer, evaluator backend class, baseline and dataset loader keeps its
written contract (hoibench/scoring/pipeline.py, hoibench/evaluator/contracts.py,
hoibench/baselines/contracts.py, hoibench/datasets/loader_protocol.py)."""
from __future__ import annotations

import ast
import inspect
import textwrap
import typing

import pytest


def _members(proto) -> tuple[set[str], set[str]]:
    """(methods, attributes) a ``typing.Protocol`` declares, its bases' included."""
    methods, attrs = set(), set()
    for klass in proto.__mro__:
        if klass in (typing.Protocol, typing.Generic, object):
            continue
        for name, value in vars(klass).items():
            if name.startswith("_"):
                continue
            if isinstance(value, property):
                attrs.add(name)
            elif callable(value):
                methods.add(name)
        attrs |= {n for n in getattr(klass, "__annotations__", {}) if not n.startswith("_")}
    return methods, attrs


def _assigned(cls) -> set[str]:
    """Names a class gives its instances: class attributes, properties, ``self.x = ...``."""
    names = set()
    for klass in cls.__mro__:
        if klass is object:
            continue
        names |= set(vars(klass))
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):
            continue
        for node in ast.walk(tree):
            targets = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, (ast.AnnAssign, ast.AugAssign)) else []
            for t in targets:
                for e in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    if isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name) and e.value.id == "self":
                        names.add(e.attr)
    return names


def _missing(cls, proto) -> list[str]:
    methods, attrs = _members(proto)
    have = _assigned(cls)
    return sorted([m for m in methods if not callable(getattr(cls, m, None))] + [a for a in attrs if a not in have])


def test_every_registered_scorer_implements_every_stage():
    from hoibench.scoring.pipeline import Scorer, _SCORERS, get_scorer
    for name in _SCORERS:
        cls = get_scorer(name)
        assert issubclass(cls, Scorer) and not inspect.isabstract(cls), (name, cls.__abstractmethods__)


def test_a_scorer_missing_a_stage_cannot_be_made():
    from hoibench.scoring.pipeline import Scorer

    class Half(Scorer):
        def open_submission(self):
            return None

    with pytest.raises(TypeError, match="abstract"):
        Half(None, None, None, None, None, {})


EVALUATOR_CLASSES = {"contrastive": "hoibench.evaluator.embed:Evaluator",
                     "t2m": "hoibench.evaluator.published_t2m:T2MEvaluator",
                     "chainhoi": "hoibench.evaluator.chainhoi_model:ChainHOIEvaluator",
                     "chois": "hoibench.evaluator.chois_t2m:ChoisEvaluator",
                     "interact": "hoibench.evaluator.interact:InteractEvaluator",
                     "recognizer": "hoibench.evaluator.recognizer:Recognizer"}


def test_every_evaluator_backend_class_keeps_its_kinds_contract():
    from hoibench.core.registry import load_object
    from hoibench.evaluator.backends import list_backends
    from hoibench.evaluator.contracts import CONTRACTS
    backends = {b.name: b for b in list_backends()}
    assert set(backends) <= set(EVALUATOR_CLASSES), f"a backend without a checked class: {set(backends) - set(EVALUATOR_CLASSES)}"
    for name, backend in backends.items():
        cls = load_object(EVALUATOR_CLASSES[name])
        assert _missing(cls, CONTRACTS[backend.kind]) == [], name


def test_the_contract_check_sees_a_missing_method():
    from hoibench.evaluator.contracts import TextMotionEvaluator

    class NoText:
        card: dict = {}
        id = "x"
        embed_dim = 4

        def embed_motion(self, features, lengths=None, batch_size=1):
            return features

    assert _missing(NoText, TextMotionEvaluator) == ["embed_text"]


def test_every_baseline_keeps_the_trainer_and_loaded_run_contracts():
    from hoibench.baselines.contracts import CONTRACTS, TRAINER_KEYWORDS
    from hoibench.baselines.registry import SPECS
    for name, spec in SPECS.items():
        if spec.kind not in CONTRACTS:          # the text-blind floor: no training, no run folder
            continue
        params = inspect.signature(spec.entry_point("train")).parameters
        assert set(TRAINER_KEYWORDS) <= set(params), (name, sorted(params))
        assert _missing(spec.entry_point("sample"), CONTRACTS[spec.kind]) == [], name


def test_every_registered_dataset_loader_keeps_the_loader_contract():
    from hoibench.datasets.catalog import LOADER_REGISTRY
    from hoibench.datasets.loader_protocol import DatasetLoader
    loaders = LOADER_REGISTRY.values()
    assert len(loaders) >= 8
    for entry in loaders:
        assert isinstance(entry.load(), DatasetLoader), entry.name


def test_every_import_format_names_a_reader_of_the_reader_contract():
    from hoibench.core.registry import load_object
    from hoibench.scoring.importers import FORMATS, IMPORT_FORMATS
    assert list(FORMATS) and set(FORMATS) == set(IMPORT_FORMATS)
    for name in FORMATS:
        reader = load_object(IMPORT_FORMATS.get(name).reader)
        assert list(inspect.signature(reader).parameters) == ["req"], name
