"""The report's ten figures (matplotlib, Agg) and the MuJoCo still: one function per figure.

Each ``_fig_*`` draws from results.json's numbers (``R``) and the logs the jobs sent back
(``logs``, keyed by job), appends ``{file, caption}`` to ``figures``, and skips itself when its
data is missing (e.g. a plan without the FPA runs).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .tables import as_number, fmt_cell


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "figure.dpi": 100,
            "savefig.dpi": 110,
            "font.size": 9,
            "axes.grid": True,
            "grid.alpha": 0.3,
            "legend.fontsize": 7,
        }
    )
    return plt


def _save(fig, out: Path, name: str, caption: str, figures: list) -> None:
    tmp = out / f".{name}.partial.png"
    fig.savefig(tmp, bbox_inches="tight")
    os.replace(tmp, out / name)
    import matplotlib.pyplot as plt

    plt.close(fig)
    figures.append({"file": name, "caption": caption})


def draw_all(out: Path, R: dict, logs: dict[str, dict]) -> list[dict]:
    """Every figure of the report; returns [{file, caption}]. A figure whose data is missing is skipped."""
    figures: list[dict] = []
    for fn in (
        _fig_step,
        _fig_rotors,
        _fig_lemniscate,
        _fig_wind,
        _fig_swarms,
        _fig_variable_d,
        _fig_anticollision,
        _fig_wind_robustness,
        _fig_sigma,
        _fig_fpa,
    ):
        fn(out, R, logs, figures)
    return figures


def _fig_step(out, R, logs, figures):
    lg = logs.get("step/table4")
    if lg is None:
        return
    plt = _plt()
    t = lg["t"]
    fig, axs = plt.subplots(2, 3, figsize=(12, 6.2))
    target = lg["pos_d"][-1, 0]
    others = [
        (k, lab, ls)
        for k, lab, ls in (("step/fpa", "FPA gains", "--"), ("step/paper_map", "eq. (1) attitude map", ":"))
        if k in logs
    ]
    paper_settle = {"x": 1.5, "y": 1.5, "z": 1.0, "psi": 1.0}
    for j, (ax, nm) in enumerate(zip(axs.flat[:4], ("x", "y", "z", "psi"))):
        if nm == "psi":
            y, ref, unit = np.rad2deg(lg["rpy"][:, 0, 2]), 25.0, "deg"
        else:
            y, ref, unit = lg["pos"][:, 0, j], target[j], "m"
        ax.plot(t, y, label="ours, Table 4 gains", color="C0")
        for k, lab, ls in others:
            o = logs[k]
            yo = np.rad2deg(o["rpy"][:, 0, 2]) if nm == "psi" else o["pos"][:, 0, j]
            ax.plot(o["t"], yo, ls, label=lab, lw=1)
        ax.axhline(ref, color="k", lw=0.8, ls="--", label="set-point")
        settle = "< 1" if nm == "psi" else paper_settle[nm]
        ax.axvline(paper_settle[nm], color="r", lw=0.8, ls=":", label=f"paper settling {settle} s")
        ax.set_title(f"{'ψ' if nm == 'psi' else nm} ({unit})")
        ax.set_xlabel("t (s)")
        ax.set_xlim(0, min(6, t[-1]))
        if j == 0:
            ax.legend(loc="lower right")
    ax = axs.flat[4]
    for i, (nm, c) in enumerate((("roll φ", "C0"), ("pitch θ", "C1"))):
        ax.plot(t, np.rad2deg(lg["rpy"][:, 0, i]), color=c, label=f"{nm}")
        ax.plot(t, np.rad2deg(lg["att_d"][:, 0, i]), color=c, ls="--", lw=0.8, label=f"{nm} commanded")
    ax.axhline(45, color="r", lw=0.8, ls=":")
    ax.axhline(-45, color="r", lw=0.8, ls=":", label="±45° (paper Fig. 7b)")
    ax.set_xlim(0, min(6, t[-1]))
    ax.set_title("(b) roll and pitch (deg)")
    ax.set_xlabel("t (s)")
    ax.legend(loc="upper right")
    ax = axs.flat[5]
    st = R["step"]["table4"]["axes"]
    rows = [["axis", "overshoot %", "settling s", "paper s"]]
    for nm in ("x", "y", "z", "psi"):
        rows.append(
            [
                nm,
                f"{st[nm]['overshoot_pct']:.3f}",
                fmt_cell(st[nm]["settling_s"], "{:.2f}"),
                "< 1" if nm == "psi" else f"{paper_settle[nm]:.1f}",
            ]
        )
    ax.axis("off")
    tb = ax.table(cellText=rows, loc="center")
    tb.scale(1, 1.5)
    fig.suptitle("Step response to x = y = z = 1 m, ψ = 25° (paper Fig. 7)")
    fig.tight_layout()
    _save(
        fig,
        out,
        "fig07_step.png",
        "Step response (paper Fig. 7): (a) x, y, z, ψ; (b) roll and pitch with "
        "their commanded values; red dotted: the paper's settling times and ±45°",
        figures,
    )


def _fig_rotors(out, R, logs, figures):
    lg = logs.get("step/table4")
    if lg is None:
        return
    plt = _plt()
    t = lg["t"]
    fig, axs = plt.subplots(1, 2, figsize=(11, 3.4))
    for i in range(4):
        axs[0].plot(t[:-1], lg["rotor"][:-1, 0, i], label=f"F{i + 1}")
    axs[0].axhline(4.5, color="r", ls=":", lw=0.8, label="saturation 4.5 N")
    axs[0].set_title("rotor thrusts (N)")
    axs[0].legend()
    for i, nm in enumerate(("U1 (N)", "U2 (N)", "U3 (N)", "U4 (N)")):
        axs[1].plot(t[:-1], lg["U"][:-1, 0, i], label=nm)
    axs[1].set_title("control inputs U1..U4 (applied, after saturation)")
    axs[1].legend()
    for a in axs:
        a.set_xlabel("t (s)")
        a.set_xlim(0, min(6, t[-1]))
    fig.tight_layout()
    _save(fig, out, "fig08_rotors.png", "Rotor thrusts and control inputs during the step (paper Fig. 8)", figures)


def _fig_lemniscate(out, R, logs, figures):
    lg = logs.get("t5/lemniscate_single/ground")
    if lg is None:
        return
    plt = _plt()
    t, p, pd = lg["t"], lg["pos"][:, 0], lg["pos_d"][:, 0]
    fig = plt.figure(figsize=(13, 3.8))
    for j, nm in enumerate("xy"):
        ax = fig.add_subplot(1, 3, j + 1)
        ax.plot(t, pd[:, j], "k--", lw=1, label=f"{nm} desired")
        ax.plot(t, p[:, j], color="C0", lw=1, label=f"{nm} ours")
        ax2 = ax.twinx()
        ax2.plot(t, (pd[:, j] - p[:, j]) * 1000, color="C3", lw=0.6, alpha=0.7)
        ax2.set_ylabel("error (mm)", color="C3")
        ax2.set_ylim(-5, 5)
        ax.set_title(f"{nm} (m)")
        ax.set_xlabel("t (s)")
        ax.legend(loc="upper left")
    ax = fig.add_subplot(1, 3, 3, projection="3d")
    ax.plot(pd[:, 0], pd[:, 1], pd[:, 2], "k--", lw=1, label="desired")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color="C0", lw=1, label="ours")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.legend()
    fig.suptitle("Lemniscate (eq. 30), single drone, no wind (paper Fig. 9)")
    fig.tight_layout()
    _save(
        fig,
        out,
        "fig09_lemniscate.png",
        "Lemniscate tracking without wind (paper Fig. 9): x and y with the error (red, right axis, mm) and the 3D path",
        figures,
    )


def _fig_wind(out, R, logs, figures):
    lg = logs.get("t5/wind_lemniscate/ground")
    if lg is None:
        return
    plt = _plt()
    t, p, pd = lg["t"], lg["pos"][:, 0], lg["pos_d"][:, 0]
    fig, axs = plt.subplots(4, 2, figsize=(12, 9), sharex=True)
    for j, nm in enumerate("xy"):
        axs[0, j].plot(t, pd[:, j], "k--", lw=1, label="desired")
        axs[0, j].plot(t, p[:, j], color="C0", lw=1, label="ours")
        axs[0, j].set_title(f"{nm} (m)")
        axs[0, j].legend(loc="upper right")
        axs[1, j].plot(t, (pd[:, j] - p[:, j]) * 1000, color="C3", lw=0.7)
        axs[1, j].set_title(f"{nm} error (mm)")
        axs[2, j].plot(t, lg["wind_speed"][:, j], color="C2", lw=0.7)
        axs[2, j].set_title(f"wind speed V{nm} (m/s)")
        axs[3, j].plot(t, lg["wind_force"][:, 0, j], color="C4", lw=0.7)
        axs[3, j].set_title(f"wind force F{nm} on the drone (N)")
        axs[3, j].set_xlabel("t (s)")
        for a in axs[:, j]:
            a.axvline(20, color="gray", ls=":", lw=0.8)
            a.axvline(50, color="gray", ls=":", lw=0.8)
    fig.suptitle("Lemniscate under the paper's wind (Fx from 20 s, Fx + Fy from 50 s), seed 0 (paper Fig. 15)")
    fig.tight_layout()
    _save(
        fig,
        out,
        "fig15_wind.png",
        "Tracking under wind (paper Fig. 15): x, y, their errors, the wind speeds "
        "Vx, Vy (eq. 35) and the forces Fx, Fy (eq. 37) on the drone",
        figures,
    )


def _fig_swarms(out, R, logs, figures):
    names = [
        n
        for n in ("circle", "lemniscate", "ascending_orbit", "scenario1", "scenario2", "scenario3")
        if f"swarm/{n}" in logs
    ]
    if not names:
        return
    plt = _plt()
    fig = plt.figure(figsize=(15, 9))
    for k, n in enumerate(names):
        lg = logs[f"swarm/{n}"]
        ax = fig.add_subplot(2, 3, k + 1, projection="3d")
        pos = lg["pos"]
        for i, nm in enumerate(lg["names"]):
            c = "C3" if i == 0 else f"C{i - 1 if i < 4 else i}"
            ax.plot(pos[:, i, 0], pos[:, i, 1], pos[:, i, 2], color=c, lw=0.7 if i else 1.2, label=nm)
            ax.scatter(*pos[0, i], color=c, marker="o", s=12)
            ax.scatter(*pos[-1, i], color=c, marker="^", s=18)
        ax.set_title(f"{n} ({lg['t'][-1]:.0f} s)")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_zlabel("z (m)")
        if k == 0:
            ax.legend(loc="upper left", fontsize=6)
    fig.suptitle("Swarm paths in 3D (paper Figs. 10–13): o start, ^ end; red = leader")
    fig.tight_layout()
    _save(
        fig, out, "swarm_paths_3d.png", "3D paths of the six drones in the swarm scenarios (paper Figs. 10–13)", figures
    )


def _fig_variable_d(out, R, logs, figures):
    lg = logs.get("variable_d")
    if lg is None:
        return
    from ..metrics import follower_distances, leader_distances

    plt = _plt()
    t, pos, D = lg["t"], lg["pos"], lg["D"]
    fig, axs = plt.subplots(1, 2, figsize=(12, 4))
    ld = leader_distances(pos)
    for i in range(ld.shape[1]):
        axs[0].plot(t, ld[:, i], lw=1, label=f"follower{i + 1}")
    axs[0].plot(t, D, "k--", lw=1, label="D(t)")
    for c in R["variable_d"]["change_times_s"]:
        axs[0].axvline(c, color="gray", ls=":", lw=0.8)
    axs[0].set_title("leader–follower horizontal distance (m)")
    axs[0].legend()
    fd, pairs = follower_distances(pos)
    for k, (i, j) in enumerate(pairs):
        axs[1].plot(t, fd[:, k], lw=0.8, label=f"F{i}–F{j}")
    ang = 2 * np.sin(np.pi / 5)
    axs[1].plot(t, D * ang, "k--", lw=1, label="adjacent slots 1.18·D")
    axs[1].plot(t, D * 2 * np.sin(2 * np.pi / 5), "k:", lw=1, label="opposite slots 1.90·D")
    axs[1].set_title("follower–follower horizontal distance (m)")
    axs[1].legend(ncol=2)
    for a in axs:
        a.set_xlabel("t (s)")
    fig.suptitle("Variable D of eq. (34): 1, 1.7, 1.2, 2 m at t = 0, 6, 11, 16 s (paper Fig. 14)")
    fig.tight_layout()
    _save(
        fig,
        out,
        "fig14_variable_d.png",
        "Distances with a variable D (paper Fig. 14): leader–follower (left), follower–follower (right)",
        figures,
    )


def _fig_anticollision(out, R, logs, figures):
    rules = [r for r in ("layers", "paper", "off") if f"ac/anti_collision/{r}" in logs]
    if not rules:
        return
    plt = _plt()
    fig, axs = plt.subplots(2, len(rules), figsize=(4.6 * len(rules), 6.5), squeeze=False)
    for k, rule in enumerate(rules):
        lg = logs[f"ac/anti_collision/{rule}"]
        t, pos = lg["t"], lg["pos"]
        ax = axs[0, k]
        for i, nm in enumerate(lg["names"]):
            ax.plot(t, pos[:, i, 2], lw=1, color="C3" if i == 0 else f"C{i - 1 if i < 4 else i}", label=nm)
        ax.set_title(f"rule '{rule}': altitude z (m)")
        ax.set_xlabel("t (s)")
        if k == 0:
            ax.legend(fontsize=6)
        n = pos.shape[1]
        i, j = np.triu_indices(n, 1)
        d = np.linalg.norm(pos[:, i] - pos[:, j], axis=-1).min(axis=1)
        dh = np.linalg.norm(pos[:, i, :2] - pos[:, j, :2], axis=-1).min(axis=1)
        ax = axs[1, k]
        ax.plot(t, d, label="min 3D separation")
        ax.plot(t, dh, lw=0.8, alpha=0.7, label="min horizontal distance")
        ax.axhline(0.8, color="gray", ls="--", lw=0.8, label="safety distance 0.8 m")
        ax.axhline(0.68, color="r", ls=":", lw=0.8, label="0.68 m (rotor tips can touch)")
        row = next(
            (r for r in R["anti_collision"]["rows"] if r["scenario"] == "anti_collision" and r["rule"] == rule), None
        )
        if row:
            ax.set_title(f"'{rule}': {row['contacts']} contacts, min {row['min_separation_m']:.2f} m")
        ax.set_ylim(0, 3)
        ax.set_xlabel("t (s)")
        if k == 0:
            ax.legend(fontsize=6)
    fig.suptitle("Anti-collision: followers crossing past the hovering leader (paper Fig. 16b)")
    fig.tight_layout()
    _save(
        fig,
        out,
        "fig16_anticollision.png",
        "Anti-collision (paper Fig. 16b): altitudes and minimum pairwise "
        "distances with our layered rule, the paper's rule and none",
        figures,
    )


def _fig_wind_robustness(out, R, logs, figures):
    sw = R.get("sweeps", {})
    keys = [k for k in ("wind_circle", "wind_circle_noff", "wind_lemniscate", "wind_lemniscate_noff") if k in sw]
    if not keys:
        return
    plt = _plt()
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.2))
    metrics = [("rmse_x", "x"), ("rmse_y", "y"), ("rmse_steady_x", "x ≥10s"), ("rmse_steady_y", "y ≥10s")]
    for a, traj in zip(axs, ("circle", "lemniscate")):
        p = R["table5"]["paper"][f"{traj}/wind"]
        for off, (key, lab) in enumerate(((f"wind_{traj}", "FF"), (f"wind_{traj}_noff", "no FF"))):
            if key not in sw:
                continue
            for mi, (mk, _label) in enumerate(metrics):
                vals = [as_number(r["metrics"].get(mk)) for r in sw[key]["runs"]]
                xs = mi + (off - 0.5) * 0.35 + np.linspace(-0.06, 0.06, len(vals))
                a.scatter(xs, vals, s=8, color=f"C{off}", label=lab if mi == 0 else None)
        a.scatter([0, 2], [p["x"], p["x"]], marker="_", s=400, color="k", label="paper x")
        a.scatter([1, 3], [p["y"], p["y"]], marker="_", s=400, color="r", label="paper y")
        a.set_xticks(range(len(metrics)), [m[1] for m in metrics])
        a.set_yscale("log")
        a.set_title(f"{traj} under wind: RMSE (m), one dot per seed")
        a.legend()
    fig.tight_layout()
    _save(
        fig,
        out,
        "wind_robustness.png",
        "Wind robustness: leader RMSE per seed (whole run and t ≥ 10 s), with "
        "and without wind feedforward, beside the paper's Table 5",
        figures,
    )


def _fig_sigma(out, R, logs, figures):
    sw = R.get("sweeps", {})
    keys = [k for k in ("sigma/wind_lemniscate", "sigma/wind_lemniscate_noff") if k in sw]
    if not keys:
        return
    plt = _plt()
    fig, axs = plt.subplots(1, 2, figsize=(11, 3.8))
    for off, key in enumerate(keys):
        s = sw[key]
        v = np.array(s["values"], float)
        for a, mk in zip(axs, ("rmse_steady_x", "rmse_steady_y")):
            mean = [as_number(r["stats"][mk]["mean"]) for r in s["results"]]
            std = [as_number(r["stats"][mk]["std"]) for r in s["results"]]
            worst = [as_number(r["stats"][mk]["worst"]) for r in s["results"]]
            lab = "no FF" if "noff" in key else "FF"
            a.errorbar(
                v + off * 0.01, mean, yerr=std, marker="o", capsize=3, color=f"C{off}", label=f"{lab} mean ± std"
            )
            a.plot(v, worst, "x", color=f"C{off}", label=f"{lab} worst")
            a.set_xlabel("σ (m/s)")
            a.set_title(f"lemniscate under wind: {mk.replace('rmse_steady_', '')} RMSE, t ≥ 10 s (m)")
            a.set_yscale("log")
    axs[0].legend()
    fig.tight_layout()
    _save(
        fig,
        out,
        "wind_sigma.png",
        "Steady RMSE against the turbulence intensity σ (mean ± std and worst over the seeds)",
        figures,
    )


def _fig_fpa(out, R, logs, figures):
    ours = R.get("table3", {}).get("ours") or []
    if not ours:
        return
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for o in ours:
        h = [as_number(x) for x in o["history"]]
        (line,) = ax.plot(
            range(len(h)), h, marker="o", ms=3, label=f"seed {o['seed']} ({fmt_cell(o['improvement_pct'], '{:.1f}')} %)"
        )
        for q in R["table3"].get("ours_paper_mode") or []:
            if q["seed"] == o["seed"]:
                hq = [as_number(x) for x in q["history"]]
                ax.plot(
                    range(len(hq)),
                    hq,
                    ls=":",
                    color=line.get_color(),
                    lw=1,
                    label=f"seed {q['seed']}, paper mode ({fmt_cell(q['improvement_pct'], '{:.1f}')} %)",
                )
    ax.axhline(R["gains"]["table4_ise"], color="k", ls="--", lw=0.8, label="paper Table 4 gains")
    if R["gains"].get("fpa_ise") is not None:
        ax.axhline(R["gains"]["fpa_ise"], color="r", ls=":", lw=0.8, label="fpa_seed1.toml")
    ax.set_xlabel("iteration (0 = initial population)")
    ax.set_ylabel("best ISE")
    ax.set_title("FPA convergence (paper Table 3)")
    ax.legend()
    fig.tight_layout()
    _save(fig, out, "fpa_convergence.png", "FPA convergence: best ISE per iteration (paper Table 3)", figures)


def draw_snapshot(out: Path, log, say) -> list[dict]:
    """A MuJoCo still of scenario1 (EGL); skipped with a note when rendering is unavailable."""
    try:
        from ..video import render_snapshot

        tt = float(min(20.0, log.t[-1]))
        render_snapshot(log, out / "snapshot_scenario1.png", time=tt, size=(960, 540))
        return [{"file": "snapshot_scenario1.png", "caption": f"MuJoCo view of scenario1 at t = {tt:g} s"}]
    except Exception as exc:  # noqa: BLE001 - optional: no EGL, no video module
        say(f"snapshot skipped: {type(exc).__name__}: {exc}")
        return []
