"""A rule flown from each drone's own view (docs/sensing.md, "Each drone decides from its own view").

Under a sensing model (anything but ``perfect``) every drone runs its own copy of the anti-collision
rule, as each Crazyflie would run its own firmware: copy i is given drone i's view only (where it
believes every drone is, the formation setpoints built from where it believes the leader is, the
leader's altitude it believes), and drone i flies row i of what its copy returns. What copy i
computes for the other rows is drone i's prediction of the others' decisions from its view; nothing
of it leaves the copy. A rule therefore needs no change to fly decentralised: its contract (row i
depends only on drone i's own state and what it senses, docs/interpretations.md §4) is now enforced
by the data each copy receives, not only by how the rule is written.

Every copy is built like the rule itself, from the same parameters; each holds its own state (paths,
offsets, the barrier filter's record). The events of drone i are copy i's events about drone i.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from .rules import Rule


class OwnViewRule:
    """``n`` copies of a rule, copy i deciding drone i's row from drone i's view.

    The interface the policy calls: ``reset(positions)``, ``references_from_view(t, view_pos,
    setpoint, setpoint_vel, setpoint_acc, formation_alt, view_vel)`` (each (n, n, ...) but
    ``setpoint_acc`` (n, 3) and ``formation_alt`` (n,)), ``events``, ``name``, ``downwash_feedforward``,
    ``separation_filter`` (the template's: its keep-out, for the checks before a run).

    With :attr:`own_rows` (the default) the separation filter of copy i computes row i only (its
    ``restrict_to``, e.g. :meth:`~.barrier_filter.BarrierFilter.restrict_to`): the rows it would
    compute for the others are thrown away here, and row i does not depend on them (the barrier's
    QP of drone i reads the others' sensed state and whether they filter, never their nominals or
    filtered commands: :func:`~.barrier_filter.barrier_step`), so every run is the same bit for bit,
    for a sixth of the QPs with 6 drones (tests/unit/test_own_row.py checks it). The barrier with its
    joint fallback computes every row (a boxed drone's cluster reads the others' references and
    nominals) and counts row i's alone (docs/barrier.md, "the joint fallback")."""

    #: copy i's separation filter computes drone i's row only (False: every row, as the rule itself)
    own_rows: bool = True

    def __init__(self, rule: Rule) -> None:
        self.rule = rule  # the template (never flown itself)
        self.n = rule.n
        self.name = rule.name
        self.params = rule.params
        self.vehicle = rule.vehicle
        self.separation_filter = rule.separation_filter
        self.copies: list[Rule] = [copy.deepcopy(rule) for _ in range(self.n)]
        if self.own_rows:
            for i, c in enumerate(self.copies):
                restrict = getattr(c.separation_filter, "restrict_to", None)
                if restrict is not None:  # copy i's filter computes row i only (the same row, bit for bit)
                    restrict(i)
        self.events: list[dict] = []

    @property
    def downwash_feedforward(self) -> bool:
        return self.rule.downwash_feedforward

    def reset(self, positions: np.ndarray) -> None:
        """Start of a run: every copy from the drones' starts (the flight plan's pads, known to all)."""
        for c in self.copies:
            c.reset(positions)
        self.events = []

    def references_from_view(
        self,
        t: float,
        view_pos: np.ndarray,
        setpoint: np.ndarray,
        setpoint_vel: np.ndarray,
        setpoint_acc: np.ndarray,
        formation_alt: np.ndarray,
        view_vel: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_d, vel_d, acc_d) (n, 3): row i from copy i's ``references`` on drone i's view (row i of
        view_pos, setpoint, setpoint_vel (n, n, 3); formation_alt[i]); a rule that estimates velocities
        takes row i of ``view_vel`` (n, n, 3) instead (its ``sense_velocities``)."""
        n = self.n
        pos_d, vel_d, acc_d = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        for i, rule in enumerate(self.copies):
            sense = getattr(rule, "sense_velocities", None)
            if sense is not None and view_vel is not None:
                sense(view_vel[i])
            p, v, a = rule.references(
                t, view_pos[i], setpoint[i], setpoint_vel[i], setpoint_acc, float(formation_alt[i])
            )
            pos_d[i], vel_d[i], acc_d[i] = p[i], v[i], a[i]
            self._take_events(rule, i)
        return pos_d, vel_d, acc_d

    # ------------------------------------------------------------------ the chunk driver's interface
    def record(self) -> object | None:
        """Copy 0's record: the type every copy's is (what the registry's checks look up); None for a rule
        with no record (no compiled step: the registry's check then says so)."""
        make = getattr(self._compiled[0], "record", None)
        return make() if callable(make) else None

    def records(self) -> tuple:
        """Each copy's record, in drone order (the chunk driver's ``rules``)."""
        return tuple(c.record() for c in self._compiled)

    def compiled_ready(self) -> bool:
        """Every copy's compiled step is all it would do now."""
        return all(c.compiled_ready() for c in self._compiled)

    @property
    def _compiled(self) -> list[Any]:
        """The copies as the chunk driver sees them: rules with a compiled step (``record``, ``compiled_ready``)."""
        return self.copies

    def take_separation_events(self) -> None:
        """After periods a compiled driver flew: each copy's separation filter's events into the copy's (its
        ``take_events``, then the rule's), and drone i's of copy i into this rule's, as
        :meth:`references_from_view` takes them, in its order (by period, then drone)."""
        start = len(self.events)
        for i, c in enumerate(self.copies):
            take = getattr(c.separation_filter, "take_events", None)  # a filter with a record's event buffer
            if take is not None:
                take()
            c.take_separation_events()
            self._take_events(c, i)
        self.events[start:] = sorted(self.events[start:], key=lambda e: (e["t"], e["drone"]))

    def _take_events(self, rule: Rule, i: int) -> None:
        """Copy i's events about drone i into this rule's; the rest (its predictions of the others) dropped."""
        if rule.events:
            self.events.extend(e for e in rule.events if e.get("drone") == i)
            rule.events.clear()
