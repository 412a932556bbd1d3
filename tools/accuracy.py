"""The physics step chosen by measured accuracy (issue 20): every bundled scenario at several steps.

    python tools/accuracy.py [--scenarios a,b] [--duration S] [--workers N] [--json report/accuracy.json]
                             [--markdown PATH] [--docs docs/physics_step.md] [--readme README.md]
    python tools/accuracy.py --contacts [--starts 100] [--duration 15] [--fine 5] [--coarse 10]
                             [--json report/accuracy_contacts.json]
    python tools/accuracy.py --from-json report/accuracy.json [--contacts-json PATH] --docs docs/physics_step.md

Study mode (default). Each bundled scenario (``scenarios/*.toml``, flown with its own rule), plus
the rule variants that the README's anti-collision table prints (``anti_collision``, ``scenario1..3``
with each of ``layers``, ``paper``, ``off``; ``--no-rule-variants`` leaves them out), is flown with
``swarm_mj.experiments.runner.run`` at every setting of ``--settings`` (default RK4 at 1, 2.5, 5 and 10 ms, and
Euler and implicitfast at 5 and 10 ms, the two steps that divide the 10-ms control period and are
candidates for the default). The 1-ms RK4 run is the reference. Per case and setting it gives

* the largest distance between the drone's centre of mass and where it is in the reference run, over
  every control-period sample, per drone (and the largest over drones), and the same for attitude;
* every summary figure that the README prints, rounded to the digits it is printed with
  (``tools/readme_tables.py``): step overshoot and settling (2 decimals), peak roll/pitch of the step
  (1 decimal), RMSE x, y (4 decimals, m) and roll, pitch (3 decimals, °) of the whole run and from
  10 s, formation settling after the start and after every change of D (2 decimals, s), contacts,
  minimum separation (2 decimals, m) and whether the run stopped. The same formats are applied to
  every case, also where the README does not print that figure (marked "not in the README");
* the contact count; the wall time of the loop as a ratio to the reference run's.

``--duration S`` shortens every case to at most S simulated seconds (quick runs; a step scenario of
10 s stays 10 s). The output is a full table (``--markdown``, and in ``--docs``), a short one (per
setting: worst deviation over all cases, whether all figures match, total contacts, time ratios;
``--readme`` writes it between ``<!-- tables:accuracy -->`` markers) and JSON (``--json``).

Contacts mode (``--contacts``). The same starts as ``swarm-mj stress --rule paper --starts 100``
(``swarm_mj.commands.stress.StressCase`` / ``stress_scenario``: 5 followers within 3 m, at least 0.6 m
apart, seeds ``--seed0`` .. ``--seed0 + starts - 1``, the leader flying the circle, 15 s), flown at the
fine step (``--fine``, 5 ms) and at the candidate (``--coarse``, 10 ms), both RK4. MuJoCo detects
contacts once per physics step, so a coarser step might let a touch fall between two steps. The
verdict holds when the total contact count at the candidate is within 5 % of the fine count and no
start with a contact at the fine step has none at the candidate.

Worker processes (``--workers``) use the spawn start method; each runs whole cases (every setting of
one case in one process, so that the time ratios compare runs in the same process).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: (integrator, timestep in s); the first is the reference.
DEFAULT_SETTINGS: tuple[tuple[str, float], ...] = (
    ("RK4", 0.001),
    ("RK4", 0.0025),
    ("RK4", 0.005),
    ("RK4", 0.01),
    ("Euler", 0.005),
    ("Euler", 0.01),
    ("implicitfast", 0.005),
    ("implicitfast", 0.01),
)
#: The rules the README's anti-collision table prints for these scenarios (readme_tables.anticollision).
RULE_VARIANT_SCENARIOS = ("anti_collision", "scenario1", "scenario2", "scenario3")
RULES = ("layers", "paper", "off")
#: Position deviation bar of the issue: the default step keeps every scenario within 1 mm of 1-ms RK4.
DEVIATION_BAR_M = 1e-3
#: Contacts mode: the total count at the candidate step within 5 % of the fine step's.
CONTACT_TOLERANCE = 0.05
#: Contacts mode: a pair touching again within this time of its last touch is counted as the same episode
#: (drones tangled in a crash touch, part and touch again every few steps).
EPISODE_GAP_S = 0.1

# Where the README prints which figure (tools/readme_tables.py): the reproduction table prints the
# step of `step`, the Table 5 RMSE of the four single-drone runs with a paper row, the formation
# settling, contacts and minimum separation of the swarm scenarios and variable D; the anti-collision
# table prints contacts / min separation / settling of `layers`, contacts / min separation of `paper`,
# contacts of `off`.
_README_RMSE = {"circle_single", "lemniscate_single", "wind_circle", "wind_lemniscate"}
_README_SWARM = {
    "circle",
    "lemniscate",
    "ascending_orbit",
    "scenario1",
    "scenario2",
    "scenario3",
    "variable_diameter",
    "anti_collision",
}


# --------------------------------------------------------------------------- printed digits


def printed(v: Any, fmt: str) -> str:
    """``v`` as the README prints it with format ``fmt`` (None: "–", inf: "never", like readme_tables.f)."""
    if v is None:
        return "–"
    if isinstance(v, str):
        if v.lower() == "inf":
            return "never"
        if v.lower() == "nan":
            return "–"
        return v
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float) and not math.isfinite(v):
        return "never" if v > 0 else ("–" if math.isnan(v) else "-never")
    s = fmt.format(v)
    # "-0.00" and "0.00" are the same printed figure
    return s[1:] if s.startswith("-") and not any(c in s for c in "123456789") else s


def same_printed(a: Any, b: Any, fmt: str) -> bool:
    """Whether ``a`` and ``b`` print the same with ``fmt`` (the README's digits)."""
    return printed(a, fmt) == printed(b, fmt)


def printed_figures(summary: dict, case: str, rule: str | None = None) -> dict[str, tuple[Any, str, bool]]:
    """The README's figures of one run summary: name -> (value, format, printed in the README).

    ``case`` is the scenario name (decides only the "printed in the README" flag); ``rule`` the
    anti-collision rule the case is flown with (None: the scenario's own).
    """
    out: dict[str, tuple[Any, str, bool]] = {}
    lead = summary["drones"]["leader"]
    is_step = "step" in lead
    if is_step:
        for ax, m in lead["step"].items():
            out[f"step {ax} overshoot %"] = (m["overshoot_pct"], "{:.2f}", True)
            out[f"step {ax} settling s"] = (m["settling_s"], "{:.2f}", True)
        out["step peak |roll| °"] = (lead["max_abs_roll_deg"], "{:.1f}", True)
        out["step peak |pitch| °"] = (lead["max_abs_pitch_deg"], "{:.1f}", True)
    rm = case in _README_RMSE
    for key, label in (("rmse", "RMSE"), ("rmse_steady", "RMSE from 10 s")):
        r = lead.get(key)
        if r is None:
            continue
        out[f"{label} x m"] = (r["x"], "{:.4f}", rm)
        out[f"{label} y m"] = (r["y"], "{:.4f}", rm)
        out[f"{label} roll °"] = (r["roll_deg"], "{:.3f}", rm)
        out[f"{label} pitch °"] = (r["pitch_deg"], "{:.3f}", rm)
    sw = case in _README_SWARM
    own = rule is None or rule == "layers"
    out["contacts"] = (int(summary["contacts"]), "{}", sw)
    if summary.get("min_separation_m") is not None:
        out["min separation m"] = (summary["min_separation_m"], "{:.2f}", sw and rule != "off")
    form = summary.get("formation")
    if form:
        for j, s in enumerate(form["settling_s"]):
            label = "formation settling s" if j == 0 else f"settling after change {j} s"
            out[label] = (s, "{:.2f}", sw and own)
    out["stopped"] = (bool(summary.get("stopped")), "{}", True)
    return out


def differing(ref: dict[str, tuple[Any, str, bool]], other: dict[str, tuple[Any, str, bool]]) -> list[dict]:
    """Figures of ``ref`` whose printed value differs in ``other`` (or that ``other`` lacks)."""
    out = []
    for name, (v, fmt, in_readme) in ref.items():
        w = other.get(name, (None, fmt, in_readme))[0]
        if not same_printed(v, w, fmt):
            num = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (v, w))
            out.append(
                {
                    "figure": name,
                    "reference": printed(v, fmt),
                    "value": printed(w, fmt),
                    "in_readme": in_readme,
                    "change": float(w - v) if num else None,
                }
            )
    for name in other.keys() - ref.keys():
        v, fmt, in_readme = other[name]
        out.append({"figure": name, "reference": "–", "value": printed(v, fmt), "in_readme": in_readme})
    return out


# --------------------------------------------------------------------------- deviations


def position_deviation(pos: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(n,) largest distance over time between ``pos`` (k, n, 3) and ``ref`` (k', n, 3) (common samples)."""
    k = min(len(pos), len(ref))
    return np.linalg.norm(pos[:k] - ref[:k], axis=2).max(axis=0)


def attitude_deviation_deg(quat: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(n,) largest rotation angle (°) over time between attitudes ``quat`` (k, n, 4) and ``ref``."""
    k = min(len(quat), len(ref))
    a, b = ref[:k], quat[:k]  # (k, n, 4) (w, x, y, z)
    w = np.einsum("kni,kni->kn", a, b)  # conj(a) ⊗ b, scalar part
    v = a[..., :1] * b[..., 1:] - b[..., :1] * a[..., 1:] - np.cross(a[..., 1:], b[..., 1:])
    return np.rad2deg(2 * np.arctan2(np.linalg.norm(v, axis=2), np.abs(w))).max(axis=0)


# --------------------------------------------------------------------------- study (worker side)


def _label(integrator: str, dt: float) -> str:
    return f"{integrator} {dt * 1e3:g} ms"


def _case_scenario(case: dict):
    from swarm_mj.scenario import load_scenario

    sc = load_scenario(case["scenario"])
    if case["rule"] is not None:
        sc = sc.with_overrides(anti_collision=case["rule"])
    if case["duration"] is not None:
        sc = sc.with_overrides(duration=min(sc.duration, float(case["duration"])))
    return sc


def fly_case(case: dict) -> dict:
    """Fly one case at every setting (the first is the reference); the study's numbers of that case.

    Each setting is compared with the reference and with ``case["current"]`` (the default step before
    this study, RK4 at 5 ms), whose figures the README printed.
    """
    from swarm_mj.experiments.runner import run

    base = _case_scenario(case)
    settings = [tuple(s) for s in case["settings"]]
    runs = []
    for integ, dt in settings:
        sc = base.with_overrides(timestep=float(dt), integrator=integ)
        t0 = time.perf_counter()
        res = run(sc, progress=False)
        wall_total = time.perf_counter() - t0
        s = res.summary
        runs.append(
            {
                "pos": np.asarray(res.log.pos),
                "quat": np.asarray(res.log.quat),
                "summary": s,
                "figs": printed_figures(s, case["scenario"], case["rule"]),
                "wall": float(s.get("wall_time_s", wall_total)),
            }
        )
    ref = runs[0]
    perturbed = None
    if case.get("perturb_m"):
        # the reference again, the leader's start moved perturb_m along +x, +y, +z, −x, ... (perturb_dirs of
        # them): how much the run moves for changes of its initial state that have nothing to do with the
        # step (its sensitivity); a figure is sensitive when any of these runs changes it
        integ, dt = settings[0]
        eps = float(case["perturb_m"])
        dirs = np.vstack([np.eye(3), -np.eye(3)])[: max(1, int(case.get("perturb_dirs", 1)))]  # (d, 3)
        runs_p = []
        for e in dirs:
            sc = base.with_overrides(timestep=float(dt), integrator=integ, leader_start=base.leader_start + eps * e)
            res = run(sc, progress=False)
            figs = printed_figures(res.summary, case["scenario"], case["rule"])
            runs_p.append(
                {
                    "direction": e.tolist(),
                    "max_deviation_m": float(position_deviation(np.asarray(res.log.pos), ref["pos"]).max()),
                    "contacts": int(res.summary["contacts"]),
                    "stopped": res.summary.get("stopped"),
                    "differing": differing(ref["figs"], figs),
                }
            )
        diffs: dict[str, dict] = {}
        for rp in runs_p:
            for d in rp["differing"]:
                diffs.setdefault(d["figure"], d)
        perturbed = {
            "perturb_m": eps,
            "directions": len(dirs),
            "label": f"{_label(integ, dt)}, leader start moved {eps * 1e6:g} µm"
            + (f" ({len(dirs)} directions)" if len(dirs) > 1 else " along x"),
            "max_deviation_m": max(rp["max_deviation_m"] for rp in runs_p),
            "contacts": [rp["contacts"] for rp in runs_p],
            "stopped": [rp["stopped"] for rp in runs_p if rp["stopped"]],
            "differing": list(diffs.values()),
            "runs": runs_p,
        }
    labels = [_label(i, d) for i, d in settings]
    cur = runs[labels.index(case["current"])] if case.get("current") in labels else None
    rows = []
    for (integ, dt), r in zip(settings, runs):
        s = r["summary"]
        dev = position_deviation(r["pos"], ref["pos"])
        att = attitude_deviation_deg(r["quat"], ref["quat"])
        row = {
            "integrator": integ,
            "timestep_s": float(dt),
            "label": _label(integ, dt),
            "max_deviation_m": float(dev.max()),
            "deviation_m": dict(zip(base.names, map(float, dev))),
            "max_attitude_deviation_deg": float(att.max()),
            "contacts": int(s["contacts"]),
            "stopped": s.get("stopped"),
            "samples": len(r["pos"]),
            "reference_samples": len(ref["pos"]),
            "wall_s": r["wall"],
            "wall_ratio": r["wall"] / ref["wall"] if ref["wall"] else float("nan"),
            "differing": differing(ref["figs"], r["figs"]),
            "figures": {k: printed(v, f) for k, (v, f, _) in r["figs"].items()},
        }
        if cur is not None:
            row["max_deviation_vs_current_m"] = float(position_deviation(r["pos"], cur["pos"]).max())
            row["differing_vs_current"] = differing(cur["figs"], r["figs"])
        rows.append(row)
    return {
        "case": case["name"],
        "scenario": case["scenario"],
        "rule": case["rule"] or base.anti_collision,
        "rule_variant": case["rule"] is not None,
        "n_drones": base.n_drones,
        "duration_s": base.duration,
        "current": case.get("current"),
        "rows": rows,
        "perturbed": perturbed,
        "sensitive": perturbed is not None and perturbed["max_deviation_m"] > DEVIATION_BAR_M,
    }


# --------------------------------------------------------------------------- study (driver side)


def make_cases(
    names: list[str],
    duration: float | None,
    settings: list[tuple[str, float]],
    rule_variants: bool,
    current: str = "RK4 5 ms",
    perturb_m: float = 0.0,
    perturb_dirs: int = 1,
) -> list[dict]:
    """Every scenario with its own rule, then the README's rule variants of the anti-collision table."""
    from swarm_mj.scenario import load_scenario

    cases = []
    for name in names:
        cases.append(
            {
                "name": name,
                "scenario": name,
                "rule": None,
                "duration": duration,
                "settings": settings,
                "current": current,
                "perturb_m": perturb_m,
                "perturb_dirs": perturb_dirs,
            }
        )
    if rule_variants:
        for name in RULE_VARIANT_SCENARIOS:
            if name not in names:
                continue
            own = load_scenario(name).anti_collision
            for rule in RULES:
                if rule != own:
                    cases.append(
                        {
                            "name": f"{name} ({rule})",
                            "scenario": name,
                            "rule": rule,
                            "duration": duration,
                            "settings": settings,
                            "current": current,
                            "perturb_m": perturb_m,
                            "perturb_dirs": perturb_dirs,
                        }
                    )
    return cases


def _cost(case: dict) -> float:
    from swarm_mj.scenario import load_scenario

    sc = load_scenario(case["scenario"])
    d = sc.duration if case["duration"] is None else min(sc.duration, case["duration"])
    return d * (1 + 0.5 * sc.n_followers)


def run_parallel(fn, jobs: list, workers: int, say) -> list:
    """``fn`` over ``jobs`` in ``workers`` spawned processes (in order of the jobs); longest first."""
    order = sorted(range(len(jobs)), key=lambda i: -jobs[i][1])
    out: list = [None] * len(jobs)
    t0 = time.perf_counter()
    if workers <= 1:
        for n, i in enumerate(order, 1):
            out[i] = fn(jobs[i][0])
            say(f"[{n}/{len(jobs)}] {jobs[i][0].get('name', i)}  {time.perf_counter() - t0:5.0f} s elapsed")
        return out
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
        futs = {pool.submit(fn, jobs[i][0]): i for i in order}
        for n, fut in enumerate(as_completed(futs), 1):
            i = futs[fut]
            out[i] = fut.result()
            say(f"[{n}/{len(jobs)}] {jobs[i][0].get('name', i)}  {time.perf_counter() - t0:5.0f} s elapsed")
    return out


def summarize_settings(cases: list[dict]) -> list[dict]:
    """The short table: per setting, worst deviation over all cases, figures, contacts, time ratios.

    A case is *sensitive* when the reference run with the leader's start moved by ``perturb_m`` (a
    change that has nothing to do with the step) already moves by more than the 1-mm bar; a figure
    is *sensitive* in a case when that perturbed run changes it too.
    """
    labels = [r["label"] for r in cases[0]["rows"]] if cases else []
    out = []
    for j, label in enumerate(labels):
        rows = [(c, c["rows"][j]) for c in cases]
        worst_c, worst_r = max(rows, key=lambda cr: cr[1]["max_deviation_m"])
        diffs = [
            {"case": c["case"], **d, "sensitive": _sensitive_figure(c, d["figure"])}
            for c, r in rows
            for d in r["differing"]
        ]
        over = [
            {
                "case": c["case"],
                "deviation_m": r["max_deviation_m"],
                "sensitive": c.get("sensitive", False),
                "perturbed_deviation_m": (c.get("perturbed") or {}).get("max_deviation_m"),
            }
            for c, r in rows
            if r["max_deviation_m"] > DEVIATION_BAR_M
        ]
        wall = sum(r["wall_s"] for _, r in rows)
        wall_ref = sum(c["rows"][0]["wall_s"] for c in cases)
        item = {
            "label": label,
            "integrator": worst_r["integrator"],
            "timestep_s": worst_r["timestep_s"],
            "worst_deviation_m": worst_r["max_deviation_m"],
            "worst_case": worst_c["case"],
            "worst_attitude_deviation_deg": max(r["max_attitude_deviation_deg"] for _, r in rows),
            "over_bar": over,
            "all_figures_match": not diffs,
            "readme_figures_match": not any(d["in_readme"] for d in diffs),
            "differing": diffs,
            "contacts": sum(r["contacts"] for _, r in rows),
            "stopped": [c["case"] for c, r in rows if r["stopped"]],
            "wall_s": wall,
            "wall_ratio": wall / wall_ref if wall_ref else float("nan"),
        }
        if all("max_deviation_vs_current_m" in r for _, r in rows):
            wc, wr = max(rows, key=lambda cr: cr[1]["max_deviation_vs_current_m"])
            dc = [
                {"case": c["case"], **d, "sensitive": _sensitive_figure(c, d["figure"])}
                for c, r in rows
                for d in r["differing_vs_current"]
            ]
            item.update(
                {
                    "worst_deviation_vs_current_m": wr["max_deviation_vs_current_m"],
                    "worst_case_vs_current": wc["case"],
                    "differing_vs_current": dc,
                    "all_figures_match_current": not dc,
                    "readme_figures_match_current": not any(d["in_readme"] for d in dc),
                }
            )
        out.append(item)
    by = {s["label"]: s for s in out}
    if "RK4 5 ms" in by:
        for s in out:
            s["speed_vs_rk4_5ms"] = by["RK4 5 ms"]["wall_s"] / s["wall_s"] if s["wall_s"] else float("nan")
    return out


def _sensitive_figure(case: dict, figure: str) -> bool:
    p = case.get("perturbed")
    return bool(p) and any(d["figure"] == figure for d in p["differing"])


def choose_step(settings: list[dict], bar_m: float = DEVIATION_BAR_M, *, allow_sensitive: bool = False) -> dict | None:
    """The largest RK4 step whose README figures all match the reference and whose deviation is <= ``bar_m``.

    ``allow_sensitive``: a case over the bar, or a figure that differs, does not count against a step
    when the reference run with a perturbed start (see :func:`summarize_settings`) is over the bar / changes
    that figure too, i.e. when the run does not fix it to that precision whatever the step.
    """

    def ok(s: dict) -> bool:
        if s["integrator"] != "RK4" or (s["stopped"] and not allow_sensitive):
            return False
        readme = [d for d in s["differing"] if d["in_readme"]]
        if allow_sensitive:
            return all(o["sensitive"] for o in s.get("over_bar", [])) and all(d.get("sensitive") for d in readme)
        return not readme and s["worst_deviation_m"] <= bar_m

    good = [s for s in settings if ok(s)]
    return max(good, key=lambda s: s["timestep_s"]) if good else None


def study(
    names: list[str],
    *,
    duration: float | None,
    workers: int,
    settings: list[tuple[str, float]],
    rule_variants: bool = True,
    perturb_m: float = 1e-6,
    perturb_dirs: int = 3,
    say=print,
) -> dict:
    """Fly the study and return the JSON document."""
    import mujoco

    from swarm_mj.experiments.parallel import machine_description

    cases = make_cases(names, duration, settings, rule_variants, perturb_m=perturb_m, perturb_dirs=perturb_dirs)
    t0 = time.perf_counter()
    results = run_parallel(fly_case, [(c, _cost(c)) for c in cases], workers, say)
    return conclude(
        {
            "meta": {
                "generated": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "machine": machine_description(),
                "mujoco": mujoco.__version__,
                "workers": workers,
                "duration_override_s": duration,
                "wall_s": time.perf_counter() - t0,
                "reference": _label(*settings[0]),
                "deviation_bar_m": DEVIATION_BAR_M,
                "perturb_m": perturb_m,
                "perturb_dirs": perturb_dirs,
                "argv": sys.argv[1:],
            },
            "cases": results,
        }
    )


def conclude(doc: dict) -> dict:
    """Add the per-setting summary and the choices to a study document (from its cases)."""
    doc["settings"] = summarize_settings(doc["cases"])
    for key, allow in (("chosen", False), ("chosen_allowing_sensitive", True)):
        c = choose_step(doc["settings"], allow_sensitive=allow)
        doc[key] = None if c is None else {"label": c["label"], "timestep_s": c["timestep_s"]}
    return doc


# --------------------------------------------------------------------------- markdown


def _mm(v: float) -> str:
    mm = v * 1e3
    if mm == 0:
        return "0"
    return f"{mm:.2g}" if mm < 0.01 else (f"{mm:.3f}" if mm < 10 else f"{mm:.1f}")


def _diff_text(diffs: list[dict], limit: int = 4) -> str:
    if not diffs:
        return "all match"
    parts = [
        f"{d['figure']} {d['reference']} → {d['value']}"
        + (f" (by {d['change']:+.2g})" if d.get("change") is not None and "contacts" not in d["figure"] else "")
        + ("" if d["in_readme"] else " (not in the README)")
        for d in diffs[:limit]
    ]
    more = f"; +{len(diffs) - limit} more" if len(diffs) > limit else ""
    return "; ".join(parts) + more


def full_table(doc: dict) -> str:
    """Per case and setting (the form for docs/physics_step.md)."""
    cur = doc["cases"][0].get("current") if doc["cases"] else None
    head = (
        "| case | setting | max deviation (mm) | per drone (mm) | max attitude deviation (°) | "
        f"deviation from {cur or 'the current step'} (mm) | contacts | printed figures vs 1-ms RK4 | "
        "wall time ÷ reference |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|---|"]
    for c in doc["cases"]:
        for j, r in enumerate(c["rows"]):
            per = ", ".join(_mm(v) for v in r["deviation_m"].values()) if len(r["deviation_m"]) > 1 else "–"
            name = f"{c['case']} ({c['duration_s']:g} s)" if j == 0 else ""
            stop = " (stopped)" if r["stopped"] else ""
            fig = "reference" if j == 0 else _diff_text(r["differing"])
            vc = r.get("max_deviation_vs_current_m")
            lines.append(
                f"| {name} | {r['label']}{stop} | {_mm(r['max_deviation_m'])} | {per} | "
                f"{r['max_attitude_deviation_deg']:.2g} | {'–' if vc is None else _mm(vc)} | {r['contacts']} | "
                f"{fig} | {r['wall_ratio']:.2f} |"
            )
        p = c.get("perturbed")
        if p:
            stop = " (stopped)" if p["stopped"] else ""
            pc = p["contacts"] if isinstance(p["contacts"], int) else ", ".join(map(str, p["contacts"]))
            lines.append(
                f"| | *{p['label']}*{stop} | *{_mm(p['max_deviation_m'])}* | | | | {pc} | "
                f"{_diff_text(p['differing'])} | |"
            )
    return "\n".join(lines)


def _readme_diffs(diffs: list[dict]) -> str:
    rd = [d for d in diffs if d["in_readme"]]
    if not rd:
        return "yes"
    sens = sum(1 for d in rd if d.get("sensitive"))
    cases = sorted({d["case"] for d in rd})
    names = ", ".join(cases[:4]) + (f" and {len(cases) - 4} more cases" if len(cases) > 4 else "")
    return f"no: {len(rd)} in {names}" + (f" ({sens} of them change with the perturbed start too)" if sens else "")


def _groups(doc: dict) -> tuple[list[dict], list[dict]]:
    """(cases without drone-drone contact and not stopped at the reference, the others)."""
    quiet = [c for c in doc["cases"] if c["rows"][0]["contacts"] == 0 and not c["rows"][0]["stopped"]]
    return quiet, [c for c in doc["cases"] if c not in quiet]


def _n_readme(rows: list, key: str) -> int:
    return sum(1 for _, r in rows for d in r.get(key, []) if d["in_readme"])


def short_table(doc: dict) -> str:
    """Per setting over every case (the form for the README)."""
    cur = doc["cases"][0].get("current") if doc["cases"] else "RK4 5 ms"
    quiet, loud = _groups(doc)
    lines = [
        f"| physics step | runs without contact ({len(quiet)}): worst deviation from 1-ms RK4 (mm) | "
        "of them over 1 mm (sensitive¹) | README figures that differ from 1 ms / from " + str(cur) + " | "
        f"runs with contacts ({len(loud)}): contacts | wall time ÷ 1-ms RK4 | speed vs RK4 5 ms |",
        "|---|---|---|---|---|---|---|",
    ]
    for j, s in enumerate(doc["settings"]):
        q = [(c, c["rows"][j]) for c in quiet]
        lo = [(c, c["rows"][j]) for c in loud]
        wc, wr = max(q, key=lambda cr: cr[1]["max_deviation_m"]) if q else (None, None)
        over = [c for c, r in q if r["max_deviation_m"] > DEVIATION_BAR_M]
        ns = sum(1 for c in over if c.get("sensitive"))
        ov = "none" if not over else f"{len(over)} ({ns})"
        figs = (
            f"without contact {_n_readme(q, 'differing')} / {_n_readme(q, 'differing_vs_current')}; "
            f"with contacts {_n_readme(lo, 'differing')} / {_n_readme(lo, 'differing_vs_current')}"
        )
        stop = sum(1 for _, r in lo if r["stopped"])
        speed = s.get("speed_vs_rk4_5ms")
        dev = "–" if wr is None else f"{_mm(wr['max_deviation_m'])} ({wc['case']})"
        lines.append(
            f"| {s['label']} | {dev} | {ov} | {figs} | {sum(r['contacts'] for _, r in lo)} "
            f"({stop} runs stopped) | {s['wall_ratio']:.2f} | {'–' if speed is None else f'{speed:.2f}×'} |"
        )
    pert = doc["meta"].get("perturb_m")
    if pert:
        lines.append("")
        lines.append(
            f"¹ sensitive: the 1-ms run itself moves more than 1 mm when the leader's start is moved {pert * 1e6:g} µm."
        )
    return "\n".join(lines)


def contacts_table(doc: dict) -> str:
    """The contacts mode as markdown: totals, verdict, the starts whose counts differ."""
    kinds = [k for k in ("fine", "coarse", "control") if k in doc]
    head = (
        "| rule | starts | run | starts with a contact | contacts | pairs that touched | contact episodes | "
        "runs that stopped | loop time (s) |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|---|"]
    for k in kinds:
        s = doc[k]
        lines.append(
            f"| `{doc['settings']['rule']}` | {doc['settings']['starts']} | {s['label']} | "
            f"{s['starts_with_contact']} | {s['contacts']} | {s.get('pairs', '–')} | {s.get('episodes', '–')} | "
            f"{len(s['stopped'])} | {s['wall_s']:.0f} |"
        )
    diff = [r for r in doc["starts"] if r["fine"] != r["coarse"]]
    lines.append("")
    lines.append(
        "Contacts are rising edges of a drone pair's contact, counted once per physics step; pairs "
        "that touched counts each pair once per start; an episode merges a pair's touches less than "
        f"{doc['verdict'].get('episode_gap_s', 0) * 1e3:g} ms apart."
    )
    lines.append("")
    if diff:
        lines.append(
            f"Starts whose counts differ ({len(diff)}; seed: fine → candidate"
            + (", control" if "control" in doc else "")
            + "): "
            + ", ".join(
                f"{r['seed']}: {r['fine']} → {r['coarse']}" + (f", {r['control']}" if "control" in r else "")
                for r in diff
            )
            + "."
        )
    else:
        lines.append("Every start has the same contact count at both steps.")
    return "\n".join(lines)


def replace_block(text: str, name: str, body: str) -> str:
    pat = re.compile(rf"(<!-- tables:{name} -->\n).*?(<!-- /tables:{name} -->)", re.DOTALL)
    if not pat.search(text):
        raise SystemExit(f"no <!-- tables:{name} --> ... <!-- /tables:{name} --> markers")
    return pat.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)


# --------------------------------------------------------------------------- docs/physics_step.md

DOC = """# The physics step

<!-- Written by `python tools/accuracy.py --docs docs/physics_step.md` from {source}; edit the tool, not this file. -->

swarm-mj's controller runs every T = 10 ms (paper eq. 38) and holds its inputs U1..U4 constant
over the period (zero-order hold); the wind force is also computed once per period. MuJoCo
integrates the rigid bodies in between with a fixed physics step h that divides T. This page
shows how h was chosen: by measuring what each candidate changes.

## Why a step as long as the control period can be enough

Over one control period the drones obey an ODE whose inputs do not change: thrust and torques
are held, the wind force is held, and the only forces that depend on the state within the
period are gravity (constant), the linear drag −K·v and the rigid-body terms (ω × Iω, the
rotation of the thrust with the body). Nothing jumps inside the period, so the right-hand side
is smooth and a single-step method of order p makes a global error ∝ h^p on it. MuJoCo's RK4
is fourth order: from 1 ms to 10 ms its truncation error grows 10⁴-fold from a very small
start, because the motion inside 10 ms is gentle (h·ω ≈ 0.2 rad per step at 10 ms even for a
drone tumbling at 18 rad/s). Two parts are first order in h at any step. The drag is evaluated
with the velocity at the start of each physics step and held over its RK4 stages: it lags the
true −K·v(t) by h/2, an extra force K·a·h/2, tiny because K/m ≈ 0.012 s⁻¹. And contact
detection runs once per physics step (measured below). Euler (semi-implicit in MuJoCo) and
implicitfast are first order throughout: their error falls only in proportion to h, which the
table shows for contrast.

`tests/unit/test_physics_step.py` checks this on a drone tumbling about all three axes under drag and a
constant wind force, with no controller, for 2 s: at 10 ms it stays within 1 mm of the 1-ms run
(0.86 mm after an 18-m drift), the difference is the drag hold predicted as
(Δh/2)·(K/m)·(x − x₀ − v₀t) to within 12 µm, and without the drag RK4's error is 4 µm and falls
16-fold when the step is halved.

The control period is where the sampling error of the closed loop lives, and it does not depend
on h: the inputs are the same zero-order-held values whatever the physics step, so a smaller h
only resolves the same piecewise-constant inputs more finely.

## The measurement

Every bundled scenario (and the rule variants that the README's anti-collision table prints)
was flown with {settings_list}, against the 1-ms RK4 run as reference (`{reference}`). For
each run the table gives the largest distance between a drone and where it is in the reference
run at the same control-period sample, over the whole run (per drone for swarms); the largest
attitude difference; the same distance from the run at {current}, the step the README's figures
were made with; whether every summary figure the README prints is the same at the digits it is
printed with (step overshoot and settling 2 decimals, peak roll/pitch 1 decimal, RMSE x, y 4
decimals in m and roll, pitch 3 decimals in °, whole run and from 10 s, formation settling and
settling after each change of D 2 decimals in s, contacts, minimum separation 2 decimals in m;
the same formats are applied to every case, and a figure the README does not print for that
case is marked so); the contact count; and the wall time of the simulation loop as a ratio to
the reference run. {duration_note}

**How sensitive each run is to anything.** A closed loop with decisions in it (the anti-collision
rules yield, hop and change layers when a distance crosses a threshold; a rotor saturates) can
turn a tiny difference into a large one: a decision taken one control period later moves a drone
by millimetres. To tell such a run from a step that is too coarse, each case is also flown at the
reference step with the leader's start moved {perturb_um:g} µm along {perturb_axes}, one run each
(the italic rows give the largest deviation and every figure any of them changes): what that
changes, no step can be expected to keep. A case is *sensitive* when this alone moves it by more
than 1 mm.

Measured on {machine} with MuJoCo {mujoco}, {workers} worker process(es), on a machine shared with
other jobs: the time ratios are indicative (`tools/bench.py` measures speed).

### Summary

{short_table}

### Per case

{full_table}

## Contacts at the coarser step

{contacts_section}

## The choice

{choice}

A scenario file can still ask for any step that divides its control period, e.g.
`timestep = 0.005` (and `integrator = "RK4" | "Euler" | "implicitfast"`).

Regenerate this page with

    python tools/accuracy.py --workers 2 --json report/accuracy.json
    python tools/accuracy.py --contacts --workers 2 --json report/accuracy_contacts.json
    python tools/accuracy.py --from-json report/accuracy.json --contacts-json report/accuracy_contacts.json \\
        --docs docs/physics_step.md
"""


def contacts_verdict(doc: dict) -> str:
    f, c = doc["fine"], doc["coarse"]
    v, st = doc["verdict"], doc["settings"]
    text = (
        f'The paper\'s rule (`anti_collision = "{st["rule"]}"`) over the {st["starts"]} stress starts '
        f"(`swarm-mj stress --rule {st['rule']} --starts {st['starts']}`: {st['followers']} followers within "
        f"{st['radius']:g} m, seeds {st['seed0']}..{st['seed0'] + st['starts'] - 1}, {st['duration']:g} s each), "
        f"RK4 at {st['fine_s'] * 1e3:g} ms and at {st['coarse_s'] * 1e3:g} ms: {f['contacts']} contacts in "
        f"{f['starts_with_contact']} starts at the fine step, {c['contacts']} in {c['starts_with_contact']} at the "
        f"candidate ({v['relative_difference'] * 100:+.1f} %, bar ±{CONTACT_TOLERANCE * 100:g} %); starts with a "
        f"contact at the fine step and none at the candidate: {', '.join(map(str, v['missed_starts'])) or 'none'}."
    )
    if "first_contact_within_one_period" in v:
        text += (
            f" Of the {v['starts_with_contact_at_both']} starts with a contact at both steps, the first contact "
            f"comes at the same time to within one control period in {v['first_contact_within_one_period']} "
            f"and within 50 ms in {v['first_contact_within_50ms']}. Pairs that touched: "
            f"{v['pairs_relative_difference'] * 100:+.1f} %; contact episodes: "
            f"{v['episodes_relative_difference'] * 100:+.1f} %."
        )
    if "control_relative_difference" in v:
        both = [p for p in doc["starts"] if p.get("fine_first_s") is not None and p.get("control_first_s") is not None]
        same = sum(1 for p in both if abs(p["control_first_s"] - p["fine_first_s"]) <= st["coarse_s"] + 1e-9)
        ndiff = sum(1 for p in doc["starts"] if p["fine"] != p.get("control", p["fine"]))
        ndiff_c = sum(1 for p in doc["starts"] if p["fine"] != p["coarse"])
        text += (
            f" Control: the fine step again with the start moved {st['control_m'] * 1e6:g} µm changes the "
            f"contact count by {v['control_relative_difference'] * 100:+.1f} % (the candidate step: "
            f"{v['relative_difference'] * 100:+.1f} %), the count of {ndiff} starts (the candidate: {ndiff_c}) and "
            f"the pairs that touched by {v['control_pairs_relative_difference'] * 100:+.1f} %; its first contact "
            f"comes within one control period of the fine run's in {same} of {len(both)} starts."
        )
    text += (
        " **By the issue's bar, contacts are counted equivalently at the candidate step.**"
        if v["holds"]
        else " **By the issue's bar (within 5 % and no start missed), contacts are not counted equivalently at the "
        "candidate step.**"
    )
    return text


def _split_text(doc: dict, label: str) -> str:
    """One step's outcome in the cases without drone-drone contact at the reference and in those with."""
    quiet, loud = _groups(doc)
    out = []
    for group, name in (
        (quiet, "without contact"),
        (loud, "with contacts or a run that stopped (a drone knocked down)"),
    ):
        if not group:
            continue
        rows = [(c, next(r for r in c["rows"] if r["label"] == label)) for c in group]
        wc, wr = max(rows, key=lambda cr: cr[1]["max_deviation_m"])
        over = [c for c, r in rows if r["max_deviation_m"] > DEVIATION_BAR_M]
        not_sens = [c["case"] for c in over if not c.get("sensitive")]
        rd = [(c["case"], d) for c, r in rows for d in r["differing"] if d["in_readme"]]
        rc = [(c["case"], d) for c, r in rows for d in r.get("differing_vs_current", []) if d["in_readme"]]
        out.append(
            f"In the {len(group)} cases {name}: worst deviation {_mm(wr['max_deviation_m'])} mm ({wc['case']}); "
            f"over 1 mm: {', '.join(c['case'] for c in over) or 'none'}"
            + (
                (
                    " (every one of them sensitive: the perturbed start alone moves it more than 1 mm)"
                    if not not_sens
                    else f" (not sensitive: {', '.join(not_sens)})"
                )
                if over
                else ""
            )
            + f"; README figures that differ from 1 ms: {len(rd)}, from {doc['cases'][0].get('current')}: "
            f"{len(rc)}."
        )
    return " ".join(out)


def _choice_text(doc: dict) -> str:
    by = {s["label"]: s for s in doc["settings"]}
    bar = f"{DEVIATION_BAR_M * 1e3:g} mm"
    out = []
    chosen = doc.get("chosen")
    if chosen and chosen["label"] == doc["meta"]["reference"]:
        chosen = None
    rk4 = sorted((s for s in doc["settings"] if s["integrator"] == "RK4"), key=lambda s: -s["timestep_s"])
    if chosen:
        s = by[chosen["label"]]
        out.append(
            f"The largest RK4 step that keeps every figure the README prints as at 1 ms and stays within "
            f"{bar} of the 1-ms run in every case is **{chosen['label']}** (worst deviation "
            f"{_mm(s['worst_deviation_m'])} mm, in {s['worst_case']})."
        )
    else:
        out.append(
            f"No RK4 step coarser than the reference keeps every figure the README prints as at 1 ms and every "
            f"case within {bar} of it."
        )
    for s in rk4:
        if s["label"] == doc["meta"]["reference"] or (chosen and s["timestep_s"] <= chosen["timestep_s"]):
            continue
        over = s.get("over_bar", [])
        rd = [d for d in s["differing"] if d["in_readme"]]
        parts = []
        if over:
            pert = doc["meta"].get("perturb_m") or 0.0
            parts.append(
                "over "
                + bar
                + " in "
                + ", ".join(
                    f"{o['case']} ({_mm(o['deviation_m'])} mm"
                    + (
                        f"; a {pert * 1e6:g}-µm start change alone: {_mm(o['perturbed_deviation_m'])} mm)"
                        if pert and o["perturbed_deviation_m"] is not None
                        else ")"
                    )
                    for o in over
                )
            )
        if rd:
            parts.append(
                "README figures that differ from 1 ms: "
                + "; ".join(
                    f"{d['case']}: {d['figure']} {d['reference']} → {d['value']}"
                    + (" (also with the start change)" if d.get("sensitive") else "")
                    for d in rd[:12]
                )
                + (f"; +{len(rd) - 12} more" if len(rd) > 12 else "")
            )
        nr = [d for d in s["differing"] if not d["in_readme"]]
        if nr:
            parts.append(f"{len(nr)} figure(s) the README does not print differ at its digits")
        rc = [d for d in s.get("differing_vs_current", []) if d["in_readme"]]
        if s["label"] != doc["cases"][0].get("current"):
            parts.append(
                f"README figures that differ from {doc['cases'][0].get('current')} (the README's step): "
                + (
                    "; ".join(f"{d['case']}: {d['figure']} {d['reference']} → {d['value']}" for d in rc[:12])
                    + (f"; +{len(rc) - 12} more" if len(rc) > 12 else "")
                    if rc
                    else "none"
                )
            )
        out.append(f"**{s['label']}**: " + ("; ".join(parts) if parts else "holds") + ".")
        out.append(_split_text(doc, s["label"]))
    cs = doc.get("chosen_allowing_sensitive")
    if cs and cs["label"] != doc["meta"]["reference"] and (not chosen or cs["timestep_s"] > chosen["timestep_s"]):
        s = by[cs["label"]]
        out.append(
            f"Counting only what a {doc['meta'].get('perturb_m', 0) * 1e6:g}-µm change of the start does not "
            f"change as well (every case over {bar} and every differing figure at {cs['label']} also moves "
            f"that much, or changes, with the perturbed start), the largest RK4 step that holds is "
            f"**{cs['label']}**; it runs {s.get('speed_vs_rk4_5ms', float('nan')):.2f}× as fast as RK4 "
            f"at 5 ms over the whole study."
        )
    return "\n\n".join(out)


def render_docs(doc: dict, contacts: dict | None, source: str) -> str:
    settings = doc["settings"]
    labels = [s["label"] for s in settings]
    m = doc["meta"]["machine"]
    dur = doc["meta"]["duration_override_s"]
    duration_note = (
        f"**Every case was shortened to at most {dur:g} s of simulated time** (a quick run; "
        f"the full study flies each scenario for its own duration)."
        if dur
        else "Every case is flown for its scenario's own duration (10 s to 180 s)."
    )
    if contacts is None:
        csec = "Not measured yet: run `python tools/accuracy.py --contacts`."
    else:
        csec = contacts_verdict(contacts) + "\n\n" + contacts_table(contacts)
    cur = doc["cases"][0].get("current") if doc["cases"] else "RK4 5 ms"
    return DOC.format(
        source=source,
        settings_list=", ".join(labels),
        reference=doc["meta"]["reference"],
        current=cur,
        perturb_um=doc["meta"].get("perturb_m", 0) * 1e6,
        perturb_axes=", ".join(["+x", "+y", "+z", "−x", "−y", "−z"][: doc["meta"].get("perturb_dirs", 1)]),
        duration_note=duration_note,
        machine=f"{m['cpu']} ({m['cores']} cores)",
        mujoco=doc["meta"]["mujoco"],
        workers=doc["meta"]["workers"],
        short_table=short_table(doc),
        full_table=full_table(doc),
        contacts_section=csec,
        choice=_choice_text(doc),
    )


# --------------------------------------------------------------------------- contacts mode


def fly_contacts(job: dict) -> dict:
    """One stress start at one step: contacts, contact times and pairs, whether it stopped, wall time.

    ``job["perturb_m"]`` moves the leader's start (and with it the random follower starts, which are
    drawn around it) along x: the control run.
    """
    from swarm_mj.commands.stress import StressCase, stress_scenario
    from swarm_mj.experiments.runner import run

    case = StressCase(**job["case"])
    sc = stress_scenario(case).with_overrides(timestep=float(job["timestep"]), integrator="RK4")
    if job.get("perturb_m"):
        sc = sc.with_overrides(leader_start=sc.leader_start + np.array([job["perturb_m"], 0.0, 0.0]))
    res = run(sc, progress=False)
    s = res.summary
    return {
        "seed": case.seed,
        "kind": job["kind"],
        "timestep_s": float(job["timestep"]),
        "contacts": int(s["contacts"]),
        "contact_log": [[float(c[0]), int(c[1]), int(c[2])] for c in res.contact_log],
        "stopped": s.get("stopped"),
        "min_separation_airborne_m": s.get("min_separation_airborne_m"),
        "wall_s": float(s.get("wall_time_s", float("nan"))),
    }


def _episodes(log: list, gap: float) -> int:
    """Contacts counted as episodes: a pair touching again within ``gap`` s of its last touch is the same one."""
    last: dict[tuple[int, int], float] = {}
    n = 0
    for t, i, j in log:
        if (i, j) not in last or t - last[(i, j)] > gap:
            n += 1
        last[(i, j)] = t
    return n


def contacts_study(
    *,
    rule: str,
    starts: int,
    seed0: int,
    followers: int,
    radius: float,
    min_spacing: float,
    duration: float,
    fine: float,
    coarse: float,
    workers: int,
    control_m: float = 1e-6,
    say=print,
) -> dict:
    """The stress starts at the fine and the candidate step (and, as a control, at the fine step again with
    the start moved ``control_m``): contact counts, per start, and the verdict of issue 20."""
    from swarm_mj.commands.stress import StressCase

    kinds = [("fine", fine, 0.0), ("coarse", coarse, 0.0)] + ([("control", fine, control_m)] if control_m else [])
    jobs = []
    for k in range(starts):
        case = StressCase(rule, seed0 + k, followers, radius, min_spacing, duration)
        for kind, dt, pm in kinds:
            jobs.append(
                (
                    {
                        "name": f"seed {seed0 + k} {kind} ({dt * 1e3:g} ms)",
                        "case": asdict(case),
                        "timestep": dt,
                        "kind": kind,
                        "perturb_m": pm,
                    },
                    1.0 / dt,
                )
            )
    t0 = time.perf_counter()
    rows = run_parallel(fly_contacts, jobs, workers, say)
    by = {(r["seed"], r["kind"]): r for r in rows}
    gap = EPISODE_GAP_S
    per_start = []
    for k in range(starts):
        item: dict[str, Any] = {"seed": seed0 + k}
        for kind, _, _ in kinds:
            r = by[(seed0 + k, kind)]
            log = r["contact_log"]
            item.update(
                {
                    kind: r["contacts"],
                    f"{kind}_stopped": r["stopped"],
                    f"{kind}_log": log,
                    f"{kind}_first_s": log[0][0] if log else None,
                    f"{kind}_pairs": len({(i, j) for _, i, j in log}),
                    f"{kind}_episodes": _episodes(log, gap),
                }
            )
        per_start.append(item)

    def side(kind: str, dt: float) -> dict:
        rs = [r for r in rows if r["kind"] == kind]
        return {
            "label": _label("RK4", dt) + (f", start moved {control_m * 1e6:g} µm" if kind == "control" else ""),
            "timestep_s": dt,
            "contacts": sum(p[kind] for p in per_start),
            "starts_with_contact": sum(p[kind] > 0 for p in per_start),
            "pairs": sum(p[f"{kind}_pairs"] for p in per_start),
            "episodes": sum(p[f"{kind}_episodes"] for p in per_start),
            "stopped": [r["seed"] for r in rs if r["stopped"]],
            "wall_s": sum(r["wall_s"] for r in rs),
        }

    def rel(a: int, b: int) -> float:
        return (b - a) / a if a else (0.0 if b == 0 else float("inf"))

    out = {kind: side(kind, dt) for kind, dt, _ in kinds}
    F, C = out["fine"], out["coarse"]
    r = rel(F["contacts"], C["contacts"])
    missed = [p["seed"] for p in per_start if p["fine"] > 0 and p["coarse"] == 0]
    first = [
        abs(p["coarse_first_s"] - p["fine_first_s"])
        for p in per_start
        if p["fine_first_s"] is not None and p["coarse_first_s"] is not None
    ]
    verdict = {
        "relative_difference": r,
        "tolerance": CONTACT_TOLERANCE,
        "missed_starts": missed,
        "new_starts": [p["seed"] for p in per_start if p["coarse"] > 0 and p["fine"] == 0],
        "holds": abs(r) <= CONTACT_TOLERANCE and not missed,
        "first_contact_within_one_period": sum(1 for x in first if x <= coarse + 1e-9),
        "first_contact_within_50ms": sum(1 for x in first if x <= 0.05 + 1e-9),
        "starts_with_contact_at_both": len(first),
        "pairs_relative_difference": rel(F["pairs"], C["pairs"]),
        "episodes_relative_difference": rel(F["episodes"], C["episodes"]),
        "episode_gap_s": gap,
    }
    if "control" in out:
        verdict["control_relative_difference"] = rel(F["contacts"], out["control"]["contacts"])
        verdict["control_pairs_relative_difference"] = rel(F["pairs"], out["control"]["pairs"])
    return {
        "meta": {
            "generated": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "wall_s": time.perf_counter() - t0,
            "workers": workers,
            "argv": sys.argv[1:],
        },
        "settings": {
            "rule": rule,
            "starts": starts,
            "seed0": seed0,
            "followers": followers,
            "radius": radius,
            "min_spacing": min_spacing,
            "duration": duration,
            "fine_s": fine,
            "coarse_s": coarse,
            "control_m": control_m,
        },
        **out,
        "starts": per_start,
        "verdict": verdict,
    }


def format_contacts(doc: dict) -> str:
    v, st = doc["verdict"], doc["settings"]
    kinds = [k for k in ("fine", "coarse", "control") if k in doc]
    lines = [f"rule {st['rule']}, {st['starts']} starts, {st['duration']:g} s each"]
    lines += [
        f"{doc[k]['label']:>28}: {doc[k]['contacts']} contacts in {doc[k]['starts_with_contact']} starts, "
        f"{doc[k]['pairs']} pairs touched, {doc[k]['episodes']} episodes ({len(doc[k]['stopped'])} stopped), "
        f"loop {doc[k]['wall_s']:.1f} s"
        for k in kinds
    ]
    lines.append(
        "per start (seed: fine / candidate" + (" / control" if "control" in doc else "") + "), those with any contact:"
    )
    lines += [
        f"  {p['seed']:>4}: {p['fine']} / {p['coarse']}"
        + (f" / {p['control']}" if "control" in p else "")
        + ("  <- differs" if p["fine"] != p["coarse"] else "")
        for p in doc["starts"]
        if p["fine"] or p["coarse"]
    ]
    lines.append(contacts_verdict(doc))
    lines.append("verdict: " + ("contacts counted equivalently" if v["holds"] else "NOT equivalent by the 5 % bar"))
    return "\n".join(lines)


# --------------------------------------------------------------------------- CLI


def parse_settings(text: str) -> list[tuple[str, float]]:
    """``"RK4:1,RK4:10,Euler:5"`` (step in ms) -> [("RK4", 0.001), ...]; the first is the reference."""
    out = []
    for part in text.split(","):
        try:
            integ, ms = part.strip().split(":")
            dt = float(ms) / 1e3
        except ValueError:
            raise SystemExit(f"accuracy: error: bad setting {part!r}; write INTEGRATOR:MS, e.g. RK4:10") from None
        if integ not in ("RK4", "Euler", "implicitfast") or not dt > 0:
            raise SystemExit(f"accuracy: error: bad setting {part!r}")
        out.append((integ, dt))
    return out


#: docs/physics_step.md from this line on is written by hand (measurements of other tools) and kept as it is
#: when ``--docs`` rewrites the page above it.
KEPT_MARK = "<!-- written by hand from here on: tools/accuracy.py --docs keeps it as it is -->"


def keep_hand_written(path: str, text: str) -> str:
    """``text`` followed by the hand-written tail (from :data:`KEPT_MARK`) of the file at ``path``, if any."""
    p = Path(path)
    old = p.read_text() if p.exists() else ""
    i = old.find(KEPT_MARK)
    return text if i < 0 else text.rstrip("\n") + "\n\n" + old[i:]


def _write(path: str, text: str) -> None:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(p.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(p)


def _json(o: Any) -> Any:
    if isinstance(o, float) and not math.isfinite(o):
        return str(o)
    if isinstance(o, dict):
        return {k: _json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_json(v) for v in o]
    if isinstance(o, np.generic):
        return o.item()
    return o


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--scenarios", help="comma-separated bundled scenario names (default: all)")
    ap.add_argument(
        "--duration",
        type=float,
        help="fly each case for at most this many seconds (quick runs); contacts mode: seconds per start (default 15)",
    )
    ap.add_argument("--workers", type=int, default=1, help="processes (spawn), default 1")
    ap.add_argument(
        "--settings",
        default=None,
        help="INTEGRATOR:MS list, the first the reference (default RK4:1,RK4:2.5,RK4:5,RK4:10,"
        "Euler:5,Euler:10,implicitfast:5,implicitfast:10)",
    )
    ap.add_argument(
        "--perturb",
        type=float,
        default=1.0,
        metavar="UM",
        help="also fly the reference with the leader's start moved UM µm along x, to measure each "
        "case's sensitivity to its initial state (default 1; 0: not)",
    )
    ap.add_argument(
        "--perturb-dirs",
        type=int,
        default=3,
        metavar="N",
        help="perturbed reference runs per case: the start moved along +x, +y, +z, -x, -y, -z, the first N (default 3)",
    )
    ap.add_argument(
        "--no-rule-variants",
        action="store_true",
        help="leave out the anti-collision table's other rules of anti_collision, scenario1..3",
    )
    ap.add_argument("--json", metavar="PATH", help="write the numbers as JSON")
    ap.add_argument("--markdown", metavar="PATH", help="write the short and the full table as markdown")
    ap.add_argument("--docs", metavar="PATH", help="write docs/physics_step.md (the full form with the reasoning)")
    ap.add_argument("--readme", metavar="PATH", help="put the short table between <!-- tables:accuracy --> markers")
    ap.add_argument("--from-json", metavar="PATH", help="do not fly: read a study's JSON (for --docs/--markdown)")
    ap.add_argument("--contacts-json", metavar="PATH", help="a contacts-mode JSON to include in --docs")
    g = ap.add_argument_group("contacts mode")
    g.add_argument("--contacts", action="store_true", help="compare contact counts over the stress starts")
    g.add_argument("--rule", default="paper", help="anti-collision rule (default paper)")
    g.add_argument("--starts", type=int, default=100, help="stress starts (default 100)")
    g.add_argument("--seed0", type=int, default=0, help="first seed (default 0, as swarm-mj stress)")
    g.add_argument("--followers", type=int, default=5)
    g.add_argument("--radius", type=float, default=3.0)
    g.add_argument("--min-spacing", type=float, default=0.6)
    g.add_argument("--fine", type=float, default=5.0, help="fine step in ms (default 5)")
    g.add_argument("--coarse", type=float, default=10.0, help="candidate step in ms (default 10)")
    g.add_argument(
        "--control",
        type=float,
        default=1.0,
        metavar="UM",
        help="also fly the fine step with the start moved UM µm, to show how much the counts change "
        "for reasons that have nothing to do with the step (default 1; 0: not)",
    )
    a = ap.parse_args(argv)
    if a.workers < 1:
        ap.error("--workers must be at least 1")
    if a.duration is not None and not a.duration > 0:
        ap.error("--duration must be positive")
    say = lambda s: print(s, file=sys.stderr, flush=True)

    if a.contacts:
        if a.starts < 1:
            ap.error("--starts must be at least 1")
        doc = contacts_study(
            rule=a.rule,
            starts=a.starts,
            seed0=a.seed0,
            followers=a.followers,
            radius=a.radius,
            min_spacing=a.min_spacing,
            duration=a.duration or 15.0,
            fine=a.fine / 1e3,
            coarse=a.coarse / 1e3,
            workers=a.workers,
            control_m=a.control * 1e-6,
            say=say,
        )
        print(format_contacts(doc))
        if a.json:
            _write(a.json, json.dumps(_json(doc), indent=1) + "\n")
        if a.markdown:
            _write(a.markdown, contacts_verdict(doc) + "\n\n" + contacts_table(doc) + "\n")
        return 0 if doc["verdict"]["holds"] else 1

    if a.from_json:
        doc = conclude(json.loads(Path(a.from_json).read_text()))
        source = a.from_json
    else:
        from swarm_mj.scenario import bundled_scenarios

        found = bundled_scenarios()
        names = list(found) if not a.scenarios else [s.strip() for s in a.scenarios.split(",") if s.strip()]
        unknown = [n for n in names if n not in found]
        if unknown:
            ap.error(f"unknown scenario(s) {', '.join(unknown)}; bundled: {', '.join(found)}")
        settings = parse_settings(a.settings) if a.settings else list(DEFAULT_SETTINGS)
        doc = study(
            names,
            duration=a.duration,
            workers=a.workers,
            settings=settings,
            rule_variants=not a.no_rule_variants,
            perturb_m=a.perturb * 1e-6,
            perturb_dirs=a.perturb_dirs,
            say=say,
        )
        doc = _json(doc)
        source = a.json or "a run of the tool"
        if a.json:
            _write(a.json, json.dumps(doc, separators=(",", ":")) + "\n")
    print(short_table(doc))
    ch = doc.get("chosen")
    cs = doc.get("chosen_allowing_sensitive")
    print(
        f"\nlargest RK4 step with every README figure as at 1 ms and <= {DEVIATION_BAR_M * 1e3:g} mm: "
        f"{ch['label'] if ch else 'none'}; allowing what a start perturbation changes too: "
        f"{cs['label'] if cs else 'none'}"
    )
    if a.markdown:
        _write(a.markdown, "## Summary\n\n" + short_table(doc) + "\n\n## Per case\n\n" + full_table(doc) + "\n")
    if a.readme:
        p = Path(a.readme)
        _write(a.readme, replace_block(p.read_text(), "accuracy", short_table(doc)))
    if a.docs:
        contacts = json.loads(Path(a.contacts_json).read_text()) if a.contacts_json else None
        _write(a.docs, keep_hand_written(a.docs, render_docs(doc, contacts, source)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
