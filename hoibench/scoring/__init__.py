"""Scoring: submissions, the one evaluation pipeline over tracks, comparisons, importers, prompts and reference rows."""
