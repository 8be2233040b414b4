"""One call from nothing to a prepared synthetic store (tests, benchmarks, the demo), and
plain template captions for synthetic clips (a text baseline independent of the annotator)."""
from __future__ import annotations

from pathlib import Path

VERB = {"lift": "lifts", "carry": "carries", "putdown": "puts down", "push": "pushes", "pull": "pulls",
        "sit": "sits on", "kick": "kicks", "hold": "holds"}
OBJ = {"boxsmall": "small box", "boxlarge": "large box", "chairwood": "wooden chair", "tablesmall": "small table",
       "stool": "stool", "yogaball": "yoga ball", "yogamat": "yoga mat", "backpack": "backpack"}
PARAPHRASES = ("a person {v} the {o}", "someone {v} a {o}", "the person {v} the {o} and then stands still",
               "a human {v} the {o} in front of them")


def build_synthetic_store(base: str | Path, clips: int, seed: int = 0, fps: float = 20.0,
                          executor: str = "serial"):
    """``hoibench synth`` (BEHAVE layout) + ``prepare`` into ``base/raw`` and ``base/data``.
    Returns ``(raw, data, manifest)``."""
    from .store import PrepareConfig, prepare
    from . import behave
    from .synthetic import write_behave_layout
    base = Path(base)
    raw, data = base / "raw", base / "data"
    write_behave_layout(raw, clips, seed=seed, progress=False, executor=executor)
    cfg = PrepareConfig("synthetic", fps=fps)
    manifest = prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"),
                       data, cfg, executor=executor, source={"root": str(raw), "generator": "hoibench synth"})
    return raw, data, manifest


def template_captions(clip_id: str) -> list[str]:
    """Paraphrases from a synthetic name ``Date0X_SubYY_<object>_<action>[_<n>]``."""
    _, _, obj, action = clip_id.split("_")[:4]
    return [p.format(v=VERB[action], o=OBJ[obj]) for p in PARAPHRASES]


def write_template_texts(data: str | Path) -> None:
    """DATA/texts/<id>.txt with :func:`template_captions` (HumanML3D lines)."""
    from .store import Store
    store = Store(data)
    (store.root / "texts").mkdir(exist_ok=True)
    for cid in store.clip_ids():
        lines = [f"{c}#{c.split()[1]}/NOUN#0.0#0.0" for c in template_captions(cid)]
        (store.root / "texts" / f"{cid}.txt").write_text("\n".join(lines) + "\n")
