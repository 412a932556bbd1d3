"""The paper's stack as a policy: formation setpoints → anti-collision → backstepping.

A policy is any callable ``policy(observation) -> action`` for :class:`~swarm_mj.env.SwarmEnv`;
this one returns U1..U4 (n, 4) and is what ``swarm-mj run`` plugs in. :meth:`BacksteppingPolicy.command`
returns the same U with the references and commanded attitude that produced it (a
:class:`~swarm_mj.env.Command`, which ``SwarmEnv.step`` records).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .control.backstepping import Backstepping
from .env import Command
from .formation.anticollision import make_rule
from .params import DEFAULT_PARAMS, QuadParams
from .scenario import Scenario


class BacksteppingPolicy:
    """Backstepping (eqs. 17–24) on formation setpoints adjusted by the anti-collision rule."""

    def __init__(self, scenario: Scenario, params: QuadParams = DEFAULT_PARAMS, *,
                 gains: np.ndarray | None = None, anti_collision: str | None = None) -> None:
        sc = scenario
        self.n = sc.n_drones
        self.controller = Backstepping(self.n, sc.gains if gains is None else gains, params=params,
                                       control_period=sc.control_period, wind_feedforward=sc.wind_feedforward,
                                       attitude_map=sc.attitude_map)
        rule_params: dict[str, Any] = {"sensing_range": sc.sensing_range, **sc.anti_collision_params}
        self.rule = make_rule(anti_collision or sc.anti_collision, self.n, **rule_params)
        self._started = False

    def reset(self) -> None:
        self.controller.reset()
        self._started = False

    @property
    def events(self) -> list[dict]:
        return self.rule.events

    def command(self, obs: dict) -> Command:
        """U1..U4 (n, 4) for the observation, with the references (n, 3) and attitude (n, 3) behind them."""
        if not self._started:
            self.rule.reset(obs["pos"])
            self._started = True
        pos_d, vel_d, acc_d = obs["setpoint"], obs["setpoint_vel"], obs["setpoint_acc"]
        if self.n > 1:
            # Anti-collision (docs/interpretations.md §4): the rule adjusts the setpoints (n, 3) and,
            # for the drones it steers, also hands the velocity/acceleration references (zero = hold x, y).
            pos_d, vel_d, acc_d = self.rule.references(float(obs["time"]), obs["pos"], pos_d, vel_d, acc_d,
                                                       float(obs["leader_pos"][2]))
        ctl = self.controller
        U = ctl.compute(obs["rpy"], obs["rpy_rate"], obs["pos"], obs["vel"], pos_d, vel_d, acc_d,
                        obs["setpoint_yaw"], wind_force=obs["wind_force"], omega_body=obs["body_rates"])
        return Command(U, pos_d, vel_d, acc_d, ctl.att_d.copy())

    def __call__(self, obs: dict) -> np.ndarray:
        return self.command(obs).U
