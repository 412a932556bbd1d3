"""``anti_collision = "barrier"`` (the jet-aware planner guarded by the barrier filter) flown in MuJoCo
(docs/barrier.md): the keep-out invariant in the summary, what ``auto`` chose and why, and the
filter's relaxations counted in the summary and the stress row."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_mj.experiments import stress
from swarm_mj.experiments.report_table import format_summary
from swarm_mj.experiments.runner import run
from swarm_mj.experiments.stress import StressCase, stress_data, stress_scenario
from swarm_mj.formation.anticollision import AUTO_CHOICE
from swarm_mj.formation.barrier import BarrierParams, keepout_radii
from swarm_mj.metrics import keepout_min_distance, keepout_time_s
from swarm_mj.physics.params import DEFAULT_PARAMS
from swarm_mj.pipeline.swarm import leader_reference
from swarm_mj.scenario import parse_scenario

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("aero", ["paper", "realistic"])
def test_barrier_flies_a_random_start(aero):
    res = run(stress_scenario(StressCase("barrier", 3, 3, 2.5, 0.6, 8.0, aero=aero)), progress=False)
    s, log = res.summary, res.log
    assert s["anti_collision_rule"] == "barrier"
    radii = keepout_radii()
    # the summary's keys are the metrics of the log (an independent path to the same numbers)
    assert s["keepout_min_distance"] == pytest.approx(keepout_min_distance(log.pos, radii))
    assert s["keepout_time_s"] == pytest.approx(keepout_time_s(log.t, log.pos, radii))
    assert s["keepout_time_s"] == 0.0 and s["contacts"] == 0 and s["crashes"] == 0
    # the text summary (what `swarm-mj run` prints) states the invariant too, where the physics has downwash
    line = f"closest ρ {s['keepout_min_distance']:.3f} (1 = on it), 0.00 s with an airborne pair inside"
    assert (line in format_summary(s, res.scenario)) == (aero == "realistic")


@pytest.mark.parametrize(("aero", "chosen"), [("paper", "layers"), ("realistic", "barrier")])
def test_auto_says_which_rule_it_chose_and_why(aero, chosen):
    """``anti_collision = "auto"`` (the circle's): the summary names the rule auto chose for the
    physics (``AUTO_CHOICE``, by whether it has downwash, not by the scenario) and the reason, and
    the text summary prints it; a rule named explicitly has no such key."""
    res = run("circle", aero=aero, duration=0.5, progress=False)
    s = res.summary
    assert res.scenario.anti_collision == "auto"
    assert s["anti_collision_rule"] == chosen
    assert s["anti_collision_auto"] == {"rule": chosen, "why": AUTO_CHOICE[aero == "realistic"][1]}
    assert f"auto chose '{chosen}': {s['anti_collision_auto']['why']}" in format_summary(s, res.scenario)
    named = run("circle", aero=aero, duration=0.5, progress=False, anti_collision=chosen).summary
    assert "anti_collision_auto" not in named


def test_relaxations_are_counted_in_the_summary_and_the_stress_row(monkeypatch):
    # limits too small for the filter's constraints (6°, 0.6 m/s²): the filter relaxes them
    # (docs/barrier.md, "Infeasible under the limits: relaxation"), and the run says how often, on
    # both drivers
    data = stress_data(StressCase("barrier", 100033, 5, 3.0, 0.6, 6.0, aero="realistic"))
    # the split's relaxations (the joint fallback meets these limits)
    limits = {"max_tilt_deg": 6.0, "accel_up": 0.6, "accel_down": 0.6}
    data["formation"]["barrier"] = {**limits, "reserve_tilt_deg": 0.0, "joint_fallback": False}
    sc = parse_scenario(data, "<test>")
    runs = [run(sc, progress=False, fused=fused) for fused in (False, True)]
    for res in runs:
        relax = [e for e in res.events if e["action"] == "relax"]
        assert res.summary["anti_collision"]["relaxations"] == len(relax) > 0
        assert all(0 <= e["other"] <= 5 and e["other"] != e["drone"] and 1 <= e["drone"] <= 5 for e in relax)
        vs = sum(e["other"] == 0 for e in relax)
        assert res.summary["anti_collision"]["relaxations_vs_leader"] == vs
        assert f"{len(relax)} barrier relaxations ({vs} against the leader" in format_summary(res.summary, res.scenario)
    assert runs[0].events == runs[1].events
    # the stress row carries the count (the same run: fly_case flies the case's scenario)
    monkeypatch.setattr(stress, "stress_scenario", lambda case: sc)
    row = stress.fly_case(StressCase("barrier", 100033, 5, 3.0, 0.6, 6.0))
    assert row["relaxations"] == len(relax)
    table = {"barrier": stress.summarize_rule([row])}
    assert row["relaxations_vs_leader"] == vs
    assert (
        f"barrier relaxations: {len(relax)} in 1 of 1 starts, {vs} against the leader (100033;"
        in stress.format_table(table, 5)
    )
    # a rule without the filter never relaxes
    plain = run(stress_scenario(StressCase("jet-aware", 100033, 5, 3.0, 0.6, 6.0, aero="realistic")), progress=False)
    assert plain.summary["anti_collision"]["relaxations"] == 0


def test_the_reserve_is_counted_in_the_summary_and_the_stress_row(monkeypatch):
    # the same start and small limits, with the reserve at 45° (docs/barrier.md, "Infeasible under the
    # limits: the reserve"): it is used, counted the same on both drivers, said in the summary's line and
    # the stress row and table, and it leaves fewer relaxations than the same start without it
    data = stress_data(StressCase("barrier", 100033, 5, 3.0, 0.6, 6.0, aero="realistic"))
    # the split's reserve (the joint fallback meets these limits within the nominal ones)
    limits = {"max_tilt_deg": 6.0, "accel_up": 0.6, "accel_down": 0.6, "joint_fallback": False}
    relaxations = {}
    for reserve in (0.0, 45.0):
        data["formation"]["barrier"] = {**limits, "reserve_tilt_deg": reserve}
        sc = parse_scenario(data, "<test>")
        runs = [run(sc, progress=False, fused=fused) for fused in (False, True)]
        counts = [r.summary["anti_collision"]["reserve_periods"] for r in runs]
        assert counts[0] == counts[1] and (counts[0] > 0) == (reserve > 0)
        relaxations[reserve] = runs[0].summary["anti_collision"]["relaxations"]
    assert relaxations[45.0] < relaxations[0.0]
    res = runs[0]
    assert f"{counts[0]} drone-periods on the barrier's reserve" in format_summary(res.summary, res.scenario)
    monkeypatch.setattr(stress, "stress_scenario", lambda case: sc)
    row = stress.fly_case(StressCase("barrier", 100033, 5, 3.0, 0.6, 6.0))
    assert row["reserve_periods"] == counts[0]
    table = {"barrier": stress.summarize_rule([row])}
    assert f"barrier reserve: {counts[0]} drone-periods in 1 of 1 starts" in stress.format_table(table, 5)


def test_the_leaders_start_is_within_its_followers_capability():
    """docs/barrier.md, "the leader's start": under ``barrier`` the leader joins its trajectory from rest,
    so the leader MuJoCo flies accelerates horizontally within a third of the followers' limit (the
    filter's horizontal limit), near its plan's peak; under ``jet-aware`` it dashes onto the circle
    (over 10 m/s² measured)."""
    limit = BarrierParams().horizontal_limit(DEFAULT_PARAMS.g)  # the followers' horizontal limit (m/s²)
    peaks = {}
    for rule in ("barrier", "jet-aware"):
        res = run(stress_scenario(StressCase(rule, 3, 3, 2.5, 0.6, 5.0, aero="realistic")), progress=False)
        log = res.log
        v, t = log.vel[:, 0], log.t
        acc = (v[5:] - v[:-5]) / (t[5:] - t[:-5])[:, None]  # the flown leader's, over 0.05 s
        early = t[5:] <= 4.0
        peaks[rule] = float(np.hypot(acc[early, 0], acc[early, 1]).max())
        if rule == "barrier":
            plan = leader_reference(res.scenario)(t[t <= 4.0])
            planned = float(np.hypot(plan.acc[:, 0], plan.acc[:, 1]).max())
    assert peaks["barrier"] < limit / 3.0 and peaks["barrier"] < 1.5 * planned
    assert peaks["jet-aware"] > 2.0 * limit


def _lift_off_s(log, i: int, floor: float) -> float:
    """The first logged time drone i is above ``floor``."""
    return float(log.t[int(np.argmax(log.pos[:, i, 2] > floor))])


def test_grounded_neighbours_outside_each_others_keep_out_lift_off_together():
    """Two followers standing 0.80 m apart, 1.11 keep-out radii (ρ on the ground, outside the filter's
    keep-out): with ``gate_rho_ground`` 1.0 (the default) both leave the ground in the same tenth of a
    second, and the keep-out holds between them as they climb side by side (ρ recomputed here from the
    log and the vehicle's radii); at 1.2 the higher index waits for the lower to climb away (docs/barrier.md,
    "take-off gate")."""
    bp = BarrierParams()
    radii = keepout_radii()  # the vehicle's keep-out, not the filter's (which adds the tracking margin)
    gap = 0.80
    assert 1.0 < gap / bp.radii(DEFAULT_PARAMS)[0] < 1.2
    data = {
        "name": "grounded-pair",
        "duration": 3.0,
        "leader": {"trajectory": "hover", "start": [0.0, 0.0, 0.0]},
        "followers": {"start": [[2.0, 0.0, 0.0], [2.0 + gap, 0.0, 0.0]]},
        "formation": {"diameter": 1.0, "anti_collision": "barrier"},
        "aero": {"model": "realistic"},
    }
    lifted = {}
    for ground in (1.0, 1.2):
        data["formation"]["barrier"] = {"gate_rho_ground": ground}
        res = run(parse_scenario(data, "<test>"), progress=False)
        log = res.log
        lifted[ground] = [_lift_off_s(log, i, bp.floor_m) for i in (1, 2)]
        pair = np.linalg.norm((log.pos[:, 1] - log.pos[:, 2]) / radii, axis=1)
        airborne = (log.pos[:, 1, 2] > bp.floor_m) & (log.pos[:, 2, 2] > bp.floor_m)
        assert pair[airborne].min() >= 1.0
        assert res.summary["keepout_time_s"] == 0.0 and res.summary["contacts"] == 0
    together, waited = lifted[1.0], lifted[1.2]
    assert abs(together[1] - together[0]) <= 0.1
    assert waited[1] - waited[0] > 0.3


def test_the_joint_fallback_is_counted_and_removes_the_relaxation(monkeypatch):
    # dev start 200522 (docs/barrier.md, "the joint fallback"): with the split alone a climbing follower
    # between the leader and a follower is relaxed; with the fallback its cluster is solved together, no
    # relaxation, the same count on both drivers, in the summary's line, the stress row and table
    data = stress_data(StressCase("barrier", 200522, 5, 3.0, 0.6, 4.0, aero="realistic"))
    found = {}
    for joint in (False, True):
        data["formation"]["barrier"] = {"joint_fallback": joint}
        sc = parse_scenario(data, "<test>")
        runs = [run(sc, progress=False, fused=fused) for fused in (False, True)]
        found[joint] = [tuple(r.summary["anti_collision"][k] for k in ("joint_periods", "relaxations")) for r in runs]
        assert found[joint][0] == found[joint][1]
    assert found[False][0] == (0, 1) and found[True][0][0] > 0 and found[True][0][1] == 0
    res, periods = runs[0], found[True][0][0]
    assert f"{periods} drone-periods in the barrier's joint fallback" in format_summary(res.summary, res.scenario)
    monkeypatch.setattr(stress, "stress_scenario", lambda case: sc)
    row = stress.fly_case(StressCase("barrier", 200522, 5, 3.0, 0.6, 4.0))
    assert row["joint_periods"] == periods
    table = {"barrier": stress.summarize_rule([row])}
    assert f"barrier joint fallback: {periods} drone-periods in 1 of 1 starts" in stress.format_table(table, 5)
