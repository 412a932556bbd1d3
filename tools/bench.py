"""Every performance figure of swarm-mj, each beside a baseline measured in the same run.

The baseline is raw ``mujoco.mj_step`` on the same compiled model (ctrl at hover thrust, a
constant ``xfrc_applied``, the drones in the air), doing the same number of physics steps, with
MuJoCo's profiling clock off as in our own steps (``swarm_mj.physics._mjstep.timer_pause``: the Python
bindings' default clock costs about a tenth of a step, so the baseline is MuJoCo at its fastest);
each row gives our time and the raw time for the same simulated work (the best of 5 repeats each,
ours and raw interleaved) and their ratio ("× raw": how many times the raw physics' time ours
takes; 1.0 would be free). In the core, runs, vector and scaling rows the ratio is the median of the
repeats' own ratios (:func:`paired`): this machine kind changes speed from one second to the next.
Rows:

* machine: CPU model (/proc/cpuinfo), cores, Python / MuJoCo / NumPy / Numba versions;
* core: ``Sim.step`` (saturation, drag, external force, contacts) on 6 drones;
* runs: real-time factor of ``runner.run`` for ``lemniscate_single`` and ``circle`` (180 s;
  30 s with --quick), without and with recording (``recording.write_recording`` to a temp
  file; overhead in %), and step by step (``fused=False``: the ordinary path the fused one,
  swarm_mj/pipeline/fast.py, is compared with; the bench compiles the chunk driver before it starts);
* env: ``SwarmEnv`` steps per second, random U near hover and with ``BacksteppingPolicy``;
* vector: ``SwarmVectorEnv`` with 64 copies of the six-drone circle, random U near hover, in
  drone-steps per second, with its default threads (one per usable CPU, at most one per block)
  and with one thread, against raw mj_step on the same batched models (its blocks, one thread),
  the threads' speed-up (the median of the paired repeats), beside ``SwarmEnv`` stepping one
  swarm at a time (against raw mj_step on its own model);
* startup: wall time of ``python -m swarm_mj.cli run circle`` in a fresh process: start-up
  (``--duration 0.1 --no-record``; baseline: a process that only imports mujoco and numpy), the
  whole 180-s run with recording with a warm Numba cache, and the same with an EMPTY Numba
  cache (``NUMBA_CACHE_DIR`` pointed at a new temporary directory: every kernel compiles; the
  fused path compiles in a background process, whose time is reported, and the run after it);
* tuning: ``tuning.cost.tune_gains`` (paper Table 2: population 50, 14 iterations) on one
  thread, on one thread per CPU and on one worker process per CPU (the default; speed-up);
  baseline: raw mj_step on a 10-copy model (the cost's block size) for the same drone-seconds;
* video: ``video.render_video`` frames per second (640x360, H.264), beside a bare
  ``mujoco.Renderer`` on the same model (if rendering is available);
* scaling: ``runner.run`` of a circle with N = 6, 25, 100 drones (followers starting on
  their slots of an (N−1)-gon, adjacent slots ≥ 1.2 m apart), wall time per simulated
  second, beside raw mj_step on the same model (interleaved);
* aero: ``runner.run`` of the six-drone circle under the ``realistic`` physics preset (ground,
  downwash, ground effect, rotor lag; docs/aero.md) beside the same run under ``paper``, wall
  time of the loop per simulated second (the "raw" column is the paper run; bar: 1.3×; at least
  5 interleaved repeats, the best of each);
* barrier: ``runner.run`` of the six-drone circle under ``realistic`` with ``--anti-collision
  barrier`` beside the same run with ``jet-aware`` (the "raw" column), wall time of the loop; the
  ratio is the median of the paired repeats' ``barrier / jet-aware`` (issue 29's bar: 1.3×);
* sensing: the same circle with ``barrier`` under the ``mocap`` sensing model beside ``perfect`` (the
  "raw" column), the median paired ratio (issue 49's bar: 1.15× on the chunk driver; docs/sensing.md,
  "Cost"), and the chunk driver's own time per period under each.

``tools/bench_peers.py`` adds swarm-mj beside its peers: crazyflow's ``Sim`` (64 worlds x 6 drones,
state control) beside ``SwarmVectorEnv(64)`` with constant commands and with the backstepping
policy, and the time to a first result (a new process flying six drones for 180 s and writing its
log: ours on empty caches and later, crazyflow); the crazyflow rows run when it is installed
(``pip install -e '.[bench]'``).

If ``tools/bench_tune.py``, ``bench_video.py``, ``bench_env.py``, ``bench_core.py`` or ``bench_peers.py``
defines ``measure(quick: bool) -> list[dict]`` (rows with the keys below), its rows are
added under "extra".

    .venv/bin/python tools/bench.py [--quick] [--json PATH] [--skip tuning video ...]

Prints the rows as they come, then a Markdown table; ``--json`` writes the same rows.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import os
import sys
import tempfile
import time
from pathlib import Path

# crazyflow (tools/bench_peers.py) must find SciPy's array API on, which is read when SciPy is first
# imported (by a dependency of swarm_mj); swarm_mj itself does not use SciPy.
os.environ.setdefault("SCIPY_ARRAY_API", "1")

# isort: off
import swarm_mj  # noqa: F401  (first: it sets MUJOCO_GL before mujoco is imported)
import mujoco
import numpy as np
# isort: on

from swarm_mj.physics._mjstep import profiler_paused

SECTIONS = ("core", "runs", "env", "vector", "startup", "tuning", "video", "scaling", "aero", "barrier", "sensing")
ROWS: list[dict] = []


def row(
    section: str,
    name: str,
    ours_s: float | None,
    raw_s: float | None,
    *,
    value: float | None = None,
    unit: str = "",
    note: str = "",
    ratio: float | None = None,
    **extra,
) -> dict:
    """One figure: our wall time and the raw baseline's for the same work, and a headline value.
    ``ratio``: when given (a median of paired repeats, :func:`paired`), instead of ours / raw."""
    r = {
        "section": section,
        "name": name,
        "value": value,
        "unit": unit,
        "ours_s": ours_s,
        "raw_s": raw_s,
        "ratio": ratio if ratio is not None else (ours_s / raw_s) if (ours_s and raw_s) else None,
        "note": note,
        **extra,
    }
    ROWS.append(r)
    v = f"{value:,.1f} {unit}" if value is not None else ""
    rat = f"{r['ratio']:.2f}× raw" if r["ratio"] is not None else ""
    print(f"  {section:<8} {name:<52} {v:>22} {rat:>12}  {note}", flush=True)
    return r


# --------------------------------------------------------------------------- machine


def machine() -> dict:
    """The machine (swarm_mj.experiments.parallel.machine_description) plus Numba and the load average."""
    from swarm_mj import _jit
    from swarm_mj.experiments.parallel import machine_description

    try:
        import numba

        nb = numba.__version__
    except ImportError:
        nb = None
    return {
        **machine_description(),
        "numba": nb,
        "jit": bool(_jit.AVAILABLE),
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
    }


def paired(ours: list[float], raw: list[float]) -> float:
    """The median over repeats of ours / raw, each pair measured back to back.

    This machine kind changes speed by up to 2× from one second to the next (the same raw
    ``mj_step`` loop: 0.69–1.16 s), so the best of ours over the best of raw can pair a fast moment
    with a slow one; a ratio taken within each repeat shares its moment, and the median of them
    is what the ratio rows report (the best-of times stay in ``ours_s``, ``raw_s``)."""
    return float(np.median(np.asarray(ours, float) / np.asarray(raw, float)))


# --------------------------------------------------------------------------- raw baseline


def raw_seconds(world, n_steps: int, *, lift: float = 2.0, clock: bool = False) -> float:
    """Wall time of ``n_steps`` raw mj_step on ``world.model`` from its initial state with the
    drones lifted to ``lift`` m (no floor contact): hover ctrl, a constant external force.
    ``clock``: with MuJoCo's profiling clock as the Python bindings leave it (on), not paused."""
    model = world.model
    d = mujoco.MjData(model)
    n = world.n_drones
    q = d.qpos.reshape(n, 7)
    q[:, 2] = np.maximum(q[:, 2], lift)
    d.ctrl[:] = np.tile([world.params.hover_thrust, 0.0, 0.0, 0.0], n)
    d.xfrc_applied[world.body_ids, 0:3] = (0.05, -0.03, 0.0)
    mujoco.mj_forward(model, d)
    step = mujoco.mj_step
    # paused as our runs step (swarm_mj/physics/_mjstep.py): the baseline is MuJoCo at its fastest
    with contextlib.nullcontext() if clock else profiler_paused():
        t0 = time.perf_counter()
        for _ in range(n_steps):
            step(model, d)
        return time.perf_counter() - t0


def raw_threads_seconds(worlds: list, n_steps: int, threads: int) -> float:
    """Wall time of :func:`raw_seconds` of every world, the worlds in ``threads`` contiguous groups, each group
    on its own thread (:class:`swarm_mj.experiments.parallel.ThreadTeam`, as the vector env splits its blocks):
    the ceiling of the vector env's threads on this machine at this moment (MuJoCo releases the GIL in
    ``mj_step``)."""
    from swarm_mj.experiments.parallel import ThreadTeam

    groups = [[worlds[int(j)] for j in g] for g in np.array_split(np.arange(len(worlds)), threads)]
    # the profiling clock is one global: paused once here, so each thread's raw_seconds finds it paused
    with ThreadTeam(threads, "bench-raw") as team, profiler_paused():
        t0 = time.perf_counter()
        team.run(lambda g: [raw_seconds(w, n_steps) for w in g], groups)
        return time.perf_counter() - t0


# --------------------------------------------------------------------------- sections


def bench_core(quick: bool, repeats: int) -> None:
    from swarm_mj.physics.sim import Sim
    from swarm_mj.physics.world import build_world

    n = 6
    world = build_world(n, positions=np.column_stack([2.0 * np.arange(n), np.zeros(n), np.full(n, 2.0)]))
    sim = Sim(world)
    U = np.tile([world.params.hover_thrust, 0.0, 0.0, 0.0], (n, 1))
    F = np.array([0.05, -0.03, 0.0])
    n_ctrl = int((5.0 if quick else 10.0) / sim.control_period)
    ours, raw = [], []
    for _ in range(min(n_ctrl, 100)):  # warm-up (JIT cache load)
        sim.step(U, F)
    for _ in range(repeats):
        sim.reset()
        t0 = time.perf_counter()
        for _ in range(n_ctrl):
            sim.step(U, F)
        ours.append(time.perf_counter() - t0)
        raw.append(raw_seconds(world, n_ctrl * sim.n_substeps))
    sim_s = n_ctrl * sim.control_period
    row(
        "core",
        f"Sim.step, {n} drones ({sim_s:g} s simulated)",
        min(ours),
        min(raw),
        value=sim_s / min(ours),
        unit="× real time",
        note=f"raw mj_step {sim_s / min(raw):,.0f}× real time; best of {repeats}; ratio: median of the paired repeats",
        ratio=paired(ours, raw),
    )


def bench_runs(quick: bool, repeats: int) -> None:
    from swarm_mj.experiments.runner import run
    from swarm_mj.output.recording import write_recording
    from swarm_mj.scenario import load_scenario

    dur = 30.0 if quick else 180.0
    for name in ("lemniscate_single", "circle"):
        sc = load_scenario(name).with_overrides(duration=dur)
        warm = run(sc.with_overrides(duration=1.0), progress=False)  # warm-up (JIT cache, imports,
        with tempfile.TemporaryDirectory() as tmp:  # the recorder's start-up)
            write_recording(warm, Path(tmp) / "warm.rrd")
        t_run, t_rec, t_raw, t_step, t_clock = [], [], [], [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = run(sc, progress=False)
            t_run.append(time.perf_counter() - t0)
            fused_share = res.extra.get("fused_periods", 0) / max(len(res.log.t) - 1, 1)
            t0 = time.perf_counter()
            run(sc, progress=False, fused=False)
            t_step.append(time.perf_counter() - t0)
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                write_recording(res, Path(tmp) / f"{name}.rrd")
                t_rec.append(time.perf_counter() - t0)
            from swarm_mj.physics.world import build_world

            w = build_world(
                sc.n_drones, positions=sc.initial_positions(), timestep=sc.timestep, integrator=sc.integrator
            )
            n_phys = int(round(dur / sc.timestep))
            t_raw.append(raw_seconds(w, n_phys))
            t_clock.append(raw_seconds(w, n_phys, clock=True))
        a, r, raw, st, rc = min(t_run), min(t_rec), min(t_raw), min(t_step), min(t_clock)
        with_rec = [x + y for x, y in zip(t_run, t_rec)]
        label = f"{name} ({sc.n_drones} drone{'s' if sc.n_drones > 1 else ''}, {dur:g} s)"
        row(
            "runs",
            f"runner.run {label}",
            a,
            raw,
            value=dur / a,
            unit="× real time",
            note=f"raw mj_step {dur / raw:,.0f}× real time; {100 * fused_share:.0f} % of the periods fused; "
            f"best of {repeats}; ratio: median of the paired repeats",
            ratio=paired(t_run, t_raw),
        )
        row(
            "runs",
            f"runner.run {label}, step by step (fused=False)",
            st,
            raw,
            value=dur / st,
            unit="× real time",
            note=f"the ordinary path; the fused one is {st / a:.2f}× faster",
            ratio=paired(t_step, t_raw),
        )
        row(
            "runs",
            f"runner.run + recording {label}",
            a + r,
            raw,
            value=dur / (a + r),
            unit="× real time",
            note=f"recording overhead {100 * r / a:.0f} % (write_recording {r:.2f} s); "
            f"{paired(with_rec, t_clock):.2f}× raw mj_step with the bindings' profiling clock on "
            f"({dur / rc:,.0f}× real time)",
            recording_overhead_pct=100 * r / a,
            ratio=paired(with_rec, t_raw),
            ratio_raw_clock_on=paired(with_rec, t_clock),
        )


def bench_env(quick: bool, repeats: int) -> None:
    from swarm_mj.control.policy import BacksteppingPolicy
    from swarm_mj.env import SwarmEnv
    from swarm_mj.scenario import load_scenario

    secs = 5.0 if quick else 10.0
    sc = load_scenario("circle").with_overrides(duration=secs)
    env = SwarmEnv(sc, terminate_on_contact=False)
    n, K, nsub = env.n, env.n_steps, env.sim.n_substeps
    p = env.params
    rng = np.random.default_rng(0)
    U = np.empty((K, n, 4))
    U[..., 0] = p.hover_thrust * rng.uniform(0.95, 1.10, (K, n))
    U[..., 1:] = rng.uniform(-0.002, 0.002, (K, n, 3))
    t_rand, t_pol, t_raw = [], [], []
    for _ in range(repeats):
        env.reset()
        t0 = time.perf_counter()
        k = 0
        while k < K:
            ts = env.step(U[k])
            k += 1
            if ts.last():
                env.reset()
        t_rand.append(time.perf_counter() - t0)
        pol = BacksteppingPolicy(sc, env.params)
        ts = env.reset()
        t0 = time.perf_counter()
        for _ in range(K):
            ts = env.step(pol(ts.observation))
            if ts.last():
                break
        t_pol.append(time.perf_counter() - t0)
        t_raw.append(raw_seconds(env.world, K * nsub))
    raw = min(t_raw)
    row(
        "env",
        f"SwarmEnv.step, random U near hover ({n} drones)",
        min(t_rand),
        raw,
        value=K / min(t_rand),
        unit="steps/s",
        note=f"raw mj_step {K / raw:,.0f} env-steps/s ({nsub} mj_step each)",
    )
    row(
        "env", f"SwarmEnv.step + BacksteppingPolicy ({n} drones)", min(t_pol), raw, value=K / min(t_pol), unit="steps/s"
    )


def bench_vector(quick: bool, repeats: int, num_envs: int = 64) -> None:
    from swarm_mj.env import SwarmEnv
    from swarm_mj.experiments.parallel import default_workers
    from swarm_mj.scenario import load_scenario
    from swarm_mj.wrappers.vector import SwarmVectorEnv

    K = 100 if quick else 300
    sc = load_scenario("circle")
    t0 = time.perf_counter()
    venv = SwarmVectorEnv(sc, num_envs=num_envs)  # the default: one thread per usable CPU (at most one per block)
    build = time.perf_counter() - t0
    one = SwarmVectorEnv(sc, num_envs=num_envs, threads=1) if venv.threads > 1 else venv
    m, n, nsub = venv.num_envs, venv.n, venv._blocks[0].sim.n_substeps
    p = venv.params
    rng = np.random.default_rng(0)
    U = np.empty((K, m, n, 4))
    U[..., 0] = p.hover_thrust * rng.uniform(0.95, 1.10, (K, m, n))
    U[..., 1:] = rng.uniform(-0.002, 0.002, (K, m, n, 3))
    U = U.reshape(K, m, 4 * n)
    env = SwarmEnv(sc, terminate_on_contact=False)

    def fly(v) -> float:
        v.reset(seed=0)
        v.step(U[0])  # first call: kernels loaded, threads started
        t0 = time.perf_counter()
        for k in range(K):
            v.step(U[k])
        return time.perf_counter() - t0

    worlds = [blk.sim.world for blk in venv._blocks]
    t_vec, t_one_thread, t_raw, t_raw1, t_rawT, t_one, t_one_raw = [], [], [], [], [], [], []
    for _ in range(repeats):
        t_vec.append(fly(venv))
        t_one_thread.append(fly(one) if one is not venv else t_vec[-1])
        t_raw.append(sum(raw_seconds(w, K * nsub) for w in worlds))
        if one is not venv:  # the same raw steps on 1 thread and on the env's threads, back to back
            t_raw1.append(raw_threads_seconds(worlds, K * nsub, 1))
            t_rawT.append(raw_threads_seconds(worlds, K * nsub, venv.threads))
        env.reset()
        t0 = time.perf_counter()
        for k in range(K):
            env.step(U[k, 0].reshape(n, 4))
        t_one.append(time.perf_counter() - t0)
        t_one_raw.append(raw_seconds(env.world, K * nsub))
    r = min(t_raw)
    blocks = sorted({blk.b for blk in venv._blocks})
    raw_note = (
        f"raw mj_step on the same {len(venv._blocks)} models ({blocks} copies each, one thread) "
        f"{K * m * n / r:,.0f} drone-steps/s; built in {build:.1f} s; best of {repeats}; "
        "ratio: median of the paired repeats"
    )
    variants = [(venv, t_vec)] + ([(one, t_one_thread)] if one is not venv else [])
    for v, t in variants:
        threads = f"{v.threads} thread{'s' if v.threads > 1 else ''}"
        row(
            "vector",
            f"SwarmVectorEnv, {m} x {n} drones, random U near hover, {threads}",
            min(t),
            r,
            value=K * m * n / min(t),
            unit="drone-steps/s",
            note=raw_note + ("" if v is one else " (the default threads; blocks stepped on threads)"),
            ratio=paired(t, t_raw),
        )
    if one is not venv:
        each = ", ".join(f"{a / b:.2f}" for a, b in zip(t_one_thread, t_vec))
        row(
            "vector",
            f"vector env threads: {venv.threads} threads over 1 thread ({m} x {n} drones)",
            None,
            None,
            value=paired(t_one_thread, t_vec),
            unit="x",
            note=f"drone-steps/s speed-up, median of the paired repeats ({each}); raw mj_step on the same models, "
            f"the blocks split the same way: {paired(t_raw1, t_rawT):.2f}x (the ceiling here and now); "
            f"{default_workers()} usable CPUs, shared with whatever else runs on the machine",
        )
    o, orw = min(t_one), min(t_one_raw)
    row(
        "vector",
        f"SwarmEnv one swarm at a time ({n} drones), random U near hover",
        o,
        orw,
        value=K * n / o,
        unit="drone-steps/s",
        note=f"raw mj_step on its model {K * n / orw:,.0f} drone-steps/s; "
        f"the vector env (1 thread): {K * m * n / min(t_one_thread) / (K * n / o):.1f}x its drone-steps/s",
        ratio=paired(t_one, t_one_raw),
    )
    venv.close()
    one.close()


def _wall(cmd: list[str], env: dict | None = None, cwd: str | None = None) -> float:
    import subprocess

    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def bench_startup(quick: bool, repeats: int) -> None:
    py = sys.executable
    base = {**os.environ}
    cli = [py, "-m", "swarm_mj.cli", "run", "circle", "--quiet"]
    with tempfile.TemporaryDirectory() as tmp:
        _wall(cli + ["--duration", "0.1", "--no-record"], base, tmp)  # warm the cache and the disk
        t_start = min(_wall(cli + ["--duration", "0.1", "--no-record"], base, tmp) for _ in range(repeats))
        t_bare = min(_wall([py, "-c", "import mujoco, numpy"], base, tmp) for _ in range(repeats))
        t_imp = min(
            _wall([py, "-c", "import swarm_mj.cli, swarm_mj.experiments.runner, swarm_mj.output.recording"], base, tmp)
            for _ in range(repeats)
        )
        row(
            "startup",
            "start-up: run circle --duration 0.1 --no-record (warm cache)",
            t_start,
            t_bare,
            value=t_start,
            unit="s",
            note=f"baseline: a process importing mujoco + numpy ({t_bare:.2f} s); "
            f"importing swarm_mj's CLI, runner, recording: {t_imp:.2f} s",
        )
        full = cli + ([] if not quick else ["--duration", "30"])
        t_warm = min(_wall(full + ["-o", str(Path(tmp) / "w.rrd")], base, tmp) for _ in range(repeats))
        cold, background, second = [], [], []
        for i in range(max(1, min(repeats, 2))):
            cache = Path(tmp) / f"numba{i}"
            cache.mkdir()
            env = {**base, "NUMBA_CACHE_DIR": str(cache)}
            cold.append(_wall(full + ["-o", str(Path(tmp) / "c.rrd")], env, tmp))
            background.append(_wait_background_compile())  # the fused path, started by that first run
            second.append(_wall(full + ["-o", str(Path(tmp) / "c2.rrd")], env, tmp))
        what = "run circle" + (" --duration 30" if quick else "") + " with recording"
        row(
            "startup",
            f"first {what}, EMPTY Numba cache",
            min(cold),
            t_warm,
            value=min(cold),
            unit="s",
            note=f"ratio: against the same run with a warm cache ({t_warm:.2f} s); the fused path then "
            f"compiled in the background for {min(background):.0f} s more",
        )
        row(
            "startup",
            f"second {what} after an empty cache (the fused path compiled)",
            min(second),
            t_warm,
            value=min(second),
            unit="s",
            note="ratio: against the same run with a warm cache",
        )
        row("startup", f"later {what} (warm cache)", t_warm, None, value=t_warm, unit="s")


def _wait_background_compile(limit_s: float = 300.0) -> float:
    """Seconds until no background compile of the fused path (its lock file) is left, at most ``limit_s``."""
    t0 = time.perf_counter()
    locks = Path(tempfile.gettempdir()).glob
    while any(locks("swarm_mj-fast-*.lock")) and time.perf_counter() - t0 < limit_s:
        time.sleep(0.25)
    return time.perf_counter() - t0


def bench_tuning(quick: bool, repeats: int) -> None:
    from swarm_mj.physics.world import build_world
    from swarm_mj.tuning.cost import StepCostSettings, TuneOptions, default_workers, tune_gains

    pop, iters = (20, 2) if quick else (50, 14)
    opts = TuneOptions(population=pop, iterations=iters, seed=1)
    settings = StepCostSettings()
    evals = pop * (iters + 1) + 1  # + the Table 4 reference
    drone_s = evals * settings.t_sim
    block = 10
    w = build_world(
        block, positions=np.column_stack([np.zeros(block), np.zeros(block), np.full(block, 2.0)]), collisions=False
    )
    probe_s = 5.0 if quick else 20.0
    t_probe = raw_seconds(w, int(probe_s / settings.timestep))
    raw_equiv = t_probe * drone_s / (block * probe_s)
    nw = default_workers()
    # 1 thread in this process; one thread per CPU in this process; the default (one process per CPU)
    configs = {"1 thread": {"workers": 1, "threads": 1}}
    if nw > 1:
        configs[f"{nw} threads"] = {"workers": 1, "threads": nw}
        configs[f"{nw} worker processes (default)"] = {}
    times, cpu = {}, {}
    for label, kw in configs.items():
        t0, c0 = time.perf_counter(), time.process_time()
        out = tune_gains(opts, settings, **kw)
        times[label], cpu[label] = time.perf_counter() - t0, time.process_time() - c0
        row(
            "tuning",
            f"tune_gains N={pop}, {iters} it., {label}",
            times[label],
            raw_equiv,
            value=evals / times[label],
            unit="ISE evals/s",
            note=f"{times[label]:.1f} s (CPU of this process {cpu[label]:.1f} s); best ISE {out.best_ise:.10g} "
            f"({out.backend})",
        )
    if nw > 1:
        row(
            "tuning",
            f"tune speed-up, {nw} worker processes (default) vs 1 thread",
            None,
            None,
            value=times["1 thread"] / times[f"{nw} worker processes (default)"],
            unit="×",
            note=f"ideal {nw}×; {nw} threads in this process: {times['1 thread'] / times[f'{nw} threads']:.2f}×",
        )
    else:
        row("tuning", "tune speed-up", None, None, note="one CPU: no speed-up to measure")
    best = min(times.values())
    # Speed-up over evaluating candidates one at a time with the product's loop (tools/bench_tune.py).
    bt = _load_tool("bench_tune")
    if bt is None or not hasattr(bt, "runner_ise"):
        row(
            "tuning",
            "speed-up over runner.run per candidate",
            None,
            None,
            note="skipped: tools/bench_tune.py (runner_ise) not found",
        )
        return
    rng = np.random.default_rng(1)
    sample = rng.uniform(opts.lower, opts.upper, (2 if quick else 5, 12))
    t0 = time.perf_counter()
    for g in sample:
        bt.runner_ise(g, settings)
    per = (time.perf_counter() - t0) / len(sample)
    one_by_one = per * evals
    row(
        "tuning",
        f"one at a time: runner.run per candidate, x{evals} (extrapolated)",
        one_by_one,
        raw_equiv,
        value=one_by_one / best,
        unit="× slower than the tune",
        note=f"{per:.3f} s per candidate over {len(sample)}; the batched tune (fastest of the above) is "
        f"{one_by_one / best:.1f}× faster",
    )
    # The stricter baseline: the tune's own evaluator flying one copy per model (batching alone).
    from swarm_mj.tuning.cost import evaluate_batch

    evaluate_batch(sample[:1], settings)  # builds the 1-copy model
    t0 = time.perf_counter()
    for g in sample:
        evaluate_batch(g[None], settings)
    per1 = (time.perf_counter() - t0) / len(sample)
    alone = per1 * evals
    row(
        "tuning",
        f"one at a time: the tune's evaluator, one copy per model, x{evals} (extrapolated)",
        alone,
        raw_equiv,
        value=alone / best,
        unit="× slower than the tune",
        note=f"{per1 * 1e3:.1f} ms per candidate over {len(sample)}; batching alone (1 thread): "
        f"{alone / times['1 thread']:.1f}×",
    )


def bench_video(quick: bool, repeats: int) -> None:
    try:
        from swarm_mj.video import render_video
    except ImportError as exc:
        row("video", "render_video", None, None, note=f"skipped: swarm_mj.video unavailable ({exc})")
        return
    from swarm_mj.experiments.runner import run

    res = run("circle", duration=6.0, progress=False)
    frames = 30 if quick else 90
    fps = 30.0
    size = (640, 360)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            render_video(
                res, Path(tmp) / "b.mp4", fps=fps, size=size, start=1.0, end=1.0 + frames / fps, progress=False
            )
            t_vid = time.perf_counter() - t0
        from swarm_mj.physics.world import build_world

        sc = res.scenario
        w = build_world(sc.n_drones, positions=sc.initial_positions())
        d = mujoco.MjData(w.model)
        r = mujoco.Renderer(w.model, height=size[1], width=size[0])
        mujoco.mj_forward(w.model, d)
        r.update_scene(d)
        r.render()
        t0 = time.perf_counter()
        for k in range(frames):
            d.qpos[2::7] = 1.0 + 0.01 * k
            mujoco.mj_forward(w.model, d)
            r.update_scene(d)
            r.render()
        t_raw = time.perf_counter() - t0
        r.close()
    except Exception as exc:  # noqa: BLE001 - no EGL on this machine
        row("video", "render_video", None, None, note=f"skipped: {type(exc).__name__}: {exc}")
        return
    row(
        "video",
        f"render_video {size[0]}x{size[1]} H.264 ({frames} frames)",
        t_vid,
        t_raw,
        value=frames / t_vid,
        unit="frames/s",
        note=f"baseline: bare mujoco.Renderer {frames / t_raw:,.0f} frames/s "
        f"(not mj_step); {frames / t_vid / fps:.2f}× playback speed",
    )


def polygon_scenario(n_drones: int, duration: float, rule: str = "paper"):
    """Circle with n_drones: followers start on the ground on their slots, adjacent slots >= 1.2 m apart."""
    from swarm_mj.formation.slots import polygon_offsets
    from swarm_mj.scenario import parse_scenario

    nf = n_drones - 1
    D = max(1.0, 0.6 / np.sin(np.pi / nf)) if nf > 1 else 1.0
    leader = np.array([0.0, 2.5, 0.0])
    starts = leader + polygon_offsets(nf, D)
    data = {
        "duration": float(duration),
        "leader": {"trajectory": "circle", "start": leader.tolist()},
        "followers": {"start": starts.tolist()},
        "formation": {"diameter": float(D), "anti_collision": rule},
    }
    return parse_scenario(data, "<bench>", name=f"polygon{n_drones}"), D


def bench_scaling(quick: bool, repeats: int, sizes=(6, 25, 100)) -> None:
    from swarm_mj.experiments.runner import run
    from swarm_mj.physics.world import build_world

    dur = 2.0 if quick else 10.0
    for n in sizes:
        sc, D = polygon_scenario(n, dur)
        w = build_world(n, positions=sc.initial_positions())
        loops, raws, setups, clocks = [], [], [], []
        for _ in range(repeats):  # interleaved: the same machine load for both
            t0 = time.perf_counter()
            res = run(sc, progress=False)
            wall = time.perf_counter() - t0
            setups.append(wall - res.summary["wall_time_s"])
            loops.append(res.summary["wall_time_s"])
            raws.append(raw_seconds(w, int(round(dur / sc.timestep))))
            clocks.append(raw_seconds(w, int(round(dur / sc.timestep)), clock=True))
        loop, raw, setup = min(loops), min(raws), min(setups)
        row(
            "scaling",
            f"{n} drones: runner.run per simulated second",
            loop / dur,
            raw / dur,
            value=1000 * loop / dur,
            unit="ms per sim s",
            ratio=paired(loops, raws),
            ratio_raw_clock_on=paired(loops, clocks),
            note=f"{1000 * loop / dur / n:.1f} ms per drone; raw {1000 * raw / dur:,.0f} ms; set-up {setup:.2f} s; "
            f"D = {D:.1f} m; contacts {res.summary['contacts']}; best of {repeats}; ratio: median of the paired repeats; "
            f"{paired(loops, clocks):.2f}× raw mj_step with the bindings' profiling clock on"
            + (f"; STOPPED {res.summary['stopped']}" if res.summary.get("stopped") else ""),
            n_drones=n,
        )


def bench_aero(quick: bool, repeats: int) -> None:
    """The realistic physics preset's cost over the paper's, per simulated second (circle, 6 drones)."""
    from swarm_mj.experiments.runner import run
    from swarm_mj.scenario import load_scenario

    dur = 30.0 if quick else 60.0
    repeats = max(repeats, 5)  # a ratio of two noisy times: the best of more interleaved repeats
    sc = load_scenario("circle").with_overrides(duration=dur)
    for aero in ("paper", "realistic"):
        run(sc.with_overrides(duration=1.0), progress=False, aero=aero)  # warm-up (JIT cache)
    loop: dict[str, list[float]] = {"paper": [], "realistic": []}
    cpu: dict[str, list[float]] = {"paper": [], "realistic": []}
    notes = {}
    for _ in range(repeats):
        for aero in ("paper", "realistic"):  # alternate: same machine load
            c0 = time.process_time()
            res = run(sc, progress=False, aero=aero)
            cpu[aero].append(time.process_time() - c0)
            loop[aero].append(res.summary["wall_time_s"])
            notes[aero] = res.summary
    p, r = min(loop["paper"]) / dur, min(loop["realistic"]) / dur
    cpu_ratio = min(cpu["realistic"]) / min(cpu["paper"])
    s = notes["realistic"]
    # the physics alone: Sim.step (saturation, force stages, mj_step, contacts, monitors) of the same
    # model under each preset, the drones hovering 2 m up at constant commands, no controller or rule
    from swarm_mj.env import SwarmEnv
    from swarm_mj.physics.aero.presets import with_aero

    steps = int(round(dur / sc.control_period))
    phys: dict[str, list[float]] = {"paper": [], "realistic": []}
    envs = {aero: SwarmEnv(with_aero(sc, aero)) for aero in ("paper", "realistic")}
    for _ in range(repeats):
        for aero, env in envs.items():
            env.reset()
            sim = env.sim
            sim.reset(positions=sim.world.initial_positions + np.array([0.0, 0.0, 2.0]))
            U = np.zeros((sim.pos.shape[0], 4))
            U[:, 0] = env.params.m * env.params.g
            t0 = time.perf_counter()
            for _ in range(steps):
                sim.step(U)
            phys[aero].append(time.perf_counter() - t0)
    pp, pr = min(phys["paper"]) / dur, min(phys["realistic"]) / dur
    row(
        "aero",
        f"realistic vs paper physics alone (Sim.step, 6 drones hovering 2 m up, {dur:g} s)",
        pr,
        pp,
        value=pr / pp,
        unit="× paper",
        note=f"paper {1000 * pp:.1f} ms, realistic {1000 * pr:.1f} ms per sim s: ground contacts, downwash, "
        f"ground effect, rotor lag; best of {repeats}",
    )
    row(
        "aero",
        f"realistic vs paper per simulated second, circle (6 drones, {dur:g} s)",
        r,
        p,
        value=r / p,
        unit="× paper",
        note=f"paper {1000 * p:.1f} ms, realistic {1000 * r:.1f} ms per sim s (bar 1.3×); process CPU time "
        f"of the whole run (set-up included) {cpu_ratio:.2f}×; realistic: crashes {s['crashes']}, "
        f"contacts {s['contacts']}; best of {repeats}",
    )


def _interleaved_runs(variants: dict, repeats: int) -> tuple[dict[str, list[float]], dict]:
    """Each variant's scenario (name -> Scenario) flown under ``realistic`` after a 1-s warm-up, the
    variants alternated ``repeats`` times (the same machine load): the loops' wall times by name, and
    each variant's last result."""
    from swarm_mj.experiments.runner import run

    for sc in variants.values():
        run(sc.with_overrides(duration=1.0), progress=False, aero="realistic")  # warm-up
    loop: dict[str, list[float]] = {name: [] for name in variants}
    notes = {}
    for _ in range(repeats):
        for name, sc in variants.items():
            res = run(sc, progress=False, aero="realistic")
            loop[name].append(res.summary["wall_time_s"])
            notes[name] = res
    return loop, notes


def bench_barrier(quick: bool, repeats: int) -> None:
    """The barrier separation filter's cost over the jet-aware rule's: the realistic circle (6 drones),
    the same run with each rule, interleaved (docs/barrier.md, "cost")."""
    from swarm_mj.scenario import load_scenario

    dur = 30.0 if quick else 180.0
    sc = load_scenario("circle").with_overrides(duration=dur)
    loop, notes = _interleaved_runs({r: sc.with_overrides(anti_collision=r) for r in ("jet-aware", "barrier")}, repeats)
    ratio = paired(loop["barrier"], loop["jet-aware"])
    s, x = notes["barrier"].summary, notes["barrier"].extra
    row(
        "barrier",
        f"barrier vs jet-aware, realistic circle (6 drones, {dur:g} s)",
        min(loop["barrier"]),
        min(loop["jet-aware"]),
        value=ratio,
        unit="× jet-aware",
        note=f"bar 1.3×; barrier: {x['fused_periods']} periods fused ({x['fast_path']}), keep-out "
        f"{s['keepout_time_s']:.2f} s, contacts {s['contacts']}; best of {repeats}; ratio: median of the paired "
        "repeats",
        ratio=ratio,
    )


def bench_sensing(quick: bool, repeats: int) -> None:
    """Each drone's own view over the oracle: the realistic circle (6 drones, barrier) under ``mocap``
    beside ``perfect``, interleaved (docs/sensing.md, "Cost"; issue 49's bar: 1.15×)."""
    from swarm_mj.scenario import load_scenario

    dur = 30.0 if quick else 180.0
    sc = load_scenario("circle").with_overrides(duration=dur, anti_collision="barrier")
    loop, notes = _interleaved_runs({p: sc.with_overrides(sensing=p) for p in ("perfect", "mocap")}, repeats)
    ratio = paired(loop["mocap"], loop["perfect"])
    s, x = notes["mocap"].summary, notes["mocap"].extra
    per = {p: 1e6 * r.extra["fused_seconds"] / max(r.extra["fused_periods"], 1) for p, r in notes.items()}
    row(
        "sensing",
        f"mocap vs perfect sensing, realistic circle, barrier (6 drones, {dur:g} s)",
        min(loop["mocap"]),
        min(loop["perfect"]),
        value=ratio,
        unit="× perfect",
        note=f"bar 1.15× on the chunk driver; mocap: {x['fused_periods']} periods fused ({x['fast_path']}), "
        f"keep-out {s['keepout_time_s']:.2f} s, contacts {s['contacts']}; perfect: "
        f"{notes['perfect'].extra['fused_periods']} fused; on the chunk driver {per['mocap']:.0f} µs a period "
        f"against {per['perfect']:.0f} ({per['mocap'] / per['perfect']:.2f}×, the last repeat); best of {repeats}; "
        "ratio: median of the paired repeats",
        ratio=ratio,
    )


def _load_tool(name: str):
    """tools/NAME.py as a module, or None when absent or broken."""
    p = Path(__file__).resolve().parent / f"{name}.py"
    if not p.exists():
        return None
    spec = importlib.util.spec_from_file_location(f"_swarm_bench_{name}", p)
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except Exception as exc:  # noqa: BLE001
        print(f"  extra    {name}: cannot import ({exc})")
        return None
    return mod


def extra(quick: bool) -> None:
    for name in ("bench_core", "bench_env", "bench_tune", "bench_video", "bench_peers"):
        mod = _load_tool(name)
        if mod is None:
            continue
        fn = getattr(mod, "measure", None)
        if fn is None:
            continue
        for r in fn(quick=quick) or []:
            row(
                "extra",
                f"{name}: {r.get('name', '?')}",
                r.get("ours_s"),
                r.get("raw_s"),
                value=r.get("value"),
                unit=r.get("unit", ""),
                note=r.get("note", ""),
            )


# --------------------------------------------------------------------------- output


def markdown(rows: list[dict], mach: dict) -> str:
    out = [
        f"Machine: {mach['cpu']}, {mach['cores']} cores ({mach['usable_cores']} usable), Python {mach['python']}, "
        f"MuJoCo {mach['mujoco']}, NumPy {mach['numpy']}, Numba {mach['numba']} (JIT {'on' if mach['jit'] else 'off'})",
        "",
        "| section | figure | value | ours (s) | raw mj_step (s) | × raw | note |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        v = f"{r['value']:,.1f} {r['unit']}" if r["value"] is not None else ""
        o = f"{r['ours_s']:.3f}" if r["ours_s"] is not None else ""
        b = f"{r['raw_s']:.3f}" if r["raw_s"] is not None else ""
        x = f"{r['ratio']:.2f}" if r["ratio"] is not None else ""
        out.append(f"| {r['section']} | {r['name']} | {v} | {o} | {b} | {x} | {r['note']} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="short runs (30 s instead of 180 s, a small tune)")
    ap.add_argument("--json", metavar="PATH", help="write the machine and every row as JSON")
    ap.add_argument(
        "--repeats",
        type=int,
        default=None,
        help="repeats of the short figures (default 5: best-of times, median paired ratios)",
    )
    ap.add_argument("--skip", nargs="+", default=[], choices=SECTIONS, help="sections to leave out")
    ap.add_argument("--sizes", nargs="+", type=int, default=[6, 25, 100], help="swarm sizes for scaling")
    args = ap.parse_args(argv)
    repeats = args.repeats or (1 if args.quick else 5)
    if repeats < 1 or any(s < 2 for s in args.sizes):
        ap.error("--repeats must be >= 1 and --sizes >= 2")
    mach = machine()
    print(
        f"machine: {mach['cpu']}, {mach['cores']} cores ({mach['usable_cores']} usable), Python {mach['python']}, "
        f"MuJoCo {mach['mujoco']}, NumPy {mach['numpy']}, Numba {mach['numba']}, load {mach['load_average']}",
        flush=True,
    )
    from swarm_mj import _jit
    from swarm_mj.experiments import runner
    from swarm_mj.pipeline import fast

    t_jit = _jit.warm_up()
    sigs = runner.preset_signatures()
    t_fused = fast.compile_now(sigs)  # (loads it when cached) every run below may use the chunk driver
    ready = all(fast.compiled(sig) for sig in sigs)
    print(
        f"kernels ready ({t_jit:.1f} s), fast path {'ready' if ready else 'NOT available'} ({t_fused:.1f} s)",
        flush=True,
    )
    t0 = time.perf_counter()
    for sec in SECTIONS:
        if sec in args.skip:
            continue
        t = time.perf_counter()
        if sec == "core":
            bench_core(args.quick, repeats)
        elif sec == "runs":
            bench_runs(args.quick, repeats)
        elif sec == "env":
            bench_env(args.quick, repeats)
        elif sec == "vector":
            bench_vector(args.quick, repeats)
        elif sec == "startup":
            bench_startup(args.quick, repeats)
        elif sec == "tuning":
            bench_tuning(args.quick, 1)
        elif sec == "video":
            bench_video(args.quick, 1)
        elif sec == "scaling":
            bench_scaling(args.quick, repeats, tuple(args.sizes))
        elif sec == "aero":
            bench_aero(args.quick, repeats)
        elif sec == "barrier":
            bench_barrier(args.quick, repeats)
        elif sec == "sensing":
            bench_sensing(args.quick, repeats)
        print(f"  ({sec}: {time.perf_counter() - t:.0f} s)", flush=True)
    extra(args.quick)
    total = time.perf_counter() - t0
    print()
    print(markdown(ROWS, mach))
    print(f"\nbench: {total:.0f} s")
    if args.json:
        data = {"machine": mach, "quick": args.quick, "repeats": repeats, "wall_s": total, "rows": ROWS}
        tmp = Path(args.json).with_name(Path(args.json).name + ".partial")
        tmp.write_text(json.dumps(data, indent=2) + "\n")
        os.replace(tmp, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
