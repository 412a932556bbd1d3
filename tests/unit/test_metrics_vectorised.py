"""The summary's metrics over whole logs (swarm_mj/metrics.py), against per-sample and per-pair loops
written from their definitions: the vectorised forms give the same bits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_mj.metrics import (
    follower_distances,
    in_jet,
    keepout_distance,
    keepout_per_sample,
    keepout_summary,
    min_separation,
    norm,
    pair_measures,
)


def _log(k: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    pos = rng.normal(size=(k, n, 3)) * [1.5, 1.5, 1.0] + [0.0, 0.0, 1.0]
    quat = rng.normal(size=(k, n, 4)) * [1.0, 0.15, 0.15, 1.0]
    return pos, quat / np.linalg.norm(quat, axis=-1, keepdims=True)


@pytest.mark.parametrize("c", [1, 2, 3, 5])
def test_norm_is_numpys_to_the_bit(c):
    x = np.random.default_rng(c).normal(size=(400, 7, c)) * 10.0
    assert np.array_equal(norm(x), np.linalg.norm(x, axis=-1))
    if c <= 3:  # the squares summed in order, as by hand
        one = x[3, 2]
        assert norm(one) == math.sqrt(sum(float(v) * float(v) for v in one))


def test_in_jet_against_its_definition_pair_by_pair():
    pos, quat = _log(40, 5, seed=1)
    pos[:, :, 2] = np.abs(pos[:, :, 2])
    pos[:, 1] = pos[:, 0] - [0.1, 0.0, 1.0]  # drone 1 under drone 0: in its jet at level flight
    r0, spread, reach, radius = 0.4, 0.15, 6.0, 0.34
    got = in_jet(pos, quat, r0=r0, spread=spread, reach=reach, radius=radius)
    for t in range(pos.shape[0]):
        for i in range(pos.shape[1]):
            w, x, y, z = quat[t, i]
            axis = -np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
            for j in range(pos.shape[1]):
                rel = pos[t, j] - pos[t, i]
                s = float(rel @ axis)
                r = math.sqrt(max(float(rel @ rel) - s * s, 0.0))
                expected = i != j and 0 < s <= reach and r < r0 + spread * s + radius
                assert got[t, i, j] == expected, (t, i, j)
    assert got[:, 0, 1].any()


def test_pair_measures_are_the_numpy_definitions_to_the_bit():
    pos, _ = _log(300, 6, seed=2)
    pos[:, :, 2] -= 0.8  # some drones below the airborne bar
    radii = np.array([0.6, 0.6, 0.9])
    dist, rho = pair_measures(pos, radii, 0.1)
    i, j = np.triu_indices(6, 1)
    offsets = pos[:, i] - pos[:, j]
    assert np.array_equal(dist, np.linalg.norm(offsets, axis=-1))
    up = pos[:, :, 2] > 0.1
    expected = np.where(up[:, i] & up[:, j], keepout_distance(offsets, radii), np.inf).min(axis=1)
    assert np.array_equal(rho, expected)
    assert np.isinf(rho).any() and np.isfinite(rho).any()  # samples with and without two airborne
    assert np.array_equal(keepout_per_sample(pos, radii, 0.1), rho)
    t = np.arange(300) * 0.01
    assert keepout_summary(t, pos, radii, pair_measures(pos, radii)[1]) == keepout_summary(t, pos, radii)
    # the distances the summary passes to min_separation are the ones it computes itself
    assert min_separation(pos, dist) == min_separation(pos)
    brute = min(float(np.linalg.norm(pos[s, a] - pos[s, b])) for s in range(300) for a in range(6) for b in range(a))
    assert min_separation(pos)[0] == pytest.approx(brute, rel=1e-15)


def test_pair_measures_keep_numpys_nan_and_small_cases():
    pos, _ = _log(5, 3, seed=3)
    pos[:, :, 2] = 1.0
    pos[2, 1, 0] = np.nan
    dist, rho = pair_measures(pos, np.ones(3))
    assert np.isnan(rho[2]) and np.isfinite(np.delete(rho, 2)).all()
    assert np.isnan(dist[2, [0, 2]]).all() and np.isfinite(dist[2, 1])  # pairs (0, 1), (0, 2), (1, 2)
    i, j = np.triu_indices(3, 1)
    numpy_rho = keepout_distance(pos[:, i] - pos[:, j], np.ones(3)).min(axis=1)
    assert np.array_equal(rho, numpy_rho, equal_nan=True)
    one = pair_measures(pos[:, :1], np.ones(3))
    assert one[0].shape == (5, 0) and np.isinf(one[1]).all()
    empty = pair_measures(pos[:0], np.ones(3))
    assert empty[0].shape == (0, 3) and empty[1].shape == (0,)


def test_follower_distances_are_numpys_norm_to_the_bit():
    pos, _ = _log(200, 6, seed=4)
    d, pairs = follower_distances(pos)
    assert pairs == [(a, b) for a in range(1, 6) for b in range(a + 1, 6)]
    expected = np.stack([np.linalg.norm(pos[:, a, :2] - pos[:, b, :2], axis=-1) for a, b in pairs], axis=1)
    assert np.array_equal(d, expected)
