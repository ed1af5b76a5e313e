"""The table of solid synthesis methods: `METHODS[name]` -> a `Method` row.

A row names the module that implements the method (osmap_cli.solid.method_<name>), which holds
`Options` (the method's options record: `Options.from_solid(solid_options)`, --quality applied)
and `run(task, options, progress)` -> SolidResult. The module loads on first use, so the table
(read by --help and the option declarations) costs nothing to import.

>>> list(METHODS)
['structure', 'osmap', 'kopf', 'legacy']
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class Method:
    """One row of the table."""

    name: str  # the --method value
    summary: str  # one line: what it does (--help, --method's choices)
    quality: str  # what --quality fast and high change for it (--help, docs)
    module: str  # osmap_cli.solid.<module>: Options and run

    def load(self):
        return importlib.import_module(f"osmap_cli.solid.{self.module}")

    @property
    def run(self):
        """run(task: SolidTask, options: Options, progress=None) -> SolidResult."""
        return self.load().run

    @property
    def options(self):
        """The options record class: Options.from_solid(SolidOptions) -> Options."""
        return self.load().Options


_OPTIMISATION_QUALITY = ("fast = one iteration per level and at most 1 similar-position "
                         "candidate, high = one iteration and 2 candidates more")

METHODS = {m.name: m for m in (
    Method(name="structure",
           summary="the 3D structure the exemplar shows first (particles, layers or a phase "
                   "field), then its appearance by the optimisation guided by it (method osmap "
                   "when the exemplar shows none)",
           quality=_OPTIMISATION_QUALITY, module="method_structure"),
    Method(name="osmap",
           summary="the OS-Map lays out the coarsest volume, then a sharpened Kopf "
                   "optimisation",
           quality=_OPTIMISATION_QUALITY, module="method_osmap"),
    Method(name="kopf",
           summary="Kopf et al. 2007 texture optimisation as published (softer, features too "
                   "large)",
           quality=_OPTIMISATION_QUALITY, module="method_kopf"),
    Method(name="legacy",
           summary="the search + mode pipeline of earlier versions (boxy)",
           quality="fast = one iteration per finer level, half the coarsest level's, at most 1 "
                   "candidate of each kind, high = one iteration more per level (2 at the "
                   "coarsest) and 2 candidates more of each kind",
           module="method_legacy"),
)}


def method_help() -> str:
    """'name: summary; ...' of every method."""
    return "; ".join(f"{m.name}: {m.summary}" for m in METHODS.values())


def quality_help() -> str:
    """What --quality does, method by method ('osmap, kopf: fast = ...; legacy: ...')."""
    names: dict[str, list[str]] = {}
    for m in METHODS.values():
        names.setdefault(m.quality, []).append(m.name)
    return "; ".join(f"{', '.join(group)}: {text}" for text, group in names.items())
