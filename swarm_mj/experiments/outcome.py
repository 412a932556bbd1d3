"""Whether a run did what it was asked: every drone took off, none crashed, none was lost.

A run can fly to its end and still fail: a drone too weak to lift (or held down) sits on the ground
beside a leader that sits there too, so its slot error is zero and its formation "settled". The
summary's ``flight`` (:func:`flight_outcome`) says what happened, drone by drone, and
``swarm-mj run`` / ``video`` / ``sweep`` exit with status 3 (:data:`~swarm_mj.commands.EXIT_FLIGHT_FAILED`)
with one line saying which drone and what (:func:`failure_line`). Decided from the log alone:

* **never took off**: its reference rose more than ``2 · TAKEOFF_CLEARANCE`` above its start at least
  :data:`TAKEOFF_GRACE_S` before the end of the run, and the drone never rose more than
  ``TAKEOFF_CLEARANCE`` above its start (the ground monitor's take-off, docs/aero.md);
* **crashed**: a ground crash (a touchdown faster than 1 m/s or tilted more than 30°; ``--aero realistic``);
* **lost**: it took off, and at the end it is back within ``TAKEOFF_CLEARANCE`` of its start height, or
  below it, while its reference holds it more than ``2 · TAKEOFF_CLEARANCE`` above.

The reference is the leader's commanded position and each follower's slot (which sits around the
leader where the leader is: followers of a leader that never took off are not asked to climb).
"""

from __future__ import annotations

import numpy as np

from ..errors import SwarmError
from ..physics.aero.ground import TAKEOFF_CLEARANCE


class FlightFailed(SwarmError):
    """Nothing flew as asked (e.g. no candidate of a tune flew the step): one line, exit status 3
    (:data:`~swarm_mj.commands.EXIT_FLIGHT_FAILED`)."""

    exit_code = 3


#: A drone is judged on its take-off only when its reference asked for the climb at least this long
#: before the end of the run (s): time to lift off even for a drone with a thrust-to-weight ratio near 1.
TAKEOFF_GRACE_S = 1.0


def flight_outcome(t: np.ndarray, z: np.ndarray, ref_z: np.ndarray, names: list[str], crashed: list[int]) -> dict:
    """The outcome of a run from its times t (k,), heights z (k, n), reference heights ref_z (k, n), the
    drones' names and the indices of the drones that crashed (module docstring): ``ok`` and the names of
    the drones that ``never_took_off``, ``crashed`` and were ``lost``."""
    out: dict = {"ok": True, "never_took_off": [], "crashed": sorted({names[i] for i in crashed}), "lost": []}
    if len(t) >= 1:
        z0 = z[0]  # (n,)
        with np.errstate(invalid="ignore"):
            asked = ref_z > z0 + 2 * TAKEOFF_CLEARANCE  # (k, n)
            rose = (z > z0 + TAKEOFF_CLEARANCE).any(axis=0)  # (n,)
            down = ~(z[-1] > z0 + TAKEOFF_CLEARANCE)  # (n,) NaN counts as down
        first = np.where(asked.any(axis=0), t[np.argmax(asked, axis=0)], np.inf)  # (n,) first time asked to climb
        never = ~rose & (t[-1] - first >= TAKEOFF_GRACE_S)
        lost = rose & down & asked[-1]
        out["never_took_off"] = [names[i] for i in np.flatnonzero(never)]
        out["lost"] = [names[i] for i in np.flatnonzero(lost)]
    out["ok"] = not (out["never_took_off"] or out["crashed"] or out["lost"])
    return out


def failure_line(flight: dict | None) -> str | None:
    """One line naming what failed (``flight failed: leader never took off; follower2 crashed``), or None."""
    if not flight or flight.get("ok", True):
        return None
    parts = []
    for key, what in (("never_took_off", "never took off"), ("crashed", "crashed"), ("lost", "was lost")):
        who = flight.get(key) or []
        if who:
            verb = what if len(who) == 1 else {"was lost": "were lost"}.get(what, what)
            parts.append(f"{', '.join(who)} {verb}")
    return "flight failed: " + "; ".join(parts)
