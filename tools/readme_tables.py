"""Fill the README's short tables and report/tables.md's full ones from what `swarm-mj report`,
`swarm-mj stress` and `tools/bench.py` wrote.

    python tools/readme_tables.py [--results report/results.json] [--bench report/bench.json]
                                  [--readme README.md] [--tables report/tables.md]

Rewrites the text between ``<!-- tables:NAME -->`` and ``<!-- /tables:NAME -->`` markers, so
that every number in the tables comes from a run, none is typed by hand. The README keeps one
short table each for the paper, the realistic physics and the speed; report/tables.md has them all.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Iterator
from pathlib import Path


def f(v, fmt="{:.4f}") -> str:
    if v is None or (isinstance(v, str) and v.lower() in ("inf", "nan")):
        return "never" if v == "inf" else "–"
    if isinstance(v, float) and not math.isfinite(v):
        return "never"
    return fmt.format(v)


def reproduction(r: dict) -> str:
    rows = ["| what | paper | ours | note |", "|---|---|---|---|"]
    st = r["step"]
    ax = st["table4"]["axes"]
    for a, name in (("x", "x"), ("y", "y"), ("z", "z"), ("psi", "ψ")):
        p = st["paper"][a]
        ps = "< 1" if a == "psi" else f(p["settling_s"], "{:.1f}")
        rows.append(
            f"| step {name}: overshoot / 2 % settling | 0 % / {ps} s | "
            f"{f(ax[a]['overshoot_pct'], '{:.2f}')} % / {f(ax[a]['settling_s'], '{:.2f}')} s | "
            f"Table 4 gains, MuJoCo |"
        )
    rows.append(
        f"| step: peak \\|roll\\|, \\|pitch\\| | within ±45° | {st['table4']['max_abs_roll_deg']:.1f}°, "
        f"{st['table4']['max_abs_pitch_deg']:.1f}° | the desired angles are clipped at 45°; the actual pitch overshoots the clip |"
    )
    t3 = r["table3"]
    paper_imp = [x["improvement_pct"] for x in t3["paper"]]
    ours_imp = [x["improvement_pct"] for x in t3["ours"]]
    seeds = ", ".join(str(x["seed"]) for x in t3["ours"])
    met = sum(1 for x in t3["ours"] if x.get("meets_bars"))
    rows.append(
        f"| FPA: ISE improvement over 14 iterations | {min(paper_imp):.1f}–{max(paper_imp):.1f} % | "
        f"{min(ours_imp):.1f}–{max(ours_imp):.1f} % (seeds {seeds}; {met} of {len(t3['ours'])} meet the step bars) | "
        f"`swarm-mj tune` defaults: step bars as constraints, Table 4 in the initial population; "
        f"seed-1 gains ISE {r['gains']['fpa_ise']:.3f} vs Table 4's {r['gains']['table4_ise']:.3f} |"
    )
    pm = t3.get("ours_paper_mode") or []
    if pm:
        pm_imp = [x["improvement_pct"] for x in pm]
        pm_met = sum(1 for x in pm if x.get("meets_bars"))
        rows.append(
            f"| FPA as printed (ISE alone, random start) | {min(paper_imp):.1f}–{max(paper_imp):.1f} % | "
            f"{min(pm_imp):.1f}–{max(pm_imp):.1f} % (seeds {seeds}; {pm_met} of {len(pm)} meet the step bars) | "
            f"`--constraints none --init random` |"
        )
    for row in r["table5"]["rows"]:
        if row.get("variant") != "ground" or row["paper"] is None:
            continue
        if row["wind"] and not row["wind_feedforward"]:
            continue
        w, s, p = row["whole"], row["steady"], row["paper"]
        label = f"Table 5 {row['trajectory']}, {'wind' if row['wind'] else 'no wind'}: RMSE x, y (m)"
        rows.append(
            f"| {label} | {p['x']:.4f}, {p['y']:.4f} | {w['x']:.4f}, {w['y']:.4f} (from 10 s: "
            f"{s['x']:.4f}, {s['y']:.4f}) | whole run from the ground at the origin |"
        )
        rows.append(
            f"| Table 5 {row['trajectory']}, {'wind' if row['wind'] else 'no wind'}: RMSE roll, pitch (°) | "
            f"{p['roll_deg']:.4f}, {p['pitch_deg']:.4f} | {w['roll_deg']:.3f}, {w['pitch_deg']:.3f} "
            f"(from 10 s: {s['roll_deg']:.3f}, {s['pitch_deg']:.3f}) | |"
        )
    sw = {x["scenario"]: x for x in r["swarms"]["rows"] if x["rule"] == "layers"}
    settle = [x["settling_s"][0] for x in sw.values()]
    rows.append(
        f"| formation settling from the start (swarm scenarios) | ≈ 3 s | "
        f"{f(min(settle), '{:.2f}')}–{f(max(settle), '{:.2f}')} s | {', '.join(sw)}; every distance within 5 cm of D |"
    )
    vd = r["variable_d"]
    rows.append(
        f"| variable D: settling after each change | ≈ 3 s | "
        f"{', '.join(f(x, '{:.2f}') for x in vd['settling_s'])} s | D = 1, 1.7, 1.2, 2 m at t = 0, 6, 11, 16 s |"
    )
    contacts = sum(x["contacts"] for x in r["swarms"]["rows"] if x["rule"] == "layers") + vd["contacts"]
    minsep = min([x["min_separation_m"] for x in sw.values()] + [vd["min_separation_m"]])
    rows.append(
        f"| drone–drone contacts in the swarm scenarios | – | {contacts} (min separation {minsep:.2f} m) | counted by MuJoCo |"
    )
    for key, label in (("wind_lemniscate", "lemniscate"), ("wind_circle", "circle")):
        sw_ = r["sweeps"].get(key)
        if not sw_:
            continue
        stt = sw_["results"][0]["stats"]
        n = len(sw_["seeds"])
        rows.append(
            f"| wind robustness, {label}: RMSE x, y over {n} seeds | one run | "
            f"x {stt['rmse_x']['mean']:.4f} ± {stt['rmse_x']['std']:.4f} (worst {stt['rmse_x']['worst']:.4f}), "
            f"y {stt['rmse_y']['mean']:.4f} ± {stt['rmse_y']['std']:.4f} (worst {stt['rmse_y']['worst']:.4f}) | "
            f"mean ± std, whole run |"
        )
    return "\n".join(rows)


def anticollision(r: dict) -> str:
    rows = [
        "| scenario | ours (`layers`): contacts / min separation / settling | paper's rule: contacts / min separation | no rule: contacts |",
        "|---|---|---|---|",
    ]
    by = {}
    for x in r["anti_collision"]["rows"]:
        by.setdefault(x["scenario"], {})[x["rule"]] = x
    for sc, d in by.items():
        L, P, N = d.get("layers"), d.get("paper"), d.get("off")
        stop = lambda x: " (diverged)" if x and x.get("stopped") else ""  # noqa: E731
        rows.append(
            f"| {sc} | {L['contacts']} / {L['min_separation_m']:.2f} m / {f(L['settling_s'][0], '{:.2f}')} s | "
            f"{P['contacts']} / {P['min_separation_m']:.2f} m{stop(P)} | {N['contacts']}{stop(N)} |"
        )
    rc = r["sweeps"].get("random_crossing")
    if rc:
        for res in rc["results"]:
            stt = res["stats"]
            rows.append(
                f"| random crossing starts ({len(rc['seeds'])} seeds), rule `{res['value']}` | "
                f"contacts mean {stt['contacts']['mean']:.1f}, worst {stt['contacts']['worst']:.0f}; "
                f"min separation worst {stt['min_separation_m']['worst']:.2f} m | | |"
            )
    return "\n".join(rows)


def _stress_tables(paths: list[Path]) -> Iterator[tuple[dict, str, dict]]:
    """(settings, rule, table row) of every rule of every ``swarm-mj stress --json`` file that exists."""
    for path in paths:
        if path.exists():
            d = json.loads(path.read_text())
            for rule, r in d["table"].items():
                yield d["settings"], rule, r


def stress(paths: list[Path]) -> str:
    """The ``swarm-mj stress --json`` tables (random crossing starts, leader flying the circle)."""
    rows = [
        "| random starts | rule | starts | starts with a contact | contacts | runs that crashed | "
        "min separation (airborne) | settling median / worst |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for st, rule, r in _stress_tables(paths):
        rows.append(
            f"| {st['followers']} followers within {st['radius']:g} m, ≥ {st['min_spacing']:g} m apart | "
            f"`{rule}` | {r['starts']} | {r['starts_with_contact']} | {r['contacts']} | "
            f"{len(r['stopped'])} | {f(r['min_separation_airborne_m'], '{:.2f}')} m | "
            f"{f(r['settling_median_s'], '{:.2f}')} / {f(r['settling_worst_s'], '{:.2f}')} s |"
        )
    return "\n".join(rows)


def aero(compare: Path, stress_paths: list[Path]) -> str:
    """The paper's physics beside the realistic one (docs/aero.md): per rule, seeded random starts
    (``tools/aero_compare.py``, 20 starts; then the full ``swarm-mj stress --aero realistic`` runs)
    and the paper's three starts: contacts, crashes, the worst downwash dip and settling."""
    rows = [
        "| starts | physics | rule | starts with a contact | contacts | ground crashes | runs stopped | "
        "worst downwash dip | settling median / worst |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    if compare.exists():
        d = json.loads(compare.read_text())
        for r in d["rows"]:
            if r["part"] != "stress":
                continue
            rows.append(
                f"| {r['starts']} random, 5 followers | {r['aero']} | `{r['rule']}` | {r['starts_with_contact']} | "
                f"{r['contacts']} | {r['crashes']} | {r['diverged']} | {f(r['downwash_dip_worst_m'], '{:.3f}')} m | "
                f"{f(r['settling_median_s'], '{:.2f}')} / {f(r['settling_worst_s'], '{:.2f}')} s |"
            )
    for st, rule, r in _stress_tables(stress_paths):
        rows.append(
            f"| {r['starts']} random, {st['followers']} followers | {st.get('aero') or 'paper'} | `{rule}` | "
            f"{r['starts_with_contact']} | {r['contacts']} | {r.get('crashes', 0)} | {len(r['stopped'])} | "
            f"{f(r.get('downwash_dip_worst_m'), '{:.3f}')} m | "
            f"{f(r['settling_median_s'], '{:.2f}')} / {f(r['settling_worst_s'], '{:.2f}')} s |"
        )
    if compare.exists():
        d = json.loads(compare.read_text())
        for r in d["rows"]:
            if (
                r["part"] != "scenario"
                or r.get("default")
                and r["scenario"] in ("anti_collision", "scenario1", "scenario2", "scenario3")
            ):
                continue
            stop = "1" if r.get("stopped") else "0"
            settle = r["settling_s"]
            rows.append(
                f"| `{r['scenario']}` | {r['aero']} | `{r['rule']}` | {int(r['contacts'] > 0)} | {r['contacts']} | "
                f"{r['crashes']} | {stop} | {f(r['downwash_dip_worst_m'], '{:.3f}')} m | "
                f"{f(settle, '{:.2f}')} s |"
            )
    return "\n".join(rows)


#: The README's short realistic-physics table: (stress file, rule) rows, then aero_compare's 20-start rows.
_REALISTIC_SHORT = ("stress5_realistic.json", "stress8_realistic.json", "stress5_crazyflie_realistic.json")


def _vehicle(settings: dict) -> str:
    """The vehicle of a stress run of another drone than the paper's, for the row's label."""
    v = settings.get("vehicle")
    return "" if v in (None, "paper") else f", `{v}`"


def realistic_short(report: Path) -> str:
    """The keep-out table of report/tables.md: the rules of ``swarm-mj stress --aero realistic`` (the
    default and the paper's) over the starts they were tuned on, with the keep-out invariant."""
    rows = [
        "| random starts | rule | starts with a contact | ground crashes | starts in the keep-out | "
        "time in it (all starts) | least keep-out ρ | worst downwash dip | settling median |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for st, rule, r in _stress_tables([report / name for name in _REALISTIC_SHORT]):
        rows.append(
            f"| {r['starts']} × {st['followers']} followers{_vehicle(st)} | `{rule}` | {r['starts_with_contact']} | "
            f"{r.get('crashes', 0)} | {r.get('starts_in_keepout', '–')} | "
            f"{f(r.get('keepout_time_total_s'), '{:.1f}')} s | {f(r.get('keepout_min_distance'), '{:.2f}')} | "
            f"{f(r.get('downwash_dip_worst_m'), '{:.3f}')} m | {f(r['settling_median_s'], '{:.2f}')} s |"
        )
    return "\n".join(rows)


#: The side-by-side stress files (issue 29): report/side_by_side/VEHICLE_PHYSICS*.json, one or more
#: ``swarm-mj stress --json`` files per vehicle and physics over the same fresh starts.
_SIDE_ORDER = ("paper", "layers", "jet-aware", "barrier")


def _seconds_or_never(v: float | None) -> str:
    """A settling time (s) as text; None or inf (a start that never settled): never."""
    return "never" if v is None or not math.isfinite(v) else f"{v:.2f}"


def side_by_side(folder: Path) -> str:
    """The README's side-by-side table: every rule under both physics for both vehicles, on the same
    fresh starts (``swarm-mj stress --seed0 100000``): contact episodes (starts with one), ground
    crashes plus runs lost, time in the keep-out (starts in it), settling median and worst, the median
    path flown per follower. Files of one vehicle and physics must share their starts (checked)."""
    rows = [
        "| vehicle | physics | rule | contact episodes (starts) | crashes + runs lost | time in keep-out (starts) "
        "| settling median / worst (s) | path per follower |",
        "|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[tuple[str, str], dict[str, tuple[dict, dict]]] = {}
    for path in sorted(folder.glob("*.json")):
        d = json.loads(path.read_text())
        st = d["settings"]
        key = (st.get("vehicle") or "paper", st["aero"])
        for rule, r in d["table"].items():
            groups.setdefault(key, {})[rule] = (st, r)
    for (vehicle, aero), rules in sorted(groups.items(), key=lambda kv: (kv[0][0] != "paper", kv[0][1] != "paper")):
        starts = {(st["seed0"], st["starts"], st["followers"], st["duration"]) for st, _ in rules.values()}
        if len(starts) != 1:
            raise SystemExit(f"side-by-side {vehicle}/{aero}: the rules flew different starts {sorted(starts)}")
        seed0, n, followers, _ = starts.pop()
        for rule in sorted(rules, key=lambda x: _SIDE_ORDER.index(x) if x in _SIDE_ORDER else len(_SIDE_ORDER)):
            _, r = rules[rule]
            med, worst = (_seconds_or_never(r[k]) for k in ("settling_median_s", "settling_worst_s"))
            rows.append(
                f"| `{vehicle}` | {aero} | `{rule}` | {r['contacts']} ({r['starts_with_contact']}) | "
                f"{r.get('crashes', 0)} + {len(r['stopped'])} | {f(r.get('keepout_time_total_s'), '{:.1f}')} s "
                f"({r.get('starts_in_keepout', '–')}) | {med} / {worst} | "
                f"{f(r.get('path_per_follower_median_m'), '{:.1f}')} m |"
            )
    rows.append("")
    rows.append(f"{n} starts of {followers} followers each, seeds {seed0}–{seed0 + n - 1} (report/side_by_side/).")
    return "\n".join(rows)


#: The README's short speed table: bench rows whose name starts with one of these.
_SPEED_SHORT = (
    "runner.run + recording circle",
    "runner.run + recording lemniscate_single",
    "SwarmVectorEnv",
    "first run circle",
    "later run circle",
)


def speed_short(b: dict) -> str:
    """The README's short speed table (report/tables.md has every row of ``tools/bench.py``)."""
    rows = ["| what | value | time ÷ raw `mj_step` time |", "|---|---|---|"]
    for prefix in _SPEED_SHORT:
        for row in b["rows"]:
            if row["name"].startswith(prefix):
                ratio = "–" if row["ratio"] is None else f"{row['ratio']:.2f}"
                val = row["value"]
                vs = f"{val:,.0f}" if val >= 100 else f"{val:.1f}"
                rows.append(f"| {row['name']} | {vs} {row['unit']} | {ratio} |")
                break
    return "\n".join(rows)


def validation(path: Path) -> str:
    """The README's downwash table: ``swarm-mj validate downwash`` on the Neural-Swarm logs
    (report/downwash_validation.json), one drone above, calibration and held-out flights apart."""
    rows = [
        "| flights | passes | model | RMSE of Fa_z | ÷ no model | mean peak error | correlation |",
        "|---|---|---|---|---|---|---|",
    ]
    if not path.exists():
        return "\n".join(rows)
    d = json.loads(path.read_text())
    for r in d["rows"]:
        split = r["split"].replace("_", "-")
        peak = -r["mean_peak_measured_g"]  # the measured peak push (gf, > 0)
        none = r["rmse_no_model_g"]
        for label, sfx in (("ours (jet)", ""), ("ours, travelling wake", "_wake"), ("gym-pybullet-drones", "_gym")):
            rmse, err, corr = r[f"rmse{sfx}_g"], r[f"mean_peak_error{sfx}_g"], r[f"corr{sfx}"]
            rows.append(
                f"| {split} | {r['n_passes']} | {label} | {rmse:.2f} gf | {rmse / none:.2f} | "
                f"{100 * err / peak:+.0f} % | {corr:.3f} |"
            )
        rows.append(f"| {split} | {r['n_passes']} | no model | {none:.2f} gf | 1 | – | – |")
    return "\n".join(rows)


SENSING_PRESETS = ("perfect", "mocap", "uwb")
SENSING_RULES = ("paper", "layers", "jet-aware", "barrier")


def _sensing_cell(t: dict | None) -> str:
    """One rule under one preset: starts with a contact, crashes, keep-out time, settling median / worst."""
    if t is None:
        return "–"
    med, worst = t.get("settling_median_s"), t.get("settling_worst_s")  # null: never (JSON has no inf)
    med_s = "never" if med is None else f(med, "{:.2f} s")
    worst_s = "never" if worst is None else f(worst, "{:.1f} s")
    return (
        f"{t['starts_with_contact']} / {t.get('crashes', 0)} / {t['keepout_time_total_s']:.1f} s / {med_s}, {worst_s}"
    )


def sensing(folder: Path) -> str:
    """The README's sensing table (docs/sensing.md): ``swarm-mj stress --sensing P --aero A --rule R ...
    --seed0 100000`` as written into ``folder`` (table_P_A.json), each rule under each preset and physics:
    starts with a contact / crashes / total keep-out time / settling median, worst."""
    rows = [
        "| physics | rule | starts | " + " | ".join(f"`{p}`" for p in SENSING_PRESETS) + " |",
        "|---|---|---|" + "---|" * len(SENSING_PRESETS),
    ]
    for aero in ("realistic", "paper"):
        data = {}
        for p in SENSING_PRESETS:
            path = folder / f"table_{p}_{aero}.json"
            data[p] = json.loads(path.read_text())["table"] if path.exists() else {}
        for rule in SENSING_RULES:
            n = next((d[rule]["starts"] for d in data.values() if rule in d), None)
            if n is None:
                continue
            cells = " | ".join(_sensing_cell(data[p].get(rule)) for p in SENSING_PRESETS)
            rows.append(f"| {aero} | `{rule}` | {n} | {cells} |")
    return "\n".join(rows)


def performance(b: dict) -> str:
    m = b["machine"]
    rows = [
        f"Measured by `python tools/bench.py` on {m['cpu']}, {m['cores']} cores, Python {m['python']}, "
        f"MuJoCo {m['mujoco']}, NumPy {m['numpy']}, Numba {m.get('numba', '–')}.",
        "",
        "| what | value | time ÷ raw `mj_step` time | note |",
        "|---|---|---|---|",
    ]
    for row in b["rows"]:
        ratio = "–" if row["ratio"] is None else f"{row['ratio']:.2f}"
        val = row["value"]
        vs = "–" if val is None else (f"{val:,.0f} {row['unit']}" if val >= 100 else f"{val:.1f} {row['unit']}")
        rows.append(f"| {row['name']} | {vs} | {ratio} | {row['note']} |")
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default="report/results.json")
    ap.add_argument("--bench", default="report/bench.json")
    ap.add_argument("--readme", default="README.md")
    ap.add_argument("--tables", default="report/tables.md")
    a = ap.parse_args()
    r = json.loads(Path(a.results).read_text())
    b = json.loads(Path(a.bench).read_text())
    stress_files = [Path(a.results).parent / "stress5.json", Path(a.results).parent / "stress8.json"]
    aero_files = [
        Path(a.results).parent / name
        for name in (
            "stress5_realistic_layers.json",
            "stress8_realistic_layers.json",
            "stress5_realistic.json",
            "stress8_realistic.json",
        )
    ]
    report = Path(a.results).parent
    compare = report / "aero_compare.json"
    targets = {
        a.readme: (
            ("reproduction", reproduction(r)),
            ("side", side_by_side(report / "side_by_side")),
            ("speed", speed_short(b)),
            ("validation", validation(report / "downwash_validation.json")),
            ("sensing", sensing(report / "sensing")),
        ),
        a.tables: (
            ("reproduction", reproduction(r)),
            ("anticollision", anticollision(r)),
            ("stress", stress(stress_files)),
            ("realistic", realistic_short(report)),
            ("aero", aero(compare, aero_files)),
            ("performance", performance(b)),
        ),
    }
    for path, tables in targets.items():
        text = Path(path).read_text()
        for name, body in tables:
            pat = re.compile(rf"(<!-- tables:{name} -->\n).*?(<!-- /tables:{name} -->)", re.S)
            if not pat.search(text):
                raise SystemExit(f"{path} has no <!-- tables:{name} --> markers")
            text = pat.sub(lambda mm, body=body: mm.group(1) + body + "\n" + mm.group(2), text)
        Path(path).write_text(text)
        print(f"updated {path}")


if __name__ == "__main__":
    main()
