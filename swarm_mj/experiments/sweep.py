"""Seeded sweeps: many runs of one scenario, local worker processes or a Ray cluster.

``sweep(scenario, seeds=20, param="wind.sigma", values=[0.4, 0.8, 1.2])`` flies the scenario
once per (value, seed) and returns, for each parameter value, the mean, standard deviation
and worst case of the key metrics (:data:`METRICS`) over the seeds.

* **Seeds.** Seed ``s`` drives the wind turbulence (the OU process of eq. 36) and, for a
  scenario with ``followers.random_start``, the random follower starts. Seeds are 0..N−1
  unless given explicitly.
* **Parameters.** ``KEY`` is a dotted path into the scenario's TOML document
  (``wind.sigma``, ``formation.diameter``, ``formation.anti_collision``,
  ``controller.wind_feedforward``, ``duration``, ...); each value is a TOML literal
  (a bare word is read as a string). The scenario is re-validated with the value, so a bad
  value is one clear :class:`~swarm_mj.errors.UserError`. ``wind.sigma = 0.4`` sets
  σ_x = σ_y = 0.4 m/s (use ``wind.sigma=[0.8,0.5]`` for one value per axis).
* **Statistics.** ``mean`` and ``std`` (sample standard deviation, ddof = 1; 0 for one
  run) are over the finite values; ``worst`` is the max for errors, settling times and
  contacts and the min for separations, with the seed it came from; ``n_nonfinite`` counts
  runs where the value was infinite (e.g. a formation that never settled), in which case
  ``worst`` is that infinity.
* **Determinism.** Each run depends only on its scenario and seed; results are put back in
  task order whatever order the workers finish in, so the statistics are identical for any
  number of workers (tested).

The runs go through the one executor, :func:`swarm_mj.experiments.parallel.map_ordered` (spawn worker
processes or Ray, results in task order, Ctrl-C handled by the parent). The command line
(``--param KEY=V1,V2``, ``--seeds``) is parsed in ``swarm_mj/commands/sweep.py``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import Any

import numpy as np

from ..errors import UserError
from ..output.progress import Progress
from ..scenario import Scenario, load_scenario, parse_scenario
from .outcome import failure_line
from .parallel import backend_name, check_run_count, map_ordered, resolve_workers

#: (key, label, worst, swarm only). ``worst`` is "max" (an error: bigger is worse) or "min".
METRICS: list[tuple[str, str, str, bool]] = [
    ("rmse_x", "leader RMSE x (m)", "max", False),
    ("rmse_y", "leader RMSE y (m)", "max", False),
    ("rmse_roll_deg", "leader RMSE roll (deg)", "max", False),
    ("rmse_pitch_deg", "leader RMSE pitch (deg)", "max", False),
    ("rmse_steady_x", "leader RMSE x, t >= 10 s (m)", "max", False),
    ("rmse_steady_y", "leader RMSE y, t >= 10 s (m)", "max", False),
    ("rmse_steady_roll_deg", "leader RMSE roll, t >= 10 s (deg)", "max", False),
    ("rmse_steady_pitch_deg", "leader RMSE pitch, t >= 10 s (deg)", "max", False),
    ("contacts", "drone-drone contacts", "max", True),
    ("min_separation_m", "min 3D separation (m)", "min", True),
    ("formation_settling_s", "formation settling, worst change (s)", "max", True),
    ("max_distance_error_m", "max formation distance error once settled (m)", "max", True),
    ("stopped", "runs stopped early (diverged)", "max", False),
]
METRIC_KEYS = [m[0] for m in METRICS]
_WORST = {m[0]: m[2] for m in METRICS}


# --------------------------------------------------------------------------- metrics of one run


def run_metrics(summary: dict) -> dict[str, float]:
    """The sweep's metrics of one run summary (:func:`swarm_mj.experiments.runner.summarize`).

    Swarm-only metrics are absent for a single drone; the steady RMSE is NaN when the run
    is shorter than ``steady_after``.
    """
    leader = summary["drones"]["leader"]
    out: dict[str, float] = {}
    r = leader["rmse"]
    rs = leader.get("rmse_steady")
    for k in ("x", "y", "roll_deg", "pitch_deg"):
        out[f"rmse_{k}"] = float(r[k])
        out[f"rmse_steady_{k}"] = float(rs[k]) if rs else float("nan")
    if summary.get("n_drones", 1) > 1:
        out["contacts"] = float(summary["contacts"])
        out["min_separation_m"] = float(summary["min_separation_m"])
        f = summary["formation"]
        out["formation_settling_s"] = float(max(f["settling_s"])) if f["settling_s"] else float("nan")
        out["max_distance_error_m"] = float(f["max_distance_error_m"])
    out["stopped"] = 1.0 if summary.get("stopped") else 0.0
    return out


def metric_stats(values: Sequence[float], seeds: Sequence[int], worst: str = "max") -> dict[str, Any]:
    """mean, std (ddof = 1 over the finite values), worst (max or min) and its seed.

    NaN values (a metric that does not apply to a run) are ignored; infinite ones are
    counted in ``n_nonfinite`` and make ``worst`` infinite.
    """
    v = np.asarray(values, dtype=float)
    s = np.asarray(seeds)
    keep = ~np.isnan(v)
    v, s = v[keep], s[keep]
    fin = np.isfinite(v)
    vf = v[fin]
    out: dict[str, Any] = {"n": int(len(v)), "n_nonfinite": int((~fin).sum())}
    out["mean"] = float(vf.mean()) if len(vf) else float("nan")
    out["std"] = float(vf.std(ddof=1)) if len(vf) > 1 else (0.0 if len(vf) else float("nan"))
    if len(v) == 0:
        out.update(worst=float("nan"), worst_seed=None, best=float("nan"))
        return out
    if worst == "min":
        i = int(np.argmin(v))
        out["best"] = float(v.max())
    else:
        i = int(np.argmax(v))
        out["best"] = float(v.min())
    out["worst"] = float(v[i])
    out["worst_seed"] = int(s[i])
    return out


# --------------------------------------------------------------------------- parameters


def _set_path(doc: dict, key: str, value: Any) -> dict:
    """A deep copy of the TOML document with ``key`` (dotted) set to ``value``."""
    import copy

    d = copy.deepcopy(doc)
    parts = key.split(".")
    node = d
    for i, p in enumerate(parts[:-1]):
        nxt = node.get(p)
        if nxt is None:
            nxt = node[p] = {}
        if not isinstance(nxt, dict):
            raise UserError(f"--param {key}: {'.'.join(parts[: i + 1])} is not a table")
        node = nxt
    node[parts[-1]] = value
    return d


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return a is not None and b is not None and np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    try:
        return bool(a == b)
    except Exception:  # noqa: BLE001 - e.g. ambiguous comparisons
        return False


def apply_param(sc: Scenario, key: str, value: Any) -> Scenario:
    """``sc`` with the TOML field ``key`` set to ``value``, validated by the scenario parser.

    Only the fields that the value changes are replaced, so earlier overrides of ``sc``
    (gains, duration, ...) survive.
    """
    if not isinstance(sc.raw, dict) or not sc.raw:
        raise UserError(f"--param {key}: scenario {sc.name!r} has no TOML document to change")
    path = sc.path or "<scenario>"
    where = f"--param {key}={value!r}"
    try:
        base = parse_scenario(sc.raw, path, name=sc.name)
        new = parse_scenario(_set_path(sc.raw, key, value), path, name=sc.name)
    except UserError as exc:
        raise UserError(f"{where}: {exc}") from None
    if key.startswith("wind.") and key != "wind.enabled" and not (base.wind.enabled and new.wind.enabled):
        raise UserError(f"{where}: scenario {sc.name!r} has no wind (wind.enabled = false), so {key} changes nothing")
    changed: dict[str, Any] = {}
    for f in fields(Scenario):
        if f.name in ("raw", "path", "name"):
            continue
        b, n, cur = getattr(base, f.name), getattr(new, f.name), getattr(sc, f.name)
        if _same(b, n):
            continue
        if is_dataclass(n) and type(n) is type(b) is type(cur):
            # e.g. WindConfig: change only the sub-fields the value changes, on sc's current value
            sub = {g.name: getattr(n, g.name) for g in fields(n) if not _same(getattr(b, g.name), getattr(n, g.name))}
            changed[f.name] = replace(cur, **sub)  # type: ignore[type-var]  # cur is a dataclass instance here
        elif isinstance(n, dict) and isinstance(b, dict) and isinstance(cur, dict):
            changed[f.name] = {**cur, **{k: v for k, v in n.items() if k not in b or not _same(b[k], v)}}
        else:
            changed[f.name] = n
    return sc.with_overrides(raw=new.raw, **changed)


def seeded(sc: Scenario, seed: int) -> Scenario:
    """The scenario for seed ``seed``: the wind seed and, if random, the follower starts' seed."""
    sc = sc.with_overrides(seed=int(seed))
    if sc.random_start is not None:
        sc = sc.with_overrides(random_start=replace(sc.random_start, seed=int(seed)))
    return sc


# --------------------------------------------------------------------------- the sweep


@dataclass(frozen=True)
class SweepTask:
    scenario: Scenario
    seed: int
    value_index: int
    duration: float | None = None


def run_task(task: SweepTask) -> dict[str, Any]:
    """One run of a sweep (worker side): the metrics, the seed and the run's wall time."""
    from .runner import run

    res = run(seeded(task.scenario, task.seed), seed=task.seed, progress=False, duration=task.duration)
    return {
        "seed": task.seed,
        "value_index": task.value_index,
        "metrics": run_metrics(res.summary),
        "wall_s": float(res.summary["wall_time_s"]),
        "sim_time_s": float(res.summary["sim_time_s"]),
        "stopped": res.summary.get("stopped"),
        "flight_failed": failure_line(res.summary.get("flight")),  # experiments/outcome.py
    }


@dataclass
class SweepResult:
    scenario: str
    n_drones: int
    seeds: list[int]
    param: str | None
    values: list[Any]
    duration: float
    runs: list[dict]  # task order: value-major, then seed
    stats: list[dict[str, dict]] = field(default_factory=list)  # per value: metric -> stats
    workers: int = 1
    backend: str = "processes"
    wall_s: float = 0.0

    def to_dict(self) -> dict:
        return {
            "scenario": self.scenario,
            "n_drones": self.n_drones,
            "seeds": self.seeds,
            "param": self.param,
            "values": self.values,
            "duration_s": self.duration,
            "workers": self.workers,
            "backend": self.backend,
            "wall_s": self.wall_s,
            "results": [{"value": v, "stats": s} for v, s in zip(self.values, self.stats)],
            "runs": [
                {
                    "value": self.values[r["value_index"]],
                    "seed": r["seed"],
                    "metrics": r["metrics"],
                    "wall_s": r["wall_s"],
                    "stopped": r["stopped"],
                    "flight_failed": r.get("flight_failed"),
                }
                for r in self.runs
            ],
        }


def compute_stats(runs: Sequence[dict], n_values: int) -> list[dict[str, dict]]:
    """Per value index, ``{metric: metric_stats(...)}`` over that value's runs (task order)."""
    out = []
    for vi in range(n_values):
        rs = [r for r in runs if r["value_index"] == vi]
        keys = [k for k in METRIC_KEYS if any(k in r["metrics"] for r in rs)]
        out.append(
            {
                k: metric_stats([r["metrics"].get(k, float("nan")) for r in rs], [r["seed"] for r in rs], _WORST[k])
                for k in keys
            }
        )
    return out


def sweep(
    scenario: Scenario | str,
    seeds: int | Iterable[int] = 20,
    param: str | None = None,
    values: Sequence[Any] | None = None,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    duration: float | None = None,
    progress: bool = False,
) -> SweepResult:
    """Fly ``scenario`` for every (value, seed) and gather mean/std/worst of :data:`METRICS`.

    ``seeds``: a count N (seeds 0..N−1) or the seeds themselves. ``param``/``values``: a
    dotted TOML key and its values (:func:`apply_param`); none = the scenario as it is.
    ``progress``: one line per completed run on stderr, under a progress bar when stderr is a
    terminal (:class:`~swarm_mj.output.progress.Progress`).
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if isinstance(seeds, (int, np.integer)):  # before the seeds' list is built
        check_run_count(int(seeds) * len(values or [None]), "--seeds")
    seed_list = list(range(int(seeds))) if isinstance(seeds, (int, np.integer)) else [int(s) for s in seeds]
    if not seed_list:
        raise UserError(f"--seeds must be >= 1, got {seeds}")
    if any(s < 0 for s in seed_list):
        raise UserError("seeds must be >= 0")
    if duration is not None and not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise UserError(f"--duration must be a positive number of seconds, got {duration}")
    if param is None:
        variants, vals = [sc], [None]
    else:
        if not values:
            raise UserError(f"--param {param}: no values")
        vals = list(values)
        variants = [apply_param(sc, param, v) for v in vals]
    tasks = [
        SweepTask(scenario=v, seed=s, value_index=vi, duration=duration)
        for vi, v in enumerate(variants)
        for s in seed_list
    ]
    total = len(tasks)
    w = resolve_workers(workers)
    t0 = time.perf_counter()
    bar = Progress(total, f"sweep {sc.name}", None if progress else False, unit="runs")
    width = len(str(total))

    def on_result(i: int, r: dict) -> None:
        bar.log(f"[{bar.done:>{width}}/{total}] {sc.name} {_run_line(r, param, vals)}")

    try:
        runs = map_ordered(run_task, tasks, workers=w, ray_address=ray_address, progress=bar, on_result=on_result)
    finally:
        bar.close()
    dur = float(duration if duration is not None else sc.duration)
    used = min(w, total)
    res = SweepResult(
        scenario=sc.name,
        n_drones=sc.n_drones,
        seeds=seed_list,
        param=param,
        values=vals,
        duration=dur,
        runs=runs,
        workers=used,
        backend=backend_name(used, ray_address),
        wall_s=time.perf_counter() - t0,
    )
    res.stats = compute_stats(runs, len(vals))
    return res


# --------------------------------------------------------------------------- text


def _run_line(r: dict, param: str | None, vals: Sequence[Any]) -> str:
    """One completed run, for the progress lines: the value, the seed and its key figures."""
    m = r["metrics"]
    what = f"{param}={vals[r['value_index']]!r} " if param else ""
    bits = [f"RMSE x {m['rmse_x']:.4f} y {m['rmse_y']:.4f} m"]
    if "contacts" in m:
        bits.append(f"contacts {m['contacts']:.0f}, min sep {m['min_separation_m']:.3f} m")
    if r["stopped"]:
        bits.append(f"STOPPED: {r['stopped']}")
    return f"{what}seed {r['seed']}: {', '.join(bits)} ({r['wall_s']:.1f} s)"


def _fmt(v: float) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "never" if v > 0 else "-inf"
    if v == int(v) and abs(v) < 1e6:
        return f"{v:.0f}"
    return f"{v:.4g}"


def format_sweep(res: SweepResult) -> str:
    """Mean, std and worst (with its seed) per metric, one block per parameter value."""
    seeds = res.seeds
    srange = f"{seeds[0]}..{seeds[-1]}" if seeds == list(range(seeds[0], seeds[-1] + 1)) else ", ".join(map(str, seeds))
    lines = [
        f"sweep {res.scenario}: {len(seeds)} seed(s) ({srange}) x {len(res.values)} value(s), "
        f"{res.duration:g} s simulated each, {res.workers} worker(s) ({res.backend}), {res.wall_s:.1f} s wall"
    ]
    labels = {m[0]: (m[1], m[2]) for m in METRICS}
    for v, st in zip(res.values, res.stats):
        lines.append("")
        if res.param:
            lines.append(f"{res.param} = {v!r}")
        lines.append(f"{'metric':<48}{'mean':>10}{'std':>10}{'worst':>10}  (seed)")
        for k, s in st.items():
            if k == "stopped" and s["worst"] == 0:
                continue
            label, w = labels[k]
            extra = f" ({s['n_nonfinite']} never)" if s["n_nonfinite"] else ""
            tag = "min" if w == "min" else "max"
            at = f"({tag} at seed {s['worst_seed']})" if s["worst_seed"] is not None else ""
            lines.append(f"{label:<48}{_fmt(s['mean']):>10}{_fmt(s['std']):>10}{_fmt(s['worst']):>10}  {at}{extra}")
    stopped = sum(1 for r in res.runs if r["stopped"])
    if stopped:
        lines.append("")
        lines.append(f"{stopped} run(s) stopped early (see --json for which)")
    return "\n".join(lines)
