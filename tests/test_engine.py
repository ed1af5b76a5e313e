"""The OS-Map engine: the paper's schedule, Kohonen special case, fast path == general path,
locality and scale, determinism."""

import math

import numpy as np
import pytest
from mechanism_stats import appearances, gradient_angle

from osmap_cli.engine import Orientation, OSMap, Schedule

SCHEDULE = Schedule(alpha_max=0.5, alpha_min=0.01, sigma_max=3.0, sigma_min=0.5)


def paper_schedule(t, total, low, high):
    """The paper's step 4, written out here (not with Schedule): value(t) = (1 - s) low + s high,
    s = (exp(phi t / T) - exp(phi)) / (1 - exp(phi)), phi = -2.5."""
    phi = -2.5
    s = (math.exp(phi * t / total) - math.exp(phi)) / (1.0 - math.exp(phi))
    return (1.0 - s) * low + s * high


@pytest.mark.parametrize("fraction, s", [(0.0, 1.0), (0.25, 0.4937019541), (0.5, 0.2227001388),
                                         (0.75, 0.0776433200), (1.0, 0.0)])
def test_schedule_is_the_papers_formula(fraction, s):
    """s(t / T) from the formula by hand (phi = -2.5): 1 at the start, 0.2227 half way, 0 at
    the end; alpha and sigma interpolate between their min and max with it."""
    total = 400
    t = np.array([fraction * total])
    alpha, sigma = Schedule(alpha_max=0.8, alpha_min=0.1, sigma_max=6.0, sigma_min=0.5).values(
        t, total)
    assert alpha[0] == pytest.approx(0.1 + s * 0.7, abs=1e-9)
    assert sigma[0] == pytest.approx(0.5 + s * 5.5, abs=1e-9)
    assert paper_schedule(t[0], total, 0.5, 6.0) == pytest.approx(sigma[0], abs=1e-12)


def test_schedule_falls_fast_then_slowly():
    """The exponential shape: most of the fall happens early (a linear schedule would be half way
    at T/2, this one is 78 % of the way), monotonically."""
    alpha, sigma = Schedule(alpha_max=1.0, alpha_min=0.0, sigma_max=1.0, sigma_min=0.0).values(
        np.arange(101), 100)
    assert np.all(np.diff(sigma) < 0) and np.array_equal(alpha, sigma)
    assert sigma[50] == pytest.approx(0.2227, abs=1e-4)
    assert sigma[10] == pytest.approx(paper_schedule(10, 100, 0.0, 1.0), abs=1e-12)


def kohonen_reference(weights, data, order, shape, wrap, schedule):
    """Textbook online Gaussian SOM in numpy (float64), updating every node, with the paper's
    schedule computed here from the formula (so the engine's Schedule is checked too)."""
    w = weights.astype(np.float64).copy()
    coords = np.stack(np.unravel_index(np.arange(len(w)), shape), 1)
    alphas = [paper_schedule(t, len(order), schedule.alpha_min, schedule.alpha_max)
              for t in range(len(order))]
    sigmas = [paper_schedule(t, len(order), schedule.sigma_min, schedule.sigma_max)
              for t in range(len(order))]
    for t, i in enumerate(order):
        x = data[i]
        c = np.argmin(((w - x) ** 2).sum(1))
        d = np.abs(coords - coords[c]).astype(np.float64)
        for a, (size, wrapped) in enumerate(zip(shape, wrap)):
            if wrapped:
                d[:, a] = np.minimum(d[:, a], size - d[:, a])
        h = alphas[t] * np.exp(-(d ** 2).sum(1) / (2 * sigmas[t] ** 2))
        w += h[:, None] * (x - w)
    return w


@pytest.mark.parametrize("shape,wrap", [((10, 12), (True, False)), ((30,), (False,)),
                                        ((4, 5, 6), (False, True, False))])
def test_special_case_is_kohonen_som(shape, wrap):
    rng = np.random.default_rng(1)
    data = rng.random((400, 3))
    order = rng.integers(0, len(data), 1500)
    som = OSMap(shape, 3, wrap=wrap, cutoff=0.0)  # isotropic, global window, no truncation
    som.init_random(data, seed=2)
    expected = kohonen_reference(som.weights, data, order, shape, wrap, SCHEDULE)
    som.train(data, order=order, schedule=SCHEDULE)
    np.testing.assert_allclose(som.weights, expected, atol=2e-5)


def test_truncated_kernel_stays_close_to_full_kernel():
    rng = np.random.default_rng(3)
    data = rng.random((300, 2))
    full = OSMap((16, 16), 2, cutoff=0.0).init_random(data, 0)
    cut = OSMap((16, 16), 2).init_random(data, 0)
    full.train(data, 3000, schedule=SCHEDULE, seed=4)
    cut.train(data, 3000, schedule=SCHEDULE, seed=4)
    assert np.abs(full.weights - cut.weights).max() < 0.05


def test_separable_path_matches_general_path():
    rng = np.random.default_rng(5)
    data = rng.random((500, 3))
    orientation = Orientation.axis_aligned([[1.0, 0.25], [0.25, 1.0], [0.6, 0.6]])
    kwargs = dict(orientation=orientation, window=(8, 9), range_kernel=(2.0, 1.0))
    fast = OSMap((20, 24), 3, **kwargs).init_random(data, 0)
    general = OSMap((20, 24), 3, path="general", **kwargs).init_random(data, 0)
    assert fast._params.separable and not general._params.separable
    fast.train(data, 4000, schedule=SCHEDULE, seed=6)
    general.train(data, 4000, schedule=SCHEDULE, seed=6)
    np.testing.assert_allclose(fast.weights, general.weights, atol=1e-5)


def test_anisotropic_kernel_orients_the_gradients():
    """Component 0 may vary only along axis 0, component 1 only along axis 1 (weight 0 across):
    each component ends up nearly constant across its broad direction."""
    rng = np.random.default_rng(8)
    data = rng.random((2000, 2))
    som = OSMap((16, 16), 2, orientation=Orientation.axis_aligned([[1.0, 0.0], [0.0, 1.0]]))
    som.init_random(data, 0).train(data, 20000, schedule=Schedule(sigma_max=4, sigma_min=0.7),
                                   seed=2)
    grid = som.grid_weights()
    assert grid[..., 0].std(axis=1).mean() < 0.02   # component 0 constant along axis 1
    assert grid[..., 1].std(axis=0).mean() < 0.02   # component 1 constant along axis 0
    assert grid[..., 0].std(axis=0).mean() > 0.2    # ...and spread along its own axis


@pytest.mark.parametrize("window, copies", [((8, 8), 16.0), ((16, 16), 4.0)])
def test_local_window_sets_the_scale(window, copies):
    """The paper's scale: a 32x32 map learning the 8x8 grid of positions with a winner window
    of w x w shows each input item about (32 / w)^2 times (measured 10.4-11.7 for 16, 3.7-4.5
    for 4); a global search shows it once (1.0-1.5: one zoomed copy)."""
    data = np.stack(np.meshgrid(np.arange(8.0), np.arange(8.0), indexing="ij"), -1)
    data = data.reshape(-1, 2)
    for seed in (0, 1):
        som = OSMap((32, 32), 2, window=window).init_random(data, seed)
        som.train(data, 20 * som.size, schedule=Schedule(sigma_max=4.0, sigma_min=0.5),
                  seed=seed + 1)
        count = appearances(som.grid_weights())
        assert 0.55 * copies < count < 1.25 * copies, (seed, count)
    whole = OSMap((32, 32), 2).init_random(data, 0)
    whole.train(data, 20 * whole.size, schedule=Schedule(sigma_max=4.0, sigma_min=0.5), seed=1)
    assert appearances(whole.grid_weights()) < 2.0


@pytest.mark.parametrize("degrees", [(30.0, 120.0), (10.0, 100.0)])
def test_each_component_varies_along_its_own_direction(degrees):
    """Orientation.angles with zero weight across P_k: component k of the trained map varies
    only along P_k; its structure tensor points there within a degree."""
    data = np.random.default_rng(0).random((3000, 2))
    orientation = Orientation.angles(np.radians(degrees), [[1.0, 0.0], [1.0, 0.0]])
    som = OSMap((24, 24), 2, orientation=orientation).init_random(data, 0)
    som.train(data, 30000, schedule=Schedule(sigma_max=4, sigma_min=0.7), seed=2)
    grid = som.grid_weights()
    for k, expected in enumerate(degrees):
        delta = (gradient_angle(grid[..., k]) - expected + 90.0) % 180.0 - 90.0
        assert abs(delta) < 1.0, (k, delta)


def test_local_window_restricts_winners():
    data = np.random.default_rng(9).random((100, 2))
    som = OSMap((32, 32), 2, window=(4, 4)).init_random(data, 0)
    from osmap_cli.engine import _inactive_buckets
    from osmap_kernels.som import train_steps
    p = som._params
    origins = np.array([[0, 10, 20]] * 50, np.int64)
    alphas, sigmas = SCHEDULE.values(np.arange(50), 50)
    winners = train_steps(som.weights, data[:50], origins, alphas, sigmas, p,
                          _inactive_buckets(), 50)
    rows, cols = np.divmod(winners, 32)
    assert rows.min() >= 10 and rows.max() < 14 and cols.min() >= 20 and cols.max() < 24


def test_periodic_component_wraps():
    angles = np.linspace(0, 2 * np.pi, 200, endpoint=False)[:, None]
    som = OSMap((40,), 1, wrap=(True,), periods=[2 * np.pi]).init_random(angles, 0)
    som.train(angles, 20000, schedule=Schedule(sigma_max=6, sigma_min=0.5), seed=1)
    w = som.weights[:, 0]
    assert w.min() >= 0 and w.max() < 2 * np.pi
    steps = np.angle(np.exp(1j * np.diff(np.r_[w, w[0]])))
    # one full turn around the ring: wrapped steps all have one sign and sum to +-2 pi
    assert abs(abs(steps.sum()) - 2 * np.pi) < 1e-3
    assert (np.sign(steps) == np.sign(steps.sum())).all()


def test_same_seed_same_weights_and_different_seed_differs():
    data = np.random.default_rng(10).random((300, 3))
    runs = [OSMap((12, 12), 3, window=(6, 6)).init_random(data, 0)
            .train(data, 3000, schedule=SCHEDULE, seed=s).weights for s in (1, 1, 2)]
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_coherent_target_copies_the_data_space():
    """With target x + J D the map learns a translated copy: neighbouring nodes differ by J."""
    pos = np.stack(np.meshgrid(np.arange(32.0), np.arange(32.0), indexing="ij"), -1).reshape(-1, 2)
    som = OSMap((24, 24), 2, window=(24, 24), target_jacobian=np.eye(2), range_kernel=(2, 1),
                bounds=[[0, 31], [0, 31]]).init_random(pos, 0)
    som.train(pos, 20000, schedule=Schedule(sigma_max=3, sigma_min=0.3, alpha_min=0.05), seed=3)
    grid = som.grid_weights()
    step_rows = np.diff(grid[..., 0], axis=0)
    assert np.mean(np.abs(step_rows - 1) < 0.25) > 0.6


def test_invalid_arguments_raise():
    with pytest.raises(ValueError):
        OSMap((4, 4, 4, 4), 2)
    with pytest.raises(ValueError):
        OSMap((8, 8), 2, window=(9, 2))
    with pytest.raises(ValueError):
        OSMap((8, 8), 2, path="fast")


@pytest.mark.parametrize("shape,wrap,window,periods", [
    ((24, 20), (False, False), None, None),             # global window
    ((24, 20), (True, True), (9, 7), None),             # local windows wrapping around
    ((6, 7, 8), (False, True, False), (4, 7, 5), None),  # 3D map
    ((30,), (True,), (12,), [0.0, 0.0, 1.0]),           # a periodic component stays off-grid
])
def test_bucket_search_finds_the_scan_winner(shape, wrap, window, periods):
    """The inverse map returns exactly the brute-force winner, ties included (model vectors on a
    coarse lattice make equal distances common), so training gives identical maps."""
    from osmap_cli.engine import _inactive_buckets
    from osmap_kernels.som import find_winner, find_winner_buckets

    rng = np.random.default_rng(11)
    data = np.round(rng.random((600, 3)) * 4) / 4
    som = OSMap(shape, 3, wrap=wrap, window=window, periods=periods).init_random(data, 0)
    p = som._params
    b = som._buckets(data)
    assert b.active and not _inactive_buckets().active
    queries = np.concatenate([data[:300], rng.random((200, 3)) * 1.6 - 0.3])  # some outside
    high = np.where(p.wrap, p.grid, p.grid - p.window + 1)
    for x in queries:
        origin = (rng.random(3) * high).astype(np.int64)
        expected = find_winner(som.weights, x, p.grid, origin, p.window, p.periods,
                               np.empty(p.grid[2]))
        assert find_winner_buckets(som.weights, x, p.grid, origin, p.window, p.periods,
                                   b) == expected

    maps = []
    for search in ("scan", "buckets"):
        m = OSMap(shape, 3, wrap=wrap, window=window, periods=periods).init_random(data, 0)
        maps.append(m.train(data, 3000, schedule=SCHEDULE, seed=4, search=search).weights)
    assert np.array_equal(maps[0], maps[1])


def test_bucket_search_with_coherent_targets_matches_scan():
    """The texture configuration (coherent targets, bounds, range kernel, rotated kernel)."""
    pos = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0), indexing="ij"), -1)
    pos = pos.reshape(-1, 2)
    maps = []
    for search in ("scan", "buckets"):
        som = OSMap((24, 24), 2, window=(16, 16), target_jacobian=[[0.9, 0.2], [-0.2, 0.9]],
                    orientation=Orientation.angles([0.3, 1.2], [[1, 0.25]] * 2),
                    range_kernel=(2, 1), bounds=[[0, 19], [0, 19]]).init_random(pos, 0)
        maps.append(som.train(pos, 4000, schedule=SCHEDULE, seed=3, search=search).weights)
    assert np.array_equal(maps[0], maps[1])


def test_switching_to_the_inverse_map_mid_run_changes_nothing():
    """train_steps scans until step bucket_from, then fills and searches the inverse map."""
    from osmap_kernels.som import train_steps

    rng = np.random.default_rng(12)
    data = rng.random((500, 2))
    xs = data[rng.integers(0, len(data), 2000)]
    origins = np.zeros((len(xs), 3), np.int64)
    alphas, sigmas = SCHEDULE.values(np.arange(len(xs)), len(xs))
    results = []
    for bucket_from in (len(xs), 0, 700):
        som = OSMap((20, 20), 2).init_random(data, 0)
        winners = train_steps(som.weights, xs, origins, alphas, sigmas, som._params,
                              som._buckets(data), bucket_from)
        results.append((winners, som.weights.copy()))
    for winners, weights in results[1:]:
        assert np.array_equal(winners, results[0][0])
        assert np.array_equal(weights, results[0][1])


def test_auto_search_switches_once_the_radius_has_shrunk():
    som = OSMap((128, 128), 2)
    pays = som._buckets_pay(np.array([30.0, 8.0, 0.5]))
    assert not pays[0] and pays[-1]
    assert not OSMap((128, 128), 2, window=(8, 8))._buckets_pay(np.array([0.5]))[0]


@pytest.mark.parametrize("shape,dim,wrap,window,sigma_max,search", [
    ((40, 36), 2, (True, False), None, 12.0, "auto"),    # long runs, split where axis 1 wraps
    ((40, 36), 3, (False, False), None, 12.0, "buckets"),  # vectorised refiling of long runs
    ((10, 11, 12), 3, (False, True, False), None, 3.0, "auto"),
    ((50,), 1, (False,), None, 10.0, "auto"),
    ((24, 20), 4, (True, True), (9, 7), 4.0, "scan"),    # the generic component loop
])
def test_classic_update_matches_the_general_loop(shape, dim, wrap, window, sigma_max, search):
    """The classic SOM's vectorised update gives the general loop's weights bit for bit: bounds
    no target can reach make the same map take the general loop."""
    from osmap_kernels.som import is_classic

    rng = np.random.default_rng(13)
    data = rng.random((500, dim))
    schedule = Schedule(sigma_max=sigma_max, sigma_min=0.5)
    maps = []
    for bounds in (None, [[-1e9, 1e9]] * dim):
        som = OSMap(shape, dim, wrap=wrap, window=window, bounds=bounds).init_random(data, 0)
        assert is_classic(som._params) == (bounds is None)
        maps.append(som.train(data, 2000, schedule=schedule, seed=5, search=search).weights)
    assert np.array_equal(maps[0], maps[1])


@pytest.mark.parametrize("shape,wrap", [((40, 32), (False, False)), ((40, 32), (True, False)),
                                        ((40, 32), (False, True)),
                                        ((3, 20, 16), (True, False, False))])
def test_blockwise_scan_finds_the_first_nearest_node(shape, wrap):
    """Whole-row windows are scanned block by block (rows split where a wrapped axis 1 wraps);
    the winner is still the nearest node and, among equally near ones (duplicated model
    vectors), the first in the window's scan order."""
    from osmap_kernels.som import find_winner

    rng = np.random.default_rng(14)
    data = np.round(rng.random((50, 3)) * 3) / 3  # few distinct values: many exact ties
    som = OSMap(shape, 3, wrap=wrap).init_random(data, 0)
    p = som._params
    w = som.weights.astype(np.float64)
    for x in np.concatenate([data[:20], rng.random((20, 3))]):
        origin = np.where(p.wrap, rng.integers(0, p.grid), 0).astype(np.int64)
        scan = np.indices(p.grid).reshape(3, -1)  # the window's nodes in scan order
        coords = (scan + origin[:, None]) % p.grid[:, None]
        order = np.ravel_multi_index(tuple(coords), tuple(p.grid))
        d2 = ((x - w[order]) ** 2).sum(1)
        got = find_winner(som.weights, x, p.grid, origin, p.window, p.periods,
                          np.empty(p.grid[2]))
        assert got == order[int(np.argmin(d2))]
