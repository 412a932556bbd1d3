"""Human-readable tables of a run summary, ours beside the paper's (docs/interpretations.md)."""

from __future__ import annotations

import math
from dataclasses import replace

from ..choices import gains_text
from ..paper import PAPER_FORMATION_SETTLING_S, PAPER_STEP, PAPER_TABLE5
from ..physics.params import DEFAULT_PARAMS
from ..scenario import trajectory_args
from ..trajectories import TRAJECTORIES
from .outcome import failure_line

#: The summary's ``controller.mixer`` in the physics line's words (swarm_mj/physics/mixing.py).
_MIXER_WORDS = {
    "attitude_priority": "attitude-priority",
    "yaw_last": "yaw-last attitude-priority",
    "clip": "per-rotor clip",
}


def _f(v, fmt: str = "{:.4f}") -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and v == float("inf"):
        return "never"
    return fmt.format(v)


def format_summary(summary: dict, scenario) -> str:
    """Per-drone RMSE, step metrics, formation, separation, contacts, events, speed; the paper's
    figures beside ours only where they compare like with like (:func:`paper_comparable`), and the
    downwash lines only where the physics has downwash."""
    s = summary
    lines = [
        f"scenario {s['scenario']}: {s['sim_time_s']:.1f} s simulated in {s['wall_time_s']:.2f} s "
        f"({s['real_time_factor']:.0f}x real time), {s['n_drones']} drone(s), seed {s['seed']}"
    ]
    if "vehicle" in s:  # what flew (swarm_mj/choices.py)
        g = s.get("gains") or {}
        lines.append(
            f"vehicle {s['vehicle']}, physics {s.get('physics', 'paper')}, "
            f"gains {gains_text(g.get('source', s.get('gains_source', '')), g.get('origin', 'scenario'))}"
        )
    paper = paper_comparable(scenario)
    leader = s["drones"]["leader"]
    lines += _step_lines(leader, paper) if "step" in leader else _rmse_lines(s, scenario, paper)
    if s["n_drones"] > 1:
        lines += _swarm_lines(s, paper, downwash=bool((s.get("aero") or {}).get("downwash")))
    lines += _physics_lines(s)
    lines += _sensing_lines(s)
    if s.get("stopped"):
        lines += ["", f"STOPPED EARLY: {s['stopped']}"]
    failed = failure_line(s.get("flight"))
    if failed:
        lines += ["", failed.replace("flight failed", "FLIGHT FAILED", 1)]
    return "\n".join(lines)


def paper_comparable(scenario) -> bool:
    """Whether the run is the paper's experiment on the paper's drone, so that the paper's figures
    compare like with like: the vehicle's parameters are Table 1's and the leader's trajectory has the
    paper's parameters (its defaults, docs/interpretations.md §3). Decided from the data, never a name."""
    if getattr(scenario, "params", DEFAULT_PARAMS) != DEFAULT_PARAMS:
        return False
    if getattr(scenario, "trajectory", None) not in TRAJECTORIES:
        return False
    given = trajectory_args(scenario)
    defaults = trajectory_args(replace(scenario, trajectory_params={}))
    return given == defaults


def _step_lines(leader: dict, paper: bool) -> list[str]:
    """The leader's step response, the paper's figures beside it where ``paper``."""
    lines = ["", "step response (leader)       ours" + ("                          paper" if paper else "")]
    lines.append("axis  overshoot %  settling s  ss error" + ("     overshoot %  settling s" if paper else ""))
    for ax in ("x", "y", "z", "psi"):
        m = leader["step"][ax]
        row = (
            f"{ax:<5} {m['overshoot_pct']:>11.3f}  {_f(m['settling_s'], '{:>10.2f}')}  {m['steady_state_error']:>8.1e}"
        )
        if paper:
            pp = PAPER_STEP[ax]
            paper_settle = "<1.0" if ax == "psi" else f"{pp['settling_s']:.1f}"
            row += f"     {pp['overshoot_pct']:>11.1f}  {paper_settle:>10}"
        lines.append(row)
    lines.append(
        f"max |roll| {leader['max_abs_roll_deg']:.1f} deg, max |pitch| {leader['max_abs_pitch_deg']:.1f}"
        f" deg, rotor thrust {leader['min_rotor_thrust_n']:.2f}..{leader['max_rotor_thrust_n']:.2f} N"
    )
    return lines


def _rmse_lines(s: dict, scenario, paper: bool) -> list[str]:
    """Every drone's RMSE, whole run and steady part; Table 5's row beside them where ``paper``."""
    lines = ["", "RMSE (eq. 38)       x (m)     y (m)     z (m)  roll (deg) pitch (deg)  max rotor (N)"]
    steady_after = float(getattr(scenario, "steady_after", 10.0))
    steady_label = f" >{steady_after:g}s"
    for name, d in s["drones"].items():
        for label, key in (("", "rmse"), (steady_label, "rmse_steady")):
            r = d.get(key)
            if r is None:
                continue
            row = (
                f"{(name + label):<16} {r['x']:>9.4f} {r['y']:>9.4f} {r['z']:>9.4f} "
                f"{r['roll_deg']:>10.4f} {r['pitch_deg']:>10.4f}"
            )
            lines.append(row + (f"  {d['max_rotor_thrust_n']:>8.2f}" if key == "rmse" else ""))
    traj = scenario.trajectory
    table5 = PAPER_TABLE5.get((traj, bool(s.get("wind")))) if paper else None
    if table5:
        lines.append(
            f"{'paper (Table 5)':<16} {table5['x']:>9.4f} {table5['y']:>9.4f} {'':>9} "
            f"{table5['roll_deg']:>10.4f} {table5['pitch_deg']:>10.4f}   "
            f"({traj}, {'with' if s.get('wind') else 'without'} wind)"
        )
        if s.get("wind") and not s.get("wind_feedforward", True):
            lines.append(
                "  (ours with the wind feedforward OFF: the controller does not know the wind; "
                "the paper's figures use it, so these are reported only)"
            )
        if s["sim_time_s"] > steady_after:
            lines.append(
                "  (whole-run RMSE is dominated by the flight from the start onto the path; "
                f"'{steady_label.strip()}' is from t = {steady_after:g} s on, "
                "docs/interpretations.md)"
            )
    return lines


def _swarm_lines(s: dict, paper: bool, downwash: bool) -> list[str]:
    """Formation settling and error, separation, contacts, the downwash keep-out and dip (where the
    physics has downwash), the anti-collision rule's events."""
    f = s["formation"]
    settled = [x is not None and math.isfinite(x) for x in f["settling_s"]]
    settle = ", ".join(
        (f"{x:.2f} s" if ok else "never settled") + f" (D change at {c:g} s)"
        for x, ok, c in zip(f["settling_s"], settled, f["change_times_s"])
    )
    beside = f"   (paper: ~{PAPER_FORMATION_SETTLING_S:g} s)" if paper else ""
    lines = ["", f"formation settling: {settle or 'no D change within the run'}{beside}"]
    final = f"final {f['final_distance_error_m'] * 100:.2f} cm"
    if any(settled):
        lines.append(f"formation distance error once settled: max {f['max_distance_error_m'] * 100:.1f} cm, " + final)
    else:
        lines.append(f"formation distance error: {final} (never settled within 5 cm)")
    lines.append(
        f"min 3D separation: {s['min_separation_m']:.3f} m ({' & '.join(s['min_separation_pair'])} "
        f"at t = {s['min_separation_at_s']:.2f} s)"
    )
    lines.append(f"drone-drone contact episodes (MuJoCo, a pair touching over consecutive steps once): {s['contacts']}")
    rho = s.get("keepout_min_distance")
    if downwash and rho is not None:  # the keep-out invariant, every rule (docs/barrier.md, "the invariant measured")
        closest = f"closest ρ {rho:.3f} (1 = on it)" if math.isfinite(rho) else "never two drones airborne"
        lines.append(
            f"downwash keep-out (the vehicle's ellipsoid, docs/barrier.md): {closest}, "
            f"{s['keepout_time_s']:.2f} s with an airborne pair inside"
        )
    dw = s.get("downwash_dip")
    if downwash and dw is not None:
        where = f" ({dw['drone']} under {dw['above']} at t = {dw['at_s']:.2f} s)" if dw["drone"] else ""
        lines.append(
            f"worst altitude dip in another drone's jet: {dw['worst_m'] * 100:.1f} cm{where}; "
            f"time with a drone in a jet {dw['time_in_jet_s']:.2f} s"
        )
    a = s["anti_collision"]
    relaxed = ""
    if a.get("relaxations"):
        vs = a.get("relaxations_vs_leader", 0)
        relaxed = f", {a['relaxations']} barrier relaxations ({vs} against the leader; docs/barrier.md)"
    if a.get("reserve_periods"):
        relaxed += f", {a['reserve_periods']} drone-periods on the barrier's reserve"
    if a.get("joint_periods"):
        relaxed += f", {a['joint_periods']} drone-periods in the barrier's joint fallback"
    lines.append(f"anti-collision rule '{a['rule']}': {a['events']} events, {a['yields']} altitude yields{relaxed}")
    auto = s.get("anti_collision_auto")
    if auto is not None:
        lines.append(f"  (auto chose '{auto['rule']}': {auto['why']})")
    return lines


def _sensing_lines(s: dict) -> list[str]:
    """What each drone knew of the others, where it was not the oracle (docs/sensing.md)."""
    sn = s.get("sensing") or {}
    if not sn.get("own_view"):
        return []
    rate = f"{sn['rate_hz']:g} Hz" if sn.get("rate_hz") else "every period"
    lines = [
        f"sensing '{sn.get('preset')}': each drone decided from its own view (σ {1000 * sn['position_noise_m']:g} mm, "
        f"{rate}, latency {1000 * sn['latency_s']:g} ms, loss {100 * sn['packet_loss']:g} %); what it believed was "
        f"off the truth by {100 * (sn.get('belief_error_m') or {}).get('median', 0.0):.1f} cm median, "
        f"{100 * (sn.get('belief_error_m') or {}).get('max', 0.0):.1f} cm at most (docs/sensing.md)"
    ]
    m = sn.get("robust_margin")
    if m:
        capped = m["applied_m"] < m["needed_m"]
        lines.append(
            f"  barrier keep-out widened by {100 * m['applied_m']:.1f} cm (the robust margin at {m['confidence']:g}"
            + (f" needs {100 * m['needed_m']:.1f} cm: capped by the formation's room, no guarantee)" if capped else ")")
        )
    return lines


def _physics_lines(s: dict) -> list[str]:
    """The physics and the controller where they are not the paper's; ground contacts and crashes."""
    aero = s.get("aero") or {}
    if not (aero.get("model", "paper") != "paper" or aero.get("ground") or aero.get("motor_tau")):
        return []
    ctl = s.get("controller") or {}
    lag = ctl.get("lag_compensation_s")
    lines = [
        f"physics '{aero.get('model')}': ground {'on' if aero.get('ground') else 'off'}, downwash "
        f"{'on' if aero.get('downwash') else 'off'}, ground effect {'on' if aero.get('ground_effect') else 'off'}, "
        f"rotor lag {1000 * float(aero.get('motor_tau') or 0):g} ms; controller: "
        f"{_MIXER_WORDS.get(str(ctl.get('mixer')), 'per-rotor clip')} mixing, "
        + (f"attitude predicted {1000 * lag[0]:g} ms ahead" if lag else "no lag compensation")
        + " (docs/aero.md)"
    ]
    if aero.get("ground"):
        lines.append(
            f"ground contacts: {s.get('ground_contacts', 0)}, crashes: {s.get('crashes', 0)} "
            "(touchdown > 1 m/s or tilt > 30°)"
        )
    return lines
