"""The structure-first solid method: analyse the exemplars, build the 3D structure they show
(particles, layers or a phase field), then fill in the appearance with the guided slice-window
optimisation. Exemplars with none of these structures are left to the slice optimisation
(`plan(...).kind == "none"`).

>>> found = plan([image], np.zeros(3, np.int64), StructureOptions())
>>> found.report()
>>> voxels, source, timings = synthesize(found, shape, StructureOptions(), seed=1, wrap=False)
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.options import Options, option
from osmap_cli.solid.structure import analysis as an
from osmap_cli.solid.structure import field as fd
from osmap_cli.solid.structure import layers as ly
from osmap_cli.solid.structure import particles as pt
from osmap_cli.solid.structure.fill import FillParams, fill, match_phases, match_regions
from osmap_cli.solid.structure.profiles import profile_ids
from osmap_cli.solid.structure.segment import Segmenter, smooth_volume

STRUCTURES = ("auto", "particles", "layers", "field", "none")
CORRECTION_SIGMA = 0.6  # voxels
LAYOUTS = ("osmap", "random")


@dataclass(frozen=True)
class StructureOptions(Options):
    """The structure method's own tunables (solid preset keys and tuning flags)."""

    structure: str = option("auto", help="the structure built: auto (the analysis decides), "
                            "particles, layers, field, or none (the slice optimisation alone)",
                            choices=STRUCTURES, tunable=True)
    phases: int = option(0, 0, 6, "colour phases of the segmentation (0: chosen from the "
                         "exemplar, 2 to 4)", tunable=True)
    fill_levels: int = option(3, 1, 5, "pyramid levels of the guided fill", tunable=True)
    fill_window: int = option(6, 4, 12, "slice window side of the guided fill", tunable=True)
    fill_iterations: int = option(4, 1, 12, "search + average iterations per level",
                                  tunable=True)
    guide_weight: float = option(1.0, 0.0, 10.0, "weight of the structure guide channels "
                                 "against the colours in the window search", tunable=True)
    guide_clip: float = option(4.0, 1.0, 32.0, "pixels from a phase boundary at which the "
                               "distance guide saturates", tunable=True)
    layout: str = option("osmap", help="the fill's coarsest positions: osmap (the OS-Map's "
                         "layout) or random", choices=LAYOUTS, tunable=True)
    phase_match: float = option(1.0, 0.0, 1.0, "how far each phase's colours are moved to the "
                                "exemplar's colours of that phase (quantile mapping)",
                                tunable=True)


@dataclass
class Plan:
    """What the analysis found and the structure model fitted to it."""

    kind: str
    analyses: list
    images: list
    ex_of_axis: np.ndarray
    ex_labels: list = field(default_factory=list)
    ex_identity: list = field(default_factory=list)
    model: object = None
    notes: list = field(default_factory=list)
    seconds: float = 0.0
    colours: np.ndarray | None = None  # layers, field: mean colour of every phase
    matrix_colour: np.ndarray | None = None  # particles: the matrix's mean colour

    def report(self) -> list[str]:
        """Lines for --analyse and --verbose."""
        lines = []
        names = ("x", "y", "z")
        for e, found in enumerate(self.analyses):
            if len(self.analyses) > 1:
                fams = ", ".join(names[a] for a in range(3) if int(self.ex_of_axis[a]) == e)
                lines.append(f"exemplar {e + 1} (slices normal to {fams}):")
            lines += [("  " if len(self.analyses) > 1 else "") + line for line in found.report()]
        lines.append(f"structure built: {self.kind}" + (f" ({'; '.join(self.notes)})"
                                                         if self.notes else ""))
        lines += self.model_lines()
        return lines

    def model_lines(self) -> list[str]:
        m = self.model
        if isinstance(m, tuple):  # particles: (sources, params, factor)
            _, params, factor = m
            return [f"particles: {params.density * factor ** 3 * 1e6:.1f} per 10^6 voxels, "
                    f"aspect {params.aspect:.2f}, gap {params.gap / factor:.1f} voxels"]
        if isinstance(m, ly.LayerModel):
            where = (f"rings around the {'xyz'[m.axis]} axis" if m.rings else
                     "planar, normal (z, y, x) = " + ", ".join(f"{v:.2f}" for v in m.normal))
            return [f"layers: {where}, spacing {m.spacing:.1f} px, waviness {m.wobble:.1f} px"]
        if isinstance(m, fd.FieldModel):
            return [f"field: phase order {list(m.order)}, sheets normal (z, y, x) = "
                    + ", ".join(f"{v:.2f}" for v in m.normal)
                    + f", anisotropy {m.anisotropy:.2f}, scale {m.scale:.2f}"]
        return []

    def summary(self) -> dict:
        """A JSON-able record for provenance."""
        out = {"structure": self.kind, "analysis": [a.summary() for a in self.analyses]}
        if self.notes:
            out["notes"] = list(self.notes)
        return out


def plan(exemplars, ex_of_axis, options: StructureOptions, seed: int = 0,
         wrap: bool = False) -> Plan:
    """Analyse the exemplars (one per distinct exemplar, ex_of_axis: which one each slice
    family shows) and fit the structure model."""
    started = time.perf_counter()
    images = [np.ascontiguousarray(im, np.float32) for im in exemplars]
    phases = options.phases or None
    analyses = [an.analyse(im, wrap, phases) for im in images]
    kinds = [a.kind for a in analyses]
    chosen = options.structure
    notes = []
    if chosen == "auto":
        if kinds.count("layers") >= max(1, (len(kinds) + 1) // 2):
            chosen = "layers"
        elif all(k == "particles" for k in kinds):
            chosen = "particles"
        elif all(k in ("field", "particles", "layers") for k in kinds) and "field" in kinds:
            chosen = "field"
        else:
            chosen = "none"
    result = Plan(chosen, analyses, images, np.asarray(ex_of_axis, np.int64), notes=notes)
    if chosen == "none":
        result.seconds = time.perf_counter() - started
        return result
    if chosen == "particles":
        _plan_particles(result, analyses, images, seed, wrap)
    else:
        seg = _joint_segmenter(images, phases, wrap)
        labels = [seg.labels(im, wrap) for im in images]
        colours = _phase_colours(images, labels)
        result.ex_labels = labels
        result.ex_identity = [colours[lb].astype(np.float32) for lb in labels]
        result.colours = colours
        if chosen == "layers":
            result.model = ly.fit_layers(images, labels, analyses, result.ex_of_axis)
        else:
            result.model = fd.fit_field(images, labels, analyses, result.ex_of_axis, seed)
    result.seconds = time.perf_counter() - started
    return result


def _joint_segmenter(images, phases, wrap) -> Segmenter:
    """One set of phase centres for all the exemplars (so a phase is the same material on every
    face): fitted on the exemplars side by side."""
    if len(images) == 1:
        return Segmenter.fit(images[0], phases, wrap)
    h = max(im.shape[0] for im in images)
    mosaic = np.concatenate([np.pad(im, ((0, h - im.shape[0]), (0, 0), (0, 0)), mode="edge")
                             for im in images], 1)
    return Segmenter.fit(mosaic, phases)


def _phase_colours(images, labels) -> np.ndarray:
    k = int(max(lb.max() for lb in labels)) + 1
    c = images[0].shape[2]
    out = np.zeros((k, c))
    for p in range(k):
        pix = np.concatenate([im[lb == p] for im, lb in zip(images, labels)])
        out[p] = pix.mean(0) if len(pix) else 0.0
    return out


def _plan_particles(result: Plan, analyses, images, seed, wrap) -> None:
    """Particle sources from every exemplar's profiles, pooled; the exemplar guides."""
    from osmap_cli.solid.structure.analysis import enlarge

    masks, sources = [], []
    factor = analyses[0].reader.factor
    for found, im in zip(analyses, images):
        if found.kind != "particles":
            raise OsmapError("--structure particles: the exemplar shows no separable particles "
                             "(run --analyse to see what it shows)")
        masks.append(found.labels.astype(bool))
        big = enlarge(im, found.reader.factor)
        sources.append(pt.sources_from(big, found.reader.working_mask(big, wrap),
                                       found.profiles, wrap))
    pooled = pt.ParticleSources(
        np.concatenate([s.diameters for s in sources]),
        np.concatenate([s.colours for s in sources]),
        pt.pooled([s.target for s in sources]) if len(sources) > 1 else sources[0].target,
        float(np.mean([s.gap for s in sources])))
    params, _ = pt.fit(pooled, seed)
    result.model = (pooled, params, factor)
    result.ex_labels = [m.astype(np.int64) for m in masks]
    result.ex_identity = []
    matrix = np.concatenate([im[~m] for im, m in zip(images, masks)]).mean(0)
    result.matrix_colour = matrix
    for im, m in zip(images, masks):
        ids, count = profile_ids(m.astype(np.int64), (1,), wrap)
        flat = ids.ravel()
        keep = flat >= 0
        area = np.maximum(np.bincount(flat[keep], minlength=count), 1)
        cols = np.stack([np.bincount(flat[keep], im.reshape(-1, im.shape[2])[keep, c], count)
                         / area for c in range(im.shape[2])], 1)
        result.ex_identity.append(np.where((ids >= 0)[..., None], cols[np.maximum(ids, 0)],
                                           matrix).astype(np.float32))


def build_structure(found: Plan, shape, seed: int, wrap: bool):
    """(labels int64 (Z, Y, X), identity float32 (Z, Y, X, C), regions int64 (Z, Y, X) or
    None, region colours (R, C) or None) of the volume: particles are regions of one colour
    each (their source profile's)."""
    if found.kind == "particles":
        sources, params, factor = found.model
        built = pt.build(shape, params, sources, seed, wrap, factor)
        inside = built.owner >= 0
        colours = sources.colours[built.source]
        identity = np.where(inside[..., None], colours[np.maximum(built.owner, 0)],
                            found.matrix_colour)
        return (inside.astype(np.int64), identity.astype(np.float32),
                built.owner.astype(np.int64), colours)
    if found.kind == "layers":
        labels = ly.build_layers(shape, found.model, seed, wrap)
    else:
        labels = fd.build_field(shape, found.model, seed, wrap)
    return labels, found.colours[labels].astype(np.float32), None, None


def synthesize(found: Plan, shape, options: StructureOptions, seed: int, wrap: bool,
               layout=None, progress=None):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3), seconds of the structure
    step): build the structure, fill it, match each phase's colours."""
    started = time.perf_counter()
    labels, identity, regions, region_colours = build_structure(found, shape, seed, wrap)
    structure_seconds = found.seconds + time.perf_counter() - started
    params = FillParams(seed=seed, wrap=wrap, levels=options.fill_levels,
                        window=options.fill_window, iterations=options.fill_iterations,
                        clip=options.guide_clip, guide_weight=options.guide_weight)
    voxels, source = fill(found.images, found.ex_of_axis, found.ex_labels, found.ex_identity,
                          labels, identity, params, layout=layout, progress=progress)
    if options.phase_match > 0:
        matched = match_phases(voxels, labels, found.images, found.ex_of_axis,
                               found.ex_labels, options.phase_match)
        if regions is not None:
            pixels = np.concatenate([im.reshape(-1, im.shape[2]) for im in found.images])
            matched = match_regions(matched, regions, region_colours, options.phase_match,
                                    pixels.min(0), pixels.max(0))
        # the corrections differ from phase to phase: applied voxel by voxel they would redraw
        # every boundary as a voxel staircase; smoothed, they keep the fill's antialiasing
        voxels = voxels + smooth_volume(matched - voxels, CORRECTION_SIGMA, wrap)
    return voxels.astype(np.float32), source, structure_seconds
