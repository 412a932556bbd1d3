"""What the report flies: the :class:`Plan` (durations, seed counts) and the jobs it makes.

:func:`plan_jobs` lists every experiment of the paper as independent jobs (:mod:`.jobs`):
the step response, Table 5 with and without wind, the swarm scenarios, variable D,
anti-collision, the seeded wind and crossing sweeps and the FPA runs of Table 3.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..experiments.sweep import SweepTask, apply_param
from ..paper import PAPER_STEP_MAX_ANGLE_DEG, PAPER_TABLE3  # noqa: F401 (re-exported)
from ..scenario import Scenario, load_scenario, parse_scenario
from .jobs import IseJob, RunJob, TuneJob

GAINS_FILE = Path("scenarios/gains/fpa_seed1.toml")
ALL_FIGURES = {
    "fig07_step.png",
    "fig08_rotors.png",
    "fig09_lemniscate.png",
    "fig15_wind.png",
    "swarm_paths_3d.png",
    "fig14_variable_d.png",
    "fig16_anticollision.png",
    "wind_robustness.png",
    "wind_sigma.png",
    "fpa_convergence.png",
    "snapshot_scenario1.png",
}

#: Table 5's scenarios (single drone; each flown from the ground, on its path and with the FPA gains).
TABLE5_SCENARIOS = ["circle_single", "wind_circle", "lemniscate_single", "wind_lemniscate"]
#: Table 5's wind scenarios without the wind feedforward (ground start only).
TABLE5_NOFF = ["wind_circle_noff", "wind_lemniscate_noff"]
#: RunLog fields kept for the figures, per Table 5 scenario.
TABLE5_KEEP = {
    "lemniscate_single": ("pos", "pos_d"),
    "circle_single": ("pos", "pos_d"),
    "wind_lemniscate": ("pos", "pos_d", "wind_speed", "wind_force"),
    "wind_circle": ("pos", "pos_d", "wind_speed", "wind_force"),
}
SWARMS = ["circle", "lemniscate", "ascending_orbit", "scenario1", "scenario2", "scenario3"]
RULES = ("layers", "paper", "off")
ANTI_COLLISION_SCENARIOS = ("anti_collision", "scenario1", "scenario2", "scenario3")
STEP_KEEP = ("pos", "rpy", "pos_d", "att_d", "rotor", "U")


@dataclass(frozen=True)
class Plan:
    """Durations (None = the scenario's own) and seed counts of a report."""

    name: str = "full"
    table5_s: float | None = None  # 180 s
    swarm_s: float | None = None  # 180 s (circle, lemniscate, ascending orbit), 60 s (scenario1..3)
    variable_d_s: float | None = None  # 30 s
    anti_s: float | None = None  # 20 s
    wind_seeds: int = 20
    wind_s: float | None = None  # 180 s
    swarm_wind_seeds: int = 10
    swarm_wind_s: float | None = None  # 180 s
    sigma_values: tuple[float, ...] = (0.4, 0.8, 1.2)
    sigma_seeds: int = 10
    crossing_seeds: int = 20
    crossing_s: float = 20.0
    fpa_seeds: tuple[int, ...] = (1, 2, 3, 5)
    fpa_population: int = 50
    fpa_iterations: int = 14
    snapshot: bool = True

    @classmethod
    def full(cls) -> Plan:
        return cls()

    @classmethod
    def quick(cls) -> Plan:
        return cls(
            name="quick",
            table5_s=30.0,
            swarm_s=15.0,
            wind_seeds=3,
            wind_s=30.0,
            swarm_wind_seeds=2,
            swarm_wind_s=15.0,
            sigma_seeds=2,
            crossing_seeds=3,
            crossing_s=10.0,
            fpa_seeds=(1,),
            fpa_population=8,
            fpa_iterations=2,
            snapshot=False,
        )


@dataclass
class FpaGains:
    """The bundled FPA-tuned gains file (``GAINS_FILE``), if found, and its metadata."""

    path: Path | None = None
    gains: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)


@dataclass
class JobList:
    """The report's jobs in plan order, as (group, job), and its sweeps (keyed, with their job indices)."""

    jobs: list[tuple[str, Any]] = field(default_factory=list)
    sweeps: dict[str, dict[str, Any]] = field(default_factory=dict)

    def add(self, group: str, job: Any) -> None:
        self.jobs.append((group, job))

    def add_sweep(
        self,
        key: str,
        sc: Scenario,
        seeds: int,
        duration: float | None,
        param: str | None = None,
        values: tuple = (None,),
    ) -> None:
        """One seeded sweep: a :class:`~swarm_mj.experiments.sweep.SweepTask` per (value, seed)."""
        variants = [sc] if param is None else [apply_param(sc, param, v) for v in values]
        idx = []
        for vi, v in enumerate(variants):
            for s in range(seeds):
                idx.append(len(self.jobs))
                self.add(f"sweep:{key}", SweepTask(scenario=v, seed=s, value_index=vi, duration=duration))
        self.sweeps[key] = {
            "scenario": sc.name,
            "param": param,
            "values": list(values),
            "seeds": list(range(seeds)),
            "duration_s": float(duration if duration is not None else sc.duration),
            "jobs": idx,
        }


def _find_gains_file() -> Path | None:
    from ..resources import SCENARIOS_DIR

    for p in (
        Path.cwd() / GAINS_FILE,
        Path(SCENARIOS_DIR) / "gains" / GAINS_FILE.name,
        Path(__file__).resolve().parents[2] / GAINS_FILE,
    ):
        if p.is_file():
            return p
    return None


def _on_path(sc: Scenario) -> Scenario:
    """The scenario with the leader starting at rest on its path (at t = 0), in the air."""
    p0 = sc.make_trajectory()(np.array([0.0])).pos[0]
    return sc.with_overrides(leader_start=np.asarray(p0, float))


def random_crossing(duration: float) -> Scenario:
    """The anti-collision scenario (hovering leader) with seeded random follower starts within 3 m."""
    base = load_scenario("anti_collision")
    data = copy.deepcopy(base.raw)
    data["followers"] = {"count": 5, "random_start": {"radius": 3.0, "min_spacing": 0.8}}
    data["duration"] = float(duration)
    data["description"] = "hovering leader, 5 followers from seeded random ground starts within 3 m"
    return parse_scenario(data, base.path, name="random_crossing")


def load_fpa_gains() -> FpaGains:
    """The FPA gains of ``GAINS_FILE`` and the metadata written beside them by ``swarm-mj tune``."""
    from ..control.backstepping import load_gains

    path = _find_gains_file()
    if path is None:
        return FpaGains()
    gains = load_gains(path)
    try:
        meta = tomllib.loads(path.read_text())
        meta = {
            k: meta[k]
            for k in (
                "ise",
                "initial_ise",
                "improvement_pct",
                "table4_ise",
                "seed",
                "iterations_done",
                "complete",
                "created",
            )
            if k in meta
        }
    except Exception:  # noqa: BLE001 - metadata is optional
        meta = {}
    return FpaGains(path, gains, meta)


def plan_jobs(plan: Plan, fpa: FpaGains) -> JobList:
    """Every job of the report, in plan order (the order that keys the results)."""
    jl = JobList()
    _step_jobs(jl, fpa)
    _table5_jobs(jl, plan, fpa)
    _swarm_jobs(jl, plan)
    _sweep_jobs(jl, plan)
    _fpa_jobs(jl, plan, fpa)
    return jl


def _step_jobs(jl: JobList, fpa: FpaGains) -> None:
    step = load_scenario("step")
    jl.add("step", RunJob(key="step/table4", scenario=step, keep=STEP_KEEP))
    jl.add(
        "step", RunJob(key="step/paper_map", scenario=step.with_overrides(attitude_map="paper"), keep=("pos", "rpy"))
    )
    if fpa.gains is not None:
        jl.add(
            "step",
            RunJob(
                key="step/fpa",
                scenario=step.with_overrides(gains=fpa.gains, gains_source=str(fpa.path)),
                keep=("pos", "rpy"),
            ),
        )


def _table5_jobs(jl: JobList, plan: Plan, fpa: FpaGains) -> None:
    for name in TABLE5_SCENARIOS:
        sc = load_scenario(name)
        jl.add(
            "t5", RunJob(key=f"t5/{name}/ground", scenario=sc, duration=plan.table5_s, keep=TABLE5_KEEP[name], every=2)
        )
        jl.add("t5", RunJob(key=f"t5/{name}/on_path", scenario=_on_path(sc), duration=plan.table5_s))
        if fpa.gains is not None:
            jl.add(
                "t5",
                RunJob(
                    key=f"t5/{name}/fpa",
                    scenario=sc.with_overrides(gains=fpa.gains, gains_source="fpa"),
                    duration=plan.table5_s,
                ),
            )
    for name in TABLE5_NOFF:
        jl.add("t5", RunJob(key=f"t5/{name}/ground", scenario=load_scenario(name), duration=plan.table5_s))


def _swarm_jobs(jl: JobList, plan: Plan) -> None:
    for name in SWARMS:
        jl.add(
            "swarm",
            RunJob(key=f"swarm/{name}", scenario=load_scenario(name), duration=plan.swarm_s, keep=("pos",), every=10),
        )
    jl.add(
        "vd",
        RunJob(
            key="variable_d", scenario=load_scenario("variable_diameter"), duration=plan.variable_d_s, keep=("pos", "D")
        ),
    )
    for name in ANTI_COLLISION_SCENARIOS:
        sc = load_scenario(name)
        for rule in RULES:
            if name != "anti_collision" and rule == sc.anti_collision:
                continue  # the swarm run above
            dur = plan.anti_s if name == "anti_collision" else plan.swarm_s
            keep = ("pos", "pos_d") if name == "anti_collision" else ()
            jl.add(
                "ac",
                RunJob(
                    key=f"ac/{name}/{rule}", scenario=sc.with_overrides(anti_collision=rule), duration=dur, keep=keep
                ),
            )
    if plan.snapshot:
        jl.add(
            "snap",
            RunJob(
                key="snapshot/scenario1",
                scenario=load_scenario("scenario1"),
                duration=min(25.0, plan.swarm_s or 60.0),
                keep=("*",),
            ),
        )


def _sweep_jobs(jl: JobList, plan: Plan) -> None:
    for name in ("wind_lemniscate", "wind_circle", "wind_lemniscate_noff", "wind_circle_noff"):
        jl.add_sweep(name, load_scenario(name), plan.wind_seeds, plan.wind_s)
    jl.add_sweep("wind_swarm", load_scenario("wind_swarm"), plan.swarm_wind_seeds, plan.swarm_wind_s)
    for name in ("wind_lemniscate", "wind_lemniscate_noff"):
        jl.add_sweep(
            f"sigma/{name}", load_scenario(name), plan.sigma_seeds, plan.wind_s, "wind.sigma", tuple(plan.sigma_values)
        )
    jl.add_sweep(
        "random_crossing",
        random_crossing(plan.crossing_s),
        plan.crossing_seeds,
        None,
        "formation.anti_collision",
        RULES,
    )


def _fpa_jobs(jl: JobList, plan: Plan, fpa: FpaGains) -> None:
    from ..control.backstepping import TABLE4_GAINS

    for s in plan.fpa_seeds:
        jl.add("fpa", TuneJob(key=f"fpa/{s}", seed=s, population=plan.fpa_population, iterations=plan.fpa_iterations))
        jl.add(
            "fpa",
            TuneJob(
                key=f"fpa_paper/{s}",
                seed=s,
                population=plan.fpa_population,
                iterations=plan.fpa_iterations,
                mode="paper",
            ),
        )
    ise_gains = [tuple(map(float, TABLE4_GAINS))]
    if fpa.gains is not None:
        ise_gains.append(tuple(map(float, fpa.gains)))
    jl.add("ise", IseJob("ise", tuple(ise_gains)))
