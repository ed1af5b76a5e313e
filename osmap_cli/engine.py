"""The Oriented and Scalable Map: a self-organizing map with an anisotropic, per-data-component
neighbourhood (orientation) and a local winner search (scale). Kohonen's SOM is the special case
of equal directions, unit weights and a global search.

>>> som = OSMap((32, 32), dim=3, wrap=(True, True))
>>> som.init_random(data, seed=0)
>>> som.train(data, steps=20_000, schedule=Schedule(sigma_max=8, sigma_min=0.5), seed=0)
>>> som.grid_weights().shape
(32, 32, 3)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_kernels.som import (
    LONG_RUN,
    Buckets,
    KernelParams,
    fill_buckets,
    find_winner,
    train_steps,
)

PHI = -2.5  # the paper's schedule constant
# Cost model of one step for choosing the winner search (seconds; fitted by the "winner search
# against window size" table of bench/bench_kernels.py, only their ratios matter): scanning
# costs SCAN_COST per window node and data component (BLOCK_SCAN_COST when the window is whole,
# unwrapped rows, which the kernel scans block-wise); the inverse map costs SEARCH_COST per
# search, plus MISS_COST per out-of-window node it meets (about map size / window size of
# them), plus REFILE_COST per updated node to keep the buckets current.
SCAN_COST = 0.6e-9
BLOCK_SCAN_COST = 0.2e-9
SEARCH_COST = 0.7e-6
MISS_COST = 25e-9
REFILE_COST = 6e-9
NODES_PER_CELL = 4.0


@dataclass(frozen=True)
class Schedule:
    """The paper's learning-rate and radius schedule.

    alpha(t) = (1 - s) alpha_min + s alpha_max, sigma likewise, with
    s = (exp(phi t / T) - exp(phi)) / (1 - exp(phi)), so s goes from 1 at t = 0 to 0 at t = T.

    >>> alpha, sigma = Schedule(sigma_max=4, sigma_min=0.5).values(np.arange(10), 10)
    """

    alpha_max: float = 0.5
    alpha_min: float = 0.01
    sigma_max: float = 4.0
    sigma_min: float = 0.5
    phi: float = PHI

    def values(self, t: np.ndarray, total: int) -> tuple[np.ndarray, np.ndarray]:
        """alpha(t) and sigma(t) as float64 arrays for the step numbers t of a T-step run."""
        t = np.asarray(t, np.float64)
        s = (np.exp(self.phi * t / total) - np.exp(self.phi)) / (1.0 - np.exp(self.phi))
        alpha = (1.0 - s) * self.alpha_min + s * self.alpha_max
        sigma = (1.0 - s) * self.sigma_min + s * self.sigma_max
        return alpha, sigma


def _cos_sin(theta):
    """cos and sin with round-off zeroed, so axis-aligned angles keep the separable path."""
    theta = np.asarray(theta, np.float64)
    c, s = np.cos(theta), np.sin(theta)
    return np.where(np.abs(c) < 1e-12, 0.0, c), np.where(np.abs(s) < 1e-12, 0.0, s)


@dataclass(frozen=True)
class Orientation:
    """Per-data-component neighbourhood shape: component k decays as
    exp(-sum_j weights[k, j] (frames[f, k, j] . D)^2 / (2 sigma^2)), where the rows
    frames[f, k, :] are an orthonormal frame of map space (P_k, P'_k[, P''_k]) and f is 0 for a
    constant orientation or the winner's node index for an orientation field.

    >>> Orientation.isotropic(dim=2, map_dims=2)                      # Kohonen's Gaussian
    >>> Orientation.axis_aligned([[1.0, 0.25], [0.25, 1.0]])         # per component, per map axis
    >>> Orientation.angles([0.0, np.pi / 2], [[1.0, 0.25], [1.0, 0.25]])  # 2D map, P_k at angle
    """

    frames: np.ndarray  # (F, d, M, M)
    weights: np.ndarray  # (d, M)

    @classmethod
    def isotropic(cls, dim: int, map_dims: int) -> Orientation:
        """Every component decays equally in every direction: the classic SOM."""
        return cls.axis_aligned(np.ones((dim, map_dims)))

    @classmethod
    def axis_aligned(cls, weights) -> Orientation:
        """weights[k, a]: how fast component k's neighbourhood decays along map axis a."""
        weights = np.asarray(weights, np.float64)
        dim, m = weights.shape
        frames = np.broadcast_to(np.eye(m), (1, dim, m, m)).copy()
        return cls(frames, weights)

    @classmethod
    def angles(cls, theta, weights) -> Orientation:
        """2D maps: P_k = (cos theta_k, sin theta_k) in (axis 0, axis 1) coordinates."""
        c, s = _cos_sin(theta)
        frames = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], 1)[None]
        return cls(frames, np.asarray(weights, np.float64))

    @classmethod
    def field(cls, theta, weights) -> Orientation:
        """2D maps: an angle per node and component, theta shape (N, d)."""
        c, s = _cos_sin(theta)
        frames = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], 2)
        return cls(frames, np.asarray(weights, np.float64))

    def quadratic_forms(self) -> np.ndarray:
        """A_k = sum_j c_kj P_kj P_kj^T, padded to 3 map axes (leading ones unused): (F,d,3,3)."""
        f, d, m, _ = self.frames.shape
        a = np.einsum("kj,fkja,fkjb->fkab", self.weights, self.frames, self.frames)
        out = np.zeros((f, d, 3, 3))
        out[:, :, 3 - m:, 3 - m:] = a
        return out


def _inactive_buckets() -> Buckets:
    """A placeholder inverse map: brute-force winner search."""
    return Buckets(active=False, comps=np.full(3, -1, np.int64), shape=np.ones(3, np.int64),
                   origin=np.zeros(3), inv_size=np.ones(3), size=np.ones(3),
                   head=np.full(1, -1, np.int64), links=np.empty((3, 0), np.int64))


# an eigenvalue of A below _FLAT times its largest is a direction the kernel does not decay along
_FLAT = 1e-12


def _truncation_extent(quad: np.ndarray, cutoff: float) -> np.ndarray:
    """Half-width per axis of {D : exp(-D^T A D / 2) >= cutoff}, max over components: (F, 3).

    Along axis a the ellipse D^T A D <= q reaches sqrt(q (A^-1)_aa). A direction of zero weight
    (an eigenvalue of A that is 0, or a round-off +-1e-17 when the frame is rotated, where the
    inverse would be garbage) reaches infinitely far along every axis it is not perpendicular to.
    """
    f, d = quad.shape[:2]
    if cutoff <= 0.0:
        return np.full((f, 3), np.inf)
    q = 2.0 * np.log(1.0 / cutoff)
    extent = np.zeros((f, 3))
    for a in range(3):
        # unused leading axes have a zero row: the extent there is irrelevant (grid size is 1)
        for fi in range(f):
            for k in range(d):
                used = [b for b in range(3) if np.any(quad[fi, k, b] != 0) or b == a]
                sub = quad[fi, k][np.ix_(used, used)]
                idx = used.index(a)
                lam, vec = np.linalg.eigh(sub)
                along = vec[idx] ** 2
                flat = lam <= _FLAT * max(lam.max(), 0.0)
                if np.any(flat & (along > _FLAT)):
                    e = np.inf
                elif flat.any():  # flat only across axis a
                    e = np.sqrt(q * np.sum(along[~flat] / lam[~flat]))
                else:
                    e = np.sqrt(q * np.linalg.inv(sub)[idx, idx])
                if not np.isfinite(e) or e > 1e12:
                    e = np.inf
                extent[fi, a] = max(extent[fi, a], e)
    return extent


class OSMap:
    """A map of nodes on a 1D, 2D or 3D grid, each holding a float32 model vector of size dim.

    Options beyond the paper (all off by default):
    - `target_jacobian` (dim x map_dims): node i is pulled toward x + J (i - c) instead of x, so
      the map learns a locally coherent copy of the data space (used for textures);
    - `range_kernel` (a, b): the update is also weighted by exp(-|target - m_i|^2 / 2 tau^2),
      tau = a sigma + b, which stops averaging across seams;
    - `periods`: per-component period (0 = none) for angles and other wrapped coordinates;
    - `bounds` (dim x 2): a target outside [lo, hi] is not applied to that node.
    `path="general"` forces the exp-per-node update even where 1D tables would do (for tests).
    """

    def __init__(self, shape, dim: int, *, wrap=None, window=None,
                 orientation: Orientation | None = None, target_jacobian=None,
                 range_kernel=None, periods=None, bounds=None, cutoff: float = 1e-3,
                 path: str = "auto"):
        self.shape = tuple(int(s) for s in shape)
        if not 1 <= len(self.shape) <= 3 or min(self.shape) < 1:
            raise ValueError(f"map shape must have 1 to 3 positive axes, got {shape}")
        if dim < 1:
            raise ValueError(f"dim must be >= 1, got {dim}")
        m = len(self.shape)
        self.dim = int(dim)
        self.wrap = tuple(bool(w) for w in (wrap if wrap is not None else (False,) * m))
        self.window = tuple(int(w) for w in (window if window is not None else self.shape))
        if len(self.wrap) != m or len(self.window) != m:
            raise ValueError("wrap and window need one entry per map axis")
        if any(not 1 <= w <= s for w, s in zip(self.window, self.shape)):
            raise ValueError(f"window {self.window} must lie within 1..map shape {self.shape}")
        self.orientation = orientation or Orientation.isotropic(self.dim, m)
        if self.orientation.frames.shape[1:] != (self.dim, m, m):
            raise ValueError("orientation frames must be (F, dim, map_dims, map_dims)")
        if self.orientation.frames.shape[0] not in (1, self.size):
            raise ValueError("an orientation field needs one frame per node")
        self.target_jacobian = (np.zeros((self.dim, m)) if target_jacobian is None
                                else np.asarray(target_jacobian, np.float64).reshape(self.dim, m))
        self.range_kernel = (0.0, 0.0) if range_kernel is None else tuple(map(float, range_kernel))
        self.periods = (np.zeros(self.dim) if periods is None
                        else np.asarray(periods, np.float64).reshape(self.dim))
        self.bounds = (np.array([[-np.inf, np.inf]] * self.dim) if bounds is None
                       else np.asarray(bounds, np.float64).reshape(self.dim, 2))
        self.cutoff = float(cutoff)
        if path not in ("auto", "general"):
            raise ValueError(f"path must be 'auto' or 'general', got {path!r}")
        self.path = path
        self.weights = np.zeros((self.size, self.dim), np.float32)
        self._params = self._kernel_params()

    @property
    def size(self) -> int:
        """Number of nodes N."""
        return int(np.prod(self.shape))

    def grid_weights(self) -> np.ndarray:
        """Model vectors shaped like the map: (*shape, dim)."""
        return self.weights.reshape(*self.shape, self.dim)

    def init_random(self, data, seed: int = 0) -> OSMap:
        """Every model vector set to a randomly drawn data item."""
        data = np.asarray(data, np.float64).reshape(-1, self.dim)
        rng = np.random.default_rng(seed)
        self.weights[:] = data[rng.integers(0, len(data), self.size)]
        return self

    def winner(self, x) -> int:
        """Index of the node nearest to x over the whole map."""
        p = self._params
        return int(find_winner(self.weights, np.asarray(x, np.float64), p.grid,
                               np.zeros(3, np.int64), p.grid, p.periods, np.empty(p.grid[2])))

    def train(self, data, steps: int | None = None, *, schedule: Schedule = Schedule(),
              seed: int = 0, order=None, progress=None, chunk: int = 1 << 15,
              search: str = "auto") -> OSMap:
        """Run the stepwise recursive algorithm for `steps` steps.

        Inputs are drawn uniformly from `data` (n, dim), or taken in the given `order` (indices),
        windows are placed uniformly at random (seeded). `progress` is an optional tqdm-like
        object whose update(n) is called after each chunk of steps. `search` picks the winner
        search: "scan" (brute force over the window), "buckets" (the inverse map; the scan when
        every component is periodic) or "auto" (the inverse map from the step on which the cost
        model says it pays: large windows, shrunken radius); all give the same winners, hence
        the same map.
        """
        if search not in ("auto", "scan", "buckets"):
            raise ValueError(f"search must be 'auto', 'scan' or 'buckets', got {search!r}")
        data = np.asarray(data, np.float64).reshape(-1, self.dim)
        rng = np.random.default_rng(seed)
        if order is None:
            if steps is None:
                raise ValueError("give steps or order")
            order = rng.integers(0, len(data), steps)
        order = np.asarray(order, np.int64)
        total = len(order)
        grid = np.array(self._params.grid)
        window = np.array(self._params.window)
        wrap = np.array(self._params.wrap)
        high = np.where(wrap, grid, grid - window + 1)
        probe = np.unique(np.linspace(0, max(total - 1, 0), 257).astype(np.int64))
        may_pay = search == "buckets" or (
            search == "auto" and self._buckets_pay(schedule.values(probe, total)[1]).any())
        buckets = self._buckets(data) if may_pay else None
        if buckets is None:
            buckets = _inactive_buckets()
        for start in range(0, total, chunk):
            idx = order[start:start + chunk]
            origins = (rng.random((len(idx), 3)) * high).astype(np.int64)
            alphas, sigmas = schedule.values(np.arange(start, start + len(idx)), total)
            pays = (np.ones(len(idx), bool) if search == "buckets"
                    else self._buckets_pay(sigmas))
            # the inverse map from the first step after which it pays for every step
            bucket_from = len(idx) - int(np.argmin(pays[::-1])) if not pays.all() else 0
            train_steps(self.weights, data[idx], origins, alphas, sigmas, self._params, buckets,
                        bucket_from)
            if progress is not None:
                progress.update(len(idx))
        return self

    def _buckets_pay(self, sigmas: np.ndarray) -> np.ndarray:
        """Per step (radius sigma): is the inverse map cheaper than scanning the window?"""
        window = float(np.prod(self.window))
        p = self._params
        updated = np.ones(len(sigmas))
        for a in range(3):
            reach = 2.0 * np.ceil(p.extent[:, a].max() * sigmas) + 1.0
            updated *= np.minimum(reach, p.grid[a])
        blockwise = (p.window[2] == p.grid[2] and not p.wrap[2]
                     and p.window[1] * p.grid[2] >= LONG_RUN)
        scan = (BLOCK_SCAN_COST if blockwise else SCAN_COST) * window * self.dim
        search = SEARCH_COST + MISS_COST * self.size / window
        return scan > search + REFILE_COST * updated

    def _buckets(self, data: np.ndarray) -> Buckets | None:
        """An inverse map over up to 3 non-periodic components (the widest spread first), with
        about NODES_PER_CELL nodes per cell; None when no component qualifies."""
        both = np.concatenate([data, self.weights.astype(np.float64)])
        lo, hi = both.min(axis=0), both.max(axis=0)
        spread = np.where(self.periods > 0, 0.0, hi - lo)
        comps = [int(k) for k in np.argsort(-spread, kind="stable")[:3] if spread[k] > 0]
        if not comps:
            return None
        cells = max(1.0, self.size / NODES_PER_CELL)
        size = float(np.prod(spread[comps]) / cells) ** (1.0 / len(comps))
        shape = np.ones(3, np.int64)
        comp_arr = np.full(3, -1, np.int64)
        origin = np.zeros(3)
        sizes = np.ones(3)
        for a, k in enumerate(comps):
            shape[a] = int(np.clip(np.ceil(spread[k] / size), 1, 4096))
            sizes[a] = spread[k] / shape[a]
            comp_arr[a] = k
            origin[a] = lo[k]
        n = self.size
        b = Buckets(active=True, comps=comp_arr, shape=shape, origin=origin, inv_size=1.0 / sizes,
                    size=sizes, head=np.empty(int(np.prod(shape)), np.int64),
                    links=np.empty((3, n), np.int64))
        fill_buckets(self.weights, b)
        return b

    def quantization_error(self, data) -> float:
        """Mean distance from each data item to its nearest model vector."""
        data = np.asarray(data, np.float64).reshape(-1, self.dim)
        return float(np.mean([np.sqrt(np.sum((self.weights[self.winner(x)] - x) ** 2))
                              for x in data]))

    def _kernel_params(self) -> KernelParams:
        m = len(self.shape)
        pad = 3 - m
        grid = np.array((1,) * pad + self.shape, np.int64)
        quad = self.orientation.quadratic_forms()
        jac = np.zeros((self.dim, 3))
        jac[:, pad:] = self.target_jacobian
        off_diagonal = quad - quad * np.eye(3)
        return KernelParams(
            grid=grid,
            wrap=np.array((False,) * pad + self.wrap),
            window=np.array((1,) * pad + self.window, np.int64),
            quad=quad,
            extent=_truncation_extent(quad, self.cutoff),
            separable=bool(self.path == "auto" and quad.shape[0] == 1
                           and not off_diagonal.any()),
            jac=jac,
            periods=self.periods.copy(),
            lo=self.bounds[:, 0].copy(),
            hi=self.bounds[:, 1].copy(),
            range_a=self.range_kernel[0],
            range_b=self.range_kernel[1],
            cutoff=self.cutoff,
        )
