"""Shared fixtures: a small synthetic dataset prepared into a store once per session."""
from __future__ import annotations

import pytest


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
