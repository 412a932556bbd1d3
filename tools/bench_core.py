"""Cost of the simulation core (swarm_mj.physics.sim.Sim.step) next to raw mujoco.mj_step.

For the 6-drone world at the default physics timestep, this times
  * raw:  ``mujoco.mj_step`` on the same model, ctrl at hover and a constant xfrc_applied,
  * core: ``Sim.step`` (saturation, drag refresh every physics step, external force,
          contact bookkeeping) with hover U and a constant external force,
over the same number of physics steps, interleaved in the same run, best of a few repeats.

    .venv/bin/python tools/bench_core.py [--seconds 10] [--repeats 5] [--drones 6]

Goal (issue): core ≤ 1.3× raw mj_step.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from swarm_mj.physics._mjstep import profiler_paused
from swarm_mj.physics.sim import Sim
from swarm_mj.physics.world import build_world

GOAL = 1.3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per repeat (default 10)")
    ap.add_argument("--repeats", type=int, default=5, help="repeats, best taken (default 5)")
    ap.add_argument("--drones", type=int, default=6, help="number of drones (default 6)")
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.repeats < 1:
        ap.error("--seconds must be > 0 and --repeats >= 1")

    n = args.drones
    positions = np.column_stack([2.0 * np.arange(n), np.zeros(n), np.full(n, 2.0)])  # apart: no contacts
    world = build_world(n, positions=positions)
    model = world.model
    sim = Sim(world)
    p = world.params
    U = np.tile([p.hover_thrust, 0.0, 0.0, 0.0], (n, 1))
    F = np.array([0.1, -0.05, 0.02])
    n_ctrl = int(round(args.seconds / sim.control_period))
    n_phys = n_ctrl * sim.n_substeps

    raw = mujoco.MjData(model)

    def run_raw() -> float:
        mujoco.mj_resetData(model, raw)
        raw.qpos[:] = sim.data.qpos
        raw.ctrl[:] = U.ravel()
        raw.xfrc_applied[world.body_ids, 0:3] = F
        mujoco.mj_forward(model, raw)
        step = mujoco.mj_step
        with profiler_paused():  # as Sim.step steps (swarm_mj/physics/_mjstep.py)
            t0 = time.perf_counter()
            for _ in range(n_phys):
                step(model, raw)
            return time.perf_counter() - t0

    def run_core() -> float:
        sim.reset()
        step = sim.step
        t0 = time.perf_counter()
        for _ in range(n_ctrl):
            step(U, F)
        return time.perf_counter() - t0

    run_raw(), run_core()  # warm-up
    t_raw, t_core = [], []
    for _ in range(args.repeats):  # interleaved: both see the same machine state
        t_raw.append(run_raw())
        t_core.append(run_core())
    best_raw, best_core = min(t_raw), min(t_core)
    if sim.contact_events:
        print(f"warning: {sim.contact_events} contacts during the benchmark")

    sim_s = n_ctrl * sim.control_period
    rows = [("raw mj_step", best_raw), ("core Sim.step", best_core)]
    print(
        f"{n} drones, timestep {model.opt.timestep * 1e3:g} ms, {sim.n_substeps} physics steps per "
        f"{sim.control_period * 1e3:g}-ms control period; {sim_s:g} s simulated "
        f"({n_phys} physics steps), best of {args.repeats}"
    )
    head = ("", "wall (s)", "ctrl steps/s", "phys steps/s", "real-time ×")
    print(f"{head[0]:<15}{head[1]:>10}{head[2]:>14}{head[3]:>14}{head[4]:>13}")
    for name, t in rows:
        print(f"{name:<15}{t:>10.4f}{n_ctrl / t:>14,.0f}{n_phys / t:>14,.0f}{sim_s / t:>13,.0f}")
    ratio = best_core / best_raw
    verdict = "meets" if ratio <= GOAL else "misses"
    print(f"ratio core/raw: {ratio:.3f}× ({verdict} the goal ≤ {GOAL}×)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
