"""Compare hand-written policies with the paper's backstepping stack, through SwarmEnv.

A policy is any callable ``policy(observation) -> action``. Here:

* ``random U``      thrust mode: U1..U4 drawn uniformly inside ``action_spec()``;
* ``PD (thrust)``   thrust mode: a textbook cascaded PD (position → tilt → torques), written below;
* ``slots``         setpoint mode: fly straight to the formation setpoints, no anti-collision;
* ``backstepping``  the paper's stack (formation → anti-collision → backstepping), ``swarm-mj run``'s policy.

    .venv/bin/python tools/compare_policies.py [--scenario anti_collision] [--duration 10] [--seed 0]

The same loop works with the Gymnasium / PettingZoo wrappers (``swarm_mj.wrappers``).
"""

from __future__ import annotations

import argparse

import numpy as np

from swarm_mj.control.policy import BacksteppingPolicy
from swarm_mj.env import SwarmEnv
from swarm_mj.scenario import load_scenario


class PDPolicy:
    """Cascaded PD in thrust mode: desired acceleration → thrust and tilt → torques (small angles)."""

    def __init__(self, params, kp=2.0, kd=2.5, kp_att=60.0, kd_att=12.0, max_tilt=0.4):
        self.p, self.kp, self.kd, self.kp_att, self.kd_att, self.max_tilt = params, kp, kd, kp_att, kd_att, max_tilt

    def __call__(self, obs):
        p = self.p
        acc = (
            self.kp * (obs["setpoint"] - obs["pos"])
            + self.kd * (obs["setpoint_vel"] - obs["vel"])
            + obs["setpoint_acc"]
        )  # (n, 3) desired acceleration
        phi, theta, psi = obs["rpy"].T
        c, s = np.cos(psi), np.sin(psi)
        att_d = np.column_stack(
            [
                (acc[:, 0] * s - acc[:, 1] * c) / p.g,  # roll
                (acc[:, 0] * c + acc[:, 1] * s) / p.g,  # pitch
                obs["setpoint_yaw"],
            ]
        )
        att_d[:, :2] = np.clip(att_d[:, :2], -self.max_tilt, self.max_tilt)
        alpha = self.kp_att * (att_d - obs["rpy"]) - self.kd_att * obs["rpy_rate"]  # angular accelerations
        U = np.empty((len(acc), 4))
        U[:, 0] = p.m * (p.g + acc[:, 2]) / (np.cos(phi) * np.cos(theta))
        U[:, 1:] = p.inertia * alpha / p.L  # torques are L·U2..U4
        return U


def episode(env: SwarmEnv, policy, seed: int) -> dict:
    """Run one episode; formation error and separation from the observations, contacts from the sim."""
    ts = env.reset(seed=seed)
    ret, errs, min_sep = 0.0, [], np.inf
    iu = np.triu_indices(env.n, 1)
    while True:
        o = ts.observation
        errs.append(np.linalg.norm(o["pos"][1:] - o["setpoint"][1:], axis=1).mean())
        min_sep = min(min_sep, np.linalg.norm(o["pos"][:, None] - o["pos"][None], axis=-1)[iu].min())
        if ts.last():
            break
        ts = env.step(policy(o))
        ret += ts.reward
    # dm_env: LAST with discount 1 = truncated (the duration); discount 0 = terminated (here, with
    # terminate_on_contact=False, only a divergence: a drone fell, flew away or went NaN)
    ended = "duration" if ts.discount == 1.0 else "diverged"
    return {
        "formation err (m)": np.mean(errs),
        "min sep (m)": min_sep,
        "contacts": env.sim.contact_events,
        "return": ret,
        "t end (s)": float(ts.observation["time"]),
        "ended": ended,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="anti_collision")
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds (default 10)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    sc = load_scenario(args.scenario).with_overrides(duration=args.duration)

    thrust = SwarmEnv(sc, terminate_on_contact=False)  # count every contact, stop only on divergence
    setpoint = SwarmEnv(sc, action="setpoint", terminate_on_contact=False)
    rng = np.random.default_rng(args.seed)
    spec = thrust.action_spec()
    runs = {
        "random U": (thrust, lambda obs: rng.uniform(spec.minimum, spec.maximum)),
        "PD (thrust)": (thrust, PDPolicy(thrust.params)),
        "slots (setpoint)": (setpoint, lambda obs: obs["setpoint"]),
        "backstepping": (thrust, BacksteppingPolicy(sc, thrust.params)),
    }
    rows = {name: episode(env, policy, args.seed) for name, (env, policy) in runs.items()}

    cols = list(next(iter(rows.values())))
    print(f"{sc.name}: {sc.n_drones} drones, {args.duration:g} s, seed {args.seed}\n")
    width = [max(len(c), 11) + 2 for c in cols]
    print(f"{'policy':18s}" + "".join(f"{c:>{w}s}" for c, w in zip(cols, width)))
    for name, r in rows.items():
        cells = (f"{v:{w}.3f}" if isinstance(v, float) else f"{v!s:>{w}}" for v, w in zip(r.values(), width))
        print(f"{name:18s}" + "".join(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
