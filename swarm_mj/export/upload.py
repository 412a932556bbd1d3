#!/usr/bin/env python3
"""Upload an exported set of Crazyflie pieces with cflib and fly them together (docs/export.md).

Written by ``swarm-mj export crazyflie`` next to ``manifest.json`` and one ``<drone>.csv`` per drone
(Crazyswarm's ``uav_trajectories`` format). It needs only cflib (``pip install cflib``) and the
Python standard library; ``--help`` and ``--dry-run`` need no radio and no cflib.

    python upload.py radio://0/80/2M/E7E7E7E701 radio://0/80/2M/E7E7E7E702 ...   # one URI per drone

Give one radio URI per drone, in the manifest's order (``leader`` first, then ``follower1``, ...).
Place each drone on the floor under its start (the manifest's ``start`` x, y; ``--dry-run`` prints
them). The script, for every drone at once (cflib's ``Swarm.parallel_safe``: one thread per drone):
uploads its pieces into the trajectory memory (cflib's ``Poly4D`` and ``TrajectoryMemory``), defines
them as trajectory 1 (``HighLevelCommander.define_trajectory``), selects the Mellinger controller
(``--controller``), waits for the position estimate, arms, takes off vertically to its start height
where the plan starts in the air and goes to its start, starts trajectory 1 on every drone
(``start_trajectory``), waits for the plan to end, and lands.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

#: The id the pieces are defined under in each drone's high-level commander.
TRAJECTORY_ID = 1
#: Columns of a row: the duration, then 8 coefficients each of x, y, z and yaw in ascending powers.
COLUMNS = 33
#: A start above this height (m) is in the air: the drone takes off to it before the plan starts.
AIRBORNE_M = 0.1
#: Controllers by name (the firmware's ``stabilizer.controller`` parameter); "keep" leaves it as it is.
CONTROLLERS = {"pid": "1", "mellinger": "2", "keep": None}


def load_set(folder: Path) -> tuple[dict, list[list[list[float]]]]:
    """The manifest and each drone's rows (pieces x 33 floats), in the manifest's order."""
    manifest = json.loads((folder / "manifest.json").read_text())
    sets = []
    for drone in manifest["drones"]:
        with open(folder / drone["csv"], newline="") as f:
            rows = list(csv.reader(f))
        pieces = [[float(v) for v in row] for row in rows[1:] if row]
        if any(len(p) != COLUMNS for p in pieces):
            raise SystemExit(f"{drone['csv']}: every row must have {COLUMNS} columns")
        sets.append(pieces)
    return manifest, sets


def poly4d_list(pieces: list[list[float]]) -> list:
    """The rows as cflib ``Poly4D`` pieces (what ``TrajectoryMemory.trajectory`` holds)."""
    from cflib.crazyflie.mem import Poly4D

    return [
        Poly4D(
            p[0],
            Poly4D.Poly(p[1:9]),
            Poly4D.Poly(p[9:17]),
            Poly4D.Poly(p[17:25]),
            Poly4D.Poly(p[25:33]),
        )
        for p in pieces
    ]


def upload(scf, pieces: list[list[float]], controller: str | None) -> None:  # noqa: ANN001 - a SyncCrazyflie
    """One drone: its pieces into trajectory memory at offset 0, defined as :data:`TRAJECTORY_ID`."""
    from cflib.crazyflie.mem import MemoryElement

    cf = scf.cf
    mem = cf.mem.get_mems(MemoryElement.TYPE_TRAJ)[0]
    mem.trajectory = poly4d_list(pieces)
    if not mem.write_data_sync():
        raise RuntimeError(f"{scf.cf.link_uri}: the upload of the pieces failed")
    cf.high_level_commander.define_trajectory(TRAJECTORY_ID, 0, len(pieces))
    if controller is not None:
        cf.param.set_value("stabilizer.controller", controller)


def arm(scf) -> None:  # noqa: ANN001
    """Arm the drone (firmware 2023.06 and later; older ones need no arming)."""
    owner = getattr(scf.cf, "supervisor", None) or scf.cf.platform
    owner.send_arming_request(True)


def to_start(scf, start: list[float], yaw: float, seconds: float) -> None:  # noqa: ANN001
    """Take off vertically to the start's height and go to the start, where the plan starts in the air."""
    if start[2] <= AIRBORNE_M:
        return
    hlc = scf.cf.high_level_commander
    hlc.takeoff(start[2], seconds, yaw=yaw)
    time.sleep(seconds + 0.5)
    hlc.go_to(start[0], start[1], start[2], yaw, 1.0)


def start(scf) -> None:  # noqa: ANN001
    scf.cf.high_level_commander.start_trajectory(TRAJECTORY_ID, 1.0, relative_position=False)


def land(scf, seconds: float) -> None:  # noqa: ANN001
    hlc = scf.cf.high_level_commander
    hlc.land(0.0, seconds)
    time.sleep(seconds + 0.5)
    hlc.stop()


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Upload the exported pieces to Crazyflies (cflib) and fly them together.",
        epilog="Needs cflib (pip install cflib, or pip install 'swarm-mj[crazyflie]'); --help and "
        "--dry-run need neither cflib nor a radio.",
    )
    p.add_argument("uris", nargs="+", metavar="URI", help="one radio URI per drone, in the manifest's order")
    p.add_argument("--folder", type=Path, default=Path(__file__).resolve().parent, help="the exported set")
    p.add_argument("--controller", choices=list(CONTROLLERS), default="mellinger", help="default: mellinger")
    p.add_argument("--takeoff-s", type=float, default=3.0, help="take-off and landing time (s, default 3)")
    p.add_argument("--dry-run", action="store_true", help="read and check the set, print the plan, fly nothing")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    manifest, sets = load_set(args.folder)
    drones = manifest["drones"]
    if len(args.uris) != len(drones):
        names = ", ".join(d["name"] for d in drones)
        print(f"upload.py: give {len(drones)} URIs, one per drone ({names}); got {len(args.uris)}", file=sys.stderr)
        return 2
    duration = float(manifest["duration_s"])
    for uri, d, pieces in zip(args.uris, drones, sets):
        x, y, z = d["start"]
        print(f"{d['name']}: {uri}, {len(pieces)} pieces; place it on the floor at x = {x:.3f}, y = {y:.3f} m")
    if args.dry_run:
        print(f"plan: {duration:.2f} s; dry run, nothing flown")
        return 0
    try:
        import cflib.crtp
        from cflib.crazyflie.swarm import CachedCfFactory, Swarm
    except ImportError:
        print("upload.py: needs cflib: pip install cflib (or pip install 'swarm-mj[crazyflie]')", file=sys.stderr)
        return 2
    cflib.crtp.init_drivers()
    per = {uri: d for uri, d in zip(args.uris, drones)}
    with Swarm(args.uris, factory=CachedCfFactory(rw_cache="./cache")) as swarm:
        controller = CONTROLLERS[args.controller]
        swarm.parallel_safe(upload, {u: [p, controller] for u, p in zip(args.uris, sets)})
        swarm.reset_estimators()
        swarm.parallel_safe(arm)
        time.sleep(1.0)
        swarm.parallel_safe(to_start, {u: [d["start"], d["start_yaw_rad"], args.takeoff_s] for u, d in per.items()})
        time.sleep(2.0)
        swarm.parallel_safe(start)  # every drone's commander starts its trajectory 1 now
        time.sleep(duration + 0.5)
        swarm.parallel_safe(land, {u: [args.takeoff_s] for u in args.uris})
    return 0


if __name__ == "__main__":
    sys.exit(main())
