"""Run a scenario: ``SwarmEnv`` + a policy, with a log, a summary and observers (DESIGN "One loop").

``run(scenario)`` steps the environment with the backstepping policy, keeps every
control-period sample in preallocated arrays (:class:`RunLog`, time axis first), and
returns them with the SPEC §7 summary. A Ctrl-C or a divergence stops the loop; the log
of what ran is kept (``RunResult.error`` says why it stopped) so that the recording can
still be written.
"""

from __future__ import annotations

import sys
import time as _time
from dataclasses import dataclass, field

import numpy as np

from .aero.presets import with_aero
from .env import SwarmEnv
from .errors import SimulationDiverged
from .kernels import warm_up
from .metrics import (downwash_dip, follower_distances, formation_settling, leader_distances, min_separation,
                      rmse, step_metrics)
from .policy import BacksteppingPolicy
from .scenario import Scenario, load_scenario

# Paper figures to print beside ours (SPEC §7).
PAPER_STEP = {"x": {"overshoot_pct": 0.0, "settling_s": 1.5}, "y": {"overshoot_pct": 0.0, "settling_s": 1.5},
              "z": {"overshoot_pct": 0.0, "settling_s": 1.0}, "psi": {"overshoot_pct": 0.0, "settling_s": 1.0}}
PAPER_TABLE5 = {
    ("circle", False): {"x": 0.0156, "y": 0.0631, "roll_deg": 0.0397, "pitch_deg": 0.0688},
    ("circle", True): {"x": 0.0398, "y": 0.0689, "roll_deg": 0.1205, "pitch_deg": 0.1965},
    ("lemniscate", False): {"x": 0.0075, "y": 0.0041, "roll_deg": 0.0173, "pitch_deg": 0.0379},
    ("lemniscate", True): {"x": 0.0321, "y": 0.0249, "roll_deg": 0.1125, "pitch_deg": 0.1841},
}
PAPER_FORMATION_SETTLING_S = 3.0


@dataclass
class RunLog:
    """Every control-period sample of a run; k = number of samples (steps + 1)."""

    names: list[str]
    t: np.ndarray            # (k,)
    pos: np.ndarray          # (k, n, 3)
    vel: np.ndarray          # (k, n, 3)
    quat: np.ndarray         # (k, n, 4)
    rpy: np.ndarray          # (k, n, 3)
    pos_d: np.ndarray        # (k, n, 3) commanded position (after anti-collision)
    slot: np.ndarray         # (k, n, 3) formation setpoint (leader: its reference)
    att_d: np.ndarray        # (k, n, 3) commanded (φ_d, θ_d, ψ_d)
    U: np.ndarray            # (k, n, 4) applied U1..U4 over the following period
    rotor: np.ndarray        # (k, n, 4) rotor thrusts F1..F4 over the following period
    wind_speed: np.ndarray   # (k, 3)
    wind_force: np.ndarray   # (k, n, 3) applied wind force over the following period
    D: np.ndarray            # (k,)
    downwash: np.ndarray | None = None       # (k, n, 3) downwash force on each drone (docs/aero.md), N
    ground_effect: np.ndarray | None = None  # (k, n, 3) ground-effect force on each drone, N

    @classmethod
    def allocate(cls, names: list[str], k: int) -> "RunLog":
        n = len(names)
        z = lambda *s: np.full(s, np.nan)  # noqa: E731
        return cls(names, z(k), z(k, n, 3), z(k, n, 3), z(k, n, 4), z(k, n, 3), z(k, n, 3), z(k, n, 3),
                   z(k, n, 3), z(k, n, 4), z(k, n, 4), z(k, 3), z(k, n, 3), z(k), z(k, n, 3), z(k, n, 3))

    def truncated(self, k: int) -> "RunLog":
        log = RunLog(self.names, *(getattr(self, f)[:k] for f in
                                   ("t", "pos", "vel", "quat", "rpy", "pos_d", "slot", "att_d", "U", "rotor",
                                    "wind_speed", "wind_force", "D")))
        log.downwash = None if self.downwash is None else self.downwash[:k]
        log.ground_effect = None if self.ground_effect is None else self.ground_effect[:k]
        return log


@dataclass
class RunResult:
    scenario: Scenario
    log: RunLog
    summary: dict
    events: list[dict]
    contact_log: list[tuple[float, int, int]]
    error: BaseException | None = None
    extra: dict = field(default_factory=dict)


class Progress:
    """A one-line progress bar on stderr (quiet when not a terminal unless forced)."""

    def __init__(self, total: int, label: str, enabled: bool | None = None) -> None:
        self.total, self.label = total, label
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self._last = -1
        self._t0 = _time.perf_counter()

    def update(self, k: int) -> None:
        if not self.enabled:
            return
        pct = int(100 * k / max(self.total, 1))
        if pct != self._last:
            self._last = pct
            bar = "#" * (pct // 4) + "-" * (25 - pct // 4)
            el = _time.perf_counter() - self._t0
            sys.stderr.write(f"\r{self.label} [{bar}] {pct:3d}%  {el:5.1f} s")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def run(scenario: Scenario | str, *, gains: np.ndarray | None = None, anti_collision: str | None = None,
        seed: int | None = None, progress: bool | None = None, duration: float | None = None,
        aero: str | None = None) -> RunResult:
    """Fly a scenario with the backstepping policy and return the log and summary.

    aero: a physics preset (``"paper"``, ``"realistic"``; docs/aero.md) replacing the scenario's.
    Never raises for Ctrl-C or divergence: the result carries the error and the log up to it.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    sc = with_aero(sc, aero)
    if duration is not None:
        sc = sc.with_overrides(duration=float(duration))
    if gains is not None:
        sc = sc.with_overrides(gains=np.asarray(gains, float), gains_source="override")
    if anti_collision is not None:
        sc = sc.with_overrides(anti_collision=anti_collision)
    compile_s = warm_up()
    if compile_s > 1.0 and progress is not False:
        print(f"compiled the control kernels in {compile_s:.0f} s (cached for later runs)", file=sys.stderr)
    env = SwarmEnv(sc, terminate_on_contact=False, raise_on_divergence=True, seed=seed)
    policy = BacksteppingPolicy(sc, env.params)
    K = env.n_steps
    log = RunLog.allocate(env.names, K + 1)
    bar = Progress(K, sc.name, progress)
    error: BaseException | None = None
    wall0 = _time.perf_counter()
    ts = env.reset()
    obs = ts.observation
    k = 0
    sim = env.sim
    ctl = policy.controller
    wind_speed = env.wind.speed
    stages = {st.name: st for st in sim.force_stages}
    dw, ge = stages.get("downwash"), stages.get("ground_effect")
    log.downwash[:] = 0.0
    log.ground_effect[:] = 0.0
    try:
        while True:
            U = policy(obs)
            log.t[k] = obs["time"]
            log.pos[k] = obs["pos"]
            log.vel[k] = obs["vel"]
            log.quat[k] = obs["quat"]
            log.rpy[k] = obs["rpy"]
            log.pos_d[k] = policy.pos_d
            log.slot[k] = obs["setpoint"]
            log.att_d[k] = ctl.att_d
            log.wind_speed[k] = wind_speed[k]
            log.D[k] = env.D[k]
            if k >= K:
                break
            ts = env.step(U)
            log.U[k] = sim.ctrl
            log.rotor[k] = sim.rotor_thrust
            log.wind_force[k] = env.last_wind_force
            if dw is not None:
                log.downwash[k] = dw.force        # over the last physics step of the period
            if ge is not None:
                log.ground_effect[k] = ge.force
            obs = ts.observation
            k += 1
            if k % 50 == 0:
                bar.update(k)
    except KeyboardInterrupt as exc:
        error = exc
    except SimulationDiverged as exc:
        error = exc
    finally:
        bar.close()
    wall = _time.perf_counter() - wall0
    n_samples = k + 1 if error is None else k
    if error is None and k > 0:
        # the last sample has no following period: hold the last inputs (zero-order hold)
        log.U[k], log.rotor[k] = log.U[k - 1], log.rotor[k - 1]
        log.downwash[k], log.ground_effect[k] = log.downwash[k - 1], log.ground_effect[k - 1]
        log.wind_force[k] = env.wind.drone_forces(k, env.sim.vel)
    log = log.truncated(max(n_samples, 1))
    summary = summarize(sc, log, env, policy, wall)
    if error is not None:
        summary["stopped"] = f"{type(error).__name__}: {error}".rstrip(": ")
    return RunResult(sc, log, summary, list(policy.events), list(sim.contact_log), error)


def summarize(sc: Scenario, log: RunLog, env: SwarmEnv, policy: BacksteppingPolicy, wall: float) -> dict:
    """The JSON summary (stable keys of the issues; more may be added)."""
    t = log.t
    sim_time = float(t[-1]) if len(t) else 0.0
    out: dict = {"scenario": sc.name, "sim_time_s": sim_time, "wall_time_s": wall,
                 "real_time_factor": sim_time / wall if wall > 0 else float("inf"),
                 "n_drones": sc.n_drones, "seed": env.seed, "gains_source": sc.gains_source,
                 "anti_collision_rule": policy.rule.name, "wind": bool(sc.wind.enabled),
                 "wind_feedforward": bool(sc.wind_feedforward), "drones": {}}
    steady = t >= sc.steady_after
    for i, name in enumerate(log.names):
        ref = log.slot[:, i] if i > 0 else log.pos_d[:, i]
        e = ref - log.pos[:, i]
        att_e = np.rad2deg(log.att_d[:, i, :2] - log.rpy[:, i, :2])
        d: dict = {
            "rmse": _rmse_dict(e, att_e),
            "rmse_steady": _rmse_dict(e[steady], att_e[steady]) if steady.any() else None,
            "max_rotor_thrust_n": float(np.nanmax(log.rotor[:, i])) if len(t) > 1 else 0.0,
            "min_rotor_thrust_n": float(np.nanmin(log.rotor[:, i])) if len(t) > 1 else 0.0,
            "max_abs_roll_deg": float(np.rad2deg(np.abs(log.rpy[:, i, 0]).max())),
            "max_abs_pitch_deg": float(np.rad2deg(np.abs(log.rpy[:, i, 1]).max())),
        }
        if i == 0 and sc.trajectory == "step" and len(t) > 1:
            target = env.reference.pos[0]
            yaw_t = float(env.reference.yaw[0])
            d["step"] = {ax: step_metrics(t, log.pos[:, 0, j], float(target[j]), float(log.pos[0, 0, j]))
                         for j, ax in enumerate("xyz")}
            d["step"]["psi"] = step_metrics(t, log.rpy[:, 0, 2], yaw_t, float(log.rpy[0, 0, 2]))
        out["drones"][name] = d
    out["contacts"] = int(env.sim.contact_events)
    out["contact_steps"] = int(env.sim.contact_steps)
    # Ground contacts and crashes (docs/aero.md); 0 when the preset has no solid ground.
    ground = next((m for m in getattr(env.sim, "monitors", []) if getattr(m, "name", "") == "ground"), None)
    out["aero"] = sc.aero.to_dict()
    out["ground_contacts"] = int(ground.ground_contacts) if ground is not None else 0
    out["crashes"] = int(ground.crashes) if ground is not None else 0
    if log.downwash is not None and len(t):
        out["downwash_force_max_n"] = float(np.linalg.norm(log.downwash, axis=2).max())
    if sc.n_drones > 1:
        sep, kk, pair = min_separation(log.pos)
        out["min_separation_m"] = sep
        out["min_separation_at_s"] = float(t[kk]) if kk >= 0 else None
        out["min_separation_pair"] = [log.names[pair[0]], log.names[pair[1]]]
        airborne = (log.pos[:, :, 2] > 0.1).all(axis=1)
        if airborne.any():
            out["min_separation_airborne_m"] = min_separation(log.pos[airborne])[0]
        dist = leader_distances(log.pos)
        changes = env.scenario.diameter_schedule().change_times
        changes = changes[changes <= sim_time]
        settling, max_err = formation_settling(t, dist, log.D, changes)
        out["formation"] = {"settling_s": settling, "change_times_s": changes.tolist(),
                            "max_distance_error_m": max_err,
                            "final_distance_error_m": float(np.abs(dist[-1] - log.D[-1]).max())}
        dip = downwash_dip(t, log.pos, log.pos_d, log.quat)
        out["downwash_dip_worst_m"] = dip["worst_m"]
        named = {key: log.names[dip[key]] if dip[key] >= 0 else None for key in ("drone", "above")}
        out["downwash_dip"] = {"worst_m": dip["worst_m"], **named, "at_s": dip["t_s"],
                               "time_in_jet_s": dip["time_in_jet_s"], "below_ref_worst_m": dip["below_ref_worst_m"]}
        ev = policy.events
        out["anti_collision"] = {"rule": policy.rule.name, "events": len(ev),
                                 "yields": sum(1 for e in ev if e["action"] in ("up", "down"))}
    else:  # the stable keys exist for one drone too
        out["min_separation_m"] = None
        out["formation"] = None
        out["downwash_dip_worst_m"] = 0.0
        out["anti_collision"] = {"rule": policy.rule.name, "events": 0, "yields": 0}
    return out


def _rmse_dict(e: np.ndarray, att_e: np.ndarray) -> dict:
    r = rmse(e)
    ra = rmse(att_e)
    return {"x": float(r[0]), "y": float(r[1]), "z": float(r[2]), "roll_deg": float(ra[0]),
            "pitch_deg": float(ra[1])}
