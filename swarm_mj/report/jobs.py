"""The report's jobs (worker side): a run, an FPA tuning, the ISE of given gains, or a sweep run.

Each job depends only on itself (scenario, seed, settings), so :func:`run_jobs` may run them in
any order on any number of workers: it runs the longest first through the one executor
(:func:`swarm_mj.experiments.parallel.map_ordered`) and puts the results back in plan order.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..experiments.parallel import map_ordered
from ..experiments.sweep import SweepTask, run_task
from ..output.progress import Progress
from ..scenario import Scenario


@dataclass(frozen=True)
class RunJob:
    key: str
    scenario: Scenario
    seed: int | None = None
    duration: float | None = None
    keep: tuple[str, ...] = ()  # RunLog fields to send back ("*" = the whole RunLog)
    every: int = 1  # keep every n-th sample


@dataclass(frozen=True)
class TuneJob:
    key: str
    seed: int
    population: int
    iterations: int
    mode: str = "bars"  # "bars": swarm-mj tune's defaults; "paper": ISE alone, random init


@dataclass(frozen=True)
class IseJob:
    key: str
    gains: tuple[tuple[float, ...], ...]


def _cost(job: Any) -> float:
    """Rough seconds of CPU, to start the longest jobs first."""
    if isinstance(job, TuneJob):
        return 0.016 * job.population * (job.iterations + 1)
    if isinstance(job, IseJob):
        return 0.4 * len(job.gains)
    sc = job.scenario
    d = job.duration if job.duration is not None else sc.duration
    return d * (0.006 + 0.002 * sc.n_drones)


def do_job(job: Any) -> Any:
    """Run one job of the report (worker side; module-level so it pickles by reference)."""
    if isinstance(job, SweepTask):
        return run_task(job)
    if isinstance(job, TuneJob):
        from ..tuning.cost import StepCostSettings, TuneOptions, tune_gains

        paper = job.mode == "paper"
        tuned = tune_gains(
            TuneOptions(
                population=job.population,
                iterations=job.iterations,
                seed=job.seed,
                init="random" if paper else "table4",
            ),
            StepCostSettings(bars=None) if paper else StepCostSettings(),
            workers=1,
        )
        c = tuned.check
        assert c is not None  # tune_gains always checks its best gains
        return {
            "seed": job.seed,
            "mode": job.mode,
            "initial_ise": tuned.initial_ise,
            "final_ise": tuned.best_ise,
            "improvement_pct": tuned.improvement_pct,
            "table4_ise": tuned.table4_ise,
            "history": [float(h) for h in tuned.history_ise],
            "best_gains": [float(g) for g in tuned.best_x],
            "meets_bars": bool(c.meets_bars),
            "max_tilt_deg": c.max_tilt_deg,
            "step": {ax: dict(m) for ax, m in c.step.items()},
            "population": job.population,
            "iterations": job.iterations,
            "wall_s": tuned.wall_s,
        }
    if isinstance(job, IseJob):
        from ..tuning.cost import step_ise

        return [float(step_ise(np.asarray(g))) for g in job.gains]
    from ..experiments.runner import run

    res = run(job.scenario, seed=job.seed, progress=False, duration=job.duration)
    out: dict[str, Any] = {"summary": res.summary, "events": res.events, "wall_s": res.summary["wall_time_s"]}
    if job.keep == ("*",):
        out["log"] = res.log
    elif job.keep:
        log = res.log
        out["log"] = {f: np.ascontiguousarray(getattr(log, f)[:: job.every]) for f in ("t",) + job.keep}
        out["log"]["names"] = list(log.names)
    return out


@dataclass
class JobResults:
    """The results of a job list: by plan index, by job key (sweep runs have none) and the wall time."""

    by_index: list[Any]
    by_key: dict[str, Any]
    wall_s: float


def describe_job(group: str, job: Any, sweeps: dict[str, dict[str, Any]]) -> str:
    """A job in a few words, for the progress lines."""
    what = getattr(job, "key", None)
    if what is not None:
        return what
    sw = sweeps[group[6:]]  # a sweep run: group "sweep:KEY"
    val = f" {sw['param']}={sw['values'][job.value_index]}" if sw["param"] else ""
    return f"sweep {group[6:]}{val} seed {job.seed}"


def run_jobs(
    jobs: list[tuple[str, Any]],
    sweeps: dict[str, dict[str, Any]],
    workers: int,
    bar: Progress | None = None,
    say: Callable[[str], None] | None = None,
) -> JobResults:
    """Run every (group, job), longest first, on ``workers`` processes; results in plan order.

    ``say(line)`` gets one line per completed job (its key, wall time and the elapsed time).
    """
    order = sorted(range(len(jobs)), key=lambda i: -_cost(jobs[i][1]))
    total = len(order)
    done = [0]
    t0 = time.perf_counter()

    def on_result(j: int, r: Any) -> None:
        done[0] += 1
        if say is None:
            return
        group, job = jobs[order[j]]
        wall = r.get("wall_s") if isinstance(r, dict) else None
        say(
            f"[{done[0]:>{len(str(total))}}/{total}] {describe_job(group, job, sweeps)}"
            + (f" ({wall:.1f} s)" if wall else "")
            + f"  {time.perf_counter() - t0:5.0f} s elapsed"
        )

    ordered = map_ordered(do_job, [jobs[i][1] for i in order], workers=workers, progress=bar, on_result=on_result)
    by_index: list[Any] = [None] * len(jobs)
    for j, i in enumerate(order):
        by_index[i] = ordered[j]
    by_key = {job.key: by_index[i] for i, (_, job) in enumerate(jobs) if getattr(job, "key", None)}
    return JobResults(by_index, by_key, time.perf_counter() - t0)
