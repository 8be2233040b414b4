"""One evaluation pipeline over registries (docs/architecture.md): tracks, protocols of two
kinds in one type, evaluator backends, scorers; a new track is one registry entry plus a
protocol file."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from hoibench.tracks import protocol as P
from hoibench.tracks.registry import get_track, list_tracks, track_for_dataset
from hoibench.tracks.track import _TRACKS, Track


def test_every_shipped_protocol_names_a_registered_track_of_its_kind():
    for proto in P.list_protocols():
        track = get_track(proto.track)
        assert proto.kind == track.protocol_kind
        assert proto.id in track.protocols and proto.dataset in track.datasets
    for track in list_tracks():
        assert [P.get_protocol(pid).track for pid in track.protocols] == [track.name] * len(track.protocols)


def test_protocol_hashes_cover_settings_not_the_track_line(tmp_path):
    src = Path(P.get_protocol("rich-cat-clean").source).read_text()
    no_track = tmp_path / "p.yaml"
    no_track.write_text("\n".join(line for line in src.splitlines() if not line.startswith("track:")))
    a, b = P.get_protocol("rich-cat-clean"), P.load_protocol(no_track)
    assert a.sha256 == b.sha256 and a.kind == b.kind == "hoi" and b.track == ""
    mb = P.get_protocol("multibody-synthetic")
    again = P.Protocol.from_plain(mb.to_dict(), "multibody", mb.track)
    assert again == mb and again.sha256 == mb.sha256


def test_a_protocol_naming_an_unknown_track_is_refused_naming_the_file_and_field(tmp_path):
    src = Path(P.get_protocol("synthetic-clean").source).read_text().replace("track: synthetic", "track: nope")
    bad = tmp_path / "bad.yaml"
    bad.write_text(src)
    with pytest.raises(ValueError, match=r"bad\.yaml: field 'track': unknown track 'nope'"):
        P.load_protocol(bad)


def test_datasets_map_to_tracks_and_unknown_ones_to_the_generic_track_of_their_kind():
    assert track_for_dataset("rich").name == "rich-cat" and get_track("rich-cat").store_kind == "human"
    assert track_for_dataset("somewhere").name == "synthetic"
    assert track_for_dataset("grab", multibody=True).name == "multibody-synthetic"
    with pytest.raises(KeyError, match="unknown track 'x'; known: behave"):
        get_track("x")


def test_evaluator_folders_are_recognised_by_their_backend(tmp_path):
    from hoibench.evaluator.backends import backend_of, load_evaluator
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "recognizer.json").write_text("{}")
    (tmp_path / "ev").mkdir()
    (tmp_path / "ev" / "card.json").write_text("{}")
    assert backend_of(tmp_path / "rec").name == "recognizer" and backend_of(tmp_path / "ev").name == "contrastive"
    assert backend_of(tmp_path) is None
    with pytest.raises(ValueError, match="a recognizer evaluator .* this track needs a contrastive one .*"
                                         "hoibench train-evaluator"):
        load_evaluator(tmp_path / "rec", kind="contrastive")
    with pytest.raises(FileNotFoundError, match="not a recognizer folder"):
        load_evaluator(tmp_path, kind="recognizer")


# ---------------------------------------------------------------------- end to end
pytest.importorskip("transformers")
pytest.importorskip("open3d")


@pytest.fixture(scope="module")
def stores(annotated_store_with_evaluator, tmp_path_factory):
    """A single-body store with an evaluator and its GT submission; a multi-body store with a
    recognizer and its GT submission."""
    from hoibench.datasets.multibody import prepare_jobs, write_synthetic_layout, dataset_name
    from hoibench.datasets.store import PrepareConfig, prepare
    from hoibench.evaluator.recognizer import train_recognizer
    from hoibench.scoring.multibody import write_multibody_submission
    from hoibench.scoring.submission import from_store

    import shutil as sh
    base = tmp_path_factory.mktemp("pipeline")
    _, data, ev = annotated_store_with_evaluator
    sh.copytree(ev, base / "ev")
    from_store(data, base / "gt")
    raw, mdata = base / "mraw", base / "mdata"
    write_synthetic_layout(raw, 27, seed=0)
    cfg = PrepareConfig(dataset_name(raw), fps=20.0)
    prepare(prepare_jobs(raw, None, mdata, cfg), mdata, cfg)
    train_recognizer(mdata, base / "rec", steps=20, seed=0)
    write_multibody_submission(mdata, base / "mgt")
    return base, data, mdata


def test_single_and_multi_body_stores_go_through_the_same_function_and_stages(stores, monkeypatch):
    from hoibench.scoring import pipeline
    from hoibench.scoring.evaluate import evaluate
    base, data, mdata = stores
    seen = []
    original = pipeline.get_scorer

    def spying(name):
        cls = original(name)

        class Spy(cls):
            def update(self, out):
                seen.append((name, "update"))
                return super().update(out)

            def replications(self):
                seen.append((name, "replications"))
                return super().replications()
        return Spy

    monkeypatch.setattr(pipeline, "get_scorer", spying)
    hoi = evaluate(base / "gt", data, base / "ev", allow_failed_gate=True)
    mb = evaluate(base / "mgt", mdata, base / "rec")
    assert hoi["protocol"] == "synthetic-clean" and mb["protocol"] == "multibody-synthetic"
    assert {s for s in seen} == {("hoi", "update"), ("hoi", "replications"), ("multibody", "update"),
                                 ("multibody", "replications")}
    assert mb["metrics"]["csiou"]["mean"] == pytest.approx(1.0) and abs(hoi["metrics"]["fid"]["mean"]) < 1e-4


def test_the_wrong_evaluator_kind_or_protocol_kind_is_one_line(stores):
    from hoibench.scoring.evaluate import EvaluationRefused, evaluate
    base, data, mdata = stores
    with pytest.raises(ValueError, match="this track needs a recognizer one"):
        evaluate(base / "mgt", mdata, base / "ev")
    with pytest.raises(EvaluationRefused, match="behave-clean@1.1 is a hoi protocol; .* multibody-synthetic track"):
        evaluate(base / "mgt", mdata, base / "rec", protocol="behave-clean")


def test_a_new_track_is_one_registry_entry_plus_a_protocol_file(stores, tmp_path, monkeypatch):
    """A store of a dataset no shipped track knows ('lab-hoi'): register a track for it and
    write its protocol; evaluate, the reference writers and the renderer find it."""
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.reference_rows import main_reference
    from hoibench.tracks.catalog import _hoi
    base, data, _ = stores
    lab = tmp_path / "lab"
    shutil.copytree(data, lab)
    manifest = json.loads((lab / "manifest.json").read_text())
    manifest["dataset"] = "lab-hoi"
    (lab / "manifest.json").write_text(json.dumps(manifest))
    monkeypatch.setitem(_TRACKS._entries, "lab-hoi",
                        _hoi("lab-hoi", ("lab-hoi",), ("lab-hoi-clean",), "a lab's own captures"))
    src = Path(P.get_protocol("synthetic-clean").source).read_text()
    proto = tmp_path / "lab-hoi-clean.yaml"
    proto.write_text(src.replace("id: synthetic-clean", "id: lab-hoi-clean").replace("track: synthetic", "track: lab-hoi")
                     .replace("dataset: synthetic", "dataset: lab-hoi"))
    assert track_for_dataset("lab-hoi").name == "lab-hoi"
    assert main_reference("from-store", lab, tmp_path / "gt") == 0
    res = evaluate(tmp_path / "gt", lab, base / "ev", protocol=str(proto), allow_failed_gate=True,
                   allow_evaluator_mismatch=True)
    assert res["protocol"] == "lab-hoi-clean" and res["dataset"] == "lab-hoi"
    assert abs(res["metrics"]["fid"]["mean"]) < 1e-4
    assert Track.__dataclass_fields__.keys() >= {"store_kind", "evaluator_kind", "columns", "submission"}


def test_a_protocol_naming_a_reference_loop_scores_with_it(stores, tmp_path, monkeypatch):
    """``embedding_loop: chainhoi`` with one replication: the scorer hands the loop one caption
    per clip, sample 0 and the GT embeddings, and reports the loop's values as they are."""
    from hoibench.metrics import legacy_loops
    from hoibench.scoring.evaluate import evaluate
    base, data, _ = stores
    src = Path(P.get_protocol("synthetic-clean").source).read_text()
    proto = tmp_path / "synthetic-chainhoi-loop.yaml"
    proto.write_text(src.replace("id: synthetic-clean", "id: synthetic-chainhoi-loop")
                     .replace("replications: 20", "replications: 1\nembedding_loop: chainhoi"))
    parsed = P.load_protocol(proto)
    assert parsed.embedding_loop == "chainhoi" and parsed.sha256 != P.get_protocol("synthetic-clean").sha256
    seen = {}
    original = legacy_loops.run_loop

    def spy(name, text, motion, gt_motion, samples=None, **kw):
        out = original(name, text, motion, gt_motion, samples, **kw)
        seen.update(name=name, shapes=(text.shape, motion.shape, gt_motion.shape), rows=out.rows(), kw=kw)
        return out

    monkeypatch.setattr(legacy_loops, "run_loop", spy)
    res = evaluate(base / "gt", data, base / "ev", protocol=str(proto), allow_failed_gate=True)
    n = res["counts"]["scored_ids"]
    assert seen["name"] == "chainhoi" and seen["kw"]["replications"] == 1
    assert (seen["kw"]["r_size"], seen["kw"]["top_k"]) == (parsed.r_precision_pool_size, 3)
    assert seen["shapes"][0][0] == seen["shapes"][1][0] == seen["shapes"][2][0] == n
    assert res["metric_variants"]["embedding_loop"] == "chainhoi" and len(res["per_replication"]) == 1
    for name in ("r_precision_top1", "r_precision_top3", "mm_dist", "fid"):
        assert res["per_replication"][0][name] == pytest.approx(seen["rows"][0][name], abs=0)
    bad = tmp_path / "bad.yaml"
    bad.write_text(proto.read_text().replace("embedding_loop: chainhoi", "embedding_loop: mine"))
    with pytest.raises(ValueError, match="bad.yaml: field 'embedding_loop' must be one of"):
        P.load_protocol(bad)
