"""Shared fixtures: a small synthetic dataset prepared into a store once per session."""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import pytest

# the disk cache (hoibench.core.disk_cache: ground-truth statistics, distance grids) goes to a folder of this
# test run, never to the user's ~/.cache; subprocesses inherit it; removed when the run ends
os.environ["HOIBENCH_CACHE"] = tempfile.mkdtemp(prefix="hoibench-test-cache-")
atexit.register(shutil.rmtree, os.environ["HOIBENCH_CACHE"], True)


@pytest.fixture(scope="session")
def synthetic_store(tmp_path_factory):
    """(raw folder, store folder, manifest) for 8 synthetic clips prepared at 20 fps."""
    pytest.importorskip("smplx")
    from hoibench.datasets.synthetic_store import build_synthetic_store
    return build_synthetic_store(tmp_path_factory.mktemp("synthetic"), 8, seed=0)


@pytest.fixture(scope="session")
def template_store(tmp_path_factory):
    """A 48-clip synthetic store (34 train / 14 test) with template captions (read-only:
    tests that change it work on a copy)."""
    pytest.importorskip("smplx")
    from hoibench.datasets.synthetic_store import build_synthetic_store, write_template_texts
    _, data, _ = build_synthetic_store(tmp_path_factory.mktemp("template_store"), 48, seed=0)
    write_template_texts(data)
    return data


@pytest.fixture(scope="session")
def annotated_store_with_evaluator(tmp_path_factory):
    """(base folder, 120-clip annotated synthetic store, tiny evaluator folder that passes its
    gate), built once per session for the modules that score end to end (read-only: tests
    that change the store or evaluator work on a copy)."""
    pytest.importorskip("smplx")
    pytest.importorskip("transformers")
    from hoibench.datasets.synthetic_store import build_synthetic_store
    from hoibench.evaluator import main_train_evaluator
    from hoibench.text.annotate import annotate_store
    base = tmp_path_factory.mktemp("scored_store")
    _, data, _ = build_synthetic_store(base, 120, seed=0)
    annotate_store(data)
    assert main_train_evaluator(data, base / "ev", size="tiny", seed=0) == 0
    return base, data, base / "ev"
