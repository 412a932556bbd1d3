"""The stagger rule (``anti_collision = "stagger"``), the worked example of docs/design.md, "A new anti-collision rule":
one module, one registration line in :mod:`swarm_mj.pipeline.registry` (``ANTI_COLLISION_RULES`` and
``RULE_KERNELS``), and it flies on the chunk driver.

Drone i ≥ 1 flies its slot raised by i·``hop`` while another drone is closer than D̄
(``safety_distance``) to it horizontally, and back at its slot once every other drone is beyond
D̄ + ``hysteresis``; the leader (index 0) flies its own reference. **Invariant**: after each update, two
drones closer than D̄ horizontally are both raised (the horizontal distance is the same seen from
either), so their altitude setpoints are their slots' raised by different multiples of ``hop``: the
pair (i, j) is |i − j|·``hop`` further apart in altitude than its slots. Decentralised: a drone decides
from its own position and the positions of the drones within D̄ + ``hysteresis`` of it (within any
sensing range the scenarios fly), with no message.

Its numbers are its own record (:class:`StaggerParams`), whose fields are today's scenario keys
(``[formation] safety_distance``, ``hop``, ``hysteresis``): :func:`~.anticollision.make_rule` fills it
from them. It logs no events (its decisions are in the log's ``pos_d``) and steers no velocity or
acceleration reference. It acts in formed flight (the squeeze of tests/integration/test_new_rule.py: contact
free). Like Fig. 5 it reacts only at D̄, so it does not carry crossing starts: ``swarm-mj stress --rule stagger
--rule paper --starts 10`` (paper physics) had contacts on 8 of 10 starts, 8 diverged; the paper's rule on 9,
6 diverged. A worked example, not a rule ``"auto"`` picks.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from .._jit import jit, warm_module
from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.records import Obs
from .rules import Rule


class StaggerParams(NamedTuple):  # its own keys: a scenario's [formation] keys of the same names
    safety_distance: float = 0.8  # D̄ (m)
    hop: float = 0.4  # (m) between the layers of consecutive indices
    hysteresis: float = 0.05  # (m) back at the slot beyond D̄ + this


class StaggerRecord(NamedTuple):
    params: StaggerParams
    raised: np.ndarray  # (n,) bool: drone i holds its raise


def _samples() -> list[tuple]:
    """stagger_update's argument types, compiled when the rule is built (before a run's clock starts)."""
    z = np.zeros((2, 3))
    return [(StaggerRecord(params=StaggerParams(), raised=np.zeros(2, dtype=np.bool_)), z, z.copy())]


@jit(inline=True, on_demand=True, samples=_samples)
def stagger_update(rec: StaggerRecord, pos: np.ndarray, sp: np.ndarray) -> np.ndarray:
    """The slots sp (n, 3) with each raised drone's altitude raised, from the positions pos (n, 3)."""
    out, p = sp.copy(), rec.params
    for i in range(1, pos.shape[0]):  # the leader, 0, flies its own reference
        near = np.inf
        for j in range(pos.shape[0]):
            if j != i:
                near = min(near, math.hypot(pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1]))
        rec.raised[i] = near < p.safety_distance or (rec.raised[i] and near <= p.safety_distance + p.hysteresis)
        if rec.raised[i]:
            out[i, 2] += i * p.hop
    return out


@jit(inline=True)
def stagger_step(rec: StaggerRecord, obs: Obs, t: float) -> tuple:
    """The registered step (registry.RULE_KERNELS' contract): never hands back; the references pass through."""
    return False, stagger_update(rec, obs.pos, obs.sp), obs.spv, obs.spa


class StaggerRule(Rule):
    """Drones near another fly raised by their index times ``hop`` (the module's docstring)."""

    name = "stagger"
    Params = StaggerParams  # make_rule fills it from a scenario's keys of the same names
    downwash_feedforward = False
    params: StaggerParams  # type: ignore[assignment]  # its own record (compiled: a NamedTuple), not a BaseParams

    def __init__(
        self, n: int, params: StaggerParams | None = None, *, vehicle: QuadParams = DEFAULT_PARAMS, **_: Any
    ) -> None:
        self.n, self.params, self.vehicle = n, params or StaggerParams(), vehicle
        self._record = StaggerRecord(params=self.params, raised=np.zeros(n, dtype=np.bool_))
        self.vel_d, self.acc_d = np.zeros((n, 3)), np.zeros((n, 3))
        self.events: list[dict] = []
        warm_module(__name__)  # its kernel compiled (or loaded from the cache) before the run's clock

    def reset(self, positions: np.ndarray) -> None:
        self._record.raised[:] = False
        self.events = []

    def record(self) -> StaggerRecord:
        return self._record

    def compiled_ready(self) -> bool:
        return True  # its compiled step is all it does

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        pos, sp = (np.ascontiguousarray(a, dtype=np.float64) for a in (positions, pos_d))
        return stagger_update(self._record, pos, sp), np.zeros(self.n, dtype=bool)
