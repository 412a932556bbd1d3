"""``swarm-mj tune``: tune the 12 backstepping gains with the Flower Pollination Algorithm.

Paper §3.2, Fig. 3, Table 2 (docs/interpretations.md §6): FPA (N = 50, 14 iterations, p = 0.04, γ = 0.02,
gains in [0.1, 12]) minimising the ISE of eq. (25) over the step manoeuvre (docs/interpretations.md §3),
t_sim = 10 s, by default subject to the controller's step bars (overshoot ≤ 1 %, settling
≤ 2 / 2 / 1.5 / 2 s, steady-state error ≤ 1 mm, tilt ≤ 55°; Deb's feasibility rules,
``swarm_mj.tuning.constraints``) and starting from a population that holds the paper's
Table 4 gains. ``--constraints none --init random`` is the paper's tune as printed. Writes
a gains TOML file (``gains = [α1..α12]`` plus the ISEs, the settings and the tuned gains'
step response) that ``swarm-mj run step --gains FILE`` and scenario files
(``[controller] gains = "FILE"``) read. The file is rewritten atomically after every
iteration, so an interrupted tune leaves the best gains so far, never a half-written file.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..tuning.cost import StepCostSettings, TuneOptions, TuneOutcome
    from ..vehicles import Vehicle

PAPER_IMPROVEMENT_PCT = (10.67, 35.45)  # paper Table 3, min and max over its runs


def add_parser(sub) -> None:
    p = sub.add_parser(
        "tune",
        help="tune the 12 backstepping gains with the Flower Pollination Algorithm",
        description="Tune α1..α12 with the Flower Pollination Algorithm (paper §3.2, Table 2) on the ISE "
        "of eq. (25) over the step (x = y = z = 1 m, ψ = 25°), by default subject to the "
        "controller's step bars and starting from the paper's Table 4 gains. Writes a gains TOML file for "
        "'swarm-mj run step --gains FILE'. The population is simulated in batched MuJoCo "
        "models, split over local worker processes (--workers) or a Ray cluster (--ray).",
    )
    p.add_argument("--population", type=int, default=50, help="flowers N (default 50, Table 2)")
    p.add_argument("--iterations", type=int, default=14, help="iterations (default 14, Table 2)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--t-sim", type=float, default=10.0, help="simulated seconds of the step (default 10)")
    p.add_argument("--p", type=float, default=0.04, help="switch probability (default 0.04, Table 2)")
    p.add_argument("--gamma", type=float, default=0.02, help="global step size γ = c (default 0.02, Table 2)")
    p.add_argument("--lower", type=float, default=0.1, help="lower bound of every gain (default 0.1; > 0)")
    p.add_argument("--upper", type=float, default=12.0, help="upper bound of every gain (default 12)")
    p.add_argument(
        "--constraints",
        choices=("step-bars", "none"),
        default="step-bars",
        help="step-bars (default): gains must also meet the step bars (overshoot ≤ 1 %%, 2 %% settling "
        "x, y ≤ 2 s, z ≤ 1.5 s, ψ ≤ 2 s, each + 2τ under a rotor lag τ, steady-state error ≤ 1 mm, "
        "tilt ≤ 55°), ranked by Deb's "
        "feasibility rules; none: the ISE of eq. (25) alone, as in the paper",
    )
    p.add_argument(
        "--init",
        choices=("table4", "random"),
        default="table4",
        help="table4 (default): the paper's Table 4 gains are one flower of the initial population, "
        "the rest uniform; random: all uniform, as in the paper's Fig. 3",
    )
    p.add_argument(
        "--vehicle",
        default="paper",
        metavar="NAME|FILE",
        help="the vehicle flown through the step: a bundled vehicle (paper, crazyflie21) or a vehicle file "
        "(docs/vehicles.md; default paper, Table 1)",
    )
    p.add_argument(
        "--motor-tau",
        type=float,
        default=None,
        metavar="S",
        help="rotor time constant (s) of the step: > 0 flies it with rotor lag and the controller of a "
        "lagged run (attitude-priority mixing, lag compensation); default: the vehicle file's motor_tau, "
        "0 (ideal rotors, the paper) where it gives none",
    )
    p.add_argument("-o", "--output", default="tuned_gains.toml", help="gains file (default tuned_gains.toml)")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes (default: one per usable CPU; 1 = in this process, on --threads threads); "
        "with --ray: actors (default: one per cluster CPU)",
    )
    p.add_argument(
        "--threads",
        type=int,
        default=None,
        help="threads flying the candidates: in this process with --workers 1 or without --workers "
        "(default: one per usable CPU), else in each worker (default 1); the tune is the same whatever the number",
    )
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="evaluate on a Ray cluster: 'local' starts one here, 'auto' or ray://HOST:PORT "
        "joins one (needs: pip install 'swarm-mj[ray]')",
    )
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=main)


#: Each 2 % settling bar grows by this many rotor time constants τ under rotor lag (docs/vehicles.md,
#: "Tuning for a vehicle"): a first-order lag delays a response by about τ, in the attitude loop and
#: again in the position loop that waits for it.
LAG_SETTLING_FACTOR = 2.0


def lagged_bars(motor_tau: float):  # noqa: ANN201 - a StepBars (imported lazily, as the command does)
    """The step bars for rotors with time constant ``motor_tau`` (s): the paper's
    (:class:`~swarm_mj.tuning.constraints.StepBars`) with each settling bar + LAG_SETTLING_FACTOR·τ;
    exactly the paper's for τ = 0."""
    from ..tuning.constraints import StepBars

    b = StepBars()
    d = LAG_SETTLING_FACTOR * float(motor_tau)
    return replace(
        b,
        settling_x_s=b.settling_x_s + d,
        settling_y_s=b.settling_y_s + d,
        settling_z_s=b.settling_z_s + d,
        settling_psi_s=b.settling_psi_s + d,
    )


# --------------------------------------------------------------------------- the gains file


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))  # shortest round-trip; inf/nan are valid TOML
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def gains_toml(
    outcome, created: datetime | None = None, vehicle: str = "paper", use: str = "swarm-mj run step --gains FILE"
) -> str:
    """The gains file for a :class:`~swarm_mj.tuning.cost.TuneOutcome` (read by ``load_gains``);
    ``vehicle``: the name of the vehicle flown (``--vehicle``), recorded in ``[settings]``; ``use``: the
    command that flies them (:func:`run_hint`)."""
    from .. import __version__

    o, s = outcome.options, outcome.settings
    created = created or datetime.now(UTC)
    done = len(outcome.history) - 1
    lines = (
        [
            "# Backstepping gains α1..α12 (roll, pitch, yaw, x, y, z pairs; paper Table 4 layout)",
            "# tuned by 'swarm-mj tune': Flower Pollination Algorithm (paper §3.2, Table 2) minimising",
            "# the ISE of eq. (25) over the step x = y = z = 1 m, ψ = 25° (docs/interpretations.md §3, §6)"
            + (", subject to the step bars [bars]." if s.bars is not None else "."),
            f'# Use: {use}, or [controller] gains = "FILE" in a scenario of this vehicle.',
            "# nan: no candidate met the bars (yet).",
            f"gains = {_toml_value([float(g) for g in outcome.best_x])}",
            f"ise = {_toml_value(outcome.best_ise)}",
            f"initial_ise = {_toml_value(outcome.initial_ise)}",
            f"improvement_pct = {_toml_value(outcome.improvement_pct)}",
            f"table4_ise = {_toml_value(outcome.table4_ise)}",
            f"beats_table4 = {_toml_value(outcome.beats_table4)}",
            f"seed = {_toml_value(int(o.seed))}",
        ]
        + ([f"meets_bars = {_toml_value(outcome.meets_bars)}"] if outcome.meets_bars is not None else [])
        + [
            f"iterations_done = {done}",
            f"complete = {_toml_value(outcome.complete)}",
            f"history = {_toml_value([float(h) for h in outcome.history_ise])}",
            f"wall_time_s = {_toml_value(round(outcome.wall_s, 3))}",
            f"created = {created.isoformat(timespec='seconds')}",
            "",
            "[settings]",
            f"population = {o.population}",
            f"iterations = {o.iterations}",
            f"p = {_toml_value(float(o.p))}",
            f"gamma = {_toml_value(float(o.gamma))}",
            f"lower = {_toml_value(float(o.lower))}",
            f"upper = {_toml_value(float(o.upper))}",
            f"t_sim = {_toml_value(float(s.t_sim))}",
            f"vehicle = {_toml_value(vehicle)}",
            f"motor_tau = {_toml_value(float(s.motor_tau))}",
            f"mixer = {_toml_value(s.mixer_flown)}",
            f"control_period = {_toml_value(float(s.control_period))}",
            f"timestep = {_toml_value(float(s.timestep))}",
            f"integrator = {_toml_value(s.integrator)}",
            f"target = {_toml_value(list(s.target))}",
            f"yaw_deg = {_toml_value(float(s.yaw_deg))}",
            f"max_tilt_deg = {_toml_value(float(s.max_tilt_deg))}",
            f"ise_weights = {_toml_value([3.0, 3.0, 1.0, 2.0, 2.0, 1.0])}",
            f"constraints = {_toml_value('step-bars' if s.bars is not None else 'none')}",
            f"init = {_toml_value(o.init)}",
            f"backend = {_toml_value(outcome.backend)}",
            f"workers = {int(outcome.workers)}",
            f"threads = {int(outcome.threads)}",
            f"swarm_mj_version = {_toml_value(__version__)}",
            "",
        ]
    )
    if s.bars is not None:
        lines += ["[bars]"] + [f"{k} = {_toml_value(float(v))}" for k, v in s.bars.as_dict().items()] + [""]
    if outcome.check is not None:
        lines.append("# the gains above flown through the step (definitions of 'swarm-mj run step --summary')")
        for ax, m in outcome.check.step.items():
            lines += [f"[step.{ax}]"] + [f"{k} = {_toml_value(float(v))}" for k, v in m.items()]
        lines += ["[step.attitude]", f"max_abs_tilt_deg = {_toml_value(outcome.check.max_tilt_deg)}", ""]
    return "\n".join(lines)


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`swarm_mj.output.atomic.write_text_atomic`): a reader
    (or an interruption) sees the old file or the new one, never half of one; a FIFO or device
    is written in place, a symlink through to its target."""
    from ..output.atomic import write_text_atomic as _write

    _write(path, text)


def write_gains_file(path: str | Path, outcome, vehicle: str = "paper", use: str | None = None) -> None:
    """Atomically write the gains file of ``outcome`` (see :func:`gains_toml`)."""
    text = gains_toml(outcome, vehicle=vehicle, use=use) if use else gains_toml(outcome, vehicle=vehicle)
    write_text_atomic(path, text)


def run_hint(vehicle_arg: str, params, target, yaw_deg: float, gains: str | Path) -> str:  # noqa: ANN001
    """The command that flies ``gains`` through the tune's step on the vehicle they were tuned for, chosen
    by the data of the bundled scenarios (never their names): one drone flying the step to ``target``
    and ``yaw_deg``, with the vehicle's parameters ``params`` (``swarm-mj run crazyflie_step --gains F``);
    where none flies this vehicle, such a step with ``--vehicle`` (``swarm-mj run step --vehicle V --gains F``)."""
    import shlex

    from ..errors import UserError
    from ..scenario import bundled_scenarios, load_scenario, trajectory_args

    steps: list[str] = []
    for name, path in bundled_scenarios().items():
        try:
            sc = load_scenario(path)
        except UserError:
            continue
        args = trajectory_args(sc)
        if sc.n_followers or sc.trajectory != "step":
            continue
        if tuple(args["target"]) != tuple(target) or float(args["yaw_deg"]) != float(yaw_deg):
            continue
        if sc.params == params:
            return shlex.join(["swarm-mj", "run", name, "--gains", str(gains)])
        steps.append(name)
    if steps:
        return shlex.join(["swarm-mj", "run", steps[0], "--vehicle", vehicle_arg, "--gains", str(gains)])
    return f"[controller] gains = {str(gains)!r} in a scenario flying vehicle {vehicle_arg}"


# --------------------------------------------------------------------------- the command


def _check_output(path: Path) -> None:
    from ..output.atomic import check_output_path

    check_output_path(path, "-o/--output")


def main(args: argparse.Namespace) -> int:
    opts, settings, vehicle, out = _checked(args)  # everything validated before any worker starts
    if not args.quiet:
        print(_announcement(args, opts, settings, vehicle), file=sys.stderr, flush=True)
    res, use = _tune(args, opts, settings, vehicle.name, out)
    if not math.isfinite(res.best_cost):
        from ..experiments.outcome import FlightFailed

        kept = f"; {out} left as it was" if out.exists() else ""
        raise FlightFailed(
            f"no candidate flew the step: every one of the {opts.population} flowers diverged in every "
            f"iteration (cost inf/nan) on vehicle {vehicle.name}; no gains file written{kept}"
        )
    write_gains_file(out, res, vehicle.name, use)
    if not args.quiet:
        print(format_outcome(res, out, run_hint(args.vehicle, settings.params, settings.target, settings.yaw_deg, out)))
    return 0


def _checked(args: argparse.Namespace) -> tuple[TuneOptions, StepCostSettings, Vehicle, Path]:
    """The tune's options, its step's settings, the vehicle and the output path, every one checked
    (:class:`UserError`) before any worker starts."""
    from ..errors import UserError
    from ..scenario import check_duration, check_seed
    from ..tuning.cost import StepCostSettings, TuneOptions
    from ..vehicles import load_vehicle

    opts = TuneOptions(
        population=args.population,
        iterations=args.iterations,
        p=args.p,
        gamma=args.gamma,
        lower=args.lower,
        upper=args.upper,
        seed=args.seed,
        init=args.init,
    )
    if not (math.isfinite(args.t_sim) and args.t_sim > 0):
        raise UserError(f"--t-sim must be a positive number of seconds, got {args.t_sim}")
    check_seed(args.seed, "--seed")
    check_duration(args.t_sim, 0.01, max(int(args.population), 1), "--t-sim")
    vehicle = load_vehicle(args.vehicle)
    tau = args.motor_tau if args.motor_tau is not None else (vehicle.motor_tau or 0.0)
    settings = StepCostSettings(
        t_sim=float(args.t_sim),
        bars=lagged_bars(float(tau)) if args.constraints == "step-bars" else None,
        params=vehicle.params(),
        motor_tau=float(tau),
        mixer=vehicle.mixer or "auto",
    )
    _check_backend(args)
    out = Path(args.output)
    _check_output(out)
    return opts, settings, vehicle, out


def _tune(
    args: argparse.Namespace, opts: TuneOptions, settings: StepCostSettings, vehicle: str, out: Path
) -> tuple[TuneOutcome, str]:
    """Run the FPA with a progress line per iteration, the best gains so far written to ``out`` after each
    (where any candidate flew); a Ctrl-C says where they are. Returns the result and the hint of the
    gains file's 'Use:' line."""
    from ..output.progress import Progress
    from ..tuning.constraints import INFEASIBLE
    from ..tuning.cost import tune_gains

    t0 = time.perf_counter()
    last: list = []
    bar = Progress(opts.iterations, "FPA tune", False if args.quiet else None, unit="iterations")
    bar.note("evaluating the initial population")

    use = run_hint(args.vehicle, settings.params, settings.target, settings.yaw_deg, "FILE")

    def on_iteration(o) -> None:
        if math.isfinite(o.best_cost):  # else every candidate so far diverged: nothing worth a file
            last[:] = [o]
            write_gains_file(out, o, vehicle, use)
        it = len(o.history) - 1
        best = (
            f"best ISE {o.best_ise:10.5f}"
            if o.best_feasible or not math.isfinite(o.best_cost)
            else f"none meets the bars yet (least violation {o.best_cost - INFEASIBLE:.3g})"
        )
        bar.note("")
        bar.update(it)
        bar.log(f"  iteration {it:3d}/{opts.iterations}  {best}  elapsed {time.perf_counter() - t0:7.1f} s")

    try:
        try:
            res = tune_gains(
                opts,
                settings,
                workers=args.workers,
                threads=args.threads,
                ray_address=args.ray,
                on_iteration=on_iteration,
            )
        finally:
            bar.close()
    except KeyboardInterrupt:
        if last:
            print(
                f"swarm-mj: interrupted after iteration {len(last[0].history) - 1}; best gains so far "
                f"(ISE {last[0].best_ise:.5f}) are in {out}",
                file=sys.stderr,
            )
        raise
    return res, use


def _check_backend(args: argparse.Namespace) -> None:
    """--workers, --threads and --ray, before any worker starts (:class:`UserError`)."""
    from ..errors import UserError

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    if args.threads is not None and args.threads < 1:
        raise UserError(f"--threads must be >= 1, got {args.threads}")
    if args.ray is not None:
        if not args.ray.strip():
            raise UserError("--ray needs an address: 'local', 'auto' or ray://HOST:PORT")
        from ..experiments.parallel import import_ray

        import_ray()  # one clear line if Ray is missing


def _announcement(args: argparse.Namespace, opts, settings, vehicle) -> str:  # noqa: ANN001
    """The tune's first lines: the FPA settings and where it runs, the vehicle and its lag, the cost."""
    from ..tuning.cost import default_workers

    if args.ray is not None:
        where = f"Ray at {args.ray}" + (f", {args.workers} actors" if args.workers else "")
    else:
        w = (default_workers() if args.threads is None else 1) if args.workers is None else args.workers
        t = (default_workers() if w == 1 else 1) if args.threads is None else args.threads
        where = (f"in this process, {t} thread(s)" if w == 1 else f"{w} worker processes") + (
            f", {t} thread(s) each" if w > 1 and t > 1 else ""
        )
    init = (
        f"; initial population: Table 4 gains + {opts.population - 1} uniform"
        if opts.init == "table4"
        else "; initial population: uniform"
    )
    return "\n".join(
        [
            f"FPA tune: N = {opts.population}, {opts.iterations} iterations, p = {opts.p:g}, γ = {opts.gamma:g}, "
            f"gains in [{opts.lower:g}, {opts.upper:g}], step t_sim = {settings.t_sim:g} s, seed {opts.seed}; "
            f"{where}",
            f"  vehicle: {vehicle.name} ({vehicle.mass:g} kg, arm {vehicle.arm_length:g} m); rotor lag "
            + (f"{1000 * settings.motor_tau:g} ms" if settings.motor_tau > 0 else "none (ideal rotors)"),
            "  cost: ISE of eq. (25)" + (", subject to the step bars (Deb's rules)" if settings.bars else "") + init,
        ]
    )


def format_outcome(res, out: Path | str, use: str | None = None) -> str:
    """The end-of-tune table: initial and final ISE, improvement, Table 4 under the same cost,
    and the tuned gains' step response against the bars."""
    lo, hi = PAPER_IMPROVEMENT_PCT
    t4, best = res.table4_ise, res.best_ise
    rel = 100.0 * (t4 - best) / t4 if math.isfinite(t4) and t4 > 0 else float("nan")
    bars = res.settings.bars
    if res.beats_table4:
        verdict = f"yes, {rel:.1f} % lower ISE"
    elif res.best_feasible:
        verdict = f"no, {-rel:.1f} % higher ISE" if rel < 0 else "no, the same gains"
    else:
        verdict = "no, the tuned gains miss the step bars"
    if res.options.init == "table4" and not (rel > 0):
        verdict += " (the initial population held Table 4; nothing better was found)"
    elif res.options.init == "table4":
        verdict += " (Table 4 was in the initial population)"
    imp = (
        f"{res.improvement_pct:9.2f} %"
        if math.isfinite(res.improvement_pct)
        else "      n/a  (no initial candidate met the bars)"
    )
    gains = ", ".join(f"{g:.4f}" for g in res.best_x)
    rows = [
        f"FPA tune finished in {res.wall_s:.1f} s ({res.backend}, {res.workers} worker(s), "
        f"{res.threads} thread(s){' each' if res.workers > 1 else ''})",
        f"  initial best ISE   {res.initial_ise:10.5f}"
        + ("   (best of the initial population meeting the bars)" if bars is not None else ""),
        f"  final ISE          {best:10.5f}",
        f"  improvement        {imp}   (paper Table 3: {lo:.1f}–{hi:.1f} %)",
        f"  Table 4 gains ISE  {t4:10.5f}   (same cost)",
        f"  beats Table 4      {verdict}",
        f"  gains α1..α12      [{gains}]",
    ]
    if res.check is not None:
        c = res.check
        b = c.bars
        st = "  ".join(
            f"{ax} {c.step[ax]['overshoot_pct']:.2f} % / {c.step[ax]['settling_s']:.2f} s"
            for ax in ("x", "y", "z", "psi")
        )
        rows.append(f"  step response      overshoot / 2 % settling: {st}; max tilt {c.max_tilt_deg:.1f}°")
        rows.append(
            f"  step bars          {'met' if c.meets_bars else 'MISSED'} (overshoot ≤ {b.overshoot_pct:g} %, "
            f"settling ≤ {b.settling_x_s:g} / {b.settling_y_s:g} / {b.settling_z_s:g} / "
            f"{b.settling_psi_s:g} s, tilt ≤ {b.max_tilt_deg:g}°)"
            + ("" if bars is not None else "; not constraints of this tune (--constraints none)")
        )
    rows.append(f"written: {out}   (try: {use or f'swarm-mj run step --gains {out}'})")
    return "\n".join(rows)
