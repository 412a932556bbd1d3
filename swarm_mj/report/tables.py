"""The report's Markdown: each paper figure or table beside ours, rendered from results.json.

:func:`render_markdown` reads only the results (``R`` as written to results.json), so the README
of the report and the README tables (``tools/readme_tables.py``) cannot disagree with the numbers.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


def as_number(v: Any) -> float:
    """A number from results.json (inf as "inf", NaN as None)."""
    if v is None:
        return float("nan")
    if isinstance(v, str):
        return float(v)
    return float(v)


def fmt_cell(v: Any, fmt: str = "{:.4f}") -> str:
    """A number for a table cell: "–" when missing, "never" when infinite."""
    if v is None:
        return "–"
    if isinstance(v, str):
        return "never" if v == "inf" else v
    if isinstance(v, float) and math.isnan(v):
        return "–"
    if isinstance(v, float) and math.isinf(v):
        return "never"
    return fmt.format(v)


def _r(v: Any) -> str:
    """An RMSE: 4 decimals like the paper, 2 significant digits below 0.001."""
    v = as_number(v)
    if not math.isfinite(v):
        return fmt_cell(v)
    return f"{v:.4f}" if abs(v) >= 1e-3 or v == 0 else f"{v:.2g}"


def _ratio(a: Any, b: Any) -> str:
    a, b = as_number(a), as_number(b)
    if not (math.isfinite(a) and math.isfinite(b)) or b == 0:
        return "–"
    return f"{a / b:.2f}×" if a / b >= 0.1 else f"{a / b:.2g}×"


def _diff(a: Any, b: Any, fmt: str = "{:+.2f}") -> str:
    a, b = as_number(a), as_number(b)
    if math.isinf(a) and a > 0:
        return "never settles"
    if not (math.isfinite(a) and math.isfinite(b)):
        return "–"
    return fmt.format(a - b)


def _table(headers: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _ms(st: dict | None, fmt: str = "{:.3g}") -> str:
    """mean ± std (worst) of a sweep statistic."""
    if not st:
        return "–"
    s = f"{fmt_cell(st['mean'], fmt)} ± {fmt_cell(st['std'], fmt)} ({fmt_cell(st['worst'], fmt)})"
    if st.get("n_nonfinite"):
        s += f", {st['n_nonfinite']} never"
    return s


def _fig(R: dict, name: str) -> str:
    for f in R.get("figures", []):
        if f["file"] == name:
            return f"![{f['caption']}]({f['file']})\n\n*{f['caption']}*\n"
    return f"*(figure {name} not drawn)*\n"


def _header(R: dict) -> list[str]:
    """The title and the run's provenance (machine, mode, time)."""
    L: list[str] = []
    m = R["meta"]
    mach = m["machine"]
    plan = m["plan"]
    L.append("# swarm-mj report: the paper's experiments beside ours\n")
    L.append(
        f"Generated {m['generated']} by `swarm-mj report` ({plan['name']} mode) in {m['wall_s']:.0f} s on "
        f"{m['workers']} worker process(es): {mach['cpu']}, {mach['cores']} cores, Python {mach['python']}, "
        f"MuJoCo {mach['mujoco']}, NumPy {mach['numpy']}. Every number below is in `results.json`. "
        + (
            "**Quick mode: shortened runs and few seeds — not the paper's experiments; run "
            "`swarm-mj report` for those.**"
            if plan["name"] != "full"
            else ""
        )
        + "\n"
    )
    return L


def _interpretations(R: dict) -> list[str]:
    """The interpretations the runs rest on (docs/interpretations.md)."""
    L: list[str] = []
    L.append("## Interpretations (docs/interpretations.md)\n")
    for it in R["interpretations"]:
        L.append(f"- **{it['name']}.** {it['text']}")
    L.append("")
    return L


def _step_section(R: dict) -> list[str]:
    """1. The step response beside the paper's Fig. 7, Fig. 8."""
    L: list[str] = []
    st = R["step"]
    L.append("## 1. Step response (paper Fig. 7, Fig. 8)\n")
    L.append(
        "Step from rest on the ground at the origin to x = y = z = 1 m, ψ = 25° (docs/interpretations.md §3); "
        "2 % settling time; overshoot in % of the step. Paper: no overshoot, no steady-state error, "
        "settling 1.5 s (x, y), 1 s (z), < 1 s (ψ).\n"
    )
    hdr = [
        "axis",
        "paper overshoot %",
        "ours overshoot %",
        "paper settling (s)",
        "ours settling (s)",
        "ours − paper (s)",
        "ours steady-state error",
    ]
    extra_cols = []
    if st.get("fpa"):
        extra_cols.append(("fpa", "FPA gains settling (s)"))
    extra_cols.append(("paper_attitude_map", "eq. (1) attitude map settling (s)"))
    hdr += [c[1] for c in extra_cols]
    rows = []
    for ax in ("x", "y", "z", "psi"):
        a = st["table4"]["axes"][ax]
        p = st["paper"][ax]
        paper_settle = "< 1.0" if ax == "psi" else f"{p['settling_s']:.1f}"
        row = [
            ax if ax != "psi" else "ψ",
            f"{p['overshoot_pct']:.0f}",
            fmt_cell(a["overshoot_pct"], "{:.3f}"),
            paper_settle,
            fmt_cell(a["settling_s"], "{:.2f}"),
            _diff(a["settling_s"], p["settling_s"]),
            fmt_cell(a["steady_state_error"], "{:.1e}"),
        ]
        for k, _ in extra_cols:
            row.append(
                fmt_cell(st[k]["axes"][ax]["settling_s"], "{:.2f}")
                + f" (overshoot {fmt_cell(st[k]['axes'][ax]['overshoot_pct'], '{:.2f}')} %)"
            )
        rows.append(row)
    L.append(_table(hdr, rows))
    t4 = st["table4"]
    L.append("")
    L.append(
        f"Peak attitude during the step (Table 4 gains): |roll| {t4['max_abs_roll_deg']:.1f}°, |pitch| "
        f"{t4['max_abs_pitch_deg']:.1f}° (paper Fig. 7b: within ±{st['paper']['max_angle_deg']:.0f}°, the clip "
        f"of the desired angles; the actual pitch overshoots the clip, docs/interpretations.md §2). Rotor thrusts "
        f"{t4['rotor_min_n']:.2f}–{t4['rotor_max_n']:.2f} N (limit 4.5 N; paper Fig. 8: within the motors' "
        f"range)."
    )
    pm = st["paper_attitude_map"]
    L.append(
        f"With eq. (1)'s attitude map: |roll| {pm['max_abs_roll_deg']:.1f}°, |pitch| {pm['max_abs_pitch_deg']:.1f}°.\n"
    )
    L.append(_fig(R, "fig07_step.png"))
    L.append(_fig(R, "fig08_rotors.png"))
    return L


def _gains_section(R: dict) -> list[str]:
    """2. The gains: paper Table 4 beside the FPA-tuned ones."""
    L: list[str] = []
    g = R["gains"]
    L.append("## 2. Gains: paper Table 4 beside FPA-tuned (Tables 2–4)\n")
    if g["fpa"] is None:
        L.append(
            "The FPA-tuned gains file `scenarios/gains/fpa_seed1.toml` is **missing** (make it with "
            "`swarm-mj tune --seed 1`); only Table 4 is shown.\n"
        )
    names = [
        "α1 (φ)",
        "α2 (φ)",
        "α3 (θ)",
        "α4 (θ)",
        "α5 (ψ)",
        "α6 (ψ)",
        "α7 (x)",
        "α8 (x)",
        "α9 (y)",
        "α10 (y)",
        "α11 (z)",
        "α12 (z)",
    ]
    rows = []
    for i, nm in enumerate(names):
        r = [nm, f"{g['table4'][i]:.4f}"]
        if g["fpa"] is not None:
            r += [f"{g['fpa'][i]:.4f}", f"{g['fpa'][i] - g['table4'][i]:+.4f}"]
        rows.append(r)
    r = ["**ISE, eq. (25)**", f"{g['table4_ise']:.4f}"]
    if g["fpa"] is not None:
        r += [f"{g['fpa_ise']:.4f}", f"{100 * (g['fpa_ise'] - g['table4_ise']) / g['table4_ise']:+.1f} %"]
    rows.append(r)
    hdr = ["gain", "paper Table 4"] + (
        [f"FPA-tuned (`{Path(g['fpa_file']).name}`)", "tuned − paper"] if g["fpa"] is not None else []
    )
    L.append(_table(hdr, rows))
    L.append(
        "\nISE of eq. (25) over our step (weights 3, 3, 1, 2, 2, 1; angles in radians; 10 s at T = 0.01 s). "
        "The paper's Table 3 ISE values (45–68) are an order of magnitude above ours for any gains; the "
        "paper does not say how its ISE is scaled (units, sampling), so compare the improvements, not "
        "the values.\n"
    )
    return L


def _settle(o: dict) -> str:
    """A tune's step settling times x / y / z / ψ (s), or "–"."""
    st = o.get("step")
    if not st:
        return "–"
    return " / ".join(f"{st[a]['settling_s']:.2f}" for a in ("x", "y", "z", "psi"))


def _verdict(o: dict) -> str:
    """Whether a tune's gains meet the step bars, and which they miss."""
    if o.get("meets_bars") is None or not o.get("step"):
        return "–"
    if o["meets_bars"]:
        return "yes"
    from ..tuning.constraints import StepBars, missed_bars

    return "**no**: " + ", ".join(missed_bars(o["step"], o.get("max_tilt_deg", 0.0), StepBars()))


def _table3_section(R: dict) -> list[str]:
    """Table 3: the FPA's convergence, the paper's runs beside ours."""
    L: list[str] = []
    g = R["gains"]
    t3 = R["table3"]
    L.append(
        f"**Table 3 (FPA convergence, {t3['settings']['iterations']} iterations, population "
        f'{t3["settings"]["population"]}, p = 0.04, γ = 0.02, bounds [0.1, 12]).** "ours" is '
        "`swarm-mj tune`'s default: the ISE subject to the step bars of the controller (Deb's "
        "feasibility rules) from an initial population holding the Table 4 gains, so its initial ISE is "
        'the better of Table 4 and the best random flower meeting the bars. "ours, paper mode" is '
        "`--constraints none --init random`, the tune as the paper prints it.\n"
    )
    rows = []
    for p in t3["paper"]:
        rows.append(
            [
                f"paper run {p['run']}",
                f"{p['initial_ise']:.2f}",
                f"{p['final_ise']:.2f}",
                f"{p['improvement_pct']:.2f} %",
                "–",
                "–",
            ]
        )

    for label, key in (("ours", "ours"), ("ours, paper mode", "ours_paper_mode")):
        for o in t3.get(key) or []:
            rows.append(
                [
                    f"{label}, seed {o['seed']}",
                    fmt_cell(o["initial_ise"], "{:.4f}"),
                    fmt_cell(o["final_ise"], "{:.4f}"),
                    f"{fmt_cell(o['improvement_pct'], '{:.2f}')} %",
                    _verdict(o),
                    _settle(o),
                ]
            )
    L.append(
        _table(
            [
                "run",
                "initial ISE (best of initial population)",
                "final ISE",
                "improvement",
                "meets step bars",
                "settling x / y / z / ψ (s)",
            ],
            rows,
        )
    )
    if t3["ours"]:
        beats = sum(1 for o in t3["ours"] if as_number(o["final_ise"]) < g["table4_ise"])
        L.append(
            f"\n{beats} of {len(t3['ours'])} of our default FPA runs end below the ISE of the paper's "
            f"Table 4 gains ({g['table4_ise']:.4f}); they start from them, so they cannot end above. "
            "Paper's improvement range: 10.67–35.45 %.\n"
        )
    L.append(_fig(R, "fpa_convergence.png"))
    return L


def _table5_section(R: dict) -> list[str]:
    """3. Table 5: the single drone's RMSE, without and with wind."""
    L: list[str] = []
    t5 = R["table5"]
    L.append("## 3. Table 5: RMSE of eq. (38), single drone, 180 s, without and with wind\n")
    L.append(
        "Whole run (eq. 38 as printed) and steady (t ≥ 10 s), docs/interpretations.md §7. "
        '"ground": start at rest on the '
        'ground at the origin (the bundled scenarios); "on path": start at rest at the path\'s t = 0 point '
        'at 2 m; "FPA": the FPA-tuned gains; "no FF": the controller does not know the wind. '
        "ours/paper for the circle is x whole-run and y steady (docs/interpretations.md §7).\n"
    )
    rows = []
    variant_label = {"ground": "ground", "on_path": "on path", "fpa": "FPA gains, ground"}
    for r in t5["rows"]:
        p = r["paper"]
        case = f"{r['trajectory']}, {'wind' if r['wind'] else 'no wind'}"
        if r["wind"] and not r["wind_feedforward"]:
            case += ", no FF"
        w, s = r["whole"], r["steady"] or {}
        yref = s.get("y") if r["trajectory"] == "circle" else w["y"]
        rows.append(
            [
                case,
                variant_label[r["variant"]],
                f"{p['x']:.4f} / {p['y']:.4f} / {p['roll_deg']:.4f} / {p['pitch_deg']:.4f}",
                " / ".join(_r(w[k]) for k in ("x", "y", "roll_deg", "pitch_deg")),
                (" / ".join(_r(s[k]) for k in ("x", "y", "roll_deg", "pitch_deg")) if s else "–"),
                f"{_ratio(w['x'], p['x'])} / {_ratio(yref, p['y'])}",
            ]
        )
    L.append(
        _table(
            [
                "case",
                "start",
                "paper x / y (m) / roll / pitch (°)",
                "ours whole run",
                "ours t ≥ 10 s",
                "ours/paper x / y",
            ],
            rows,
        )
    )
    L.append("")
    L.append(_fig(R, "fig09_lemniscate.png"))
    L.append(_fig(R, "fig15_wind.png"))
    return L


def _swarm_section(R: dict) -> list[str]:
    """4. The swarm scenarios (paper Figs. 10–13)."""
    L: list[str] = []
    sw = R["swarms"]
    L.append("## 4. Swarm scenarios (paper Figs. 10–13)\n")
    L.append(
        "Leader + 5 followers, D = 1 m, our default anti-collision (layers). Contacts are MuJoCo "
        "drone–drone contacts; separation is the minimum 3D centre distance over the run (all samples; "
        '"airborne": while every drone is above 0.1 m). Paper: formation in ≈ 3 s, no collision.\n'
    )
    rows = []
    for r in sw["rows"]:
        first_settle = r["settling_s"][0] if r["settling_s"] else None
        rows.append(
            [
                r["scenario"],
                f"{r['duration_s']:.0f}",
                str(r["contacts"]),
                f"{r['min_separation_m']:.3f}",
                fmt_cell(r["min_separation_airborne_m"], "{:.3f}"),
                fmt_cell(first_settle, "{:.2f}"),
                f"{sw['paper_settling_s']:.0f}",
                _diff(first_settle, sw["paper_settling_s"]),
                f"{100 * r['max_distance_error_m']:.1f}",
                f"{r['altitude_yields']}",
            ]
        )
    L.append(
        _table(
            [
                "scenario",
                "duration (s)",
                "contacts",
                "min separation (m)",
                "airborne (m)",
                "formation settling (s)",
                "paper (s)",
                "ours − paper (s)",
                "max distance error once settled (cm)",
                "altitude yields",
            ],
            rows,
        )
    )
    L.append("")
    L.append(_fig(R, "swarm_paths_3d.png"))
    return L


def _variable_d_section(R: dict) -> list[str]:
    """5. Variable D (eq. 34, paper Fig. 14)."""
    L: list[str] = []
    vd = R["variable_d"]
    L.append("## 5. Variable D (eq. 34, paper Fig. 14)\n")
    rows = []
    sched = vd["schedule"] if isinstance(vd["schedule"], list) else [[0.0, vd["schedule"]]]
    for (t0, D), s in zip(sched, vd["settling_s"]):
        rows.append(
            [
                f"{t0:g}",
                f"{D:g}",
                fmt_cell(s, "{:.2f}"),
                f"≈ {vd['paper_settling_s']:.0f}",
                _diff(s, vd["paper_settling_s"]),
            ]
        )
    L.append(_table(["change at t (s)", "D (m)", "ours settling (s)", "paper (s)", "ours − paper (s)"], rows))
    L.append(
        f"\nContacts {vd['contacts']}, minimum separation {vd['min_separation_m']:.3f} m, largest distance "
        f"error once settled {100 * vd['max_distance_error_m']:.1f} cm. The first settling (t = 0) includes "
        f"the take-off from the ground starts of eq. (31).\n"
    )
    L.append(_fig(R, "fig14_variable_d.png"))
    return L


def _anti_collision_section(R: dict) -> list[str]:
    """6. Anti-collision: the rules on the fixed starts (paper Fig. 5, Fig. 16b)."""
    L: list[str] = []
    ac = R["anti_collision"]
    L.append("## 6. Anti-collision (paper Fig. 5, Fig. 16b): our rule beside the paper's and none\n")
    L.append(
        "`anti_collision`: followers start on the far side of their slots and cross past the hovering "
        'leader; scenario1–3: the paper\'s starts of eqs. (31)–(33). A run "stopped" when a collision '
        "made the simulation diverge (a drone flipped or left the arena).\n"
    )
    rows = []
    for r in ac["rows"]:
        first_settle = r["settling_s"][0] if r["settling_s"] else None
        rows.append(
            [
                r["scenario"],
                f"`{r['rule']}`",
                str(r["contacts"]),
                f"{r['min_separation_m']:.3f}",
                fmt_cell(first_settle, "{:.2f}"),
                str(r["altitude_yields"]),
                "stopped: " + r["stopped"] if r["stopped"] else "ok",
            ]
        )
    L.append(
        _table(
            ["scenario", "rule", "contacts", "min separation (m)", "formation settling (s)", "altitude yields", "run"],
            rows,
        )
    )
    return L


def _random_crossing_section(R: dict) -> list[str]:
    """The rules over the seeded random crossing starts."""
    L: list[str] = []
    rc = R["sweeps"]["random_crossing"]
    L.append(
        f"\n**Seeded random crossing starts** (hovering leader, 5 followers on the ground within 3 m, "
        f"{len(rc['seeds'])} seeds, {rc['duration_s']:.0f} s): mean ± std (worst).\n"
    )
    rows = []
    for res, v in zip(rc["results"], rc["values"]):
        s = res["stats"]
        runs = [r for r in rc["runs"] if r["value"] == v]
        with_contact = sum(1 for r in runs if as_number(r["metrics"].get("contacts", 0)) > 0)
        stopped = sum(1 for r in runs if r["stopped"])
        rows.append(
            [
                f"`{v}`",
                f"{with_contact}/{len(runs)}",
                _ms(s.get("contacts"), "{:.1f}"),
                _ms(s.get("min_separation_m"), "{:.3f}"),
                _ms(s.get("formation_settling_s"), "{:.2f}"),
                str(stopped),
            ]
        )
    L.append(
        _table(
            [
                "rule",
                "seeds with a contact",
                "contacts",
                "min separation (m)",
                "formation settling (s)",
                "runs stopped",
            ],
            rows,
        )
    )
    L.append("")
    L.append(_fig(R, "fig16_anticollision.png"))
    return L


def _wind_section(R: dict) -> list[str]:
    """7. Wind robustness over seeds (Table 5 under wind, Fig. 15)."""
    L: list[str] = []
    L.append("## 7. Wind robustness over seeds (Table 5 under wind, Fig. 15)\n")
    L.append("Each seed draws a different OU turbulence (eq. 36). mean ± std (worst over the seeds); paper: one run.\n")
    rows = []
    for key in ("wind_circle", "wind_lemniscate", "wind_circle_noff", "wind_lemniscate_noff"):
        swp = R["sweeps"][key]
        s = swp["results"][0]["stats"]
        traj = "circle" if "circle" in key else "lemniscate"
        p = R["table5"]["paper"][f"{traj}/wind"]
        ff = "no FF" if key.endswith("noff") else "FF"
        for ax, pk in (("x", "x"), ("y", "y"), ("roll_deg", "roll_deg"), ("pitch_deg", "pitch_deg")):
            rows.append(
                [
                    f"{traj}, {ff}",
                    ax.replace("_deg", " (°)"),
                    f"{p[pk]:.4f}",
                    _ms(s.get(f"rmse_{ax}")),
                    _ms(s.get(f"rmse_steady_{ax}")),
                    f"{len(swp['seeds'])}",
                ]
            )
    L.append(_table(["case", "RMSE", "paper", "ours whole run", "ours t ≥ 10 s", "seeds"], rows))
    return L


def _wind_swarm_section(R: dict) -> list[str]:
    """The swarm under wind and the turbulence intensity sweep."""
    L: list[str] = []
    ws = R["sweeps"]["wind_swarm"]
    s = ws["results"][0]["stats"]
    L.append(
        f"\n**Swarm under wind** (`wind_swarm`: six-drone circle, wind on every drone, {len(ws['seeds'])} "
        f"seeds, {ws['duration_s']:.0f} s): contacts {_ms(s.get('contacts'), '{:.1f}')}, min separation "
        f"{_ms(s.get('min_separation_m'), '{:.3f}')} m, formation settling "
        f"{_ms(s.get('formation_settling_s'), '{:.2f}')} s, max formation distance error "
        f"{_ms(s.get('max_distance_error_m'), '{:.3f}')} m, leader RMSE x (t ≥ 10 s) "
        f"{_ms(s.get('rmse_steady_x'))} m.\n"
    )
    L.append(
        "**Turbulence intensity** (σx = σy = σ; default σx = 0.8, σy = 0.5 m/s, docs/interpretations.md §5), "
        "lemniscate "
        "under wind, steady RMSE (t ≥ 10 s):\n"
    )
    rows = []
    for key in ("sigma/wind_lemniscate", "sigma/wind_lemniscate_noff"):
        swp = R["sweeps"][key]
        for v, res in zip(swp["values"], swp["results"]):
            s = res["stats"]
            rows.append(
                [
                    ("no FF" if "noff" in key else "FF"),
                    f"{v:g}",
                    _ms(s.get("rmse_steady_x")),
                    _ms(s.get("rmse_steady_y")),
                    _ms(s.get("rmse_steady_roll_deg")),
                    _ms(s.get("rmse_steady_pitch_deg")),
                    str(len(swp["seeds"])),
                ]
            )
    L.append(_table(["controller", "σ (m/s)", "x (m)", "y (m)", "roll (°)", "pitch (°)", "seeds"], rows))
    L.append("")
    L.append(_fig(R, "wind_robustness.png"))
    L.append(_fig(R, "wind_sigma.png"))
    return L


def _figures_section(R: dict) -> list[str]:
    """The MuJoCo view, the list of figures and the jobs' cost."""
    L: list[str] = []
    m = R["meta"]
    if any(f["file"] == "snapshot_scenario1.png" for f in R.get("figures", [])):
        L.append("## MuJoCo view\n")
        L.append(_fig(R, "snapshot_scenario1.png"))
    L.append("## Figures\n")
    for f in R.get("figures", []):
        L.append(f"- [`{f['file']}`]({f['file']}): {f['caption']}")
    L.append("")
    L.append(f"*Jobs: {m['jobs']}, CPU time in the runs {m.get('cpu_s_in_runs', 0):.0f} s, wall {m['wall_s']:.0f} s.*")
    return L


#: The report's sections, in order: each takes results.json (``R``) and returns its Markdown lines.
SECTIONS = (
    _header,
    _interpretations,
    _step_section,
    _gains_section,
    _table3_section,
    _table5_section,
    _swarm_section,
    _variable_d_section,
    _anti_collision_section,
    _random_crossing_section,
    _wind_section,
    _wind_swarm_section,
    _figures_section,
)


def render_markdown(R: dict) -> str:
    """The report's README from results.json (``R`` as written there): :data:`SECTIONS` in turn."""
    L: list[str] = []
    for section in SECTIONS:
        L += section(R)
    return "\n".join(L) + "\n"


def load_results(path: str | Path) -> dict:
    """results.json as written by :func:`swarm_mj.report.build_report`."""
    return json.loads(Path(path).read_text())
