"""The slot assignment of ``barrier``'s planner (swarm_mj/formation/slots.py, capt_assignment;
docs/barrier.md, "slot assignment"): a permutation; every pair satisfies the pairwise condition of
CAPT; the sum of squared distances no larger than the identity's; the global optimum (brute force)
satisfies the same condition; and straight paths flown in step from it keep every pair at least
min(start gap, goal gap)/√2 apart (the separation the condition implies, sampled along the paths)."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_mj.formation.slots import capt_assignment, polygon_offsets


def _cost(x: np.ndarray, g: np.ndarray, sigma) -> float:
    return float(((x - g[list(sigma)]) ** 2).sum())


def _pairwise_ok(x: np.ndarray, g: np.ndarray, sigma) -> bool:
    m = len(sigma)
    return all(np.dot(x[i] - x[j], g[sigma[i]] - g[sigma[j]]) >= -1e-9 for i in range(m) for j in range(m))


@settings(max_examples=150, deadline=None)
@given(m=st.integers(2, 7), seed=st.integers(0, 10**6), spread=st.floats(0.5, 5.0))
def test_assignment_is_a_pairwise_optimal_permutation(m, seed, spread):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-spread, spread, (m, 2))
    g = polygon_offsets(m, 1.0)[:, :2] + rng.uniform(-3.0, 3.0, 2)
    sigma = capt_assignment(x, g)
    assert sorted(sigma.tolist()) == list(range(m))
    assert _pairwise_ok(x, g, sigma)
    assert _cost(x, g, sigma) <= _cost(x, g, range(m)) + 1e-12
    best = min(itertools.permutations(range(m)), key=lambda s: _cost(x, g, s))
    assert _pairwise_ok(x, g, best)  # the optimum satisfies the condition the loop enforces
    # straight paths in step: x_i + s·(g_σ(i) − x_i), s in [0, 1]
    s = np.linspace(0.0, 1.0, 201)[:, None, None]
    paths = x[None] + s * (g[sigma][None] - x[None])  # (201, m, 2)
    for i in range(m):
        for j in range(i + 1, m):
            gap = np.linalg.norm(paths[:, i] - paths[:, j], axis=1).min()
            bound = min(np.linalg.norm(x[i] - x[j]), np.linalg.norm(g[sigma[i]] - g[sigma[j]])) / np.sqrt(2.0)
            assert gap >= bound - 1e-9


def test_crossing_pair_swaps_goals():
    x = np.array([[0.0, 0.0], [1.0, 0.0]])
    g = np.array([[1.0, 5.0], [0.0, 5.0]])  # index order crosses the two paths
    assert capt_assignment(x, g).tolist() == [1, 0]
    assert capt_assignment(x, g[::-1]).tolist() == [0, 1]
