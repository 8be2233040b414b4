"""Shared fixtures: a small synthetic dataset prepared into a store once per session."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def synthetic_store(tmp_path_factory):
    """(raw folder, store folder, manifest) for 8 synthetic clips prepared at 20 fps."""
    pytest.importorskip("smplx")
    from hoibench.datasets import behave
    from hoibench.datasets.synthetic import write_behave_layout
    from hoibench.store import PrepareConfig, prepare

    base = tmp_path_factory.mktemp("synthetic")
    raw, data = base / "raw", base / "data"
    write_behave_layout(raw, 8, seed=0, progress=False)
    cfg = PrepareConfig("synthetic", fps=20.0)
    manifest = prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"),
                       data, cfg)
    return raw, data, manifest
