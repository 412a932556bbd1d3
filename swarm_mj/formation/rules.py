"""The anti-collision rules' interface (:class:`Rule`), no rule (:class:`NoRule`) and the paper's
rule as printed (:class:`PaperRule`: Fig. 5, the separation step alone; docs/interpretations.md §4).

Every rule has the same small interface, vectorised over drones (index 0 is the leader):

    rule.reset(positions (n, 3))
    pos_d, steer = rule.update(t, positions (n, 3), pos_d (n, 3), formation_alt)

``pos_d`` are the formation setpoints (slot of each follower, paper §4; the leader's own
reference in row 0) and come back adjusted. ``steer`` (n,) flags the drones whose velocity
and acceleration references the rule sets itself: ``rule.vel_d`` (n, 3) and ``rule.acc_d``
(n, 3) (zero for a drone told to hold its (x, y)); the others keep the formation's
references. ``rule.references(t, positions, pos_d, vel_d, acc_d, formation_alt)`` does both
and returns the controller's references (pos_d, vel_d, acc_d) (n, 3), the steered drones'
rows taken from the rule (what the policy calls; for the formed swarm the layered rule does
it in one compiled kernel). Each rule appends its decisions to ``rule.events`` as dicts
``{t, drone, other, action}``: up, down, release (Fig. 5); cross, hold, aside, drop (the
layered rule's transition). Every rule reads its numbers from ``rule.params``, its own record
(:mod:`~swarm_mj.formation.rule_params`: :class:`~.rule_params.PaperParams` for ``paper``, and so on),
and what it asks of the controller from ``rule.controller_params``
(:class:`~.rule_params.ControllerParams`).

Decentralised (docs/interpretations.md §4): a drone's decision uses only its own state, the leader's position
(through its slot and the formation altitude) and the positions of drones within its
sensing range (velocities of neighbours are estimated from their successive positions).
No rule reads another drone's internal state; the layered rule uses the other drones'
indices (the priority of Fig. 5: higher index yields) and whether they are still in
transit to their slot, which a drone broadcasts or which its neighbours can tell from
its altitude (a formed drone flies at the formation altitude).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..physics.params import DEFAULT_PARAMS, QuadParams
from ..pipeline.records import Rule as FormedRecord
from .layered import horizontal_distances, idle_record, merge_rows
from .rule_params import (
    CONTROLLER_KEYS,
    CONTROLLER_PRESETS,
    PRESETS,
    BaseParams,
    ControllerParams,
    PaperParams,
)
from .separation import SeparationFilter, fig5_react


class Rule:
    """What every rule shares: :meth:`references` from the rule's own ``update``.

    A new rule subclasses it with ``name``, ``events``, ``vel_d``, ``acc_d`` (n, 3), ``reset(positions)``
    and ``update(t, positions, pos_d, formation_alt) -> (pos_d, steer)`` (see the module docstring),
    and is registered in :data:`ANTI_COLLISION_RULES` (which makes it a scenario's
    ``formation.anti_collision`` value and a ``--anti-collision`` choice). Its parameter record is
    ``Params`` (the fields it reads; its default is :data:`~.rule_params.PRESETS`' entry of its
    name, else ``Params()``)."""

    #: the rule's parameter record type (a scenario's keys that are its fields fill it: make_rule)
    Params: ClassVar[type] = BaseParams
    params: BaseParams
    controller_params: ControllerParams

    name: str
    n: int
    events: list[dict]
    vel_d: np.ndarray  # (n, 3) velocity reference of the steered drones
    acc_d: np.ndarray  # (n, 3) acceleration reference of the steered drones
    #: a reference-level separation step (:class:`~.separation.SeparationFilter`), or None
    separation_filter: SeparationFilter | None = None

    def __init__(
        self, n: int, params: BaseParams | None = None, *, vehicle: QuadParams = DEFAULT_PARAMS, **overrides: Any
    ) -> None:
        """``params``: the rule's record (default: :data:`PRESETS`' entry of its ``name``, else
        ``Params()``, its sizes scaled to ``vehicle`` by :meth:`~.rule_params.BaseParams.for_vehicle`),
        with ``overrides`` (any of its fields, and of :class:`~.rule_params.ControllerParams`;
        :class:`UserError` for another key or a bad value). ``vehicle``: the drones' parameters, whose
        rotor span the keep-out is built from (``rule.vehicle``)."""
        self.n = n
        self.vehicle = vehicle
        asked = {k: overrides.pop(k) for k in CONTROLLER_KEYS if k in overrides}
        self.controller_params = CONTROLLER_PRESETS.get(self.name, ControllerParams()).with_overrides(asked, where="")
        if params is None:
            params = (PRESETS[self.name] if self.name in PRESETS else self.Params()).for_vehicle(vehicle)
        self.params = params.with_overrides(overrides, where="")

    def reset(self, positions: np.ndarray) -> None:
        """Start of a run with the drones at positions (n, 3)."""
        raise NotImplementedError

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Adjusted setpoints pos_d (n, 3) and the drones it steers, steer (n,) bool."""
        raise NotImplementedError

    def take_separation_events(self) -> None:
        """Move the ``separation_filter``'s events (e.g. a barrier filter's relaxations) into this
        rule's ``events``, so that a run's summary and recording count them with the rule's own."""
        f = self.separation_filter
        if f is not None and f.events:
            self.events.extend(f.events)
            f.events.clear()

    @property
    def downwash_feedforward(self) -> bool:
        """Whether the controller is to compensate the downwash of the other drones (when the physics
        has one; see :class:`~swarm_mj.control.policy.DownwashFeedforward`): the rule's
        :class:`~.rule_params.ControllerParams` (its default :data:`~.rule_params.CONTROLLER_PRESETS`')."""
        return self.controller_params.downwash_feedforward

    def references(
        self,
        t: float,
        positions: np.ndarray,
        pos_d: np.ndarray,
        vel_d: np.ndarray,
        acc_d: np.ndarray,
        formation_alt: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`update` and the references the controller needs, (pos_d, vel_d, acc_d) (n, 3):
        the drones the rule steers take its velocity and acceleration references."""
        return _merged(self, *self.update(t, positions, pos_d, formation_alt), vel_d, acc_d)


class NoRule(Rule):
    """No anti-collision (``anti_collision = "off"``): setpoints pass through unchanged."""

    name = "off"
    Params = BaseParams  # it reads nothing

    def __init__(self, n: int, params: BaseParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)
        self.events: list[dict] = []
        self.vel_d = np.zeros((n, 3))
        self.acc_d = np.zeros((n, 3))
        self._record: FormedRecord | None = None

    def reset(self, positions: np.ndarray) -> None:
        self.events = []

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pass the formation setpoints (n, 3) through; steer nobody."""
        return pos_d, np.zeros(self.n, dtype=bool)

    def record(self) -> FormedRecord:
        """Its compiled step for the chunk driver: the formed step's record, ``on`` False (the driver
        passes the setpoints through), built once."""
        if self._record is None:
            self._record = idle_record(self.n)
        return self._record

    def compiled_ready(self) -> bool:
        """Its compiled step is all it does: always."""
        return True


def _merged(
    rule, pos_d: np.ndarray, steer: np.ndarray, vel_d: np.ndarray, acc_d: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pos_d, vel_d, acc_d) with the rows of the steered drones (n,) from rule.vel_d, rule.acc_d."""
    vel_d, acc_d = merge_rows(
        steer,
        rule.vel_d,
        rule.acc_d,
        np.ascontiguousarray(vel_d, dtype=np.float64),
        np.ascontiguousarray(acc_d, dtype=np.float64),
    )
    return pos_d, vel_d, acc_d


def rownorm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of v (n, k) (np.linalg.norm(v, axis=1), without its overhead)."""
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def pair_distances(positions: np.ndarray) -> np.ndarray:
    """Pairwise horizontal distances (n, n), +inf on the diagonal."""
    return horizontal_distances(np.ascontiguousarray(positions, dtype=np.float64))


class PaperRule(Rule):
    """The paper's rule exactly as printed (Fig. 5, §4), with the details docs/interpretations.md §4 fixes.

    When two drones are closer than the safety distance D̄ = 0.8 m in the horizontal
    plane, the one with the higher index yields (a follower always yields to the leader):
    its altitude setpoint moves by ``hop`` = 0.4 m, up if it is not below the other drone,
    else down, its (x, y) setpoint unchanged. It returns to the formation altitude once
    every drone it yields to is back beyond D̄ + ``hysteresis`` (docs/interpretations.md §4: "a little
    hysteresis"; the paper does not say when a drone returns).
    """

    name = "paper"
    Params = PaperParams
    params: PaperParams

    def __init__(self, n: int, params: PaperParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)
        p = self.params
        self.safety = p.safety_distance
        self.hop = p.hop
        self.hysteresis = p.hysteresis
        self._lower = np.tri(n, k=-1, dtype=bool)  # [i, j]: j < i, so i yields to j
        self.vel_d = np.zeros((n, 3))  # (n, 3) velocity reference of steered drones
        self.acc_d = np.zeros((n, 3))  # (n, 3) acceleration reference of steered drones
        self.reset(np.zeros((n, 3)))

    def reset(self, positions: np.ndarray) -> None:
        self.offset = np.zeros(self.n)  # (n,) current altitude offset of each drone
        self.events: list[dict] = []

    def _react(self, t: float, positions: np.ndarray, h: np.ndarray, active: np.ndarray) -> None:
        """Fig. 5: trigger and release the altitude offsets of the drones flagged ``active`` (n,)
        (:func:`~swarm_mj.formation.separation.fig5_react`)."""
        fig5_react(t, positions, h, active, self.offset, self.events, self.safety, self.hop, self.hysteresis)

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fig. 5 on every drone: altitude offsets only, (x, y) setpoints unchanged."""
        h = pair_distances(positions)
        self._react(t, positions, h, np.ones(self.n, dtype=bool))
        pos_d = pos_d.copy()
        pos_d[:, 2] += self.offset
        return pos_d, np.zeros(self.n, dtype=bool)
