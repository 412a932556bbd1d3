"""The physics step (issue 20, docs/physics_step.md): a coarse RK4 step against a fine one, and the
accuracy tool's "same at the printed digits" comparison.

The flight: one drone, no controller, inputs held (zero-order hold) for 2 s: thrust U1 = 6 N (above
its weight of 4.77 N) and constant body torques, so it tumbles about all three axes (body rates up
to ≈ 18 rad/s) while drifting ≈ 18 m; a constant wind force on top, and the linear drag of paper
eq. (1) that the simulator applies. Flown through :class:`swarm_mj.physics.sim.Sim` with RK4 at 10 ms (the
step equal to the control period) and at 1 ms.

What the difference is made of, checked separately below:

* RK4's truncation error, ∝ h⁴: with the drag off the position difference is 4 µm at 10 ms, and
  halving the step divides the error by ≈ 16 (position with the drag off, attitude with it on: the
  drag acts at the centre of mass and makes no torque).
* The drag is evaluated with the velocity at the start of each physics step and held over its RK4
  stages (``swarm_mj.physics.sim``; ``docs/interpretations.md``, "drag"). Held over a step h it lags the true
  −K·v(t) by h/2 on average, i.e. an extra force K·a·h/2, so the position moves by
  (h/2)·(K/m)·(x(t) − x(0) − v(0)·t) per axis (the double integral of a). Between h = 10 ms and 1 ms
  that is (9 ms / 2)·(K/m)·(x − x0 − v0·t): 0.86 mm after 2 s of this flight, which is the whole
  difference but for 12 µm.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from swarm_mj.physics.params import DEFAULT_PARAMS, QuadParams
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world

ROOT = Path(__file__).resolve().parents[2]
T = 0.01  # control period (s)
DURATION = 2.0  # s
U_HELD = np.array([[6.0, 0.3, -0.2, 0.25]])  # (1, 4) U1 (N), U2..U4 (N; torque = L·U)
WIND_FORCE = np.array([0.4, -0.3, 0.1])  # (3,) N, world frame
V0 = np.array([1.0, -0.5, 0.2])  # (3,) m/s initial velocity
START = np.array([0.0, 0.0, 100.0])  # high enough never to reach the floor


def fly(dt: float, params: QuadParams = DEFAULT_PARAMS, integrator: str = "RK4") -> tuple[np.ndarray, np.ndarray]:
    """Positions (k, 3) and quaternions (k, 4) at every control period of the tumbling flight."""
    world = build_world(1, positions=[START], timestep=dt, integrator=integrator, collisions=False, params=params)
    sim = Sim(world, T)
    d = sim.data
    d.qvel[0:3] = V0
    k = round(DURATION / T)
    pos, quat = np.empty((k + 1, 3)), np.empty((k + 1, 4))
    pos[0], quat[0] = d.qpos[0:3], d.qpos[3:7]
    for i in range(1, k + 1):
        sim.step(U_HELD, WIND_FORCE)
        pos[i], quat[i] = d.qpos[0:3], d.qpos[3:7]
    assert np.isfinite(pos).all() and np.isfinite(quat).all()
    return pos, quat


def angle_deg(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Rotation angle (°) between attitudes q and r (k, 4), computed without arccos's loss near 1."""
    w = (q * r).sum(axis=1)
    v = r[:, :1] * q[:, 1:] - q[:, :1] * r[:, 1:] - np.cross(r[:, 1:], q[:, 1:])
    return np.rad2deg(2 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w)))


@pytest.fixture(scope="module")
def flights() -> dict:
    return {dt: fly(dt) for dt in (0.001, 0.005, 0.01)}


def test_flight_tumbles_and_drifts(flights):
    """The flight is the hard case it claims to be: fast body rates, a long drift."""
    pos, quat = flights[0.001]
    assert np.linalg.norm(pos[-1] - pos[0]) > 10.0
    rate = angle_deg(quat[1:], quat[:-1]).max() / T  # °/s between samples
    assert np.deg2rad(rate) > 10.0


def test_10ms_rk4_within_1mm_of_1ms(flights):
    """Position within 1 mm, attitude within 0.005°, over the whole flight.

    1 mm is the issue's bar for the scenarios; this uncontrolled flight is harsher than any of them
    (nothing pulls it back to a path; measured 0.86 mm, nearly all of it the drag hold that
    :func:`test_drag_hold_explains_the_difference` predicts). The attitude sees no drag (no torque),
    only RK4's h⁴ error: measured 6.7e-4°; 0.005° leaves a factor 7.
    """
    p1, q1 = flights[0.001]
    p10, q10 = flights[0.01]
    assert np.linalg.norm(p10 - p1, axis=1).max() <= 1e-3
    assert angle_deg(q10, q1).max() <= 5e-3


def test_drag_hold_explains_the_difference(flights):
    """p(10 ms) − p(1 ms) is (9 ms / 2)·(K/m)·(x − x0 − v0·t) per axis, to within 50 µm (measured 12 µm,
    the RK4 truncation and the second-order terms of the hold); the difference itself is 0.86 mm."""
    p1, _ = flights[0.001]
    p10, _ = flights[0.01]
    t = np.arange(len(p1))[:, None] * T
    P = DEFAULT_PARAMS
    predicted = ((0.01 - 0.001) / 2) * (P.drag / P.m) * (p1 - p1[0] - V0 * t)  # (k, 3)
    diff = p10 - p1
    assert np.linalg.norm(diff, axis=1).max() > 5e-4  # the effect is there to be explained
    assert np.linalg.norm(diff - predicted, axis=1).max() <= 5e-5


def test_rk4_error_falls_with_the_fourth_power(flights):
    """Halving the step from 10 to 5 ms divides RK4's error by ≈ 2⁴ = 16 (accepted: 10 to 25): the
    attitude (no drag torque) in this flight, the position with the drag off."""
    _, q1 = flights[0.001]
    a10 = angle_deg(flights[0.01][1], q1).max()
    a5 = angle_deg(flights[0.005][1], q1).max()
    assert 10 <= a10 / a5 <= 25
    no_drag = QuadParams(Kx=0.0, Ky=0.0, Kz=0.0)
    r1, r5, r10 = (fly(dt, no_drag)[0] for dt in (0.001, 0.005, 0.01))
    e10 = np.linalg.norm(r10 - r1, axis=1).max()
    e5 = np.linalg.norm(r5 - r1, axis=1).max()
    assert 10 <= e10 / e5 <= 25
    assert e10 <= 2e-5  # 4 µm measured: without the drag hold RK4 is far below 1 mm


def test_first_order_integrators_are_far_worse(flights):
    """For contrast: Euler at 10 ms is off by centimetres on the same flight (first order)."""
    p1, _ = flights[0.001]
    pe, _ = fly(0.01, integrator="Euler")
    assert np.linalg.norm(pe - p1, axis=1).max() > 1e-2


# --------------------------------------------------------------------------- the tool's comparison


def _tool():
    spec = importlib.util.spec_from_file_location("accuracy_tool", ROOT / "tools" / "accuracy.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_same_printed_digits():
    acc = _tool()
    assert acc.same_printed(0.10040248, 0.1001, "{:.2f}")
    assert not acc.same_printed(1.43, 1.4351, "{:.2f}")  # 1.43 vs 1.44
    assert acc.same_printed(1.43, 1.4349, "{:.2f}")
    assert acc.same_printed(0.00188247, 0.00188244, "{:.4f}")
    assert not acc.same_printed(0.00184, 0.00196, "{:.4f}")  # 0.0018 vs 0.0020
    assert acc.same_printed(-0.001, 0.001, "{:.2f}")  # "-0.00" prints as 0.00
    assert acc.same_printed(float("inf"), "inf", "{:.2f}")  # never settled, in memory and from JSON
    assert not acc.same_printed(float("inf"), 9.99, "{:.2f}")
    assert acc.same_printed(None, None, "{:.2f}") and not acc.same_printed(None, 0.0, "{:.2f}")
    assert not acc.same_printed(3, 4, "{}")


def _summary(settle: list, rmse_x: float, contacts: int = 0) -> dict:
    r = {"x": rmse_x, "y": 0.01, "z": 0.0, "roll_deg": 0.1, "pitch_deg": 0.2}
    return {
        "drones": {"leader": {"rmse": r, "rmse_steady": dict(r), "max_abs_roll_deg": 1.0, "max_abs_pitch_deg": 2.0}},
        "contacts": contacts,
        "min_separation_m": 0.8,
        "formation": {"settling_s": settle},
    }


def test_differing_lists_changed_figures():
    acc = _tool()
    ref = acc.printed_figures(_summary([3.34, 2.1], 0.01234), "variable_diameter")
    assert acc.differing(ref, acc.printed_figures(_summary([3.344, 2.1], 0.012341), "variable_diameter")) == []
    d = acc.differing(ref, acc.printed_figures(_summary([3.34, 2.2], 0.01234, contacts=1), "variable_diameter"))
    assert {x["figure"] for x in d} == {"settling after change 1 s", "contacts"}
    assert all(x["in_readme"] for x in d)
    # RMSE is printed in the README only for the Table 5 single-drone runs
    d = acc.differing(ref, acc.printed_figures(_summary([3.34, 2.1], 0.0125), "variable_diameter"))
    assert [(x["figure"], x["in_readme"]) for x in d] == [("RMSE x m", False), ("RMSE from 10 s x m", False)]


def test_choose_step_takes_the_largest_rk4_step_that_holds():
    acc = _tool()

    def s(label, integ, dt, dev):
        return {
            "label": label,
            "integrator": integ,
            "timestep_s": dt,
            "worst_deviation_m": dev,
            "stopped": [],
            "differing": [],
            "over_bar": [],
        }

    rows = [
        s("a", "RK4", 0.001, 0.0),
        s("b", "RK4", 0.005, 2e-4),
        s("c", "RK4", 0.01, 8e-4),
        s("d", "Euler", 0.02, 0.0),
    ]
    assert acc.choose_step(rows)["label"] == "c"
    rows[2]["worst_deviation_m"] = 1.5e-3
    rows[2]["over_bar"] = [{"case": "x", "sensitive": True}]
    assert acc.choose_step(rows)["label"] == "b"
    assert acc.choose_step(rows, allow_sensitive=True)["label"] == "c"  # x moves as much with a nudged start
    rows[1]["differing"] = [{"figure": "RMSE x m", "in_readme": False, "sensitive": False}]
    assert acc.choose_step(rows)["label"] == "b"  # not a figure the README prints
    rows[1]["differing"] = [{"figure": "contacts", "in_readme": True, "sensitive": False}]
    assert acc.choose_step(rows)["label"] == "a"
    assert acc.choose_step(rows, allow_sensitive=True)["label"] == "c"
    rows[2]["differing"] = [{"figure": "contacts", "in_readme": True, "sensitive": False}]
    assert acc.choose_step(rows, allow_sensitive=True)["label"] == "a"


def test_contact_episodes_merge_a_pairs_quick_retouches():
    acc = _tool()
    log = [[1.00, 0, 1], [1.02, 0, 1], [1.05, 0, 1], [1.05, 1, 2], [1.50, 0, 1], [1.58, 1, 2]]
    assert acc._episodes(log, 0.1) == 4  # (0,1) at 1.00–1.05 and at 1.50; (1,2) at 1.05 and at 1.58
    assert acc._episodes(log, 0.01) == 6
