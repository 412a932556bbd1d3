"""Unit tests of the Flower Pollination Algorithm optimiser (swarm_mj.tuning.fpa, docs/interpretations.md §6)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.tuning.fpa import FPAResult, fpa, levy_steps, mantegna_sigma, random_search

D = 4
BOX = (np.full(D, -5.12), np.full(D, 5.12))
SHIFT = 1.3


def sphere(X: np.ndarray) -> np.ndarray:
    return np.sum(X**2, axis=1)


def shifted_rastrigin(X: np.ndarray) -> np.ndarray:
    Z = X - SHIFT
    return 10.0 * X.shape[1] + np.sum(Z**2 - 10.0 * np.cos(2.0 * np.pi * Z), axis=1)


class Recorder:
    """Batched cost wrapper that keeps a copy of every batch and its costs."""

    def __init__(self, f):
        self.f = f
        self.batches: list[np.ndarray] = []
        self.costs: list[np.ndarray] = []

    def __call__(self, X: np.ndarray) -> np.ndarray:
        c = np.asarray(self.f(X), dtype=float)
        self.batches.append(X.copy())
        self.costs.append(c.copy())
        return c


# --------------------------------------------------------------------------- determinism


def test_same_seed_same_result_different_seed_different():
    a = fpa(shifted_rastrigin, BOX, population=10, iterations=5, seed=7)
    b = fpa(shifted_rastrigin, BOX, population=10, iterations=5, seed=7)
    c = fpa(shifted_rastrigin, BOX, population=10, iterations=5, seed=8)
    assert isinstance(a, FPAResult)
    np.testing.assert_array_equal(a.best_x, b.best_x)
    np.testing.assert_array_equal(a.population, b.population)
    np.testing.assert_array_equal(a.history, b.history)
    assert a.best_cost == b.best_cost and a.seed == 7
    assert not np.array_equal(a.best_x, c.best_x)
    assert not np.array_equal(a.population, c.population)


# --------------------------------------------------------------------------- beats random search


@pytest.mark.parametrize(
    ("f", "max_ratio"),
    [(sphere, 1e-2), (shifted_rastrigin, 0.8)],
    ids=["sphere", "shifted_rastrigin"],
)
def test_fpa_beats_random_search_same_budget(f, max_ratio):
    # Paper defaults p=0.04, gamma=0.02; N=20, 200 iterations -> 4020 evaluations.
    # Over 40 blocks of 5 seeds the worst observed median ratio was ~2.5e-5
    # (sphere) and ~0.61 (Rastrigin), so these thresholds leave a clear margin.
    seeds = range(5)
    ours = [fpa(f, BOX, population=20, iterations=200, seed=s) for s in seeds]
    budget = ours[0].n_evaluations
    assert budget == 20 * 201
    base = [random_search(f, BOX, budget, seed=s, batch=20) for s in seeds]
    assert all(r.n_evaluations == budget for r in base)
    med_fpa = float(np.median([r.best_cost for r in ours]))
    med_rs = float(np.median([r.best_cost for r in base]))
    assert med_fpa < max_ratio * med_rs, (med_fpa, med_rs)


def test_fpa_converges_near_sphere_optimum():
    r = fpa(sphere, BOX, population=20, iterations=200, seed=0)
    assert r.best_cost < 1e-3
    assert np.all(np.abs(r.best_x) < 0.05)
    assert r.best_cost < r.initial_best_cost


# --------------------------------------------------------------------------- invariants


def test_history_non_increasing_and_consistent():
    r = fpa(shifted_rastrigin, BOX, population=12, iterations=25, seed=3)
    assert r.history.shape == (26,)
    assert np.all(np.diff(r.history) <= 0.0)
    assert r.history[0] == r.initial_best_cost
    assert r.history[-1] == r.best_cost
    assert r.best_cost == pytest.approx(float(shifted_rastrigin(r.best_x[None])[0]))
    assert r.best_cost == r.costs.min()
    assert r.population.shape == (12, D) and r.costs.shape == (12,)


def test_candidates_and_best_stay_within_bounds_when_optimum_is_outside():
    lower, upper = np.array([-1.0, -2.0, 0.0]), np.array([1.0, 2.0, 3.0])
    rec = Recorder(lambda X: np.sum((X - 10.0) ** 2, axis=1))  # optimum outside the box
    r = fpa(rec, (lower, upper), population=10, iterations=40, p=0.5, gamma=1.0, seed=1)
    for X in rec.batches:
        assert np.all(X >= lower) and np.all(X <= upper)
    assert np.all(r.population >= lower) and np.all(r.population <= upper)
    assert np.all(r.best_x >= lower) and np.all(r.best_x <= upper)
    np.testing.assert_allclose(r.best_x, upper, atol=0.2)  # pushed into the corner


def test_one_batched_call_per_iteration_and_greedy_replacement():
    n, iters = 8, 15
    rec = Recorder(shifted_rastrigin)
    seen = []
    r = fpa(
        rec,
        BOX,
        population=n,
        iterations=iters,
        p=0.3,
        gamma=0.5,
        seed=5,
        callback=lambda it, bx, bc, h: seen.append((it, bx.copy(), bc, h.copy())),
    )
    assert len(rec.batches) == iters + 1
    assert all(X.shape == (n, D) for X in rec.batches)
    assert r.n_evaluations == n * (iters + 1)

    # Replay greedy replacement from the recorded batches: each flower keeps its
    # candidate only if strictly better, so no flower's cost ever increases.
    X, F = rec.batches[0].copy(), rec.costs[0].copy()
    for it, (C, FC) in enumerate(zip(rec.batches[1:], rec.costs[1:]), start=1):
        better = FC < F
        F_new = np.where(better, FC, F)
        assert np.all(F_new <= F)
        X[better], F = C[better], F_new
        assert seen[it][2] == F.min()
    np.testing.assert_array_equal(r.population, X)
    np.testing.assert_array_equal(r.costs, F)

    # Callback: iterations 0..iters, growing history, best-so-far.
    assert [s[0] for s in seen] == list(range(iters + 1))
    assert seen[0][2] == rec.costs[0].min() == r.initial_best_cost
    for it, _bx, bc, h in seen:
        assert h.shape == (it + 1,) and h[-1] == bc
    np.testing.assert_array_equal(seen[-1][1], r.best_x)
    np.testing.assert_array_equal(seen[-1][3], r.history)


def test_local_pollination_is_difference_of_two_other_flowers():
    # p=0: every candidate is x_i + eps (x_j - x_k), eps in [0,1], j != k, both != i.
    # Flowers start in a small cube far from the walls so that nothing is clipped.
    n = 6
    rng = np.random.default_rng(0)
    x0 = rng.uniform(-0.5, 0.5, size=(n, D))
    rec = Recorder(sphere)
    fpa(rec, BOX, population=n, iterations=1, p=0.0, seed=2, x0=x0)
    X, C = rec.batches
    np.testing.assert_array_equal(X, x0)
    for i in range(n):
        step = C[i] - X[i]
        found = False
        for j, k in itertools.permutations([m for m in range(n) if m != i], 2):
            diff = X[j] - X[k]
            eps = float(step @ diff / (diff @ diff))
            if -1e-12 <= eps <= 1 + 1e-12 and np.allclose(step, eps * diff, atol=1e-12):
                found = True
                break
        assert found, f"candidate {i} is not a local-pollination move"


def test_global_pollination_moves_along_direction_to_best():
    # p=1: every candidate is x_i + gamma * L * (g_best - x_i) per dimension, so
    # the best flower stays put and each coordinate moves only along (g - x_i).
    n = 10
    rng = np.random.default_rng(1)
    x0 = rng.uniform(-0.5, 0.5, size=(n, D))
    rec = Recorder(sphere)
    fpa(rec, BOX, population=n, iterations=1, p=1.0, gamma=0.02, seed=4, x0=x0)
    X, C = rec.batches
    g = X[np.argmin(rec.costs[0])]
    best = int(np.argmin(rec.costs[0]))
    np.testing.assert_array_equal(C[best], X[best])
    ratio = (C - X) / (g - X + (np.arange(n) == best)[:, None])  # L * gamma per entry
    ratio = np.delete(ratio, best, axis=0) / 0.02
    assert np.all(np.isfinite(ratio))
    assert not np.allclose(ratio, ratio[0, 0])  # independent per flower and dimension


# --------------------------------------------------------------------------- Levy steps


def test_levy_steps_are_heavy_tailed_and_symmetric():
    assert mantegna_sigma(1.5) == pytest.approx(0.6966, abs=1e-4)
    L = levy_steps(np.random.default_rng(0), (10_000,), lam=1.5)
    a = np.abs(L)
    med = float(np.median(a))
    assert np.isfinite(med) and 0.4 < med < 0.9
    # A Gaussian sample of 10k never exceeds ~6x its median |x|; Mantegna lambda=1.5
    # has a power-law tail P(|L| > x) ~ x^-1.5: about 2.5 % lie beyond 10x the
    # median (a Cauchy, lambda=1, would give ~6 %).
    assert a.max() > 10 * med
    frac = float(np.mean(a > 10 * med))
    assert 0.015 < frac < 0.04, frac
    assert 0.47 < float(np.mean(L > 0)) < 0.53
    g = np.abs(np.random.default_rng(0).normal(size=10_000))
    assert g.max() < 10 * np.median(g)  # the check above does discriminate


def test_levy_steps_shape_and_seed():
    a = levy_steps(np.random.default_rng(3), (7, 4))
    b = levy_steps(np.random.default_rng(3), (7, 4))
    assert a.shape == (7, 4)
    np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------- inf / NaN costs


def test_inf_and_nan_costs_are_handled():
    def half_diverges(X: np.ndarray) -> np.ndarray:
        c = sphere(X - 1.0)
        c[X[:, 0] > 0.0] = np.inf  # half the box "diverges"
        c[(X[:, 0] <= 0.0) & (X[:, 1] > 4.0)] = np.nan
        return c

    r = fpa(half_diverges, BOX, population=20, iterations=200, seed=0)
    assert np.isfinite(r.best_cost)
    assert r.best_x[0] <= 0.0 and r.best_x[1] <= 4.0
    assert not np.any(np.isnan(r.costs)) and not np.any(np.isnan(r.history))
    assert np.all(np.diff(r.history) <= 0.0)
    assert r.best_cost < r.initial_best_cost
    # The constrained optimum is (0, 1, 1, 1) with cost 1 (worst of 200 seeds: 1.02).
    assert r.best_cost < 1.1


def test_all_inf_costs_do_not_crash():
    r = fpa(lambda X: np.full(X.shape[0], np.nan), BOX, population=5, iterations=3, seed=0)
    assert r.best_cost == np.inf and r.initial_best_cost == np.inf
    assert np.all(r.history == np.inf)
    assert r.best_x.shape == (D,)
    assert np.all(r.best_x >= BOX[0]) and np.all(r.best_x <= BOX[1])


# --------------------------------------------------------------------------- x0


def test_x0_seeds_the_initial_population():
    good = np.full(D, SHIFT)  # the Rastrigin optimum
    r = fpa(shifted_rastrigin, BOX, population=10, iterations=2, seed=0, x0=good[None])
    assert r.initial_best_cost == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(r.best_x, good)
    # Without x0 the random start is nowhere near it.
    r0 = fpa(shifted_rastrigin, BOX, population=10, iterations=2, seed=0)
    assert r0.initial_best_cost > 1.0


@pytest.mark.parametrize(
    "x0",
    [np.zeros((2, D + 1)), np.full((1, D), 6.0), np.zeros((11, D)), np.full((1, D), np.nan)],
    ids=["wrong_dim", "outside", "too_many", "nan"],
)
def test_bad_x0_raises(x0):
    with pytest.raises(UserError, match="x0"):
        fpa(sphere, BOX, population=10, iterations=1, x0=x0)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"population": 3}, "population"),
        ({"population": 0}, "population"),
        ({"iterations": 0}, "iterations"),
        ({"iterations": -2}, "iterations"),
        ({"p": -0.01}, r"\bp\b"),
        ({"p": 1.5}, r"\bp\b"),
        ({"p": float("nan")}, r"\bp\b"),
        ({"gamma": 0.0}, "gamma"),
        ({"gamma": -0.1}, "gamma"),
        ({"gamma": float("inf")}, "gamma"),
        ({"bounds": (np.zeros(D), np.zeros(D))}, "bounds"),
        ({"bounds": (np.array([0.0, 1.0]), np.array([1.0, 0.5]))}, "bounds"),
        ({"bounds": (np.zeros(3), np.ones(4))}, "bounds"),
        ({"bounds": (np.zeros((2, 2)), np.ones((2, 2)))}, "bounds"),
        ({"bounds": (np.array([0.0, -np.inf]), np.ones(2))}, "bounds"),
        ({"bounds": (np.array([0.0, np.nan]), np.ones(2))}, "bounds"),
    ],
)
def test_bad_settings_raise_user_error_naming_the_setting(kwargs, name):
    calls = []

    def cost(X):
        calls.append(1)
        return sphere(X)

    args = {"bounds": BOX, **kwargs}
    bounds = args.pop("bounds")
    with pytest.raises(UserError, match=name):
        fpa(cost, bounds, **args)
    assert not calls  # validated before any (expensive) evaluation


def test_cost_of_wrong_shape_raises():
    with pytest.raises(UserError, match="cost"):
        fpa(lambda X: np.zeros(X.shape[0] + 1), BOX, population=5, iterations=1)


def test_random_search_baseline():
    r = random_search(sphere, BOX, 105, seed=0, batch=50)
    assert r.n_evaluations == 105 and r.history.shape == (3,)
    assert np.all(np.diff(r.history) <= 0.0)
    assert r.best_cost == r.costs[0] == r.history[-1]
    assert r.population.shape == (50, D)
    assert np.all(r.best_x >= BOX[0]) and np.all(r.best_x <= BOX[1])
    assert r.best_cost == pytest.approx(float(sphere(r.best_x[None])[0]))
