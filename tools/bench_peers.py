"""swarm-mj beside its peers, in one run: learning throughput and time to a first result (issue 30).

**Throughput** (section "peers", when crazyflow is installed: ``pip install -e '.[bench]'``):
64 worlds x 6 drones, one command every 10 ms, in drone-command-steps per second
(worlds x drones x commands / wall time), the three interleaved in every repeat (best of the
repeats; the ratios are the medians of the repeats' own ratios, as in tools/bench.py):

* crazyflow ``Sim(n_worlds=64, n_drones=6, control="state")`` (its Mellinger controller at
  100 Hz, physics at its default 500 Hz, JAX on this machine's CPU): ``state_control`` with a
  constant hover set-point, then ``step(5)`` (five physics steps = 10 ms), the last one waited
  for (``block_until_ready``); its compile time (the first step) is reported apart;
* ``SwarmVectorEnv("circle", num_envs=64)`` with constant U (hover thrust, no torque), on its
  default threads (one per usable CPU) and on one thread (the threads' speed-up, paired);
* the same with the product's ``BacksteppingPolicy``, one per copy, on each copy's observation.

**Time to a first result** (section "first result"): the wall time of a whole new process
that flies six drones for 180 s and writes its log, from the shell prompt to its exit:

* ours: ``python -m swarm_mj.cli run circle -o LOG.rrd`` with EMPTY caches (``NUMBA_CACHE_DIR``
  a new directory: every kernel compiles), and later with the warm cache;
* crazyflow (when installed): :func:`crazyflow_flight` in a new process: ``Sim(1 world, 6
  drones, state control)`` following a circle of the same size at 100 Hz commands for 180 s,
  positions logged at every command and written to a ``.npz``; JAX compiles the step in every
  new process (no persistent compilation cache by default);
* gym-pybullet-drones (when importable): its own example ``python -m gym_pybullet_drones.examples.pid
  --num_drones 6 --gui False --plot False --obstacles False --duration_sec 180`` (PyBullet at its
  default 240 Hz, its DSLPIDControl at 48 Hz, six drones on a circle of way-points, its ``Logger``
  saving the log). It is not on PyPI (``pip install gym-pybullet-drones``: "No matching
  distribution found"); it installs from its git repository (``pybullet`` itself is on PyPI), or its
  source can be put on ``PYTHONPATH``.

    .venv/bin/python tools/bench_peers.py [--quick] [--repeats 3] [--skip throughput first]

``measure(quick)`` returns the rows for ``tools/bench.py`` (its "extra" section).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("SCIPY_ARRAY_API", "1")  # crazyflow needs it before SciPy is first imported

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import _wait_background_compile, _wall, paired  # noqa: E402  (tools/bench.py: one copy of each)

N_WORLDS, N_DRONES = 64, 6
CF_FREQ, CF_CMD_HZ = 500, 100  # crazyflow's physics and state-control frequencies (Hz)
FLIGHT_S = 180.0  # the first-result flight


def has_crazyflow() -> bool:
    return importlib.util.find_spec("crazyflow") is not None


# --------------------------------------------------------------------------- throughput


def throughput(K: int, repeats: int) -> list[dict]:
    """The three throughput rows and the two ratios (module docstring), interleaved ``repeats`` times."""
    from swarm_mj.control.policy import BacksteppingPolicy
    from swarm_mj.scenario import load_scenario
    from swarm_mj.wrappers.vector import SwarmVectorEnv

    sc = load_scenario("circle")
    venv = SwarmVectorEnv(sc, num_envs=N_WORLDS)  # its default threads: one per usable CPU (at most one per block)
    venv1 = SwarmVectorEnv(sc, num_envs=N_WORLDS, threads=1)
    m, n, p = venv.num_envs, venv.n, venv.params
    hover = np.tile([p.hover_thrust, 0.0, 0.0, 0.0], (m, n)).reshape(m, 4 * n)  # (m, 4n)
    policies = [BacksteppingPolicy(sc, p) for _ in range(m)]

    def ours_constant(v=venv) -> float:
        v.reset(seed=0)
        t0 = time.perf_counter()
        for _ in range(K):
            v.step(hover)
        return time.perf_counter() - t0

    def ours_backstepping() -> float:
        obs, _ = venv.reset(seed=0)
        for pol in policies:
            pol.reset()
        U = np.empty((m, 4 * n))
        t0 = time.perf_counter()
        for _ in range(K):
            for i, pol in enumerate(policies):
                U[i] = pol({key: v[i] for key, v in obs.items()}).reshape(-1)
            obs, *_ = venv.step(U)
        return time.perf_counter() - t0

    cf = None
    if has_crazyflow():
        from crazyflow.control import Control
        from crazyflow.sim import Sim

        t0 = time.perf_counter()
        cf = Sim(n_worlds=N_WORLDS, n_drones=N_DRONES, control=Control.state, freq=CF_FREQ, state_freq=CF_CMD_HZ)
        cf.reset()
        cf_build = time.perf_counter() - t0
        cmd = np.zeros((N_WORLDS, N_DRONES, 16))  # x, y, z, v, a, q (x, y, z, w), ω
        cmd[..., 0:3] = np.asarray(cf.data.states.pos) + [0.0, 0.0, 1.0]
        cmd[..., 12] = 1.0
        sub = CF_FREQ // CF_CMD_HZ  # physics steps per command
        t0 = time.perf_counter()
        cf.state_control(cmd)
        cf.step(sub)
        cf.data.states.pos.block_until_ready()
        cf_compile = time.perf_counter() - t0

    def crazyflow_state() -> float:
        cf.reset()
        cf.data.states.pos.block_until_ready()
        t0 = time.perf_counter()
        for _ in range(K):
            cf.state_control(cmd)
            cf.step(sub)
        cf.data.states.pos.block_until_ready()
        return time.perf_counter() - t0

    ours_constant()  # first calls: kernels loaded, threads started
    t_c, t_c1, t_b, t_cf = [], [], [], []
    for _ in range(repeats):
        t_c.append(ours_constant())
        t_c1.append(ours_constant(venv1))
        t_b.append(ours_backstepping())
        if cf is not None:
            t_cf.append(crazyflow_state())
    work = K * m * n  # drone-command-steps
    th = f"threads={venv.threads}"
    venv.close()
    venv1.close()
    rows = [
        {
            "name": f"SwarmVectorEnv('circle', num_envs={m}, {th}), {n} drones, constant U (hover)",
            "ours_s": min(t_c),
            "value": work / min(t_c),
            "unit": "drone-command-steps/s",
            "note": f"{K} commands of 10 ms; best of {repeats}; the default threads (one per usable CPU)",
        },
        {
            "name": f"SwarmVectorEnv('circle', num_envs={m}, threads=1), {n} drones, constant U (hover)",
            "ours_s": min(t_c1),
            "value": work / min(t_c1),
            "unit": "drone-command-steps/s",
            "note": f"{K} commands of 10 ms; best of {repeats}; {th} over threads=1: {paired(t_c1, t_c):.2f}x "
            "(median of the paired repeats; the machine's CPUs are shared with whatever else runs)",
        },
        {
            "name": f"SwarmVectorEnv('circle', num_envs={m}, {th}) + BacksteppingPolicy per copy",
            "ours_s": min(t_b),
            "value": work / min(t_b),
            "unit": "drone-command-steps/s",
            "note": f"{K} commands; best of {repeats}; the policy's share: {1 - min(t_c) / min(t_b):.0%}",
        },
    ]
    if cf is None:
        rows.append({"name": "crazyflow", "note": "skipped: crazyflow is not installed (pip install -e '.[bench]')"})
        return rows
    rows += [
        {
            "name": f"crazyflow Sim({N_WORLDS} worlds x {N_DRONES}), state control, physics {CF_FREQ} Hz",
            "ours_s": min(t_cf),
            "value": work / min(t_cf),
            "unit": "drone-command-steps/s",
            "note": f"{K} commands of 10 ms (step({sub})); JAX on CPU; built in {cf_build:.1f} s, "
            f"first step (compile) {cf_compile:.1f} s; best of {repeats}",
        },
        {
            "name": "crazyflow (state control) / ours (constant U)",
            "value": paired(t_c, t_cf),
            "unit": "x",
            "note": "drone-command-steps/s ratio; median of the paired repeats",
        },
        {
            "name": "crazyflow (state control) / ours (BacksteppingPolicy)",
            "value": paired(t_b, t_cf),
            "unit": "x",
            "note": "drone-command-steps/s ratio; median of the paired repeats",
        },
    ]
    return rows


# --------------------------------------------------------------------------- first result


def crazyflow_flight(out: str, duration: float = FLIGHT_S) -> None:
    """One world of six crazyflow drones following a circle of radius 2 m at 1 m height (period 30 s,
    each drone on its own phase) by state control at 100 Hz for ``duration`` s; positions (K, 6, 3) and
    times (K,) written to ``out`` (.npz). What a crazyflow user runs to get a first log."""
    from crazyflow.control import Control
    from crazyflow.sim import Sim

    sim = Sim(n_worlds=1, n_drones=N_DRONES, control=Control.state, freq=CF_FREQ, state_freq=CF_CMD_HZ)
    sim.reset()
    K = int(round(duration * CF_CMD_HZ))
    sub = CF_FREQ // CF_CMD_HZ
    phase = 2 * np.pi * np.arange(N_DRONES) / N_DRONES  # (6,)
    w = 2 * np.pi / 30.0
    cmd = np.zeros((1, N_DRONES, 16))
    cmd[..., 12] = 1.0
    log = np.empty((K, N_DRONES, 3))
    for k in range(K):
        t = k / CF_CMD_HZ
        a = w * t + phase
        cmd[0, :, 0], cmd[0, :, 1], cmd[0, :, 2] = 2.0 * np.cos(a), 2.0 * np.sin(a), 1.0
        cmd[0, :, 3], cmd[0, :, 4] = -2.0 * w * np.sin(a), 2.0 * w * np.cos(a)
        sim.state_control(cmd)
        sim.step(sub)
        log[k] = np.asarray(sim.data.states.pos[0])
    np.savez(out, t=np.arange(1, K + 1) / CF_CMD_HZ, pos=log)


def first_result(duration: float, repeats: int) -> list[dict]:
    """Wall time of a new process that flies six drones for ``duration`` s and writes its log."""
    py, base = sys.executable, {**os.environ}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ours = [py, "-m", "swarm_mj.cli", "run", "circle", "--quiet", "--duration", f"{duration:g}"]
        cold = []
        for i in range(repeats):
            cache = Path(tmp) / f"numba{i}"
            cache.mkdir()
            cold.append(_wall(ours + ["-o", f"cold{i}.rrd"], {**base, "NUMBA_CACHE_DIR": str(cache)}, tmp))
            _wait_background_compile()  # the fused path compiles in the background after a first run
        _wall(ours + ["-o", "warm0.rrd"], base, tmp)  # the user's own cache, warm
        warm = [_wall(ours + ["-o", f"warm{i + 1}.rrd"], base, tmp) for i in range(repeats)]
        rows.append(
            {
                "name": f"ours: run circle ({duration:g} s, 6 drones) with its log, EMPTY caches",
                "ours_s": min(cold),
                "value": min(cold),
                "unit": "s",
                "note": f"a new process, NUMBA_CACHE_DIR empty (every kernel compiles); best of {repeats}",
            }
        )
        rows.append(
            {
                "name": f"ours: run circle ({duration:g} s, 6 drones) with its log, later (warm cache)",
                "ours_s": min(warm),
                "value": min(warm),
                "unit": "s",
                "note": f"best of {repeats}",
            }
        )
        if has_crazyflow():
            cf = [py, str(Path(__file__).resolve()), "--crazyflow-flight", "cf.npz", "--duration", f"{duration:g}"]
            t_cf = [_wall(cf, base, tmp) for _ in range(repeats)]
            rows.append(
                {
                    "name": f"crazyflow: 1 world x 6 drones, state control, {duration:g} s, log to .npz",
                    "ours_s": min(t_cf),
                    "value": min(t_cf),
                    "unit": "s",
                    "note": f"a new process (JAX compiles in each); {min(t_cf) / min(warm):.1f}x ours later, "
                    f"{min(t_cf) / min(cold):.1f}x ours on empty caches; best of {repeats}",
                }
            )
        else:
            rows.append({"name": "crazyflow first result", "note": "skipped: crazyflow is not installed"})
        if importlib.util.find_spec("gym_pybullet_drones") is not None:
            gpd = [py, "-m", "gym_pybullet_drones.examples.pid", "--num_drones", str(N_DRONES), "--gui", "False"]
            gpd += ["--plot", "False", "--obstacles", "False", "--duration_sec", f"{duration:g}"]
            t_gpd = [_wall(gpd + ["--output_folder", f"gpd{i}"], base, tmp) for i in range(repeats)]
            rows.append(
                {
                    "name": f"gym-pybullet-drones: examples.pid, 6 drones, {duration:g} s, its Logger's log",
                    "ours_s": min(t_gpd),
                    "value": min(t_gpd),
                    "unit": "s",
                    "note": f"a new process; PyBullet 240 Hz, PID at 48 Hz; {min(t_gpd) / min(warm):.1f}x ours later; "
                    f"best of {repeats}",
                }
            )
        else:
            rows.append(
                {
                    "name": "gym-pybullet-drones first result",
                    "note": "not measured: not importable (not on PyPI; install it from its git repository)",
                }
            )
    return rows


# --------------------------------------------------------------------------- entry points


def measure(quick: bool = False, repeats: int | None = None, skip: tuple[str, ...] = ()) -> list[dict]:
    """Rows for tools/bench.py ("extra"): throughput, then the first-result processes."""
    r = repeats or (1 if quick else 3)
    rows = []
    if "throughput" not in skip:
        rows += [{"section": "peers", **x} for x in throughput(100 if quick else 500, r)]
    if "first" not in skip:
        rows += [{"section": "first result", **x} for x in first_result(30.0 if quick else FLIGHT_S, r)]
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer commands, 30-s flights, one repeat")
    ap.add_argument("--repeats", type=int, default=None, help="repeats (default 3; 1 with --quick)")
    ap.add_argument("--skip", nargs="+", default=[], choices=("throughput", "first"), help="parts to leave out")
    ap.add_argument("--crazyflow-flight", metavar="OUT", help=argparse.SUPPRESS)  # the first-result process
    ap.add_argument("--duration", type=float, default=FLIGHT_S, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.crazyflow_flight:
        crazyflow_flight(args.crazyflow_flight, args.duration)
        return 0
    if args.repeats is not None and args.repeats < 1:
        ap.error("--repeats must be >= 1")
    for r in measure(args.quick, args.repeats, tuple(args.skip)):
        v = f"{r['value']:,.1f} {r.get('unit', '')}" if r.get("value") is not None else ""
        print(f"  {r['section']:<13} {r['name']:<78} {v:>30}  {r.get('note', '')}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
