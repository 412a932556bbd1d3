"""Flower Pollination Algorithm (Yang 2012), batched and drone-agnostic.

This is the optimiser of paper Fig. 3 with the corrections of docs/interpretations.md §6:

* global pollination moves a flower *towards* the best one,
  ``x_i + gamma * L(lambda) * (g_best - x_i)`` (the paper prints the sign the
  other way round), with a Lévy step ``L`` drawn per dimension by Mantegna's
  algorithm, ``lambda = 1.5``;
* local pollination is ``x_i + eps * (x_j - x_k)``, ``eps ~ U(0, 1)``, with
  ``j != k`` (both also different from ``i``) drawn at random;
* every candidate is clipped to the bounds and replaces its parent only when its
  cost is strictly lower (greedy replacement); the global best is updated once
  per iteration.

The cost function is *batched*: it receives the whole population of candidate
moves, ``(n, d)``, and returns ``(n,)`` costs, one call per iteration, so that a
caller can simulate a whole population in one physics model. A cost may be
``+inf`` (e.g. a diverged simulation); ``NaN`` is read as ``+inf``.

Defaults are the paper's Table 2: ``N = 50`` flowers, 14 iterations, switch
probability ``p = 0.04`` and step size ``gamma = 0.02``.

Nothing here knows about drones; see ``swarm_mj.tuning`` callers for that.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..paper import TABLE2_FPA

__all__ = [
    "Bounds",
    "CostFn",
    "Callback",
    "FPAResult",
    "fpa",
    "levy_steps",
    "mantegna_sigma",
    "random_search",
    "validate_bounds",
]

Bounds = tuple[np.ndarray, np.ndarray]
"""``(lower (d,), upper (d,))`` box of the search space."""

CostFn = Callable[[np.ndarray], np.ndarray]
"""Batched cost: ``(n, d)`` candidates -> ``(n,)`` costs (lower is better)."""

Callback = Callable[[int, np.ndarray, float, np.ndarray], None]
"""``callback(iteration, best_x, best_cost, history)``; ``history`` holds the
best cost after iterations ``0..iteration`` (index 0 = initial population)."""


@dataclass(frozen=True)
class FPAResult:
    """Outcome of :func:`fpa` (or :func:`random_search`).

    Attributes:
        best_x: best point found, ``(d,)``.
        best_cost: its cost (``inf`` if every evaluation was inf/NaN).
        initial_best_cost: best cost of the initial population (first batch for
            random search).
        history: best cost after each iteration, index 0 = initial population;
            ``(iterations + 1,)`` for FPA, one entry per batch for random search.
            Non-increasing.
        n_evaluations: number of points passed to the cost function.
        population: final population, ``(N, d)`` (random search: the best
            ``batch`` points seen, best first).
        costs: costs of ``population``, ``(N,)``, NaN already mapped to inf.
        seed: seed of the ``np.random.default_rng`` that drove the run.
    """

    best_x: np.ndarray
    best_cost: float
    initial_best_cost: float
    history: np.ndarray
    n_evaluations: int
    population: np.ndarray
    costs: np.ndarray
    seed: int | None


# --------------------------------------------------------------------------- helpers


def validate_bounds(bounds: Bounds) -> tuple[np.ndarray, np.ndarray]:
    """Check a ``(lower, upper)`` box and return it as two float ``(d,)`` arrays.

    Raises :class:`UserError` if the shapes differ or are not 1-D and non-empty,
    if any value is not finite, or if ``lower >= upper`` in any dimension.
    """
    try:
        lower_raw, upper_raw = bounds
        lower = np.asarray(lower_raw, dtype=float)
        upper = np.asarray(upper_raw, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UserError(f"bounds must be a pair (lower, upper) of numeric arrays ({exc})") from None
    if lower.ndim != 1 or upper.ndim != 1 or lower.shape != upper.shape or lower.size == 0:
        raise UserError(
            f"bounds lower and upper must be 1-D arrays of the same non-zero length, "
            f"got shapes {lower.shape} and {upper.shape}"
        )
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise UserError("bounds must be finite numbers")
    bad = np.flatnonzero(lower >= upper)
    if bad.size:
        i = int(bad[0])
        raise UserError(
            f"bounds need lower < upper in every dimension; dimension {i} has lower={lower[i]!r} >= upper={upper[i]!r}"
        )
    return lower, upper


def mantegna_sigma(lam: float = 1.5) -> float:
    """Scale ``sigma_u`` of the numerator of Mantegna's Lévy step.

    ``sigma_u = [Gamma(1+lam) sin(pi lam / 2) / (Gamma((1+lam)/2) lam 2^((lam-1)/2))]^(1/lam)``
    (Yang 2012, eq. for ``L`` in the global pollination step).
    """
    num = math.gamma(1.0 + lam) * math.sin(math.pi * lam / 2.0)
    den = math.gamma((1.0 + lam) / 2.0) * lam * 2.0 ** ((lam - 1.0) / 2.0)
    return (num / den) ** (1.0 / lam)


def levy_steps(rng: np.random.Generator, shape: tuple[int, ...], lam: float = 1.5) -> np.ndarray:
    """Lévy-flight step lengths ``L`` by Mantegna's algorithm (paper Fig. 3, global step).

    ``L = u / |v|^(1/lam)`` with ``u ~ N(0, sigma_u^2)`` and ``v ~ N(0, 1)``, drawn
    independently for every entry of ``shape`` (one per flower and dimension).
    For ``0 < lam < 2`` the distribution is heavy-tailed (tail ``~ |L|^-(1+lam)``).
    """
    if not (0.0 < lam <= 2.0):
        raise UserError(f"Levy exponent lambda must be in (0, 2], got {lam!r}")
    u = rng.normal(0.0, mantegna_sigma(lam), size=shape)
    v = rng.normal(0.0, 1.0, size=shape)
    return u / np.abs(v) ** (1.0 / lam)


def _evaluate(cost: CostFn, X: np.ndarray) -> np.ndarray:
    """Call the batched cost once and return finite-or-inf float costs ``(n,)``."""
    raw = np.asarray(cost(X.copy()), dtype=float)
    if raw.shape != (X.shape[0],):
        raw = raw.reshape(-1) if raw.size == X.shape[0] else raw
    if raw.shape != (X.shape[0],):
        raise UserError(
            f"cost function must return one cost per candidate, shape ({X.shape[0]},), got shape {np.shape(raw)}"
        )
    return np.where(np.isnan(raw), np.inf, raw)


def _check_int(name: str, value: int, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise UserError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise UserError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _pick_partners(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """For each flower ``i`` draw ``j != k``, both ``!= i`` (needs ``n >= 3``)."""
    i = np.arange(n)
    # j uniform over the n-1 others, k uniform over the n-2 others different from i and j.
    j = (i + rng.integers(1, n, size=n)) % n
    k = rng.integers(0, n - 2, size=n)
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    k = k + (k >= lo)
    k = k + (k >= hi)
    return j, k


def _check_steps(p: float, gamma: float) -> tuple[float, float]:
    """The switch probability ``p`` in [0, 1] and the step size ``gamma`` > 0, as floats (else UserError)."""
    if not (isinstance(p, (int, float, np.floating, np.integer)) and 0.0 <= float(p) <= 1.0):
        raise UserError(f"switch probability p must be in [0, 1], got {p!r}")
    if not (
        isinstance(gamma, (int, float, np.floating, np.integer)) and math.isfinite(float(gamma)) and float(gamma) > 0.0
    ):
        raise UserError(f"step size gamma must be a finite number > 0, got {gamma!r}")
    return float(p), float(gamma)


def _initial_population(
    rng: np.random.Generator, lower: np.ndarray, upper: np.ndarray, n: int, x0: np.ndarray | None
) -> np.ndarray:
    """The initial population (n, d) (Fig. 3, "initialise"): uniform in the box, its first rows the
    points of ``x0`` (checked: shape (k, d) or (d,), k <= n, finite, inside the box)."""
    d = lower.size
    X = lower + rng.random((n, d)) * (upper - lower)
    if x0 is not None:
        seeds = np.asarray(x0, dtype=float)
        if seeds.ndim == 1:
            seeds = seeds[None, :]
        if seeds.ndim != 2 or seeds.shape[1] != d:
            raise UserError(f"x0 must have shape (k, {d}), got {np.shape(x0)}")
        if seeds.shape[0] > n:
            raise UserError(f"x0 has {seeds.shape[0]} rows, more than population={n}")
        if not np.all(np.isfinite(seeds)):
            raise UserError("x0 must be finite")
        if np.any(seeds < lower) or np.any(seeds > upper):
            raise UserError("x0 must lie inside bounds")
        X[: seeds.shape[0]] = seeds
    return X


def _candidates(
    rng: np.random.Generator,
    X: np.ndarray,
    best_x: np.ndarray,
    p: float,
    gamma: float,
    lower: np.ndarray,
    upper: np.ndarray,
) -> np.ndarray:
    """One iteration's candidate moves (n, d), clipped to the box: global pollination towards the best with
    probability ``p``, else local (steps 1 and 2 of :func:`fpa`; the draws in the same order every call)."""
    n, d = X.shape
    is_global = np.asarray(rng.random(n) < p)  # (n,) bool
    levy = levy_steps(rng, (n, d))
    eps = rng.random((n, 1))
    j, k = _pick_partners(rng, n)
    glob = X + gamma * levy * (best_x - X)  # docs/interpretations.md §6: towards g_best
    loc = X + eps * (X[j] - X[k])
    cand = np.where(is_global[:, None], glob, loc)
    return np.clip(cand, lower, upper)


# --------------------------------------------------------------------------- FPA


def fpa(
    cost: CostFn,
    bounds: Bounds,
    *,
    population: int = TABLE2_FPA.population,
    iterations: int = TABLE2_FPA.iterations,
    p: float = TABLE2_FPA.p,
    gamma: float = TABLE2_FPA.gamma,
    seed: int | None = 0,
    x0: np.ndarray | None = None,
    callback: Callback | None = None,
) -> FPAResult:
    """Minimise a batched ``cost`` over a box with the Flower Pollination Algorithm.

    Implements paper Fig. 3 (Yang 2012) with docs/interpretations.md §6's corrections. Per iteration:

    1. for every flower ``i``, with probability ``p`` global pollination
       ``x_i + gamma * L * (g_best - x_i)`` (towards the best, docs/interpretations.md §6; ``L``
       Mantegna Lévy steps with ``lambda = 1.5``, per dimension), otherwise local
       pollination ``x_i + eps * (x_j - x_k)`` with ``eps ~ U(0, 1)``;
    2. clip all candidates to ``bounds``; evaluate them in *one* call of ``cost``;
    3. greedy replacement: keep a candidate only if its cost is strictly lower
       than its parent's;
    4. update the global best and call ``callback``.

    Args:
        cost: batched cost ``(n, d) -> (n,)``; ``inf`` and ``NaN`` (read as
            ``inf``) are allowed.
        bounds: ``(lower (d,), upper (d,))``.
        population: number of flowers ``N`` (>= 4; paper Table 2: 50).
        iterations: number of iterations after the initial evaluation (>= 1;
            Table 2: 14).
        p: switch probability of global pollination, in ``[0, 1]`` (Table 2: 0.04).
        gamma: global step-size scale, > 0 (Table 2: 0.02).
        seed: seed for ``np.random.default_rng``; the same seed gives the same run.
        x0: optional ``(k, d)`` (or ``(d,)``) points that seed the first ``k``
            flowers (``k <= population``, inside bounds); the rest are uniform.
        callback: ``callback(iteration, best_x, best_cost, history)`` called after
            the initial evaluation (iteration 0) and after every iteration.

    Returns:
        :class:`FPAResult`; ``n_evaluations == population * (iterations + 1)``.

    Raises:
        UserError: on a bad setting (message names it) or a cost of wrong shape.
    """
    lower, upper = validate_bounds(bounds)
    n = _check_int("population", population, 4)
    iterations = _check_int("iterations", iterations, 1)
    p, gamma = _check_steps(p, gamma)

    rng = np.random.default_rng(seed)
    X = _initial_population(rng, lower, upper, n, x0)
    F = _evaluate(cost, X)
    n_eval = n
    best = int(np.argmin(F))
    best_x, best_cost = X[best].copy(), float(F[best])
    initial_best_cost = best_cost
    history = np.empty(iterations + 1)
    history[0] = best_cost
    if callback is not None:
        callback(0, best_x.copy(), best_cost, history[:1].copy())

    for it in range(1, iterations + 1):
        # 1.-2. Candidate moves from the population at the start of the iteration, clipped; one batched call.
        cand = _candidates(rng, X, best_x, p, gamma, lower, upper)
        Fc = _evaluate(cost, cand)
        n_eval += n
        # 3. Greedy replacement.
        better = Fc < F
        X[better] = cand[better]
        F[better] = Fc[better]
        # 4. Global best.
        i_best = int(np.argmin(F))
        if F[i_best] < best_cost:
            best_x, best_cost = X[i_best].copy(), float(F[i_best])
        history[it] = best_cost
        if callback is not None:
            callback(it, best_x.copy(), best_cost, history[: it + 1].copy())

    return FPAResult(
        best_x=best_x,
        best_cost=best_cost,
        initial_best_cost=initial_best_cost,
        history=history,
        n_evaluations=n_eval,
        population=X,
        costs=F,
        seed=seed,
    )


# --------------------------------------------------------------------------- baseline


def random_search(
    cost: CostFn,
    bounds: Bounds,
    n_evaluations: int,
    seed: int | None = 0,
    batch: int = 50,
) -> FPAResult:
    """Uniform random search in the box: the baseline FPA must beat.

    Draws ``n_evaluations`` uniform points in batches of ``batch`` (one ``cost``
    call per batch; the last batch may be smaller). ``history`` has one entry per
    batch; ``population``/``costs`` are the best ``batch`` points seen, best first.
    """
    lower, upper = validate_bounds(bounds)
    d = lower.size
    total = _check_int("n_evaluations", n_evaluations, 1)
    batch = _check_int("batch", batch, 1)
    rng = np.random.default_rng(seed)

    keep_X = np.empty((0, d))
    keep_F = np.empty(0)
    history: list[float] = []
    done = 0
    while done < total:
        m = min(batch, total - done)
        X = lower + rng.random((m, d)) * (upper - lower)
        F = _evaluate(cost, X)
        done += m
        allX, allF = np.vstack([keep_X, X]), np.concatenate([keep_F, F])
        order = np.argsort(allF, kind="stable")[:batch]
        keep_X, keep_F = allX[order], allF[order]
        history.append(float(keep_F[0]))

    hist = np.asarray(history)
    return FPAResult(
        best_x=keep_X[0].copy(),
        best_cost=float(keep_F[0]),
        initial_best_cost=float(hist[0]),
        history=hist,
        n_evaluations=done,
        population=keep_X,
        costs=keep_F,
        seed=seed,
    )
