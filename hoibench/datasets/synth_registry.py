"""The raw layouts ``hoibench synth --layout L`` writes, registered: each entry's writer (a
lazy ``"module:function"`` called as ``writer(out, n, seed=...)``), what it writes and where,
and what it takes and leaves: ``defects`` (``--defect``), ``executor`` (``--executor``) and
whether it writes proxy body models to ``OUT/body_models``."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..core.registry import Registry, load_object

__all__ = ["SynthLayout", "SYNTH_LAYOUTS", "register_layout", "layout_names", "layouts_with"]


@dataclass(frozen=True)
class SynthLayout:
    name: str
    writer: str                 # "module:function", writer(out, n, seed=..., [defects=..., executor=...])
    what: str                   # what it writes ("clips", "grab sequences")
    where: str                  # in which layout ("in GRAB's layout")
    help: str = ""              # what ``--layout``'s help says of it (layouts with the same text share a line)
    takes_defects: bool = False
    takes_executor: bool = False
    writes_body_models: bool = True

    def load(self) -> Any:
        return load_object(self.writer)


SYNTH_LAYOUTS: Registry[SynthLayout] = Registry("synthetic layout")


def register_layout(layout: SynthLayout) -> SynthLayout:
    """Add a layout (listed after the ones before it); a name registered twice is refused."""
    return SYNTH_LAYOUTS.add(layout.name, layout)


def layout_names() -> list[str]:
    """Every registered layout, in registration order."""
    return SYNTH_LAYOUTS.in_order()


def layouts_with(flag: str) -> list[str]:
    """The layouts whose ``flag`` (``takes_defects``, ...) is true, in registration order."""
    return [n for n in layout_names() if getattr(SYNTH_LAYOUTS.get(n), flag)]


_P = __package__
_RELEASE = "multi-body sequences in that release's layout"
for _layout in (
    SynthLayout("behave", f"{_P}.synthetic:write_behave_layout", "clips", "in the behave layout",
                takes_defects=True, takes_executor=True),
    SynthLayout("omomo", f"{_P}.synthetic_layouts:write_omomo_layout", "clips", "in the omomo layout"),
    SynthLayout("rich", f"{_P}.synthetic_layouts:write_rich_layout", "clips", "in the rich layout"),
    SynthLayout("multibody", f"{_P}.multibody:write_synthetic_layout", "multi-body clips",
                "(hoibench's multi-body layout)", help="hands, people and objects in hoibench's multi-body layout",
                writes_body_models=False),
    SynthLayout("grab", f"{_P}.grab_layout:write_grab_layout", "grab sequences", "in GRAB's layout", help=_RELEASE),
    SynthLayout("core4d", f"{_P}.core4d_layout:write_core4d_layout", "core4d sequences", "in CORE4D's layout",
                help=_RELEASE),
    SynthLayout("interact", f"{_P}.interact_layout:write_interact_layout", "interact sequences",
                "in InterAct's processed layout", help="InterAct's processed layout (proxy body models)"),
    SynthLayout("taco", f"{_P}.taco_layout:write_taco_layout", "taco sequences", "in TACO's layout", help=_RELEASE),
    SynthLayout("oakink2", f"{_P}.oakink2_layout:write_oakink2_layout", "oakink2 sequences", "in OAKINK2's layout",
                help=_RELEASE),
):
    register_layout(_layout)
