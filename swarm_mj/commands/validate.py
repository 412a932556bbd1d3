"""``swarm-mj validate downwash --data DIR [--vehicle ID=NAME_OR_FILE ...] [--json PATH]``: the
downwash model against real flight logs (docs/validation.md).

Decodes the Neural-Swarm raw Crazyflie logs under DIR, computes each drone's measured vertical
residual force Fa_z with the dataset's own system identification (the sysid file each session's
readme.txt assigns to it), finds the passes of one drone under another, predicts the force from the
logged states with our jet model (swarm_mj.physics.aero.downwash), the same with a travelling wake,
gym-pybullet-drones' empirical model and no model, and prints RMSE, the peaks' errors, correlation
and the peaks per vertical-separation bin, for the calibration and the held-out flights, and for the
bottom of three-drone stacks.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

_ID = re.compile(r"^cf\d+$")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="check an aerodynamic model against real flight logs (downwash: the Neural-Swarm logs)",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
    )
    what = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    d = what.add_parser("downwash", help="the downwash model against the Neural-Swarm Crazyflie logs")
    d.add_argument("--data", required=True, metavar="DIR", help="folder of the logs (e.g. ../shared/neural-swarm)")
    d.add_argument(
        "--vehicle",
        action="append",
        default=[],
        metavar="ID=NAME_OR_FILE",
        help="vehicle of drone ID (a log's prefix, e.g. cf50): a bundled vehicle or a vehicle TOML file "
        "(default: crazyflie21 for the drones the readme gives defaultcf.txt)",
    )
    d.add_argument(
        "--mass",
        action="append",
        default=[],
        metavar="ID=GRAMS",
        help="mass of drone ID in grams for the residual force (default: its sysid file's, or the dataset's 32 g "
        "for defaultcf.txt)",
    )
    d.add_argument("--json", metavar="PATH", help="write every figure to this JSON file (atomically)")
    d.add_argument(
        "--passes",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="print each pass's peak, measured and predicted, and its error (default: on)",
    )
    d.add_argument("--quiet", action="store_true", help="no progress lines")
    d.set_defaults(func=main)


def _pairs(values: list[str], option: str) -> dict[str, str]:
    from ..errors import UserError

    out: dict[str, str] = {}
    for v in values:
        key, sep, val = v.partition("=")
        key = key.strip().lower()
        if not sep or not _ID.match(key) or not val.strip():
            raise UserError(f"{option} {v!r}: expected ID=VALUE with ID a log's drone prefix such as cf50")
        if key in out:
            raise UserError(f"{option}: {key} given twice")
        out[key] = val.strip()
    return out


def main(args: argparse.Namespace) -> int:
    from ..errors import UserError
    from ..output.atomic import check_output_path, write_json_atomic
    from ..validation.analysis import Setup
    from ..validation.report import format_doc, validate_downwash
    from ..vehicles import load_vehicle

    data = Path(args.data)
    if not data.is_dir():
        raise UserError(f"--data {args.data}: no such folder")
    if args.json:
        check_output_path(args.json, "--json", suffixes=[".json"])
    vehicles = {k: load_vehicle(v) for k, v in _pairs(args.vehicle, "--vehicle").items()}
    masses: dict[str, float] = {}
    for k, v in _pairs(args.mass, "--mass").items():
        try:
            masses[k] = float(v)
        except ValueError:
            raise UserError(f"--mass {k}={v}: not a number of grams") from None
        if not masses[k] > 0 or masses[k] == float("inf"):
            raise UserError(f"--mass {k}={v}: must be a positive number of grams")

    def progress(line: str) -> None:
        if not args.quiet:
            print(line, file=sys.stderr, flush=True)

    doc = validate_downwash(data, Setup(vehicles=vehicles, masses=masses), progress)
    print(format_doc(doc, passes=args.passes))
    if args.json:
        write_json_atomic(args.json, doc)
        print(f"wrote {args.json}")
    return 0
