"""Tests of swarm_mj.physics.wind: paper eqs. (35)–(37) as fixed by docs/interpretations.md §5.

Statistical tolerances are derived from the sample size in each test (effective
sample size of an AR(1) series, variances of the estimators); the reasoning is
written next to each one. Seeds are fixed, so the tests are deterministic; the
tolerances say how far a *correct* generator may land (K standard deviations,
K = 5: a false failure for a fresh seed has probability < 1e-5 per statistic),
and the negative tests show that a wrong generator lands outside them.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from swarm_mj.errors import UserError
from swarm_mj.physics.wind import (
    ALWAYS_ON,
    PAPER_SCHEDULE,
    WindConfig,
    WindField,
    deterministic_speed,
    force_from_speed,
    ou_filter,
    ou_series,
    relative_force,
    schedule_mask,
)

RHO, CD, AREA = 1.225, 1.0, 0.025
K = 5.0  # standard deviations allowed for a statistic


# --------------------------------------------------------------------------- OU helpers


def _ou_checks(series: list[np.ndarray], dt: float, tau: float, sigma: float) -> dict[str, tuple[float, float, float]]:
    """Pooled statistics of independent OU series (each (N,)) vs theory.

    Returns {name: (measured, expected, tolerance)}. With a = exp(-dt/tau), S series of
    N samples each, Gaussian AR(1) asymptotics (Bartlett):

    * mean: Var(mean) = sigma^2 / N_eff, N_eff = N (1-a)/(1+a) per series;
      pooled over S series, sd = sigma / sqrt(S N_eff).
    * variance (about the known mean 0, m2 = mean(X^2)):
      Var(m2) = 2 sigma^4 (1+a^2) / ((1-a^2) N); pooled: / S.
    * lag-1 autocorrelation r_1 (expected a): Var(r_1) = (1-a^2)/N; pooled: / S.
    * lag-h autocorrelation, h = tau/dt samples (expected a^h = e^-1):
      Var(r_h) = [(1+a^2)(1-a^{2h})/(1-a^2) - 2 h a^{2h}] / N; pooled: / S.
    The autocorrelations are ratio estimators with a bias of order 1/N_eff; the
    tolerance adds 1/(S N_eff) for it.
    """
    S = len(series)
    N = series[0].size
    a = math.exp(-dt / tau)
    h = int(round(tau / dt))
    n_eff = N * (1 - a) / (1 + a)
    allX = np.concatenate(series)
    m2 = float(np.mean(allX**2))
    mean = float(np.mean(allX))
    # Ratio of pooled sums (each series' lags only within itself).
    c0 = sum(float(np.dot(x, x)) for x in series)
    r1 = sum(float(np.dot(x[1:], x[:-1])) for x in series) / c0
    rh = sum(float(np.dot(x[h:], x[:-h])) for x in series) / c0
    bias = 1.0 / (S * n_eff)
    sd_mean = sigma / math.sqrt(S * n_eff)
    sd_var = sigma**2 * math.sqrt(2 * (1 + a * a) / ((1 - a * a) * N * S))
    sd_r1 = math.sqrt((1 - a * a) / (N * S))
    a2h = a ** (2 * h)
    sd_rh = math.sqrt(((1 + a * a) * (1 - a2h) / (1 - a * a) - 2 * h * a2h) / (N * S))
    return {
        "mean": (mean, 0.0, K * sd_mean),
        "variance": (m2, sigma**2, K * sd_var),
        "lag1": (r1, a, K * sd_r1 + bias),
        "lag_tau": (rh, math.exp(-1.0), K * sd_rh + bias),
    }


def _failures(checks: dict[str, tuple[float, float, float]]) -> list[str]:
    return [name for name, (got, want, tol) in checks.items() if not abs(got - want) <= tol]


def _describe(checks: dict[str, tuple[float, float, float]]) -> str:
    return "; ".join(f"{n}: {g:.5f} vs {w:.5f} ± {t:.5f}" for n, (g, w, t) in checks.items())


# --------------------------------------------------------------------------- OU: exactness


def test_ou_filter_equals_the_plain_recursion():
    """The blocked cumulative-sum AR(1) equals X_i = a X_{i-1} + w_i term by term."""
    rng = np.random.default_rng(7)
    k = 3001
    a = np.array([math.exp(-0.01 / 2.0), math.exp(-0.01 / 0.05), 0.0])
    x0 = rng.standard_normal(3)
    w = rng.standard_normal((k - 1, 3))
    got = ou_filter(x0, w, a)
    ref = np.empty((k, 3))
    ref[0] = x0
    for i in range(1, k):
        ref[i] = a * ref[i - 1] + w[i - 1]
    # |X| is at most ~ sqrt(1/(1-a^2)) * 5 ≈ 50; float64 relative error ~1e-15 per term.
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-11)


# --------------------------------------------------------------------------- OU: statistics

SEEDS = (11, 12, 13, 14, 15)


@pytest.mark.parametrize("dt, n", [(0.01, 200_000), (0.1, 20_000)])
def test_ou_statistics_match_theory(dt: float, n: int):
    """Mean 0, variance sigma^2, lag-1 autocorrelation a, lag-tau autocorrelation e^-1.

    Same 2000 s of series at two sample periods: the discretisation is exact, so the
    statistics must not depend on dt. Both axes of WindField (sigma_x 0.8, sigma_y 0.5,
    tau 2 s), 5 seeds pooled. At dt = 0.01: a = 0.99501, N_eff ≈ 500 per seed, so
    tolerances ≈ mean ±0.08 m/s (x), variance ±10 %, lag-1 ±9e-4, lag-tau ±0.055.
    """
    cfg = WindConfig()
    turb = [WindField(cfg, dt=dt, seed=s).turbulence(n) for s in SEEDS]  # each (n, 2)
    for axis in (0, 1):
        checks = _ou_checks([x[:, axis] for x in turb], dt, cfg.tau[axis], cfg.sigma[axis])
        assert _failures(checks) == [], f"axis {'xy'[axis]}: {_describe(checks)}"

    # x and y are independent: lag-0 cross-correlation ~ 0. For two independent AR(1)
    # with the same a, Var(r_xy) = (1+a^2)/((1-a^2) N); pooled over S seeds.
    a = math.exp(-dt / 2.0)
    sxy = sum(float(np.dot(x[:, 0], x[:, 1])) for x in turb)
    sxx = sum(float(np.dot(x[:, 0], x[:, 0])) for x in turb)
    syy = sum(float(np.dot(x[:, 1], x[:, 1])) for x in turb)
    rxy = sxy / math.sqrt(sxx * syy)
    tol = K * math.sqrt((1 + a * a) / ((1 - a * a) * n * len(SEEDS)))
    assert abs(rxy) <= tol, f"cross-correlation {rxy:.4f} beyond ±{tol:.4f}"


def test_ou_statistics_catch_wrong_generators():
    """The checks above have teeth: a wrong a or a wrong noise scale fails them."""
    dt, tau, sigma, n = 0.01, 2.0, 0.8, 200_000

    def pooled(tau_used: float, scale_fix: bool = True) -> list[np.ndarray]:
        out = []
        for s in SEEDS:
            rng = np.random.default_rng(s)
            if scale_fix:
                out.append(ou_series(n, dt, np.array([tau_used]), np.array([sigma]), rng)[:, 0])
            else:
                # Forgetting sqrt(1 - a^2): X_i = a X_{i-1} + sigma eta_i (variance sigma^2/(1-a^2)).
                a = math.exp(-dt / tau_used)
                x0 = np.array([sigma * rng.standard_normal()])
                out.append(ou_filter(x0, sigma * rng.standard_normal((n - 1, 1)), np.array([a]))[:, 0])
        return out

    good = _ou_checks(pooled(tau), dt, tau, sigma)
    assert _failures(good) == [], _describe(good)

    # a from tau/2: lag-1 gives 0.99005 instead of 0.99501 (≈ 50 sd off), lag-tau e^-2.
    wrong_a = _ou_checks(pooled(tau / 2), dt, tau, sigma)
    assert {"lag1", "lag_tau"} <= set(_failures(wrong_a)), _describe(wrong_a)

    # a from 2 tau: lag-tau e^-1/2 = 0.61.
    wrong_a2 = _ou_checks(pooled(2 * tau), dt, tau, sigma)
    assert {"lag1", "lag_tau"} <= set(_failures(wrong_a2)), _describe(wrong_a2)

    # Noise without sqrt(1 - a^2): variance 100 sigma^2.
    wrong_scale = _ou_checks(pooled(tau, scale_fix=False), dt, tau, sigma)
    assert "variance" in _failures(wrong_scale), _describe(wrong_scale)


def test_ou_starts_from_the_stationary_law():
    """X_0 ~ N(0, sigma^2) (documented choice), not X_0 = 0.

    3000 independent seeds, one sample each: the sample variance of n i.i.d. normals has
    sd sigma^2 sqrt(2/n) = 0.026 sigma^2, so ±K sd = ±13 %. X_0 = 0 would give 0.
    """
    n = 3000
    x0 = np.array([WindField(WindConfig(), seed=s).turbulence(1)[0] for s in range(n)])  # (n, 2)
    for axis, sigma in ((0, 0.8), (1, 0.5)):
        var = float(np.mean(x0[:, axis] ** 2))
        assert abs(var - sigma**2) <= K * sigma**2 * math.sqrt(2 / n), (axis, var)
        assert abs(float(np.mean(x0[:, axis]))) <= K * sigma / math.sqrt(n)


# --------------------------------------------------------------------------- seeding


def _times(t_end: float = 180.0, dt: float = 0.01, t0: float = 0.0) -> np.ndarray:
    return t0 + dt * np.arange(int(round((t_end - t0) / dt)) + 1)


def test_same_seed_same_series_different_seed_different():
    t = _times(60.0)
    a1 = WindField(WindConfig(), seed=42).sample(t)
    a2 = WindField(WindConfig(), seed=42).sample(t)
    b = WindField(WindConfig(), seed=43).sample(t)
    np.testing.assert_array_equal(a1.speed, a2.speed)
    np.testing.assert_array_equal(a1.force, a2.force)
    # Different seeds: the turbulence differs at (almost) every sample.
    assert np.mean(a1.speed[:, :2] != b.speed[:, :2]) > 0.99
    # Pure: sampling twice from the same field gives the same series.
    f = WindField(WindConfig(), seed=None)
    np.testing.assert_array_equal(f.sample(t).speed, f.sample(t).speed)
    # Prefix property: a shorter run sees the start of the longer one.
    short = WindField(WindConfig(), seed=42).sample(t[:1000])
    np.testing.assert_array_equal(short.speed, a1.speed[:1000])


# --------------------------------------------------------------------------- speed and force


def test_speed_is_eq35_without_turbulence():
    """With sigma = 0 the speed is eq. (35) exactly, written here independently."""
    t = _times(180.0)
    s = WindField(WindConfig(sigma=(0.0, 0.0)), seed=0).sample(t)
    vx = 5.2 + 2 * np.sin(0.05 * t) + 0.5 * np.sin(0.5 * t)
    vy = 3 + 1.5 * np.sin(0.04 * t + math.pi / 3)
    np.testing.assert_allclose(s.speed[:, 0], vx, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.speed[:, 1], vy, rtol=0, atol=1e-12)
    assert np.all(s.speed[:, 2] == 0.0)


def test_turbulence_is_added_to_the_deterministic_part():
    cfg = WindConfig()
    f = WindField(cfg, seed=5)
    t = _times(30.0, t0=10.0)
    s = f.sample(t)
    np.testing.assert_allclose(
        s.speed - deterministic_speed(t, cfg), np.c_[f.turbulence(t.size), np.zeros(t.size)], rtol=0, atol=1e-12
    )


def test_force_is_half_rho_cd_a_abs_v_v_where_on():
    """F = 0.5 rho Cd A |V| V per axis, computed here from the reported speed."""
    t = _times(180.0)
    s = WindField(WindConfig(), seed=3).sample(t)
    expected = 0.5 * RHO * CD * AREA * np.abs(s.speed) * s.speed
    on = s.on_mask
    np.testing.assert_allclose(s.force[on], expected[on], rtol=1e-14, atol=0)
    assert np.all(s.force[~on] == 0.0)
    # Spot values: at 100 s both axes on, forces of order 0.5*1.225*0.025*5^2 ≈ 0.38 N.
    i = int(round(100.0 / 0.01))
    assert s.force[i, 0] == pytest.approx(0.5 * 1.225 * 1.0 * 0.025 * s.speed[i, 0] ** 2, rel=1e-14)


def test_force_has_the_sign_of_the_speed():
    """A wind towards -x/-y pushes towards -x/-y (the paper's V^2 would push towards +)."""
    v = np.array([[-4.0, 3.0, 0.0], [2.0, -0.5, 0.0]])
    f = force_from_speed(v, RHO, CD, AREA)
    np.testing.assert_allclose(
        f,
        [[-0.5 * RHO * AREA * 16, 0.5 * RHO * AREA * 9, 0.0], [0.5 * RHO * AREA * 4, -0.5 * RHO * AREA * 0.25, 0.0]],
        rtol=1e-15,
    )
    cfg = WindConfig(mean=(-6.0, -2.0), sinusoids_x=(), sinusoids_y=(), sigma=(0.0, 0.0), schedule=ALWAYS_ON)
    s = WindField(cfg, seed=0).sample(_times(1.0))
    np.testing.assert_allclose(s.force[:, 0], -0.5 * RHO * AREA * 36)
    np.testing.assert_allclose(s.force[:, 1], -0.5 * RHO * AREA * 4)
    assert np.all(s.force[:, 2] == 0.0)


def test_default_schedule_is_the_papers():
    t = _times(180.0)
    s = WindField(WindConfig(), seed=1).sample(t)

    def at(time: float) -> int:
        return int(round(time / 0.01))

    # 10 s: no force at all, but the speed is reported.
    assert np.all(s.force[at(10.0)] == 0.0)
    assert s.speed[at(10.0), 0] != 0.0 and s.speed[at(10.0), 1] != 0.0
    # 30 s: only x.
    assert s.force[at(30.0), 0] != 0.0
    assert s.force[at(30.0), 1] == 0.0 and s.force[at(30.0), 2] == 0.0
    # 60 s: x and y.
    assert s.force[at(60.0), 0] != 0.0 and s.force[at(60.0), 1] != 0.0
    assert s.force[at(60.0), 2] == 0.0
    # Edges: [20, 50) for x alone, [50, end] for x and y, 180 s included.
    assert s.on_mask[at(19.99)].tolist() == [False, False, False]
    assert s.on_mask[at(20.0)].tolist() == [True, False, False]
    assert s.on_mask[at(49.99)].tolist() == [True, False, False]
    assert s.on_mask[at(50.0)].tolist() == [True, True, False]
    assert s.on_mask[at(180.0)].tolist() == [True, True, False]
    assert np.all(s.force[~s.on_mask] == 0.0)


def test_empty_schedule_is_never_on_and_always_on_is_explicit():
    t = _times(100.0)
    never = WindField(WindConfig(schedule=()), seed=0).sample(t)
    assert not never.on_mask.any() and np.all(never.force == 0.0) and np.all(never.speed[:, 0] != 0.0)
    always = WindField(WindConfig(schedule=ALWAYS_ON), seed=0).sample(t)
    assert always.on_mask[:, :2].all() and not always.on_mask[:, 2].any()
    overlap = schedule_mask(np.array([5.0, 15.0, 25.0]), [(0, 20, "x"), (10, 30, "y")])
    assert overlap.tolist() == [[True, False, False], [True, True, False], [False, True, False]]


def test_disabled_wind_is_zero():
    s = WindField(WindConfig.none(), seed=0).sample(_times(100.0))
    assert np.all(s.speed == 0.0) and np.all(s.force == 0.0) and not s.on_mask.any()
    assert WindConfig.none() == WindConfig(enabled=False)


def test_relative_airspeed_force():
    wind = np.array([5.0, -3.0, 0.0])
    vel = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.0], [7.0, 0.0, 1.0]])
    f = relative_force(wind, vel, np.array([True, True, False]), RHO, CD, AREA)
    c = 0.5 * RHO * CD * AREA
    np.testing.assert_allclose(f, [[c * 25, -c * 9, 0.0], [0.0, 0.0, 0.0], [-c * 4, -c * 9, 0.0]], rtol=1e-15)
    assert np.all(relative_force(wind, vel, np.zeros(3, bool)) == 0.0)

    t = _times(100.0)
    off = WindField(WindConfig(), seed=2).sample(t)
    on = WindField(WindConfig(relative_airspeed=True), seed=2).sample(t)
    i = int(round(60.0 / 0.01))
    # Off (default): every drone feels the same force, whatever its velocity.
    np.testing.assert_array_equal(off.drone_forces(i, vel), np.tile(off.force[i], (3, 1)))
    # On: a drone at rest feels the plain force; one moving with the wind feels nothing.
    fr = on.drone_forces(i, np.vstack([np.zeros(3), on.speed[i]]))
    np.testing.assert_allclose(fr[0], on.force[i], rtol=1e-15)
    np.testing.assert_allclose(fr[1], 0.0, atol=1e-15)
    # Before 20 s the schedule masks the relative force as well.
    assert np.all(on.drone_forces(int(round(10.0 / 0.01)), vel) == 0.0)


def test_times_must_be_uniform_at_dt():
    f = WindField(WindConfig(), dt=0.01, seed=0)
    f.sample(np.cumsum(np.full(1000, 0.01)))  # accumulated float steps are fine
    with pytest.raises(ValueError, match="uniformly spaced"):
        f.sample(np.arange(100) * 0.02)
    with pytest.raises(ValueError, match="uniformly spaced"):
        f.sample(np.array([0.0, 0.01, 0.03]))
    with pytest.raises(ValueError):
        WindField(WindConfig(), dt=0.0)
    assert len(f.sample(np.array([3.0]))) == 1 and len(f.sample(np.array([]))) == 0


# --------------------------------------------------------------------------- config


def test_defaults_are_spec():
    c = WindConfig()
    assert c.mean == (5.2, 3.0) and c.tau == (2.0, 2.0) and c.sigma == (0.8, 0.5)
    assert (c.rho, c.cd, c.area) == (1.225, 1.0, 0.025)
    assert c.schedule == PAPER_SCHEDULE and c.enabled and not c.relative_airspeed
    assert c.sinusoids_x == ((2.0, 0.05, 0.0), (0.5, 0.5, 0.0))
    assert c.sinusoids_y == ((1.5, 0.04, math.pi / 3),)


def test_from_toml_table():
    doc = tomllib.loads(
        """
        [wind]
        enabled = true
        mean = [5.2, 3.0]
        sinusoids_x = [[2.0, 0.05, 0.0], [0.5, 0.5, 0.0]]
        sinusoids_y = [[1.5, 0.04, 1.0471975511965976]]
        tau = [2.0, 2.0]
        sigma = [0.8, 0.5]
        rho = 1.225
        cd = 1
        area = 0.025
        schedule = [[20.0, 50.0, "x"], [50.0, inf, "xy"]]
        relative_airspeed = false
        """
    )
    assert WindConfig.from_dict(doc["wind"], "s.toml") == WindConfig()
    assert WindConfig.from_dict({}, "s.toml") == WindConfig()
    c = WindConfig.from_dict({"tau": 3, "sigma": [0.0, 0.1], "schedule": [[0, 1e9, "yx"]]}, "s.toml")
    assert c.tau == (3.0, 3.0) and c.sigma == (0.0, 0.1) and c.schedule == ((0.0, 1e9, "yx"),)
    assert WindConfig.from_dict(WindConfig().to_dict(), "s.toml") == WindConfig()


@pytest.mark.parametrize(
    "table, field",
    [
        ({"speed": 3}, "speed"),
        ({"feedforward": True}, "feedforward"),
        ({"tau": [-1.0, 2.0]}, "tau"),
        ({"tau": [2.0, 0.0]}, "tau"),
        ({"sigma": [0.8, -0.1]}, "sigma"),
        ({"rho": -1.0}, "rho"),
        ({"cd": -0.5}, "cd"),
        ({"area": -0.025}, "area"),
        ({"schedule": [[50.0, 20.0, "x"]]}, "schedule[0]"),
        ({"schedule": [[20.0, 50.0, "x"], [60.0, 60.0, "y"]]}, "schedule[1]"),
        ({"schedule": [[20.0, 50.0, "xz"]]}, "schedule[0]"),
        ({"schedule": [[20.0, 50.0, ""]]}, "schedule[0]"),
        ({"schedule": [[20.0, 50.0, "xx"]]}, "schedule[0]"),
        ({"schedule": [[20.0, 50.0]]}, "schedule[0]"),
        ({"mean": [5.2]}, "mean"),
        ({"mean": "fast"}, "mean"),
        ({"sinusoids_x": [[2.0, 0.05]]}, "sinusoids_x[0]"),
        ({"sinusoids_y": [[1.5, 0.04, "pi"]]}, "sinusoids_y[0]"),
        ({"enabled": "yes"}, "enabled"),
        ({"relative_airspeed": 1}, "relative_airspeed"),
        ({"rho": float("nan")}, "rho"),
    ],
)
def test_config_errors_name_the_field(table: dict, field: str):
    with pytest.raises(UserError) as e:
        WindConfig.from_dict(table, "scenarios/x.toml")
    assert e.value.where == f"scenarios/x.toml: wind.{field}"
    assert str(e.value).startswith(f"scenarios/x.toml: wind.{field}: ")


def test_direct_construction_is_validated_too():
    with pytest.raises(UserError) as e:
        WindConfig(tau=(-2.0, 2.0))
    assert e.value.where == "wind.tau"
    # Lists are stored as tuples (the config stays hashable and comparable).
    c = WindConfig(mean=[1, 2], schedule=[[0, 5, "x"]])
    assert c.mean == (1.0, 2.0) and c.schedule == ((0.0, 5.0, "x"),)
    hash(c)
