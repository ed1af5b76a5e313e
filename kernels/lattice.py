"""Lattice-consistent positions: the kernels that keep a regular texture on its lattice.

A regular exemplar repeats after its period vectors (osmap_cli.synth.lattice). An output pixel
p shows the texture's lattice at phase psi(p) = G p + b (cycles, one per period vector: G the
output lattice's dual times the output-to-exemplar Jacobian, b the phase the whole output
agrees on); an exemplar position s has phase N s + phase_map[s] (N the dual; phase_map 0 for
one exemplar, a map of shape (1, 1, 2); each exemplar's own phase in an atlas of several).
s is *consistent* with p when the two phases agree: then the structure at s lands on the
output's lattice at p, and copies placed at consistent positions keep the lattice across their
borders, however far apart.

`lattice_snap` moves a position to the nearest consistent one: by the nearest lattice
displacement for a 2D lattice (integral positions stay integral), and for stripes along the
image axis closest to the stripes' normal (so that rounding keeps it consistent: within half
a pixel of the stripe the phase asks for). A consistent position snaps to itself.
"""

from collections import namedtuple

import numpy as np
from numba import njit

# A lattice as the kernels read it.
#   rank      int64    0: no lattice (nothing snaps), 1: stripes, 2: a 2D lattice
#   n00..n11  float64  the dual N (rank x 2, row i: cycles per exemplar pixel along period i)
#   t00..t11  float64  the basis T (2 x rank, column i: period vector i, exemplar pixels)
#   g00..g11  float64  G: output phase per output pixel (rank x 2)
#   b0, b1    float64  b: output phase at the origin (cycles)
#   integral  bool     positions are integers (identity Jacobian): round snapped positions
#   axis      int64    stripes: 0 or 1, the image axis closest to the normal (snaps move along it)
#   keep      float64  a position continuing a neighbour's copy stays while within this many
#                      pixels of its phase (0.5: always the nearest; more where the output's
#                      lattice differs a little from the exemplar's, a tileable output, or an
#                      atlas's exemplars sit at their own phases, so that copies drift a
#                      little before they break)
LatticeParams = namedtuple("LatticeParams", "rank n00 n01 n10 n11 t00 t01 t10 t11 g00 g01 g10 "
                                            "g11 b0 b1 integral axis keep")

NO_LATTICE = LatticeParams(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                           0.0, False, 0, 0.5)

# A lattice per region of the exemplar (guided synthesis of several materials, each keeping its
# own lattice or none):
#   table    float64 (R, 18): row r holds region r's LatticeParams fields in order (integral
#            1.0 or 0.0; rank 0: the region has no lattice, its positions never snap); a table
#            of no rows: one lattice, the LatticeParams argument, for the whole exemplar
#   regions  int32 (h, w): the region of each exemplar pixel (read only with a table)
NO_TABLE = np.zeros((0, 18), np.float64)
NO_REGIONS = np.zeros((1, 1), np.int32)


@njit(cache=True, inline="always")
def region_lattice(lp, table, regions, cy, cx):
    """The lattice at exemplar position (cy, cx): its region's row of `table`, or lp when the
    table has no rows."""
    if table.shape[0] == 0:
        return lp
    iy = min(max(int(np.floor(cy + 0.5)), 0), regions.shape[0] - 1)
    ix = min(max(int(np.floor(cx + 0.5)), 0), regions.shape[1] - 1)
    r = regions[iy, ix]
    return LatticeParams(np.int64(table[r, 0]), table[r, 1], table[r, 2], table[r, 3],
                         table[r, 4], table[r, 5], table[r, 6], table[r, 7], table[r, 8],
                         table[r, 9], table[r, 10], table[r, 11], table[r, 12], table[r, 13],
                         table[r, 14], table[r, 15] != 0.0, np.int64(table[r, 16]),
                         table[r, 17])


@njit(cache=True, inline="always")
def _wrapped(f):
    """f minus the nearest integer, in [-0.5, 0.5)."""
    return f - np.floor(f + 0.5)


@njit(cache=True, inline="always")
def _phase_at(phase_map, cy, cx, c):
    """phase_map[c] at the nearest pixel of (cy, cx) (a (1, 1, 2) map: one value for all)."""
    iy = min(max(int(np.floor(cy + 0.5)), 0), phase_map.shape[0] - 1)
    ix = min(max(int(np.floor(cx + 0.5)), 0), phase_map.shape[1] - 1)
    return phase_map[iy, ix, c]


@njit(cache=True, inline="always")
def lattice_offsets(cy, cx, y, x, lp, phase_map):
    """(w0, w1): the phase differences (cycles, in [-0.5, 0.5)) between exemplar position
    (cy, cx) and output pixel (y, x), per period vector (w1 = 0 for stripes)."""
    f0 = (lp.n00 * cy + lp.n01 * cx + _phase_at(phase_map, cy, cx, 0)
          - (lp.g00 * y + lp.g01 * x + lp.b0))
    w0 = _wrapped(f0)
    w1 = 0.0
    if lp.rank == 2:
        f1 = (lp.n10 * cy + lp.n11 * cx + _phase_at(phase_map, cy, cx, 1)
              - (lp.g10 * y + lp.g11 * x + lp.b1))
        w1 = _wrapped(f1)
    return w0, w1


@njit(cache=True, inline="always")
def lattice_snap(cy, cx, y, x, lp, phase_map, keep=0.5):
    """The consistent position nearest (cy, cx) for output pixel (y, x) (see the module
    docstring); (cy, cx) itself when it is consistent or lp.rank is 0, or when it lies
    within `keep` pixels of its phase (integral positions)."""
    if lp.rank == 0:
        return cy, cx
    w0, w1 = lattice_offsets(cy, cx, y, x, lp, phase_map)
    if lp.rank == 2:
        ry = lp.t00 * w0 + lp.t01 * w1
        rx = lp.t10 * w0 + lp.t11 * w1
        if lp.integral:
            if abs(ry) <= keep and abs(rx) <= keep:
                return cy, cx
            ry = np.floor(ry + 0.5)
            rx = np.floor(rx + 0.5)
        return cy - ry, cx - rx
    # stripes: move along the axis closest to the normal, by the distance that puts the
    # position on its stripe (normal distance w0 * period; n / |n|^2 = t)
    step = w0 / (lp.n00 if lp.axis == 0 else lp.n01)
    if lp.integral:
        if abs(step) <= keep:
            return cy, cx
        step = np.floor(step + 0.5)
    if lp.axis == 0:
        return cy - step, cx
    return cy, cx - step


@njit(cache=True, inline="always")
def lattice_shift_ok(dy, dx, lp):
    """Whether moving a consistent copy by (dy, dx) keeps it consistent (the shift is a
    lattice vector, or runs along the stripes, to within what snapping tolerates)."""
    if lp.rank == 0:
        return True
    zero = np.zeros((1, 1, 2), np.float32)
    # the shift's own phase: a position at the origin moved by (dy, dx), for pixel (0, 0) of a
    # lattice whose output phase is 0 everywhere
    flat = LatticeParams(lp.rank, lp.n00, lp.n01, lp.n10, lp.n11, lp.t00, lp.t01, lp.t10,
                         lp.t11, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lp.integral, lp.axis, 0.5)
    sy, sx = lattice_snap(np.float64(dy), np.float64(dx), 0, 0, flat, zero)
    return abs(sy - dy) < 1e-9 and abs(sx - dx) < 1e-9


@njit(cache=True)
def snap_field(pos, lattice, phase_map, lo0, hi0, lo1, hi1, table, regions):
    """Every position of pos (float32 (H, W, 2)) moved to the nearest consistent one inside
    [lo, hi]: the snapped one (a position within lp.keep pixels of its phase stays), else the
    nearest of its lattice neighbours one period either way that is inside; a position with
    none inside stays. lp: `lattice`, or the position's region's (table, regions). Returns a
    new field."""
    H, W = pos.shape[0], pos.shape[1]
    out = pos.copy()
    for y in range(H):
        for x in range(W):
            lp = region_lattice(lattice, table, regions, np.float64(pos[y, x, 0]),
                                np.float64(pos[y, x, 1]))
            if lp.rank == 0:
                continue
            sy, sx = lattice_snap(np.float64(pos[y, x, 0]), np.float64(pos[y, x, 1]), y, x, lp,
                                  phase_map, lp.keep)
            if lo0 <= sy <= hi0 and lo1 <= sx <= hi1:
                out[y, x, 0] = sy
                out[y, x, 1] = sx
                continue
            best = np.inf
            for i in range(-1, 2):
                for j in range(-1, 2):
                    if lp.rank == 1 and j != 0:
                        continue
                    if lp.rank == 1:
                        if lp.axis == 0:
                            cy = sy + i / lp.n00
                            cx = sx
                        else:
                            cy = sy
                            cx = sx + i / lp.n01
                    else:
                        cy = sy + i * lp.t00 + j * lp.t01
                        cx = sx + i * lp.t10 + j * lp.t11
                    if lp.integral:
                        cy = np.floor(cy + 0.5)
                        cx = np.floor(cx + 0.5)
                    cy, cx = lattice_snap(cy, cx, y, x, lp, phase_map)
                    if not (lo0 <= cy <= hi0 and lo1 <= cx <= hi1):
                        continue
                    d = (cy - pos[y, x, 0]) ** 2 + (cx - pos[y, x, 1]) ** 2
                    if d < best:
                        best = d
                        out[y, x, 0] = cy
                        out[y, x, 1] = cx
    return out


@njit(cache=True)
def phase_sums(pos, lattice, phase_map, table, regions):
    """sum over the field of exp(2 pi i f) per period vector, f = N s + phase_map[s] - G p (the
    output phase b = 0): the circular mean's numerator of the phase the field's copies sit
    at. complex128 (R, 2): one row per region of `table` (each summing the positions in its
    region, under its own lattice; the rows' b must be 0), or (1, 2) for `lattice`."""
    out = np.zeros((max(table.shape[0], 1), 2), np.complex128)
    H, W = pos.shape[0], pos.shape[1]
    for y in range(H):
        for x in range(W):
            cy = np.float64(pos[y, x, 0])
            cx = np.float64(pos[y, x, 1])
            lp = region_lattice(lattice, table, regions, cy, cx)
            if lp.rank == 0:
                continue
            r = 0
            if table.shape[0] != 0:
                iy = min(max(int(np.floor(cy + 0.5)), 0), regions.shape[0] - 1)
                ix = min(max(int(np.floor(cx + 0.5)), 0), regions.shape[1] - 1)
                r = regions[iy, ix]
            w0, w1 = lattice_offsets(cy, cx, y, x, lp, phase_map)
            out[r, 0] += np.exp(2j * np.pi * w0)
            if lp.rank == 2:
                out[r, 1] += np.exp(2j * np.pi * w1)
    return out
