"""Hosted evaluation on existing engines: a Codabench competition bundle with hidden test
motions (:mod:`.bundle`), the scoring program it runs (:mod:`.scoring`), what participants
may have (:mod:`.public`), an EvalAI adapter (:mod:`.evalai`) and the import of an engine's
exported leaderboard into hoibench entries (:mod:`.engine_results`). Every score comes from
:func:`hoibench.scoring.evaluate.evaluate`, the function ``hoibench evaluate`` runs.
docs/hosting.md."""
