"""The report's numbers: results.json assembled from the job results, section by section.

Every number of the report's README and of the README tables comes from here
(:func:`assemble`), through results.json, so the two cannot disagree.
"""

from __future__ import annotations

import datetime as _dt
import sys
from dataclasses import asdict
from typing import Any

from ..experiments.parallel import machine_description
from ..experiments.sweep import compute_stats
from ..output.atomic import json_safe
from ..paper import PAPER_FORMATION_SETTLING_S, PAPER_STEP, PAPER_TABLE5
from .jobs import JobResults
from .plan import (
    ANTI_COLLISION_SCENARIOS,
    PAPER_STEP_MAX_ANGLE_DEG,
    PAPER_TABLE3,
    RULES,
    SWARMS,
    TABLE5_NOFF,
    TABLE5_SCENARIOS,
    FpaGains,
    JobList,
    Plan,
)

#: The interpretations of the paper that the report lists (docs/interpretations.md has them all, with reasons).
INTERPRETATIONS = [
    (
        "D is the circumradius",
        'The paper\'s pentagon "diameter" D is read as the leader-to-follower '
        "distance (docs/interpretations.md §4): as a true diameter, D = 1 m would put followers 0.5 m from the "
        "leader (the paper's "
        "own collision distance) and adjacent followers 0.59 m apart, inside the 0.8 m safety distance, for good.",
    ),
    (
        "F^w/m",
        "Eqs. (1), (23)–(24) print the wind term as F^w/Ix and F^w/Iy; it is a force on the body, so "
        "F^w/m is used (docs/interpretations.md §2).",
    ),
    (
        "Finite-difference attitude derivatives",
        "The paper is silent on the desired attitude derivatives "
        "(ẋ1d, ẍ1d, ...); they are the finite difference of the commanded angles over the control period T = "
        "0.01 s. With them set to zero the Table 4 gains oscillate with > 200 % overshoot "
        "(docs/interpretations.md §2).",
    ),
    (
        "Exact attitude map",
        "Our controller maps the commanded Euler-angle accelerations exactly onto body "
        'torques (MuJoCo integrates the true rigid body, with body rates); attitude_map = "paper" uses eq. (1)\'s '
        "map instead (Euler rates in place of body rates). The step is shown with both.",
    ),
    (
        "Rotor saturation",
        "Each rotor thrust is limited to [0, 4.5] N (thrust/weight ≈ 3.8): the commanded "
        "U1..U4 are mapped to F1..F4, clipped and mapped back, so the wrench applied is one the motors can "
        "deliver (docs/interpretations.md §1). Desired roll/pitch are clipped to ±45°.",
    ),
    (
        "Wind defaults τ, σ",
        "The paper gives no OU correlation time or intensity: τx = τy = 2 s, σx = 0.8 m/s, "
        "σy = 0.5 m/s, exact discretisation at T, X0 drawn from the stationary law; force ½ρCdA|V|V per axis "
        "(the paper's V² loses the sign, and its σ stands for ρ); schedule Fx on [20, 50) s, Fx + Fy from 50 s; "
        "wind feedforward with the true force on, as in the paper (docs/interpretations.md §5).",
    ),
    (
        "FPA sign fix",
        "Global pollination moves towards the best, x + γ·Lévy(λ)·(g* − x) (Yang 2012); the "
        "paper's pseudo-code prints x + rand·c·(x − g*), which moves away from it (docs/interpretations.md §6). "
        "Bounds [0.1, 12].",
    ),
    (
        "RMSE twice",
        "The whole-run RMSE of eq. (38) is mostly the first seconds, the flight from the start "
        "(on the ground at the origin) onto the path; the paper does not say where its drone starts. So every "
        'RMSE is given whole-run and from t = 10 s on ("steady"); for the circle, compare x whole-run and y '
        "steady with the paper (docs/interpretations.md §7). A start on the path at hover is shown too.",
    ),
    (
        "Layered anti-collision",
        "The paper's rule as printed (trigger at 0.8 m horizontal, one 0.4 m hop) lets "
        "drones closing at 2–4 m/s pass within centimetres (docs/interpretations.md §4). Our default under "
        'the paper\'s physics, "layers", '
        "has each follower k "
        "climb in place to its own layer (formation altitude + 0.4·k m), cross on it, and drop to the formation "
        "altitude only when no nearby drone is between its layer and that altitude; the reactive rule stays on "
        'afterwards. The paper\'s rule ("paper") and no rule ("off") are shown beside it. Contacts are '
        "MuJoCo drone–drone contacts, never hidden.",
    ),
    (
        "Formation settling",
        "Settling after a change of D: the first time after which every leader–follower "
        'horizontal distance stays within 5 cm of D until the next change ("never" if it does not).',
    ),
]


def assemble(plan: Plan, fpa: FpaGains, jl: JobList, res: JobResults, workers: int) -> dict[str, Any]:
    """results.json's content (before :func:`jsonable`), figures and wall times aside."""
    by_key = res.by_key
    R: dict[str, Any] = {}
    R["meta"] = {
        "generated": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "plan": asdict(plan),
        "workers": workers,
        "jobs": len(jl.jobs),
        "machine": machine_description(),
        "swarm_mj_argv": sys.argv[1:],
    }
    R["interpretations"] = [{"name": a, "text": b} for a, b in INTERPRETATIONS]
    R["step"] = step_section(by_key)
    R["gains"] = gains_section(by_key, fpa)
    R["table3"] = table3_section(by_key, plan)
    R["table5"] = table5_section(by_key)
    R["swarms"] = {
        "paper_settling_s": PAPER_FORMATION_SETTLING_S,
        "rows": [swarm_entry(n, by_key[f"swarm/{n}"]) for n in SWARMS],
    }
    R["variable_d"] = {
        **swarm_entry("variable_diameter", by_key["variable_d"]),
        "paper_settling_s": PAPER_FORMATION_SETTLING_S,
        "schedule": _variable_d_schedule(jl),
    }
    R["anti_collision"] = {
        "rows": [
            swarm_entry(name, _ac_run(by_key, name, rule), rule) for name in ANTI_COLLISION_SCENARIOS for rule in RULES
        ]
    }
    R["sweeps"] = sweeps_section(jl, res)
    return R


def _ac_run(by_key: dict[str, Any], name: str, rule: str) -> dict:
    """The run of ``name`` with ``rule``: its own job, or the swarm run when that is the scenario's rule."""
    key = f"ac/{name}/{rule}"
    return by_key[key] if by_key.get(key) else by_key[f"swarm/{name}"]


def _variable_d_schedule(jl: JobList) -> Any:
    return next(job.scenario.diameter for _, job in jl.jobs if getattr(job, "key", None) == "variable_d")


def _step_entry(r: dict) -> dict:
    d = r["summary"]["drones"]["leader"]
    return {
        "axes": d["step"],
        "max_abs_roll_deg": d["max_abs_roll_deg"],
        "max_abs_pitch_deg": d["max_abs_pitch_deg"],
        "rotor_min_n": d["min_rotor_thrust_n"],
        "rotor_max_n": d["max_rotor_thrust_n"],
        "gains_source": r["summary"]["gains_source"],
    }


def step_section(by_key: dict[str, Any]) -> dict:
    """The step response (Figs. 7–8) with Table 4's gains, eq. (1)'s attitude map and the FPA gains."""
    return {
        "paper": {**PAPER_STEP, "max_angle_deg": PAPER_STEP_MAX_ANGLE_DEG, "psi_settling_note": "< 1 s"},
        "table4": _step_entry(by_key["step/table4"]),
        "paper_attitude_map": _step_entry(by_key["step/paper_map"]),
        "fpa": _step_entry(by_key["step/fpa"]) if "step/fpa" in by_key else None,
    }


def gains_section(by_key: dict[str, Any], fpa: FpaGains) -> dict:
    """Table 4's and the FPA file's gains with their ISE."""
    from ..control.backstepping import TABLE4_GAINS

    ise = by_key["ise"]
    return {
        "table4": [float(g) for g in TABLE4_GAINS],
        "table4_ise": ise[0],
        "fpa_file": str(fpa.path) if fpa.path else None,
        "fpa": [float(g) for g in fpa.gains] if fpa.gains is not None else None,
        "fpa_ise": ise[1] if fpa.gains is not None else None,
        "fpa_file_meta": fpa.meta,
    }


def table3_section(by_key: dict[str, Any], plan: Plan) -> dict:
    """Table 3: the FPA runs, ours (with the step bars, and in the paper's mode) beside the paper's."""
    return {
        "paper": [{"run": a, "initial_ise": b, "final_ise": c, "improvement_pct": d} for a, b, c, d in PAPER_TABLE3],
        "ours": [by_key[f"fpa/{s}"] for s in plan.fpa_seeds],
        "ours_paper_mode": [by_key[f"fpa_paper/{s}"] for s in plan.fpa_seeds],
        "settings": {
            "population": plan.fpa_population,
            "iterations": plan.fpa_iterations,
            "p": 0.04,
            "gamma": 0.02,
            "bounds": [0.1, 12.0],
        },
    }


def table5_section(by_key: dict[str, Any]) -> dict:
    """Table 5: the leader's RMSE, whole run and steady, per scenario and start variant."""
    rows = []
    for name in TABLE5_SCENARIOS + TABLE5_NOFF:
        for variant in ("ground", "on_path", "fpa"):
            r = by_key.get(f"t5/{name}/{variant}")
            if r is None:
                continue
            s = r["summary"]
            d = s["drones"]["leader"]
            traj = "circle" if "circle" in name else "lemniscate"
            rows.append(
                {
                    "scenario": name,
                    "trajectory": traj,
                    "wind": bool(s["wind"]),
                    "wind_feedforward": bool(s["wind_feedforward"]),
                    "variant": variant,
                    "duration_s": s["sim_time_s"],
                    "whole": d["rmse"],
                    "steady": d["rmse_steady"],
                    "paper": PAPER_TABLE5[(traj, bool(s["wind"]))],
                    "stopped": s.get("stopped"),
                }
            )
    return {
        "paper": {f"{k[0]}/{'wind' if k[1] else 'no_wind'}": v for k, v in PAPER_TABLE5.items()},
        "rows": rows,
        "steady_after_s": 10.0,
    }


def swarm_entry(name: str, r: dict, rule: str | None = None) -> dict:
    """One swarm run: contacts, separation, formation settling and error, the leader's RMSE."""
    s = r["summary"]
    f = s["formation"]
    return {
        "scenario": name,
        "rule": rule or s["anti_collision_rule"],
        "duration_s": s["sim_time_s"],
        "contacts": s["contacts"],
        "min_separation_m": s["min_separation_m"],
        "min_separation_airborne_m": s.get("min_separation_airborne_m"),
        "min_separation_pair": s["min_separation_pair"],
        "min_separation_at_s": s["min_separation_at_s"],
        "settling_s": f["settling_s"],
        "change_times_s": f["change_times_s"],
        "max_distance_error_m": f["max_distance_error_m"],
        "final_distance_error_m": f["final_distance_error_m"],
        "anti_collision_events": s["anti_collision"]["events"],
        "altitude_yields": s["anti_collision"]["yields"],
        "leader_rmse": s["drones"]["leader"]["rmse"],
        "leader_rmse_steady": s["drones"]["leader"]["rmse_steady"],
        "stopped": s.get("stopped"),
    }


def sweeps_section(jl: JobList, res: JobResults) -> dict:
    """Every seeded sweep: statistics per value and each run's metrics."""
    out = {}
    for key, sw in jl.sweeps.items():
        runs = [res.by_index[i] for i in sw["jobs"]]
        stats = compute_stats(runs, len(sw["values"]))
        out[key] = {k: v for k, v in sw.items() if k != "jobs"} | {
            "results": [{"value": v, "stats": st} for v, st in zip(sw["values"], stats)],
            "runs": [
                {
                    "value": sw["values"][r["value_index"]],
                    "seed": r["seed"],
                    "metrics": r["metrics"],
                    "stopped": r["stopped"],
                }
                for r in runs
            ],
        }
    return out


def jsonable(o: Any) -> Any:
    """results.json's strict JSON: :func:`swarm_mj.output.atomic.json_safe` with infinities as "inf"/"-inf"."""
    return json_safe(o, inf_as_string=True)
