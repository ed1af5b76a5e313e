"""The structure-first solid method's steps before and after the fill: analyse the exemplars
and fit a model of the 3D structure they show (particles, layers, veins or a phase field),
build that structure for a volume, and finally match each phase's colours to the exemplar's.
Exemplars with none of these structures are left to the slice optimisation
(`plan(...).kind == "none"`).

>>> found = plan([image], np.zeros(3, np.int64))
>>> found.report()
>>> built = build_structure(found, (64, 64, 64), seed=1, wrap=False)
>>> voxels = finish(filled_voxels, found, built, strength=1.0)
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.solid.structure import analysis as an
from osmap_cli.solid.structure import cells as cl
from osmap_cli.solid.structure import field as fd
from osmap_cli.solid.structure import layers as ly
from osmap_cli.solid.structure import particles as pt
from osmap_cli.solid.structure import sheets as sh
from osmap_cli.solid.structure.crowding import decorrelate_particles
from osmap_cli.solid.structure.detail import noise_detail, residual_detail
from osmap_cli.solid.structure.fill import match_phases, match_regions
from osmap_cli.solid.structure.particle_colour import ColourSpreads, match_particles
from osmap_cli.solid.structure.profiles import profile_ids
from osmap_cli.solid.structure.segment import Segmenter, gaussian_blur, smooth_volume

COVERAGE_SIGMA = 0.5  # voxels: phase fields' boundaries antialiased this much
MATCH_SIGMA = 0.5  # voxels: the colour matching maps the fill's content blurred this much


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
            count = f"{params.density * factor ** 3 * 1e6:.1f} per 10^6 voxels"
            gap = f"{params.gap / factor:.1f} voxels"
            if isinstance(params, cl.CellParams):
                return [f"packed cells: {count}, walls {gap}, {params.lloyd} Lloyd steps"]
            return [f"particles: {count}, aspect {params.aspect:.2f}, gap {gap}"]
        if isinstance(m, ly.LayerModel):
            where = (f"rings around the {'xyz'[m.axis]} axis" if m.rings else
                     "planar, normal (z, y, x) = " + ", ".join(f"{v:.2f}" for v in m.normal))
            if m.tilt:
                where += f" (turned {m.tilt:.0f} deg about the grain: no face along the layers)"
            return [f"layers: {where}, spacing {m.spacing:.1f} px, waviness {m.wobble:.1f} px"]
        if isinstance(m, sh.SheetModel):
            return ["veins: sheets normal (z, y, x) = " + ", ".join(f"{v:.2f}" for v in m.normal)
                    + f", spacing {m.spacing * m.scale:.1f} px along u, perturbation "
                    f"{m.amplitude:.1f} x {m.warp_length:.1f} px"]
        if isinstance(m, fd.FieldModel):
            return [f"field: phase order {list(m.order)}, sheets normal (z, y, x) = "
                    + ", ".join(f"{v:.2f}" for v in m.normal)
                    + f", anisotropy {m.anisotropy:.2f}, scale {m.scale:.2f}"]
        return []

    def summary(self) -> dict:
        """A JSON-able record for provenance."""
        out = {"structure": self.kind, "analysis": [a.summary() for a in self.analyses]}
        if isinstance(self.model, sh.SheetModel):
            m = self.model
            out["sheets"] = {"normal_zyx": [round(float(v), 4) for v in m.normal],
                             "spacing_px": round(m.spacing * m.scale, 3),
                             "perturbation": round(m.amplitude, 3),
                             "warp_length_px": round(m.warp_length, 3)}
        if self.notes:
            out["notes"] = list(self.notes)
        return out


def plan(exemplars, ex_of_axis, structure: str = "auto", phases: int = 0, seed: int = 0,
         wrap: bool = False, probe_cap: int | None = None) -> Plan:
    """Analyse the exemplars (one per distinct exemplar, ex_of_axis: which one each slice
    family shows) and fit the model of the structure `structure` (auto: the one the analysis
    finds); `phases`: colour phases of the segmentation (0: chosen from the exemplar);
    `probe_cap`: the largest side of the volume to build, which caps the particle fit's probe
    volume (particles.fit: a small volume costs a small fit)."""
    started = time.perf_counter()
    images = [np.ascontiguousarray(im, np.float32) for im in exemplars]
    phases = phases or None
    analyses = [an.analyse(im, wrap, phases) for im in images]
    kinds = [a.kind for a in analyses]
    chosen = structure
    notes = []
    if chosen == "auto":
        if kinds.count("layers") >= max(1, (len(kinds) + 1) // 2):
            chosen = "layers"
        elif all(k == "particles" for k in kinds):
            chosen = "particles"
        elif (all(k in ("veins", "field", "particles", "layers") for k in kinds)
              and kinds.count("veins") >= max(1, kinds.count("field"))):
            chosen = "veins"
        elif "field" in kinds and all(k in ("veins", "field", "particles", "layers")
                                      for k in kinds):
            chosen = "field"
        else:
            chosen = "none"
    result = Plan(chosen, analyses, images, np.asarray(ex_of_axis, np.int64), notes=notes)
    if chosen == "none":
        result.seconds = time.perf_counter() - started
        return result
    if chosen == "particles":
        _plan_particles(result, analyses, images, seed, wrap, probe_cap)
    else:
        seg = _joint_segmenter(images, phases, wrap)
        labels = [seg.labels(im, wrap) for im in images]
        colours = _phase_colours(images, labels)
        result.ex_labels = labels
        result.ex_identity = [colours[lb].astype(np.float32) for lb in labels]
        result.colours = colours
        if chosen == "layers":
            result.model = ly.fit_layers(images, labels, analyses, result.ex_of_axis)
        elif chosen == "veins":
            result.model = sh.fit_sheets(labels, analyses, result.ex_of_axis, seed)
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


def _plan_particles(result: Plan, analyses, images, seed, wrap, probe_cap=None) -> None:
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
        float(np.mean([s.gap for s in sources])),
        ColourSpreads.pooled([s.spreads for s in sources]))
    params, _ = cl.fit_packing(analyses, pooled, seed, factor=factor, cap=probe_cap)
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


@dataclass(frozen=True)
class Built:
    """A volume's structure: labels int64 (Z, Y, X) (the phase of every voxel); identity float32
    (Z, Y, X, I) (the guide's identity channels); coverage float32 (Z, Y, X, K): every phase's
    share of each voxel (antialiased boundaries); regions int64 (Z, Y, X) with their colours
    (R, C) and source profiles (R,) when the phases hold regions of one colour each
    (particles), else None; walls: packed cells' tessellation (cells.Walls), else None; bands:
    layers' and veins' bands (layers.Bands: the coordinate u across them, whose level sets are
    their sheets), else None."""

    labels: np.ndarray
    identity: np.ndarray
    coverage: np.ndarray
    regions: np.ndarray | None = None
    region_colours: np.ndarray | None = None
    region_sources: np.ndarray | None = None  # each region's source profile (particles)
    walls: cl.Walls | None = None
    bands: ly.Bands | None = None


def build_structure(found: Plan, shape, seed: int, wrap: bool) -> Built:
    """The volume's structure (particles: each a region of its source profile's colour)."""
    if found.kind == "particles":
        sources, params, factor = found.model
        built = cl.build_packing(shape, params, sources, seed, wrap, factor)
        inside = built.owner >= 0
        colours = sources.colours[built.source]
        identity = np.where(inside[..., None], colours[np.maximum(built.owner, 0)],
                            found.matrix_colour)
        share = np.clip(0.5 + built.sdf, 0.0, 1.0)  # the particle's share of the voxel
        return Built(inside.astype(np.int64), identity.astype(np.float32),
                     np.stack([1.0 - share, share], -1).astype(np.float32),
                     built.owner.astype(np.int64), colours, built.source, built.walls)
    k = len(found.colours)
    bands = None
    if found.kind in ("layers", "veins"):
        bands = (ly.layer_bands if found.kind == "layers" else sh.sheet_bands)(
            shape, found.model, seed, wrap)
        labels = bands.labels()
        # the bands' boundaries are smooth surfaces: antialiased from their distance along
        # u, without the voxel staircases that blurring the labels keeps (the fill would
        # copy them as edges along the grid)
        coverage = bands.coverage(k)
    else:
        labels = fd.build_field(shape, found.model, seed, wrap)
        onehot = (labels[..., None] == np.arange(k)).astype(np.float32)
        coverage = smooth_volume(onehot, COVERAGE_SIGMA, wrap)
    # the identity guide antialiased like the coverage: hard phase steps on the voxel grid
    # would make the fill copy their staircases (axis-aligned edges)
    identity = coverage @ found.colours.astype(np.float32)
    return Built(labels, identity.astype(np.float32), coverage, bands=bands)


def finish(voxels, found: Plan, built: Built, strength: float, wrap: bool,
           record=None) -> np.ndarray:
    """The fill's voxels with each phase's colours (and each particle's mean) moved `strength`
    of the way to the exemplar's. record(stage, voxels), when given, sees the colours after
    each step ("phases", then for particles "means" and "particles")."""
    record = record or (lambda stage, values: None)
    if strength <= 0:
        return voxels
    pixels = np.concatenate([im.reshape(-1, im.shape[2]) for im in found.images])
    # the mapping stretches contrast: applied to the fill's low-pass (onto the exemplar's
    # low-pass), it does not amplify the fill's faint 1-voxel hatching, which stays as it is
    low = smooth_volume(voxels, MATCH_SIGMA, wrap)
    blurred = [gaussian_blur(im, MATCH_SIGMA, wrap).astype(np.float32) for im in found.images]
    # the 2-voxel period is mapped too for particles (a 1-voxel gap is structure) and layers
    # (left unmapped, the grain reads coarser: planks' scale 1.26 against 0.83 at 64^3)
    nyquist = built.regions is not None or found.kind == "layers"
    matched = match_phases(low, built.labels, built.coverage, blurred, found.ex_of_axis,
                           found.ex_labels, nyquist=nyquist, wrap=wrap) + (voxels - low)
    record("phases", matched)
    if built.regions is not None:
        matched = match_regions(matched, built.regions, built.region_colours,
                                built.coverage[..., 1], pixels.min(0), pixels.max(0))
        record("means", matched)
        matched = match_particles(matched, built.regions, built.region_sources,
                                  found.model[0].spreads, built.coverage[..., 1],
                                  pixels.min(0), pixels.max(0))
        record("particles", matched)
        if built.walls is None:  # packed cells' thin walls pool no matrix
            matched = decorrelate_particles(matched, built.labels, found.images,
                                            found.ex_of_axis, found.ex_labels, wrap)
    return (voxels + strength * (matched - voxels)).astype(np.float32)


def add_detail(voxels, source, found: Plan, built: Built, images, ex_of_axis, strength: float,
               seed: int, wrap: bool, veins: str = "noise", grain: float = 0.0) -> np.ndarray:
    """The filled voxels with the exemplar's residual detail, `strength` of its variance per
    phase. Particles and layers copy it from every voxel's source pixel (residual_detail).
    Veins take it as noise with the detail's spectrum, their whole fine band then drawn out
    along the sheets' local planes (noise_detail, `grain` the in-sheet blur in voxels, 0:
    fitted; `veins` "copy": copied as the others, "none": none): copied, it follows the fill's
    window lattice, which their wide uniform regions show as a grid. Phase fields take none."""
    if found.kind in ("particles", "layers") or (found.kind == "veins" and veins == "copy"):
        return residual_detail(voxels, source, images, ex_of_axis, built.labels,
                               found.ex_labels, strength, wrap)
    if found.kind == "veins" and veins == "noise":
        return noise_detail(voxels, images, ex_of_axis, built.labels, found.ex_labels, strength,
                            seed, sh.sheet_normals(built.bands.u, built.bands.period), wrap, grain)
    return voxels
