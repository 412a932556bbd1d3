"""The tuner on every core (issue 30): the evaluator on several threads gives each copy's result bit for
bit as one thread, the tune too; the threads default to the usable CPUs; by default the tune's workers
are processes forked from a single-threaded parent (spawned otherwise), with the same results."""

from __future__ import annotations

import os
import sys
import threading

import numpy as np
import pytest

from swarm_mj.cli import main as cli_main
from swarm_mj.errors import UserError
from swarm_mj.paper import TABLE4_GAINS
from swarm_mj.tuning import BatchEvaluator, StepCostSettings, TuneOptions, make_population_cost, tune_gains
from swarm_mj.tuning import evaluator as evaluator_mod
from swarm_mj.tuning.backends import worker_start_method
from swarm_mj.tuning.evaluator import evaluate_batch

SHORT = StepCostSettings(t_sim=2.0)


def _batch() -> np.ndarray:
    """(11, 12): Table 4, uniform flowers of the default box, one far outside it (flips), one NaN."""
    X = 0.1 + np.random.default_rng(7).random((11, 12)) * 11.9
    X[0] = TABLE4_GAINS
    X[4] = 100.0  # the 10-ms loop goes unstable
    X[8, 2] = np.nan
    return X


def _outputs(ev: BatchEvaluator, X: np.ndarray) -> dict[str, np.ndarray]:
    out = {"cost": ev.evaluate(X), "ranked": ev.ranked(X)}
    out |= {"violation": ev.violation.copy(), "tilt": ev.max_tilt_deg.copy(), "diverged_at": ev.diverged_at.copy()}
    for ax, metrics in ev.step.items():
        out |= {f"{ax}.{k}": v.copy() for k, v in metrics.items()}
    return out


def test_threads_give_the_same_results_bit_for_bit():
    X = _batch()
    one = _outputs(BatchEvaluator(len(X), SHORT, block=3, threads=1), X)
    assert np.isinf(one["cost"][[4, 8]]).all() and np.isfinite(np.delete(one["cost"], [4, 8])).all()
    for threads in (2, 3, 11, 40):  # 40: capped at one copy per thread
        ev = BatchEvaluator(len(X), SHORT, block=3, threads=threads)
        assert ev.threads == min(threads, len(X)) and len(ev.groups) == ev.threads
        other = _outputs(ev, X)
        assert other.keys() == one.keys()
        for key in one:
            np.testing.assert_array_equal(other[key], one[key], err_msg=f"{key}, {threads} threads")


def test_a_block_of_diverged_copies_is_no_longer_stepped():
    X = np.vstack([TABLE4_GAINS, np.full((2, 12), 100.0), TABLE4_GAINS])  # blocks (0, 1) and (2, 3)
    ev = BatchEvaluator(4, SHORT, block=1, threads=2)
    cost = ev.evaluate(X)
    assert np.isinf(cost[1:3]).all() and np.isfinite(cost[[0, 3]]).all() and cost[0] == cost[3]
    t_end = ev.sims[0].time
    assert t_end == pytest.approx(SHORT.t_sim)
    for i in (1, 2):  # stepped up to the period where the copy diverged, not after
        assert ev.sims[i].time == pytest.approx(ev.diverged_at[i] * SHORT.control_period)
        assert ev.sims[i].time < t_end


def test_same_tune_whatever_the_number_of_threads():
    opts = TuneOptions(population=7, iterations=2, seed=3)
    one = tune_gains(opts, SHORT, workers=1, threads=1)
    two = tune_gains(opts, SHORT, workers=1, threads=2)
    assert one.threads == 1 and two.threads == 2 and two.backend == "in-process"
    np.testing.assert_array_equal(two.best_x, one.best_x)
    np.testing.assert_array_equal(two.history, one.history)
    np.testing.assert_array_equal(two.result.population, one.result.population)
    np.testing.assert_array_equal(two.result.costs, one.result.costs)


def test_threads_default_to_the_usable_cpus():
    usable = len(os.sched_getaffinity(0))
    with make_population_cost(SHORT, workers=1) as cost:  # in this process: one thread per usable CPU
        assert cost.backend == "in-process" and cost.threads == usable
    with make_population_cost(SHORT, threads=3) as cost:  # only threads given: in this process
        assert cost.backend == "in-process" and cost.threads == 3
    with make_population_cost(SHORT, workers=2) as cost:  # processes: one thread each unless asked
        assert cost.backend == "processes" and cost.threads == 1
    with make_population_cost(SHORT) as cost:  # the default: a process per usable CPU (one CPU: in-process)
        assert cost.workers == usable and cost.threads == 1
        assert cost.backend == ("processes" if usable > 1 else "in-process")
    X = _batch()[:3]
    evaluate_batch(X, SHORT)
    assert (SHORT, 3, min(usable, 3)) in evaluator_mod._EVALUATORS


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")
def test_workers_fork_from_a_single_threaded_process_and_spawn_otherwise():
    alone = threading.active_count() == 1  # (other tests of the session may have left a thread)
    assert worker_start_method() == ("fork" if alone else "spawn")
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert worker_start_method() == "spawn"
    finally:
        stop.set()
        other.join()
    with make_population_cost(SHORT, workers=2) as cost:
        assert cost.start_method == ("fork" if alone else "spawn")


def test_forked_and_spawned_workers_give_the_in_process_costs(monkeypatch):
    from swarm_mj.tuning import backends

    X = _batch()
    here = BatchEvaluator(len(X), SHORT, threads=1).ranked(X)
    for method in ("fork", "spawn") if sys.platform.startswith("linux") else ("spawn",):
        monkeypatch.setattr(backends, "worker_start_method", lambda m=method: m)
        with make_population_cost(SHORT, workers=2) as cost:
            assert cost.start_method == method
            np.testing.assert_array_equal(cost(X), here)


def test_an_error_in_one_thread_is_raised_and_stops_the_others(monkeypatch):
    python_body = evaluator_mod.python_body

    def fails_in_the_second_group(fn, stages=None):  # the evaluator's command (period.command's Python body)
        if stages is not None:  # the period's own body (its stages) as it is
            return python_body(fn, stages)
        command = python_body(fn)

        def checked(ctl, *args):
            if ctl.gains.a_att[0, 0] == 2.5:  # α1 of the group's first copy
                raise RuntimeError("boom")
            return command(ctl, *args)

        return checked

    monkeypatch.setattr(evaluator_mod, "python_body", fails_in_the_second_group)
    X = np.tile(TABLE4_GAINS, (4, 1))
    X[2:, 0] = 2.5  # the second group's copies
    ev = BatchEvaluator(4, SHORT, threads=2)
    with pytest.raises(RuntimeError, match="boom"):
        ev.evaluate(X)
    assert ev.sims[0].time < SHORT.t_sim  # the first group stopped early


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_bad_thread_counts_are_user_errors(bad):
    with pytest.raises(UserError, match="threads"):
        BatchEvaluator(2, SHORT, threads=bad)
    with pytest.raises(UserError, match="threads"):
        make_population_cost(SHORT, threads=bad)


def test_cli_threads_zero_exits_2_with_one_line(tmp_path, capsys):
    rc = cli_main(["tune", "--threads", "0", "-o", str(tmp_path / "g.toml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--threads" in err[0]
    assert not (tmp_path / "g.toml").exists()
