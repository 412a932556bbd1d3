"""How far a drone sinks in another's downwash under the default backstepping controller (docs/aero.md).

Two drones in MuJoCo under the ``realistic`` preset (or ``--aero`` another): an upper one
holding (0, 0, ``--alt``) and a lower one flying a straight line at (x, 0, alt − depth) from
x = −2 m to +2 m at ``--speed`` m/s, with position, velocity and (along x) acceleration
references, both under the paper's backstepping controller (Table 4 gains). For each depth,
prints the worst altitude dip of the lower drone while it is within 1 m (horizontally) of the
upper one (its reference altitude minus its altitude), the same for the lower drone HOLDING
directly below the upper one (steady state), and the jet's centreline speed and half-width
at that depth (the turbulent-jet model, swarm_mj.physics.aero.downwash).

    python tools/aero_dip.py                 # depths 0.4 0.8 1.2 m, 1 m/s
    python tools/aero_dip.py --depths 0.4 --speed 0.5 --json dip.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def fly(
    depth: float, speed: float, alt: float, aero: str, hold: bool = False, settle: float = 3.0, offset: float = 0.0
) -> dict:
    """One two-drone flight; returns the worst dip (m) of the lower drone near the upper one
    (``hold``: holding ``offset`` m aside of the point right below it)."""
    from swarm_mj.control.backstepping import TABLE4_GAINS, Backstepping
    from swarm_mj.physics.aero import install, preset
    from swarm_mj.physics.observation import observe_kernel
    from swarm_mj.physics.sim import Sim
    from swarm_mj.physics.world import build_world

    cfg = preset(aero)
    T = 0.01
    x0 = offset if hold else -2.0
    upper = np.array([0.0, 0.0, alt])
    lower = np.array([x0, 0.0, alt - depth])
    world = build_world(2, positions=np.array([upper, lower]), ground=cfg.ground, motor_tau=cfg.motor_tau)
    sim = Sim(world, T)
    if not cfg.is_paper:
        install(sim, cfg)
    # Start hovering: the rotors at hover thrust (with rotor lag, the filter state too).
    ctl = Backstepping(2, TABLE4_GAINS, params=world.params, control_period=T)
    if sim.motor_lag:
        sim.data.act[0::4] = world.params.hover_thrust
    t_cross = 4.0 / speed
    n_steps = round((settle + (0.0 if hold else t_cross) + (3.0 if hold else 1.0)) / T)
    z3 = np.zeros((2, 3))
    worst, zs = 0.0, []
    for k in range(n_steps):
        t = k * T
        pos, vel, _quat, omega, rpy, rpy_rate, *_ = observe_kernel(sim.qpos, sim.qvel, 10.0)
        pos_d = np.array([upper, lower])
        vel_d = z3.copy()
        if not hold and t >= settle:
            pos_d[1, 0] = min(x0 + speed * (t - settle), 2.0)
            vel_d[1, 0] = speed if pos_d[1, 0] < 2.0 else 0.0
        U = ctl.compute(rpy, rpy_rate, pos, vel, pos_d, vel_d, z3, np.zeros(2), wind_force=z3, omega_body=omega)
        sim.step(U)
        if t >= settle and (hold or abs(sim.pos[1, 0] - sim.pos[0, 0]) < 1.0):  # near the upper one
            dip = pos_d[1, 2] - sim.pos[1, 2]
            worst = max(worst, dip)
            zs.append(dip)
    return {"depth_m": depth, "worst_dip_m": float(worst), "final_dip_m": float(zs[-1]) if zs else float("nan")}


def main(argv: list[str] | None = None) -> int:
    from swarm_mj.physics.aero.downwash import centreline_velocity, half_width, hover_induced_velocity
    from swarm_mj.physics.params import DEFAULT_PARAMS as P

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--depths", nargs="+", type=float, default=[0.4, 0.8, 1.2])
    ap.add_argument("--speed", type=float, default=1.0, help="lower drone's crossing speed (m/s)")
    ap.add_argument("--alt", type=float, default=2.5, help="upper drone's altitude (m)")
    ap.add_argument("--aero", default="realistic", choices=["paper", "realistic"])
    ap.add_argument(
        "--offsets",
        nargs="*",
        type=float,
        default=[],
        help="also the holding dip this far aside (m, horizontally) at each depth",
    )
    ap.add_argument("--json", metavar="PATH")
    a = ap.parse_args(argv)
    u_h = float(hover_induced_velocity(P.hover_thrust))
    l = 2 * P.L
    rows = []
    print(f"aero {a.aero}; hover-induced velocity U_H = {u_h:.2f} m/s; motor distance l = {l:.2f} m")
    print(f"{'depth (m)':>9} {'U_c (m/s)':>9} {'r_1/2 (m)':>9} {'cross dip (m)':>13} {'hold dip (m)':>12}")
    for d in a.depths:
        c = fly(d, a.speed, a.alt, a.aero)
        h = fly(d, a.speed, a.alt, a.aero, hold=True)
        row = {
            "depth_m": d,
            "centreline_speed_mps": float(centreline_velocity(d, u_h, l)),
            "half_width_m": float(half_width(d, l)),
            "crossing_dip_m": c["worst_dip_m"],
            "holding_dip_worst_m": h["worst_dip_m"],
            "holding_dip_final_m": h["final_dip_m"],
            "speed_mps": a.speed,
        }
        rows.append(row)
        print(
            f"{d:>9.2f} {row['centreline_speed_mps']:>9.2f} {row['half_width_m']:>9.3f} "
            f"{row['crossing_dip_m']:>13.3f} {row['holding_dip_worst_m']:>12.3f}"
        )
        for off in a.offsets:
            o = fly(d, a.speed, a.alt, a.aero, hold=True, offset=off)
            row.setdefault("holding_dip_aside_m", {})[str(off)] = o["worst_dip_m"]
            print(f"{'':>9} holding {off:g} m aside: dip {o['worst_dip_m']:.3f} m")
    if a.json:
        Path(a.json).write_text(json.dumps({"aero": a.aero, "u_h_mps": u_h, "rows": rows}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
