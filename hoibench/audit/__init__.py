"""Metric validity audit: controlled corruptions of a store's ground-truth test clips
(:mod:`hoibench.audit.corruptions`: the :data:`FAMILIES` registry and :func:`apply`)."""
from .checks import Context
from .corruptions import FAMILIES, FamilySpec, apply, spec_object_nouns, split_context

__all__ = ["FAMILIES", "Context", "FamilySpec", "apply", "spec_object_nouns", "split_context"]
