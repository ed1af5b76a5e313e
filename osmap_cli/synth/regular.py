"""Regular textures keep their lattice: the lattice at each pyramid level, as the refinement's
kernels take it (osmap_kernels.lattice).

Copies whose exemplar positions are *consistent* with their output pixels (the texture's
lattice at the position lands on the output's lattice at the pixel) continue each other's
structure across their borders: courses stay straight, weaves and knits stay in step, lines of
text keep their spacing. From the first level whose shortest period spans LATTICE_MIN_PERIOD
exemplar pixels, the field is moved to consistent positions (each copy by less than half a
period), every candidate of the refinement is snapped to one, and whole-copy shifts keep to
the lattice. The output's phase is the one most of the field already has (or 0 where pinned
pixels fix it). An exemplar guide painted in a few values (guided synthesis of several
materials) gives each of its regions its own lattice, or none (RegionLattices).

>>> lattice = resolve_lattice("12,0", exemplar)      # --lattice DX,DY: stripes 12 px apart
>>> level = level_lattice(lattice, 4, np.eye(2), pos, lo, hi)
>>> pos = level.snap(pos, lo, hi)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.synth.lattice import Lattice, find_lattice, parse_lattice
from osmap_kernels.lattice import (
    NO_LATTICE,
    NO_REGIONS,
    NO_TABLE,
    LatticeParams,
    phase_sums,
    snap_field,
)

__all__ = ["BAND_LEFTOVER", "LATTICE_MIN_PERIOD", "LevelLattice", "RegionLattices",
           "atlas_phase", "describe", "guide_regions", "lattice_text", "leftover", "level_labels",
           "level_lattice", "region_lattices", "resolve_lattice", "wrapped"]

# a level follows the lattice once its shortest period spans this many exemplar pixels (at
# coarser levels a period is a pixel or two, which integral positions cannot resolve)
LATTICE_MIN_PERIOD = 3.0
# where the output's lattice differs from the exemplar's (a tileable output, a tileable photo's
# bands), a copy continues while within this many pixels of the output's phase
DRIFT_KEEP = 1.0
# a tileable photo keeps its lattice when it holds a whole number of periods across each axis
# to within this many exemplar pixels (the mismatch its wrap line then shows at most)
BAND_LEFTOVER = 1.0
# a tileable output keeps the lattice when fitting a whole number of periods across it moves
# copies of --max-copy pixels by at most this much (exemplar pixels) against one another
WRAP_DRIFT = 0.5
_NO_PHASE = np.zeros((1, 1, 2), np.float32)
# an exemplar guide of at most this many values, each covering at least REGION_MIN_AREA
# pixels, is a painted map of materials: each value's region keeps its own lattice
MAX_REGIONS = 8
REGION_MIN_AREA = 32 * 32


@dataclass(frozen=True)
class RegionLattices:
    """A lattice per region of the exemplar (guided synthesis of several materials): values,
    the exemplar guide's value of each region; labels, int32 (h, w) each exemplar pixel's
    region; lattices, each region's Lattice or None; outputs, each region's output lattice
    where it differs from the exemplar's (a tileable output: `wrapped`), else None."""

    values: tuple
    labels: np.ndarray
    lattices: tuple
    outputs: tuple

    def any(self) -> bool:
        return any(lat is not None for lat in self.lattices)


def guide_regions(guide: np.ndarray) -> tuple[tuple, np.ndarray] | None:
    """(values, int32 labels (h, w)) when the exemplar guide is a map of a few materials (2 to
    MAX_REGIONS values, each on at least REGION_MIN_AREA pixels), else None (a gradient, a
    height map, a luminance)."""
    guide = np.asarray(guide, np.float32)
    values, labels, counts = np.unique(guide, return_inverse=True, return_counts=True)
    if not 2 <= len(values) <= MAX_REGIONS or counts.min() < REGION_MIN_AREA:
        return None
    return tuple(float(v) for v in values), labels.reshape(guide.shape).astype(np.int32)


def region_lattices(value: str, exemplar: np.ndarray, regions) -> RegionLattices:
    """Each region's lattice (`regions`: guide_regions' answer), read from the region's own
    pixels (the bounding box of the region, its other pixels left out), as --lattice `value`
    (auto or off) asks."""
    values, labels = regions
    found = []
    for r in range(len(values)):
        mask = labels == r
        rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        box = slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)
        found.append(resolve_lattice(value, exemplar[box], mask[box]))
    return RegionLattices(values, labels, tuple(found), (None,) * len(values))


def resolve_lattice(value: str, exemplar: np.ndarray, known: np.ndarray | None = None
                    ) -> Lattice | None:
    """The lattice `--lattice VALUE` asks for: auto (read from the exemplar, from its `known`
    pixels when given; None when it has none), off (None) or the vectors given
    (DX,DY[:DX,DY])."""
    if value == "off":
        return None
    if value == "auto":
        return find_lattice(exemplar, known)
    try:
        return parse_lattice(value)
    except ValueError as exc:
        raise OsmapError(f"--lattice {value}: {exc}") from None


def lattice_text(lattice: Lattice | RegionLattices | None) -> str:
    """The lattice as provenance records it: 'none', or the vectors as --lattice takes them
    (a lattice per guide region: 'guide 0: none; guide 1: 0.00,12.00')."""
    if isinstance(lattice, RegionLattices):
        return "; ".join(f"guide {v:g}: {lattice_text(lat)}"
                         for v, lat in zip(lattice.values, lattice.lattices))
    if lattice is None:
        return "none"
    return ":".join(f"{v[1]:.2f},{v[0]:.2f}" for v in lattice.vectors)


def describe(lattice: Lattice | RegionLattices | None) -> str:
    """One phrase for a report: 'none', 'stripes every 12.9 px (--lattice 0.2,12.9)', ...
    (a lattice per guide region: 'guide 0: none; guide 1: stripes ...')."""
    if isinstance(lattice, RegionLattices):
        return "; ".join(f"guide {v:g}: {describe(lat)}"
                         for v, lat in zip(lattice.values, lattice.lattices))
    if lattice is None:
        return "none"
    flag = lattice_text(lattice)
    if len(lattice.vectors) == 1:
        return f"stripes every {lattice.shortest():.1f} px (--lattice {flag})"
    return f"2D lattice (--lattice {flag})"


def wrapped(lattice: Lattice, out_shape, jac, span: float) -> Lattice | None:
    """The lattice nearest `lattice` that a wrapping output of `out_shape` (H, W) holds a
    whole number of times across each axis (a tileable output: the wrap line is then a
    lattice line like any other), or None when it strays from `lattice` by more than
    WRAP_DRIFT exemplar pixels over `span` output pixels (rigid copies of that size would no
    longer meet in step). jac: the output-to-exemplar Jacobian (2x2)."""
    N = lattice.dual()
    length = np.asarray(out_shape, np.float64)
    span_j = np.asarray(jac, np.float64) @ np.diag(length)
    counts = np.rint(N @ span_j)
    # cycles the fit adds per output pixel along each axis, times a period, over the span
    periods = 1.0 / np.hypot(N[:, 0], N[:, 1])
    drift = np.abs(N @ span_j - counts) / length[None, :] * periods[:, None] * span
    if float(drift.max()) > WRAP_DRIFT:
        return None
    fitted = counts @ np.linalg.pinv(span_j)
    if np.linalg.matrix_rank(fitted) < len(lattice.vectors):
        return None
    basis = np.linalg.pinv(fitted)
    return Lattice(tuple(tuple(float(c) for c in basis[:, i]) for i in range(basis.shape[1])),
                   lattice.strength)


@dataclass(frozen=True)
class LevelLattice:
    """The lattice of one pyramid level: its kernel record and phase maps."""

    params: LatticeParams
    phase_map: np.ndarray  # float32 (h, w, 2): each exemplar's phase in an atlas; or (1, 1, 2)
    # a lattice per region of the exemplar (osmap_kernels.lattice): float64 (R, 18) and int32
    # (h, w); no rows: `params` everywhere
    table: np.ndarray = field(default_factory=lambda: NO_TABLE)
    regions: np.ndarray = field(default_factory=lambda: NO_REGIONS)

    @property
    def regional(self) -> bool:
        return self.table.shape[0] != 0

    def snap(self, pos: np.ndarray, lo, hi) -> np.ndarray:
        """pos (float32 (H, W, 2)) with every position moved to a consistent one in [lo, hi]."""
        return snap_field(np.ascontiguousarray(pos, np.float32), self.params, self.phase_map,
                          float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), self.table,
                          self.regions)


def level_lattice(lattice: Lattice | RegionLattices | None, level_scale: int, jac,
                  pos: np.ndarray, lo, hi, phase_map: np.ndarray | None = None,
                  pinned_phase: bool = False, output: Lattice | None = None
                  ) -> LevelLattice | None:
    """The lattice at a level `level_scale` times coarser than the exemplar, or None before its
    periods are long enough (LATTICE_MIN_PERIOD). jac: the uniform output-to-exemplar
    Jacobian; pos: the level's current positions, whose prevailing phase the output takes
    (pinned_phase: phase 0, the one kept pixels at their own positions have); phase_map:
    float32 (h, w, 2) exemplar phases (an atlas); output: the output's own lattice when it
    differs from the exemplar's (a tileable output: `wrapped`). A RegionLattices gives each
    region its own lattice and phase (the positions in that region's prevailing one)."""
    if lattice is None:
        return None
    phases = _NO_PHASE if phase_map is None else np.ascontiguousarray(phase_map, np.float32)
    pos = np.ascontiguousarray(pos, np.float32)
    if isinstance(lattice, RegionLattices):
        return _regional(lattice, level_scale, jac, pos, phases, pinned_phase)
    record = _level_record(lattice, level_scale, jac, output, phase_map is not None)
    if record is None:
        return None
    b = np.zeros(2)
    if not pinned_phase:
        b = _phase(phase_sums(pos, record(0.0, 0.0), phases, NO_TABLE, NO_REGIONS)[0],
                   record(0.0, 0.0).rank)
    return LevelLattice(record(*b), phases)


def _level_record(lattice: Lattice, level_scale: int, jac, output: Lattice | None,
                  atlas: bool):
    """record(b0, b1) -> the level's LatticeParams at output phase b, or None before the
    lattice's periods are long enough (see level_lattice)."""
    level = lattice.scaled(1.0 / level_scale)
    if level.shortest() < LATTICE_MIN_PERIOD:
        return None
    jac = np.asarray(jac, np.float64)
    N = level.dual()
    T = level.basis()
    rank = N.shape[0]
    G = (N if output is None else output.scaled(1.0 / level_scale).dual()) @ jac
    N2, T2, G2 = np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))
    N2[:rank], T2[:, :rank], G2[:rank] = N, T, G
    integral = bool(np.array_equal(jac, np.eye(2)))
    # copies drift against an output lattice that differs from the exemplar's (or a phase map)
    keep = DRIFT_KEEP if output is not None or atlas else 0.5
    axis = int(abs(N2[0, 1]) > abs(N2[0, 0]))

    def record(b0, b1):
        return LatticeParams(rank, *(float(v) for v in N2.ravel()),
                             *(float(v) for v in T2.ravel()), *(float(v) for v in G2.ravel()),
                             float(b0), float(b1), integral, axis, keep)
    return record


def _phase(sums: np.ndarray, rank: int) -> np.ndarray:
    """The output phase b (cycles) the circular mean of a field's phases gives."""
    b = np.angle(sums) / (2 * np.pi)
    b[rank:] = 0.0
    return b


def _regional(lattice: RegionLattices, level_scale: int, jac, pos: np.ndarray,
              phases: np.ndarray, pinned_phase: bool) -> LevelLattice | None:
    """level_lattice of a lattice per region: the kernels' table and this level's regions."""
    records = [None if lat is None else _level_record(lat, level_scale, jac, out, False)
               for lat, out in zip(lattice.lattices, lattice.outputs)]
    if all(r is None for r in records):
        return None
    regions = level_labels(lattice.labels, level_scale)
    table = np.array([_row(NO_LATTICE if r is None else r(0.0, 0.0)) for r in records])
    if not pinned_phase:
        sums = phase_sums(pos, NO_LATTICE, phases, table, regions)
        table = np.array([_row(NO_LATTICE if r is None else r(*_phase(s, r(0.0, 0.0).rank)))
                          for r, s in zip(records, sums)])
    return LevelLattice(NO_LATTICE, phases, np.ascontiguousarray(table, np.float64), regions)


def level_labels(labels: np.ndarray, level_scale: int) -> np.ndarray:
    """int32 region labels (h, w) at a pyramid level `level_scale` times coarser: each level
    pixel (i, j) covers finest pixels from (i, j) * level_scale on, and takes its centre's."""
    rows = np.minimum(np.arange(-(-labels.shape[0] // level_scale)) * level_scale
                      + level_scale // 2, labels.shape[0] - 1)
    cols = np.minimum(np.arange(-(-labels.shape[1] // level_scale)) * level_scale
                      + level_scale // 2, labels.shape[1] - 1)
    return np.ascontiguousarray(labels[rows][:, cols], np.int32)


def _row(params: LatticeParams) -> list:
    """A LatticeParams as a row of the kernels' region table."""
    return [float(v) for v in params]


def leftover(lattice: Lattice, shape) -> float:
    """How far (exemplar pixels) a photo of `shape` (H, W) falls short of or beyond a whole
    number of periods across either axis: the lattice's mismatch across its wrap lines."""
    N = lattice.dual()
    periods = 1.0 / np.hypot(N[:, 0], N[:, 1])
    cycles = N @ np.diag(np.asarray(shape, np.float64))
    return float((np.abs(cycles - np.rint(cycles)) * periods[:, None]).max())


def atlas_phase(lattice: Lattice, exemplars, origins, shape, level: int) -> np.ndarray:
    """float32 (h, w, 2): the phase map of an atlas level (`shape`) holding `exemplars` at
    `origins` (finest-level (row, col)): in each exemplar's part, the phase that puts its own
    lattice in step with the first exemplar's (its lattice's offset, read by demodulating its
    luminance at the lattice's frequencies), minus its origin's phase."""
    N = lattice.dual()
    out = np.zeros((*shape, 2), np.float32)
    scale = 2 ** level
    reference = None
    for ex, (y0, x0) in zip(exemplars, origins):
        own = _lattice_phase(ex, N)
        if reference is None:
            reference = own
        phase = own - reference - N @ np.array([y0, x0], np.float64)
        h, w = ex.shape[:2]
        rows = slice(y0 // scale, -(-(y0 + h) // scale))
        cols = slice(x0 // scale, -(-(x0 + w) // scale))
        out[rows, cols, :len(phase)] = phase
    return out


def _lattice_phase(exemplar: np.ndarray, N: np.ndarray) -> np.ndarray:
    """The phase (cycles, per row of N) at which the exemplar's luminance repeats: the
    structure at position e has lattice coordinates N e + phase."""
    x = np.asarray(exemplar, np.float64)
    gray = x[..., :3].mean(axis=2) if x.ndim == 3 else x
    gray = gray - gray.mean()
    rows, cols = np.indices(gray.shape, dtype=np.float64)
    out = []
    for n in N:
        z = np.sum(gray * np.exp(-2j * np.pi * (n[0] * rows + n[1] * cols)))
        out.append(np.angle(z) / (2 * np.pi))
    return np.array(out)
