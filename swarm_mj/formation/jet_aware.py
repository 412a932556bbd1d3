"""The downwash-aware rule (``jet-aware``, the planner ``barrier`` guards; docs/interpretations.md §4,
why and what was measured: docs/anticollision.md): the planner (:class:`~.planner.LayeredRule`) with
the jet-aware separation of :mod:`.separation` and its preset's gentler paths."""

from __future__ import annotations

from typing import Any

import numpy as np

from .layered import any_below, react_needed
from .planner import CROSS, FORMED, LayeredRule, PlanStep
from .rule_params import JetAwareParams
from .rules import pair_distances
from .separation import (
    closing_only,
    descending_onto,
    hold_above,
    never_through,
    offset_candidates,
    stacked_react,
)


class JetAwareRule(LayeredRule):
    """``anti_collision = "jet-aware"``, a planner for physics with downwash (``--aero realistic``;
    ``barrier`` guards it, and ``"auto"`` picks that): the layered rule made downwash-aware and its
    formed phase made to settle.

    **What is the paper's** (Fig. 5, §4): as in :class:`~.planner.LayeredRule`. **What is the
    layered rule's** (ours): climb in place to a layer of its own, cross on it along a limited
    path, drop over the slot. **What is new here** (ours); 5. and 6. are its preset's values
    (:data:`~.rule_params.PRESETS`), 1. what it asks of the controller
    (:data:`~.rule_params.CONTROLLER_PRESETS`), 2.–4. and 7. its separation (their numbers: the fields
    :class:`~.rule_params.JetAwareParams` adds to the planner's):

    1. *feedforward* — ``downwash_feedforward``: the controller compensates the downwash force
       it predicts (:class:`~swarm_mj.control.policy.DownwashFeedforward`), as it does the wind.
    2. *yield by the slots* — a follower whose slot is within D̄ of a lower index's yields to it
       by the slots, once, before they meet (:func:`~.separation.stacked_react`).
    3. *stacked offsets* — invariant: two drones of which one yields to the other are ``hop``
       apart in offset, however many are involved; never an offset under ``floor_clearance``
       (:func:`~.separation.stacked_react`).
    4. *never through* — invariant: a formed follower's altitude target never crosses a drone
       whose keep-out overlaps its own in plan view (now, or over ``horizon`` for a pair closing
       faster than ``closing_min``) (:func:`~.separation.never_through`).
    5. *gentler crossings* — ``max_speed`` 3 m/s, ``max_accel`` 4 m/s² on the layers.
    6. *gentler formed descents* — ``formed_descent_accel`` 3 m/s² for a follower that has joined.
    7. *early hold* — invariant: a descending formed follower's target stays ``hop`` above a drone
       crossing below it within D̄ + ``crossing_hold`` (now or predicted) (:func:`~.separation.hold_above`).
    """

    name = "jet-aware"
    Params = JetAwareParams
    params: JetAwareParams
    jet_aware_checks = True  # the formed step hands slots within D̄ and overlapping keep-outs to Python

    def __init__(self, n: int, params: JetAwareParams | None = None, **overrides: Any) -> None:
        super().__init__(n, params, **overrides)

    def update(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        if not self._all_formed:  # (formed, the compiled formed step sets both: layered.formed_update)
            self.set_slots(self.slots(pos_d))
            self._formation_alt[0] = formation_alt
        return super().update(t, positions, pos_d, formation_alt)

    def set_slots(self, pos_d: np.ndarray) -> None:
        """The setpoints (n, 3) whose horizontal distances 2. of the class docstring reads (row 0:
        the leader's reference); :meth:`update` sets them every step."""
        self._slot_h[:] = pair_distances(pos_d)

    @property
    def slot_yield(self) -> bool:
        """Some slots (the last set, :meth:`set_slots`) are within D̄ of each other."""
        return bool(any_below(self._slot_h, self.safety))

    def _react(self, t: float, positions: np.ndarray, h: np.ndarray, active: np.ndarray) -> None:
        """2.–3. of the class docstring (:func:`~.separation.stacked_react`)."""
        if not self.slot_yield and not react_needed(self.offset, h, self.safety):
            return
        p = self.params
        lowest = p.floor_clearance - float(self._formation_alt[0])
        cands = offset_candidates(self.hop, lowest, p.max_hops_down, p.max_hops_up)
        args = (self._slot_h, self.safety, self.hop, self.hysteresis, cands)
        stacked_react(t, positions, h, active, self.offset, self.events, *args)

    def _through(self, positions: np.ndarray, z_target: np.ndarray, formed: np.ndarray, soon: np.ndarray) -> np.ndarray:
        """4. of the class docstring (:func:`~.separation.never_through`)."""
        return never_through(positions, z_target, formed, soon, self.overlap, self.hop)

    def _closing(self, positions: np.ndarray, h: np.ndarray, soon: np.ndarray) -> np.ndarray:
        """``soon`` (n, n) for the pairs closing faster than ``closing_min``, else ``h`` (n, n)
        (:func:`~.separation.closing_only`)."""
        return closing_only(positions, self.vel, h, soon, self.params.closing_min)

    def _formed(self, s: PlanStep) -> None:
        super()._formed(s)
        formed = self.phase == FORMED
        formed[0] = False
        s.z_target = self._through(s.positions, s.z_target, formed, self._closing(s.positions, s.h, s.soon))
        if s.in_transit:
            s.z_target = self._over_crossing(s.z, s.soon, s.z_target, formed)

    def _over_crossing(self, z: np.ndarray, soon: np.ndarray, z_target: np.ndarray, formed: np.ndarray) -> np.ndarray:
        """7. of the class docstring: ``z_target`` (n,) of the ``formed`` (n,) followers held ``hop``
        above every crossing drone below them (altitudes ``z`` (n,)) that is, or is predicted to be
        (``soon`` (n, n)), within D̄ + ``crossing_hold`` horizontally."""
        near = soon < self.safety + self.params.crossing_hold
        below = descending_onto(z, z_target, formed, self.phase == CROSS, near, self.clearance)
        return hold_above(z, z_target, below, self.hop)

    def _update_formed(
        self, t: float, positions: np.ndarray, pos_d: np.ndarray, formation_alt: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The layered rule's formed step while its separation has work to do, with 2.–4. of the
        class docstring."""
        h = pair_distances(positions)
        self._react(t, positions, h, self._all)
        offset = self.offset
        if (h[1:] < self.overlap).any():
            soon = self._closing(positions, h, self._approach(positions, self.horizon))
            z_t = self._through(positions, formation_alt + offset, self._followers, soon)
            offset = z_t - formation_alt
        return self._formed_paths(dt, pos_d, formation_alt, offset)
