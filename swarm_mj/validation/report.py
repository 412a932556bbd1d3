"""The validation's results: the JSON document and the printed tables (docs/validation.md, "Results")."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .analysis import MODELS, PassResult, Setup, analyse_flight, calibrate_gain, drone_setup, load_all, table
from .params import CALIBRATION

#: What each model column is.
MODEL_NOTES = {
    "jet": (
        "the simulator's downwash (swarm_mj.physics.aero.downwash.jet_on_drone): Bauersfeld et al. 2024 turbulent "
        "jet, five-plate drag on the lower vehicle's plates (docs/aero.md), x the upper vehicle's downwash_gain"
    ),
    "wake": (
        "the same jet with a travelling wake (swarm_mj.physics.aero.wake): "
        "each upper drone's state when the air left it"
    ),
    "gym": "gym-pybullet-drones BaseAviary._downwash, cf2x.urdf coefficients, the upper drone's rotor radius",
    "none": "Fa = 0",
}
#: The bars on the held-out single passes (issue 47).
BARS = {"rmse_ratio_max": 0.35, "peak_error_fraction_max": 0.15, "corr_min": 0.93}


def _rows(
    results: list[PassResult], key: Callable[[PassResult], tuple[str, str]], bins: tuple[float, ...]
) -> list[dict]:
    groups: dict[tuple[str, str], list[PassResult]] = {}
    for q in results:
        groups.setdefault(key(q), []).append(q)
    order = {"calibration": 0, "held_out": 1}
    rows = []
    for (split, label), sel in sorted(groups.items(), key=lambda kv: (order.get(kv[0][0], 2), kv[0][1])):
        row = {"split": split, "pairing": label, **table(sel, MODELS, bins)}
        rows.append(row)
    return rows


def bars(row: dict) -> dict:
    """The issue's done-when figures of one row, measured, with whether each bar is met."""
    ratio = row["rmse_g"] / row["rmse_no_model_g"]
    frac = row["mean_peak_error_g"] / abs(row["mean_peak_measured_g"])
    return {
        "rmse_ratio": ratio,
        "rmse_ratio_gym": row["rmse_gym_g"] / row["rmse_no_model_g"],
        "peak_error_fraction": frac,
        "peak_error_fraction_gym": row["mean_peak_error_gym_g"] / abs(row["mean_peak_measured_g"]),
        "corr": row["corr"],
        "corr_gym": row["corr_gym"],
        "met": {
            "rmse": ratio <= BARS["rmse_ratio_max"],
            "peak": abs(frac) <= BARS["peak_error_fraction_max"],
            "corr": row["corr"] is not None and row["corr"] >= BARS["corr_min"],
        },
    }


def validate_downwash(data: Path, setup: Setup, progress: Callable[[str], None] | None = None) -> dict:
    """Run the whole validation on the logs under ``data``; return the JSON document."""
    p = setup.params
    flights = load_all(data, progress)
    for drone in setup.vehicles:
        if not any(drone in f.drones for f in flights):
            raise_unknown(drone, data)
    for drone in setup.masses:
        if not any(drone in f.drones for f in flights):
            raise_unknown(drone, data, "--mass")
    results: list[PassResult] = []
    drones: dict[str, dict] = {}
    gains: dict[str, float] = {}  # vehicle -> its downwash_gain (from its vehicle file)
    left_out: list[dict] = []
    offsets: dict[str, dict] = {}
    for f in flights:
        found = analyse_flight(f, setup, left_out=left_out, offsets=offsets)
        results += found
        for d in f.drones:
            s = drone_setup(f, d, setup)
            drones.setdefault(d, {"vehicle": s.vehicle.name, "sysid": s.thrust.source, "mass_g": s.mass_g})
            gains[s.vehicle.name] = s.vehicle.downwash_gain
        if progress:
            n1 = sum(not q.p.stack for q in found)
            progress(f"analysed {f.name}: {n1} single passes, {len(found) - n1} under a stack")
    single = [q for q in results if not q.p.stack]
    stack = [q for q in results if q.p.stack]
    cal = [q for q in single if q.split == "calibration"]
    rows = _rows(single, lambda q: (q.split, q.pairing), p.dz_bins)
    doc: dict[str, Any] = {
        "command": "swarm-mj validate downwash",
        "data": str(data),
        "units": "forces in grams-force (gf; 1 gf = 9.81e-3 N), Fa_z < 0 pushes down; separations dz in m",
        "models": MODEL_NOTES,
        "params": dataclasses.asdict(p),
        "calibration_flights": [f"{s}/{e}" for s, e in CALIBRATION],
        "flights": {
            f.name: ("calibration" if (f.session.name, f.experiment) in CALIBRATION else "held_out") for f in flights
        },
        "drones": drones,
        "calibration_fit": {
            "downwash_gain_used": gains,
            # one factor on top of the gains used (every calibration flight flies one vehicle kind)
            "refit_factor": calibrate_gain(cal) if cal else None,
            "fitted_on": "single passes of the calibration flights",
        },
        "rows": rows,
        "stacks": _rows(stack, lambda q: (q.split, q.pairing), p.dz_bins),
        "by_experiment": _rows(single, lambda q: (q.split, q.flight.rsplit("/", 1)[0]), p.dz_bins),
        "bars": {f"{r['split']}: {r['pairing']}": bars(r) for r in rows if r["n_passes"]},
        "left_out": left_out,
        "free_air_offsets": offsets,
    }
    for r in doc["by_experiment"]:
        r.pop("peaks")  # each pass's peak is listed once, under rows and stacks
    return doc


def raise_unknown(drone: str, data: Path, option: str = "--vehicle") -> None:
    from ..errors import UserError

    raise UserError(f"{option} {drone}=...: no log of {drone} under {data}")


def _f(x: float | None, width: int = 6, digits: int = 2) -> str:
    return " " * (width - 1) + "-" if x is None else f"{x:{width}.{digits}f}"


#: Printed columns of a row: (heading, key, width, digits).
COLUMNS = (
    ("RMSE jet", "rmse_g", 9, 2),
    ("wake", "rmse_wake_g", 6, 2),
    ("gym", "rmse_gym_g", 7, 2),
    ("none", "rmse_no_model_g", 6, 2),
    ("| peak meas", "mean_peak_measured_g", 12, 2),
    ("| peak err jet", "mean_peak_error_g", 15, 2),
    ("wake", "mean_peak_error_wake_g", 6, 2),
    ("gym", "mean_peak_error_gym_g", 7, 1),
    ("| corr jet", "corr", 11, 3),
    ("wake", "corr_wake", 6, 3),
    ("gym", "corr_gym", 6, 3),
)


def format_row(row: dict, title: str) -> list[str]:
    """A row as printed: the models' figures overall, then per vertical-separation bin."""
    lines = [f"{title}: {row['pairing']} ({row['split']}), {row['n_passes']} passes"]
    lines.append("  dz (m)       n |" + "".join(f"{h:>{w}s}" for h, _, w, _ in COLUMNS))
    for label, r in [("all", row)] + [(f"{b['dz_m'][0]:.2f}-{b['dz_m'][1]:.2f}", b) for b in row["bins"]]:
        if r.get("n_passes"):
            cells = "".join(_f(r[k], w, dg) for _, k, w, dg in COLUMNS)
            lines.append(f"  {label:10s} {r['n_passes']:3d} |{cells}")
    return lines


def _pass_line(q: dict) -> str:
    return (
        f"    {q['flight']} t={q['t_s']:6.2f} s dz={q['dz_m']:.2f} m: peak {q['measured_g']:6.1f}, "
        f"jet {q['jet_g']:6.1f} ({q['jet_g'] - q['measured_g']:+5.1f}), wake {q['wake_g']:6.1f}, gym {q['gym_g']:7.1f}"
    )


def _bars_line(name: str, b: dict) -> str:
    def met(k: str) -> str:
        return "met" if b["met"][k] else "NOT met"

    return (
        f"bars, {name}: RMSE / no model {b['rmse_ratio']:.3f} (gym {b['rmse_ratio_gym']:.2f}; "
        f"<= {BARS['rmse_ratio_max']:g}: {met('rmse')}); "
        f"mean peak error {100 * b['peak_error_fraction']:+.1f} % of the measured peak "
        f"(gym {100 * b['peak_error_fraction_gym']:+.0f} %; within {100 * BARS['peak_error_fraction_max']:g} %: "
        f"{met('peak')}); corr {b['corr']:.3f} (gym {b['corr_gym']:.3f}; >= {BARS['corr_min']:g}: {met('corr')})"
    )


def format_doc(doc: dict, passes: bool = False) -> str:
    """The printed report: each row's table, the stacks', the bars on the held-out flights."""
    fit = doc["calibration_fit"]
    out = [
        "downwash validation, forces in gf (Fa_z < 0: pushed down); the vehicles' downwash_gain: "
        + ", ".join(f"{name} {g:.3f}" for name, g in fit["downwash_gain_used"].items())
        + (
            f" (a refit on the calibration flights would multiply it by {fit['refit_factor']:.4f})"
            if fit["refit_factor"] is not None
            else " (no calibration flight under --data to refit it on)"
        )
    ]
    for row in doc["rows"]:
        out += format_row(row, "one drone above")
        out += [_pass_line(q) for q in row["peaks"]] if passes else []
    for row in doc["stacks"]:
        out += format_row(row, "bottom of a three-drone stack")
        out += [_pass_line(q) for q in row["peaks"]] if passes else []
    out += [_bars_line(name, b) for name, b in doc["bars"].items()]
    return "\n".join(out)
