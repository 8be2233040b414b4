"""The ground truth's statistics cached between evaluations (hoibench.scoring.reference_cache):
a second evaluation reads them instead of embedding again and gets the very same result; any
input they depend on changes the key; a damaged file is recomputed; the cache can be off."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from hoibench.core import disk_cache as dc
from hoibench.scoring import reference_cache as rc


def _scorer(store_dir, ev_dir):
    from hoibench.evaluator.backends import load_evaluator
    from hoibench.datasets.store import Store
    from hoibench.scoring.hoi import HOIScorer
    from hoibench.tracks.protocol import default_protocol_id, get_protocol
    from hoibench.tracks.registry import track_for
    store = Store(store_dir)
    proto = get_protocol(default_protocol_id(store.manifest))
    ev = load_evaluator(ev_dir, kind="contrastive", **HOIScorer.evaluator_options)
    return HOIScorer(store, proto, ev, track_for(store, None), "sub", {})


def _prepared(store_dir, ev_dir):
    s = _scorer(store_dir, ev_dir)
    s.prepare()
    return s


def _same(a, b):
    assert np.array_equal(a.st.real_all, b.st.real_all) and a.st.real_all.dtype == b.st.real_all.dtype
    assert len(a.st.sets_all) == len(b.st.sets_all)
    assert all(np.array_equal(x, y) for x, y in zip(a.st.sets_all, b.st.sets_all))
    assert json.dumps(a.st.gate, sort_keys=True) == json.dumps(b.st.gate, sort_keys=True)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(dc.CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path / "cache" / "reference"


def test_a_second_evaluation_reads_the_cache_and_gets_the_same_statistics(annotated_store_with_evaluator, cache,
                                                                          monkeypatch):
    from hoibench.scoring.hoi import HOIScorer
    _, data, ev = annotated_store_with_evaluator
    first = _prepared(data, ev)
    files = list(cache.glob("*.npz"))
    assert len(files) == 1
    monkeypatch.setenv(dc.CACHE_ENV, "off")
    fresh = _prepared(data, ev)                                       # computed, nothing written
    _same(first, fresh)
    monkeypatch.setenv(dc.CACHE_ENV, str(cache.parent))

    def refuse(*_a, **_k):
        raise AssertionError("embedded again although cached")
    monkeypatch.setattr(HOIScorer, "_ground_truth_embeddings", refuse)
    hit = _prepared(data, ev)
    _same(hit, fresh)
    assert hit.ev._model is None            # nothing embeds text: the text branch is never built


def test_the_key_follows_captions_clip_files_protocol_and_evaluator(annotated_store_with_evaluator, tmp_path):
    from hoibench.scoring.hoi import _caption_lines
    from hoibench.tracks.protocol import get_protocol
    _, data, ev = annotated_store_with_evaluator
    s = _scorer(data, ev)
    ids = s.store.clip_ids("test")
    lines = {c: _caption_lines(data, c) for c in ids}

    def key(**kw):
        args = dict(store=s.store, protocol=s.proto, evaluator_id=s.ev.id, test_ids=ids, lines=lines, mode="clean",
                    fps=20.0)
        args.update(kw)
        return rc.reference_key(**args)
    base = key()
    assert key() == base
    changed = dict(lines)
    changed[ids[0]] = lines[ids[1]]
    others = [key(lines=changed), key(test_ids=ids[1:]), key(evaluator_id="0" * 64),
              key(protocol=get_protocol("synthetic-legacy")), key(mode="legacy"), key(fps=30.0)]
    assert len({base, *others}) == 1 + len(others)
    copy = tmp_path / "store"
    shutil.copytree(data, copy)
    clip = copy / "clips" / f"{ids[0]}.npz"
    s2 = _scorer(copy, ev)
    before = rc.reference_key(s2.store, s2.proto, s2.ev.id, ids, lines, "clean", 20.0)
    clip.write_bytes(clip.read_bytes() + b"\0")                        # a rewritten clip file
    assert rc.reference_key(s2.store, s2.proto, s2.ev.id, ids, lines, "clean", 20.0) != before


def test_a_damaged_file_is_recomputed_and_the_cache_can_be_off(annotated_store_with_evaluator, cache,
                                                               monkeypatch):
    _, data, ev = annotated_store_with_evaluator
    first = _prepared(data, ev)
    (path,) = cache.glob("*.npz")
    path.write_bytes(b"not a zip")
    again = _prepared(data, ev)                                        # recomputed and written again
    _same(first, again)
    assert rc.load_reference(path.stem, len(first.st.test_ids)) is not None
    assert rc.load_reference(path.stem, len(first.st.test_ids) + 1) is None    # another split size
    for off in ("off", "0", ""):
        monkeypatch.setenv(dc.CACHE_ENV, off)
        assert dc.cache_dir() is None
        assert rc.save_reference("k", first.st.real_all, first.st.sets_all, first.st.gate) is None


def test_an_evaluator_without_a_content_id_is_never_cached(annotated_store_with_evaluator, cache):
    """Evaluators built in memory have no verified id: two of them must not share statistics."""
    _, data, ev = annotated_store_with_evaluator
    s = _scorer(data, ev)
    s.ev.card = {k: v for k, v in s.ev.card.items() if k != "evaluator_id"}
    assert s.ev.id is None
    s.prepare()
    assert not cache.exists() or not list(cache.glob("*.npz"))
