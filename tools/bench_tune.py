"""Wall time of the full FPA tune and its speed-up over evaluating candidates one at a time.

The full default tune (paper Table 2: N = 50, 14 iterations, t_sim = 10 s; 750 evaluations
plus the Table 4 reference) is timed end to end with the default worker processes and in
one process. The one-at-a-time baselines evaluate a sample of the same kind of candidates
(uniform in the box, as the FPA's initial population) one simulation per candidate and are
extrapolated per candidate to the tune's 751 evaluations:

* "runner.run per candidate": one Python simulation per candidate through the product's own
  loop (``runner.run`` of the step scenario with the candidate's gains, as one would without
  a batched cost) and the ISE from its log: the issue's "one simulation at a time";
* "one model per candidate": the tune's own evaluator with a 1-drone model (reused, so model
  building is not even counted), a stricter baseline: the gain of batching alone. MuJoCo's
  RK4 step of a drone in a batch (about 3 µs) is most of the batched time, which bounds it.

    .venv/bin/python tools/bench_tune.py [--sample 10] [--runner-sample 3] [--seed 1] [--workers N]

Goals (issue 6): full tune ≤ 60 s on this 2-core machine; ≥ 10× faster than one at a time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from swarm_mj.experiments.runner import run
from swarm_mj.metrics import ise
from swarm_mj.physics.state import wrap_angle
from swarm_mj.tuning.cost import (
    StepCostSettings,
    TuneOptions,
    default_workers,
    evaluate_batch,
    step_ise,
    table4_ise,
    tune_gains,
)

GOAL_WALL_S = 60.0
GOAL_SPEEDUP = 10.0


def runner_ise(gains: np.ndarray, settings: StepCostSettings) -> float:
    """ISE of eq. (25) from the log of ``runner.run('step')`` (the first K samples)."""
    res = run("step", gains=gains, progress=False, duration=settings.t_sim)
    if res.error is not None:
        return float("inf")
    log, K = res.log, settings.n_samples
    e = np.empty((K, 6))
    e[:, 0:3] = log.pos_d[:K, 0] - log.pos[:K, 0]
    e[:, 3:5] = log.att_d[:K, 0, 0:2] - log.rpy[:K, 0, 0:2]
    e[:, 5] = wrap_angle(log.att_d[:K, 0, 2] - log.rpy[:K, 0, 2])
    return float(ise(e, settings.control_period))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=int, default=10, help="candidates evaluated one at a time (default 10)")
    ap.add_argument(
        "--runner-sample", type=int, default=3, help="candidates run through runner.run (default 3; 0 to skip)"
    )
    ap.add_argument("--seed", type=int, default=1, help="FPA seed (default 1)")
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default 1: in this process)")
    ap.add_argument("--threads", type=int, default=None, help="threads (default: one per CPU in this process)")
    ap.add_argument("--skip-in-process", action="store_true", help="do not time the 1-thread in-process tune")
    args = ap.parse_args(argv)
    if args.sample < 1 or args.runner_sample < 0:
        ap.error("--sample must be >= 1 and --runner-sample >= 0")

    opts = TuneOptions(seed=args.seed)
    settings = StepCostSettings()
    workers = 1 if args.workers is None else args.workers
    n_eval = opts.population * (opts.iterations + 1) + 1  # + the Table 4 reference
    table4_ise(settings)  # warm-up (JIT kernels, imports)

    rows: list[tuple[str, float]] = []
    in_process_s = float("nan")
    t0 = time.perf_counter()
    par = tune_gains(opts, settings, workers=workers, threads=args.threads)
    rows.append((f"FPA tune, batched, {par.workers} process(es) x {par.threads} thread(s)", time.perf_counter() - t0))
    if workers == 1 and par.threads == 1:
        in_process_s = rows[0][1]
    elif not args.skip_in_process:
        t0 = time.perf_counter()
        one = tune_gains(opts, settings, workers=1, threads=1)
        in_process_s = time.perf_counter() - t0
        rows.append(("FPA tune, batched, in-process, 1 thread", in_process_s))
        if not (np.array_equal(one.best_x, par.best_x) and one.best_ise == par.best_ise):
            print("WARNING: the 1-process and multi-process tunes differ")

    rng = np.random.default_rng(12345)
    lower, upper = opts.bounds
    X = lower + rng.random((args.sample, 12)) * (upper - lower)  # (s, 12) like the initial population
    batched = evaluate_batch(X, settings)  # (s,) also warms the 1-drone model
    evaluate_batch(X[:1], settings)
    t0 = time.perf_counter()
    alone = np.array([evaluate_batch(X[i : i + 1], settings)[0] for i in range(args.sample)])
    per_alone = (time.perf_counter() - t0) / args.sample
    rows.append((f"one model per candidate (x{n_eval}, from {args.sample})", per_alone * n_eval))
    fin = np.isfinite(batched)
    same = np.array_equal(np.isfinite(alone), fin) and np.allclose(alone[fin], batched[fin], rtol=1e-9, atol=0)
    if args.runner_sample:
        k = min(args.runner_sample, args.sample)
        t0 = time.perf_counter()
        via_runner = np.array([runner_ise(X[i], settings) for i in range(k)])
        per_runner = (time.perf_counter() - t0) / k
        rows.append((f"runner.run per candidate (x{n_eval}, from {k})", per_runner * n_eval))
        plain = step_ise(X[:k], settings)  # (k,) the plain ISE, not the ranked cost
        fin_r = np.isfinite(plain)
        same_r = np.allclose(via_runner[fin_r], plain[fin_r], rtol=1e-9, atol=0)

    print(
        f"Full FPA tune: N = {opts.population}, {opts.iterations} iterations, t_sim = {settings.t_sim:g} s, "
        f"seed {opts.seed}: {n_eval} evaluations; {workers} worker process(es) x {par.threads} thread(s) "
        f"on {default_workers()} CPU(s)"
    )
    print(
        f"  initial best ISE {par.initial_ise:.5f}, final {par.best_ise:.5f} "
        f"({par.improvement_pct:.1f} %), Table 4 {par.table4_ise:.5f}"
    )
    ref = rows[-1][1] if args.runner_sample else rows[-1][1]
    base_alone = per_alone * n_eval
    head = ("", "wall (s)", "per eval (ms)", "× vs one model/cand.", "× vs runner.run")
    print(f"{head[0]:<52}{head[1]:>10}{head[2]:>15}{head[3]:>22}{head[4]:>17}")
    for name, t in rows:
        vs_runner = f"{ref / t:>17.1f}" if args.runner_sample else f"{'-':>17}"
        print(f"{name:<52}{t:>10.2f}{1e3 * t / n_eval:>15.2f}{base_alone / t:>22.1f}{vs_runner}")
    wall = rows[0][1]
    speedup = base_alone / wall
    print(
        f"batched == one at a time on the sample (rtol 1e-9): {'yes' if same else 'NO'}"
        + (f"; == runner.run ISE: {'yes' if same_r else 'NO'}" if args.runner_sample else "")
    )
    print(f"full tune {wall:.1f} s ({'meets' if wall <= GOAL_WALL_S else 'misses'} the goal ≤ {GOAL_WALL_S:g} s)")
    if args.runner_sample:
        vs_run = ref / wall
        print(
            f"speed-up over one simulation per candidate through the product's loop (runner.run): {vs_run:.1f}× "
            f"({'meets' if vs_run >= GOAL_SPEEDUP else 'misses'} the goal ≥ {GOAL_SPEEDUP:g}×)"
        )
    print(
        f"speed-up over the tune's own evaluator flying one copy per model: {speedup:.1f}× "
        f"({'meets' if speedup >= GOAL_SPEEDUP else 'misses'} the goal ≥ {GOAL_SPEEDUP:g}× on this stricter "
        f"baseline; batching alone, one process: {base_alone / in_process_s:.1f}×)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
