"""Human-readable tables of a run summary, ours beside the paper's (docs/interpretations.md)."""

from __future__ import annotations

import math

from ..paper import PAPER_FORMATION_SETTLING_S, PAPER_STEP, PAPER_TABLE5


def _f(v, fmt: str = "{:.4f}") -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and v == float("inf"):
        return "never"
    return fmt.format(v)


def format_summary(summary: dict, scenario) -> str:
    """Per-drone RMSE, step metrics, formation, separation, contacts, events, speed."""
    lines: list[str] = []
    s = summary
    lines.append(
        f"scenario {s['scenario']}: {s['sim_time_s']:.1f} s simulated in {s['wall_time_s']:.2f} s "
        f"({s['real_time_factor']:.0f}x real time), {s['n_drones']} drone(s), seed {s['seed']}"
    )
    leader = s["drones"]["leader"]
    if "step" in leader:
        lines.append("")
        lines.append("step response (leader)       ours                          paper")
        lines.append("axis  overshoot %  settling s  ss error     overshoot %  settling s")
        for ax in ("x", "y", "z", "psi"):
            m = leader["step"][ax]
            pp = PAPER_STEP[ax]
            paper_settle = "<1.0" if ax == "psi" else f"{pp['settling_s']:.1f}"
            lines.append(
                f"{ax:<5} {m['overshoot_pct']:>11.3f}  {_f(m['settling_s'], '{:>10.2f}')}  "
                f"{m['steady_state_error']:>8.1e}     {pp['overshoot_pct']:>11.1f}  {paper_settle:>10}"
            )
        lines.append(
            f"max |roll| {leader['max_abs_roll_deg']:.1f} deg, max |pitch| {leader['max_abs_pitch_deg']:.1f}"
            f" deg, rotor thrust {leader['min_rotor_thrust_n']:.2f}..{leader['max_rotor_thrust_n']:.2f} N"
        )
    else:
        lines.append("")
        lines.append("RMSE (eq. 38)       x (m)     y (m)     z (m)  roll (deg) pitch (deg)  max rotor (N)")
        steady_after = float(getattr(scenario, "steady_after", 10.0))
        steady_label = f" >{steady_after:g}s"
        for name, d in s["drones"].items():
            for label, key in (("", "rmse"), (steady_label, "rmse_steady")):
                r = d.get(key)
                if r is None:
                    continue
                lines.append(
                    f"{(name + label):<16} {r['x']:>9.4f} {r['y']:>9.4f} {r['z']:>9.4f} "
                    f"{r['roll_deg']:>10.4f} {r['pitch_deg']:>10.4f}  "
                    f"{d['max_rotor_thrust_n']:>8.2f}"
                    if key == "rmse"
                    else f"{(name + label):<16} {r['x']:>9.4f} {r['y']:>9.4f} {r['z']:>9.4f} "
                    f"{r['roll_deg']:>10.4f} {r['pitch_deg']:>10.4f}"
                )
        traj = scenario.trajectory
        if traj in ("circle", "lemniscate") and scenario.trajectory_params.get("climb_rate", 0) == 0:
            paper = PAPER_TABLE5.get((traj, bool(s.get("wind"))))
            if paper:
                lines.append(
                    f"{'paper (Table 5)':<16} {paper['x']:>9.4f} {paper['y']:>9.4f} {'':>9} "
                    f"{paper['roll_deg']:>10.4f} {paper['pitch_deg']:>10.4f}   "
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
    if s["n_drones"] > 1:
        f = s["formation"]
        settled = [x is not None and math.isfinite(x) for x in f["settling_s"]]
        settle = ", ".join(
            (f"{x:.2f} s" if ok else "never settled") + f" (D change at {c:g} s)"
            for x, ok, c in zip(f["settling_s"], settled, f["change_times_s"])
        )
        lines.append("")
        lines.append(
            f"formation settling: {settle or 'no D change within the run'}   (paper: ~{PAPER_FORMATION_SETTLING_S:g} s)"
        )
        final = f"final {f['final_distance_error_m'] * 100:.2f} cm"
        if any(settled):
            lines.append(
                f"formation distance error once settled: max {f['max_distance_error_m'] * 100:.1f} cm, " + final
            )
        else:
            lines.append(f"formation distance error: {final} (never settled within 5 cm)")
        lines.append(
            f"min 3D separation: {s['min_separation_m']:.3f} m ({' & '.join(s['min_separation_pair'])} "
            f"at t = {s['min_separation_at_s']:.2f} s)"
        )
        lines.append(
            f"drone-drone contact episodes (MuJoCo, a pair touching over consecutive steps once): {s['contacts']}"
        )
        rho = s.get("keepout_min_distance")
        if rho is not None:  # the keep-out invariant, every rule (docs/barrier.md, "the invariant measured")
            closest = f"closest ρ {rho:.3f} (1 = on it)" if math.isfinite(rho) else "never two drones airborne"
            lines.append(
                f"downwash keep-out (the vehicle's ellipsoid, docs/barrier.md): {closest}, "
                f"{s['keepout_time_s']:.2f} s with an airborne pair inside"
            )
        dw = s.get("downwash_dip")
        if dw is not None:
            where = f" ({dw['drone']} under {dw['above']} at t = {dw['at_s']:.2f} s)" if dw["drone"] else ""
            lines.append(
                f"worst altitude dip in another drone's jet: {dw['worst_m'] * 100:.1f} cm{where}; "
                f"time with a drone in a jet {dw['time_in_jet_s']:.2f} s"
            )
        a = s["anti_collision"]
        relaxed = f", {a['relaxations']} barrier relaxations (docs/barrier.md)" if a.get("relaxations") else ""
        lines.append(f"anti-collision rule '{a['rule']}': {a['events']} events, {a['yields']} altitude yields{relaxed}")
        auto = s.get("anti_collision_auto")
        if auto is not None:
            lines.append(f"  (auto chose '{auto['rule']}': {auto['why']})")
    aero = s.get("aero") or {}
    if aero.get("model", "paper") != "paper" or aero.get("ground") or aero.get("motor_tau"):
        ctl = s.get("controller") or {}
        lag = ctl.get("lag_compensation_s")
        lines.append(
            f"physics '{aero.get('model')}': ground {'on' if aero.get('ground') else 'off'}, downwash "
            f"{'on' if aero.get('downwash') else 'off'}, ground effect {'on' if aero.get('ground_effect') else 'off'}, "
            f"rotor lag {1000 * float(aero.get('motor_tau') or 0):g} ms; controller: "
            f"{'attitude-priority' if ctl.get('mixer') == 'attitude_priority' else 'per-rotor clip'} mixing, "
            + (f"attitude predicted {1000 * lag[0]:g} ms ahead" if lag else "no lag compensation")
            + " (docs/aero.md)"
        )
        if aero.get("ground"):
            lines.append(
                f"ground contacts: {s.get('ground_contacts', 0)}, crashes: {s.get('crashes', 0)} "
                "(touchdown > 1 m/s or tilt > 30°)"
            )
    if s.get("stopped"):
        lines.append("")
        lines.append(f"STOPPED EARLY: {s['stopped']}")
    return "\n".join(lines)
