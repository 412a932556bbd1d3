"""Stress test of the anti-collision rules: many seeded random starts, MuJoCo contacts counted per rule.

Each start puts ``followers`` followers on the ground at random within ``radius`` of the leader, at
least ``min_spacing`` apart (``scenario.random_follower_starts``, seeded ``seed0``, ``seed0`` + 1,
...), the leader flying the circle (docs/interpretations.md §3). The same starts are flown with every
rule (docs/interpretations.md §4), in parallel, and for each rule :func:`summarize_rule` gives:
starts flown, starts with any drone–drone contact (counted by MuJoCo), total contacts, runs that
crashed (a drone knocked into the floor: the run stops there), the smallest 3D centre distance seen
while every drone was airborne, and the median and worst formation settling time (every leader
distance within 5 cm of D; inf: never settled).

The command line is ``swarm_mj/commands/stress.py`` (``swarm-mj stress``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import UserError
from ..formation.anticollision import ANTI_COLLISION_RULES, resolve_rule
from ..output.progress import Progress
from ..physics.aero.presets import preset
from ..scenario import MAX_SEED, RandomStart, check_random_start_feasible, check_seed
from ..starts import MAX_RANGE_M
from .parallel import check_run_count, map_ordered

RULES = tuple(ANTI_COLLISION_RULES)  # layers, paper, off, jet-aware ("auto" picks one)


@dataclass(frozen=True)
class StressCase:
    """One flight: a rule, a seed and the random-start request."""

    rule: str
    seed: int
    followers: int
    radius: float
    min_spacing: float
    duration: float
    sensing_range: float = 4.0
    trajectory: str = "circle"
    diameter: float = 1.0
    aero: str = "paper"  # physics preset (docs/aero.md)
    vehicle: str | None = None  # [vehicle] model (docs/vehicles.md); None: the paper's drone
    gains: str | None = None  # a gains file; None: the vehicle's, else Table 4 (swarm_mj/choices.py)
    sensing: str = "perfect"  # [sensing] preset (docs/sensing.md); its range is sensing_range (the alias)


def stress_scenario(case: StressCase):
    """The :class:`~swarm_mj.scenario.Scenario` of one case: leader at the origin on the
    ground flying ``case.trajectory``, random follower starts seeded ``case.seed``."""
    from ..scenario import parse_scenario

    return parse_scenario(stress_data(case), "<stress>")


def stress_data(case: StressCase) -> dict:
    """The scenario table of one case (``swarm-mj stress --save-scenario`` writes it as TOML)."""
    return {
        "name": f"stress-{case.rule}-{case.seed}",
        "duration": case.duration,
        "seed": case.seed,
        "leader": {"trajectory": case.trajectory, "start": [0.0, 0.0, 0.0]},
        "followers": {
            "count": case.followers,
            "random_start": {"radius": case.radius, "min_spacing": case.min_spacing, "seed": case.seed},
        },
        "formation": {"diameter": case.diameter, "anti_collision": case.rule, "sensing_range": case.sensing_range},
        "aero": {"model": case.aero},
        **({"vehicle": {"model": case.vehicle}} if case.vehicle is not None else {}),
        **({"controller": {"gains": case.gains}} if case.gains is not None else {}),
        **({"sensing": {"preset": case.sensing}} if case.sensing != "perfect" else {}),
    }


def fly_case(case: StressCase) -> dict:
    """Fly one case with :func:`swarm_mj.experiments.runner.run`; the numbers the table needs."""
    from .runner import run

    res = run(stress_scenario(case), progress=False)
    s = res.summary
    settle = s["formation"]["settling_s"][0] if s["formation"]["settling_s"] else float("inf")
    return {
        "rule": case.rule,
        "seed": case.seed,
        "contacts": int(s["contacts"]),
        "contact_log": [list(c) for c in res.contact_log],
        "min_separation_m": float(s["min_separation_m"]),
        "min_separation_airborne_m": float(s.get("min_separation_airborne_m", float("inf"))),
        "settling_s": float(settle),
        "yields": int(s["anti_collision"]["yields"]),
        "relaxations": int(s["anti_collision"]["relaxations"]),
        "relaxations_vs_leader": int(s["anti_collision"]["relaxations_vs_leader"]),
        "reserve_periods": int(s["anti_collision"]["reserve_periods"]),
        "joint_periods": int(s["anti_collision"].get("joint_periods", 0)),
        "stopped": s.get("stopped"),
        "crashes": int(s.get("crashes", 0)),
        "ground_contacts": int(s.get("ground_contacts", 0)),
        "downwash_dip_m": float(s.get("downwash_dip_worst_m", 0.0)),
        "time_in_jet_s": float((s.get("downwash_dip") or {}).get("time_in_jet_s", 0.0)),
        "keepout_min_distance": float(s.get("keepout_min_distance") or float("inf")),
        "keepout_time_s": float(s.get("keepout_time_s", 0.0)),
        "path_per_follower_m": path_per_follower(res.log.pos),
    }


def path_per_follower(pos: np.ndarray) -> float:
    """The mean over the followers (rows 1.. of pos (k, n, 3)) of the length of the path each flew (m):
    the sum of the distances between its successive logged positions (one per control period)."""
    if pos.shape[0] < 2 or pos.shape[1] < 2:
        return 0.0
    steps = np.linalg.norm(np.diff(pos[:, 1:], axis=0), axis=2)  # (k − 1, n − 1)
    return float(np.nansum(steps, axis=0).mean())


def summarize_rule(rows: list[dict]) -> dict:
    """Per-rule line of the table from the rows of :func:`fly_case`."""
    settle = np.array([r["settling_s"] for r in rows], dtype=float)
    return {
        "starts": len(rows),
        "starts_with_contact": sum(r["contacts"] > 0 for r in rows),
        "contacts": sum(r["contacts"] for r in rows),
        "min_separation_airborne_m": min((r["min_separation_airborne_m"] for r in rows), default=float("inf")),
        "settling_median_s": float(np.median(settle)) if len(settle) else float("nan"),
        "settling_worst_s": float(settle.max()) if len(settle) else float("nan"),
        "seeds_with_contact": [r["seed"] for r in rows if r["contacts"] > 0],
        "stopped": [r["seed"] for r in rows if r["stopped"]],
        "downwash_dip_worst_m": max((r["downwash_dip_m"] for r in rows), default=0.0),
        "downwash_dip_worst_seed": max(rows, key=lambda r: r["downwash_dip_m"])["seed"] if rows else None,
        "time_in_jet_worst_s": max((r["time_in_jet_s"] for r in rows), default=0.0),
        "crashes": sum(r.get("crashes", 0) for r in rows),
        "seeds_with_crash": [r["seed"] for r in rows if r.get("crashes", 0) > 0],
        "ground_contacts": sum(r.get("ground_contacts", 0) for r in rows),
        # the keep-out invariant (docs/barrier.md): worst normalised distance, time inside
        "keepout_min_distance": min((r["keepout_min_distance"] for r in rows), default=float("inf")),
        "keepout_time_worst_s": max((r["keepout_time_s"] for r in rows), default=0.0),
        "keepout_time_total_s": sum(r["keepout_time_s"] for r in rows),
        "starts_in_keepout": sum(r["keepout_time_s"] > 0 for r in rows),
        # the barrier filter's relaxations (constraints infeasible within the limits, docs/barrier.md)
        "relaxations": sum(r.get("relaxations", 0) for r in rows),
        "seeds_relaxed": [r["seed"] for r in rows if r.get("relaxations", 0) > 0],
        "relaxations_vs_leader": sum(r.get("relaxations_vs_leader", 0) for r in rows),
        # … and its drone-periods on the reserve's wider tilt (docs/barrier.md, "the reserve")
        "reserve_periods": sum(r.get("reserve_periods", 0) for r in rows),
        "starts_with_reserve": sum(r.get("reserve_periods", 0) > 0 for r in rows),
        # … and its drone-periods flown from a boxed drone's cluster QP (docs/barrier.md, "the joint fallback")
        "joint_periods": sum(r.get("joint_periods", 0) for r in rows),
        "starts_with_joint": sum(r.get("joint_periods", 0) > 0 for r in rows),
        "path_per_follower_median_m": float(np.median([r.get("path_per_follower_m", np.nan) for r in rows]))
        if rows
        else float("nan"),
    }


def stress(
    rules: list[str],
    starts: int,
    case: StressCase,
    workers: int | None = None,
    progress: bool = False,
) -> tuple[dict, list[dict]]:
    """Fly ``starts`` seeded random starts with each rule, in parallel; (per-rule table, rows).

    ``case`` is the request every start shares (its ``seed`` the first seed, its ``rule`` ignored):
    the followers, their random start, the duration, sensing range, formation diameter, physics,
    vehicle and gains (:class:`StressCase`). The flights go through
    :func:`swarm_mj.experiments.parallel.map_ordered` (spawn workers, CPU affinity, Ctrl-C handled by
    the parent); rows come back in case order, rule-major then seed. ``progress``: a progress bar on
    stderr when it is a terminal.
    """
    check_stress_case(case, starts, workers)
    # "auto" flies, and is reported as, the rule it stands for under this physics
    rules = list(dict.fromkeys(resolve_rule(r, preset(case.aero).downwash) for r in rules))
    check_run_count(len(rules) * starts, "--starts")
    check_rules_fit(rules, case)
    cases = [replace(case, rule=rule, seed=case.seed + k) for rule in rules for k in range(starts)]
    with Progress(len(cases), "stress", None if progress else False, unit="starts") as bar:
        rows = map_ordered(fly_case, cases, workers=workers, progress=bar)
    table = {rule: summarize_rule([r for r in rows if r["rule"] == rule]) for rule in rules}
    return table, rows


def check_stress_case(case: StressCase, starts: int = 1, workers: int | None = None) -> None:
    """One :class:`UserError` line for a request that cannot fly, before anything flies."""
    if starts < 1 or case.followers < 1:
        raise UserError("--starts and --followers must be at least 1")
    check_seed(case.seed, "--seed0")
    if case.seed + starts - 1 > MAX_SEED:  # the seeds flown are seed0 .. seed0 + starts - 1
        raise UserError(f"--seed0 {case.seed} + --starts {starts} - 1 is beyond the largest seed, {MAX_SEED}")
    if case.duration <= 0:
        raise UserError("--duration must be positive")
    if not 0 < case.sensing_range <= MAX_RANGE_M:  # as a scenario's [formation] sensing_range
        raise UserError(f"--sensing-range must be positive and <= {MAX_RANGE_M:g} m, got {case.sensing_range:g}")
    if not (np.isfinite(case.diameter) and case.diameter > 0):
        raise UserError(f"--diameter must be positive, got {case.diameter:g}")
    if workers is not None and workers < 1:
        raise UserError("--workers must be at least 1")
    check_random_start_feasible(
        case.followers, RandomStart(radius=case.radius, min_spacing=case.min_spacing), "<stress>"
    )


def check_rules_fit(rules: list[str], case: StressCase) -> None:
    """Every rule with a separation filter (``barrier``) must leave the formation reachable at
    ``case.diameter`` (:func:`~swarm_mj.experiments.runner.check_keepout_fits`), checked here so that
    the request fails in one line before any worker starts."""
    from ..formation.anticollision import make_rule
    from .runner import check_keepout_fits

    for rule in rules:
        sc = stress_scenario(replace(case, rule=rule))
        made = make_rule(rule, sc.n_drones, vehicle=sc.params, barrier=sc.barrier_params)
        check_keepout_fits(sc, made, where="--diameter")


def format_table(table: dict, followers: int, sensing: str = "perfect") -> str:
    """The per-rule table as text (episodes: drone–drone contact episodes, a pair of drones in contact
    over consecutive physics steps counted once, docs/physics_step.md; crashed: runs stopped as
    diverged; crashes: ground crashes, docs/aero.md; dip: the worst downwash dip,
    docs/interpretations.md §4; path: the median over starts of the mean path flown per follower);
    ``sensing``: the preset flown, named in the header unless ``perfect``."""
    head = (
        f"{'rule':<11} {'starts':>6} {'w/contact':>9} {'episodes':>8} {'crashed':>7} {'crashes':>7} "
        f"{'min sep (m)':>11} {'settle med (s)':>14} {'settle worst (s)':>16} {'dip (m)':>8} "
        f"{'keep-out ρ':>10} {'in keep-out (s)':>15} {'path (m)':>8}"
        f"   ({followers} followers{'' if sensing == 'perfect' else f', sensing {sensing}'})"
    )
    lines = [head]
    for rule, r in table.items():
        lines.append(
            f"{rule:<11} {r['starts']:>6} {r['starts_with_contact']:>9} {r['contacts']:>8} "
            f"{len(r['stopped']):>7} {r.get('crashes', 0):>7} {r['min_separation_airborne_m']:>11.3f} "
            f"{r['settling_median_s']:>14.2f} {r['settling_worst_s']:>16.2f} "
            f"{r['downwash_dip_worst_m']:>8.3f} {r['keepout_min_distance']:>10.3f} {r['keepout_time_total_s']:>15.2f} "
            f"{r.get('path_per_follower_median_m', float('nan')):>8.2f}"
        )
        if r["seeds_with_contact"]:
            seeds = r["seeds_with_contact"]
            lines.append(f"           seeds with contact: {_seed_list(seeds)}")
        if r.get("relaxations"):
            seeds = r["seeds_relaxed"]
            lines.append(
                f"           barrier relaxations: {r['relaxations']} in {len(seeds)} of {r['starts']} starts, "
                f"{r.get('relaxations_vs_leader', 0)} against the leader ({_seed_list(seeds)}; docs/barrier.md)"
            )
        if r.get("reserve_periods"):
            lines.append(
                f"           barrier reserve: {r['reserve_periods']} drone-periods in {r['starts_with_reserve']} of "
                f"{r['starts']} starts (a tilt up to the reserve's; docs/barrier.md)"
            )
        if r.get("joint_periods"):
            lines.append(
                f"           barrier joint fallback: {r['joint_periods']} drone-periods in {r['starts_with_joint']} of "
                f"{r['starts']} starts (a boxed drone's cluster solved together; docs/barrier.md)"
            )
    return "\n".join(lines)


def _seed_list(seeds: list[int]) -> str:
    """The first 20 seeds, comma-separated, and " ..." when there are more."""
    return ", ".join(map(str, seeds[:20])) + (" ..." if len(seeds) > 20 else "")


def replay_lines(table: dict, rows: list[dict], scenario_file: str | None) -> list[str]:
    """One line per rule: its worst start (most contacts, then smallest airborne separation) and
    the ``swarm-mj run`` command that flies it again (same starts, same wind: seed S)."""
    import shlex

    f = shlex.quote(scenario_file) if scenario_file else "STRESS.toml"
    out = []
    for rule in table:
        rs = [r for r in rows if r["rule"] == rule]
        if not rs:
            continue
        w = max(rs, key=lambda r: (r["contacts"], -r["min_separation_airborne_m"]))
        out.append(
            f"worst '{rule}' start: seed {w['seed']} ({w['contacts']} contacts, min airborne separation "
            f"{w['min_separation_airborne_m']:.3f} m); replay: swarm-mj run {f} --seed {w['seed']} "
            f"--anti-collision {rule}"
        )
    if not scenario_file:
        out.append("  (STRESS.toml: add --save-scenario STRESS.toml to write the scenario these starts flew)")
    return out
