"""Which corruption families an audit draws from: single-body stores the registry of
:mod:`hoibench.audit.corruptions`, multi-body stores that of
:mod:`hoibench.audit.multibody_families`. An audit document names its layout
(``layout: multibody``; absent: single-body)."""
from __future__ import annotations

from typing import Mapping

from .corruptions import FAMILIES, FamilySpec
from .multibody_families import MULTIBODY_FAMILIES

#: the layouts an audit corrupts, and their family registries
REGISTRIES: dict[str, dict[str, FamilySpec]] = {"single": FAMILIES, "multibody": MULTIBODY_FAMILIES}


def registry(layout: str = "single") -> dict[str, FamilySpec]:
    """The family registry of ``layout`` (``single`` | ``multibody``)."""
    if layout not in REGISTRIES:
        raise ValueError(f"layout: expected one of {', '.join(REGISTRIES)}, got {layout!r}")
    return REGISTRIES[layout]


def layout_of(doc: Mapping) -> str:
    """The layout an audit document was made for."""
    return str(doc.get("layout", "single"))


def known_families() -> list[str]:
    """Every family name of every layout, in registry order (single-body first)."""
    return list(dict.fromkeys(f for reg in REGISTRIES.values() for f in reg))


__all__ = ["REGISTRIES", "registry", "layout_of", "known_families"]
