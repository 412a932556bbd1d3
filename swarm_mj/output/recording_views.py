"""What each drone believed, in the recording (docs/sensing.md, "The recording"): drawn from the run
log's :class:`~swarm_mj.sensing.log.ViewLog` (none under the oracle ``perfect``), one observer at a time.

Entities, on the ``sim_time`` timeline, one sample per control period like the rest of the recording:

* ``world/views/<observer>/ghosts``: the other drones where ``<observer>`` believed they were, one
  point per drone it held a message from (labelled by the drone it stands for; greyed leader red or
  follower blue); entries out of range (``UNSEEN_M`` away) are left out;
* ``world/views/<observer>/leader_link`` (followers): a line from the follower's true position to
  its ghost of the leader;
* ``views/<observer>/age/<other>``: seconds since ``<other>`` sent what ``<observer>`` held (no
  sample where it held nothing).

The blueprint's 3D view shows one observer's ghosts (:func:`default_observer`) and hides the others'
(each ``world/views/<observer>`` is in the tree, ticked off); the ghosts are drawn at the time cursor
only (a one-period time range), not as the 10-s trail; a tab plots the same observer's ages.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from rerun.blueprint.api import VisualizerLike

from ..sensing.stage import UNSEEN_M

GHOST_LEADER_COLOR = [235, 150, 150, 170]  # recording.LEADER_COLOR greyed, translucent
GHOST_FOLLOWER_COLOR = [150, 180, 235, 170]  # recording.FOLLOWER_COLOR greyed, translucent
LINK_COLOR = [200, 120, 200, 170]


def default_observer(names: list[str]) -> str:
    """The observer whose view the blueprint shows: the first follower (the leader if alone)."""
    return names[1] if len(names) > 1 else names[0]


def ghost_paths(name: str) -> list[str]:
    """The entities of one observer drawn in the 3D view at the time cursor only."""
    return [f"/world/views/{name}/ghosts", f"/world/views/{name}/leader_link"]


def view_overrides(names: list[str], period_s: float) -> Mapping[Any, VisualizerLike]:
    """The 3D view's per-entity overrides: every observer but :func:`default_observer` hidden, and
    each ghost entity queried over the last period only (one sample: the view's time range is 10 s)."""
    now = rrb.VisibleTimeRanges(
        [
            rrb.VisibleTimeRange(
                "sim_time",
                start=rrb.TimeRangeBoundary.cursor_relative(nanos=-max(int(round(period_s * 1e9)) - 1, 0)),
                end=rrb.TimeRangeBoundary.cursor_relative(),
            )
        ]
    )
    shown = default_observer(names)
    out: dict[Any, VisualizerLike] = {}
    for name in names:
        if name != shown:
            out[f"/world/views/{name}"] = rrb.EntityBehavior(visible=False)
        for p in ghost_paths(name):
            out[p] = now
    return out


def age_overrides(names: list[str]) -> Mapping[Any, VisualizerLike]:
    """The age plot's overrides: every observer but :func:`default_observer` hidden."""
    shown = default_observer(names)
    return {f"/views/{name}": rrb.EntityBehavior(visible=False) for name in names if name != shown}


def log_views(views, pos: np.ndarray, times_s: np.ndarray, names: list[str], radius: float) -> None:
    """Log each observer's ghosts, its line to the leader's ghost and its ages from ``views`` (a
    ViewLog), the true positions ``pos`` (k, n, 3) and the sample times (s)."""
    k, n = len(times_s), len(names)
    times = rr.TimeColumn("sim_time", duration=times_s)
    believed, age = views.pos[:k], views.age[:k]
    held = views.mask[:k] & (believed[..., 0] < 0.5 * UNSEEN_M) & np.isfinite(believed).all(axis=-1)  # (k, n, n)
    # each ghost's class id is the index of the drone it stands for: its label and colour come from
    # one static annotation context, not from a string and a colour per point and period
    rr.log(
        "/world/views",
        rr.AnnotationContext(
            [
                rr.AnnotationInfo(id=j, label=nm, color=GHOST_LEADER_COLOR if j == 0 else GHOST_FOLLOWER_COLOR)
                for j, nm in enumerate(names)
            ]
        ),
        static=True,
    )
    for i, name in enumerate(names):
        others = np.array([j for j in range(n) if j != i], dtype=np.int64)
        seen = held[:, i, others]  # (k, n-1); row-major: sample by sample, the others in order
        base = f"/world/views/{name}"
        if seen.any():
            rr.log(f"{base}/ghosts", rr.Points3D.from_fields(radii=[radius], show_labels=True), static=True)
            cols = rr.Points3D.columns(
                positions=believed[:, i, others][seen],
                class_ids=np.broadcast_to(others.astype(np.uint16), (k, others.size))[seen],
            )
            rr.send_columns(f"{base}/ghosts", indexes=[times], columns=cols.partition(seen.sum(axis=1)))
        lead = held[:, i, 0]
        if i > 0 and lead.any():
            strips = np.stack([pos[:k, i], believed[:, i, 0]], axis=1)[lead]  # (m, 2, 3)
            rr.log(f"{base}/leader_link", rr.LineStrips3D.from_fields(colors=[LINK_COLOR], radii=[0.004]), static=True)
            rr.send_columns(
                f"{base}/leader_link",
                indexes=[times],
                columns=rr.LineStrips3D.columns(strips=strips).partition(lead.astype(np.int64)),
            )
        for j in others:
            ok = np.isfinite(age[:, i, j])
            if ok.any():
                path = f"/views/{name}/age/{names[j]}"
                rr.log(path, rr.SeriesLines(names=[f"{names[j]} (s)"]), static=True)
                rr.send_columns(
                    path,
                    indexes=[rr.TimeColumn("sim_time", duration=times_s[ok])],
                    columns=rr.Scalars.columns(scalars=age[ok, i, j]),
                )
