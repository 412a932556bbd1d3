"""The controller's step bars as constraints of the tune (Deb's feasibility rules).

The ISE of eq. (25) weighs the slow tail of a step lightly: on its own it can prefer gains
whose y-axis settles in just over 2 s (seed 1, Table 2 settings: 2.05 s) for a lower ISE.
Gains that are to replace Table 4 must also meet the step bars of the backstepping issue,
so by default the tune treats those bars as constraints:

* overshoot ≤ 1 % on x, y, z and ψ;
* 2 % settling ≤ 2.0 s (x, y), ≤ 1.5 s (z), ≤ 2.0 s (ψ);
* steady-state error ≤ 1 mm (x, y, z) and ≤ 1e-3 rad (ψ) at the end of the run;
* |roll|, |pitch| ≤ 55° throughout (docs/interpretations.md §2 reads the issue's 50° as 55°).

**Deb's feasibility rules** (Deb 2000) rank the candidates: one that meets every bar beats
one that does not; two that meet them compare by ISE; two that do not compare by their
total violation :func:`step_violation`. The FPA only *compares* costs (greedy replacement
and the best flower), so the scalar :func:`ranked_cost` (ISE when feasible, else
``INFEASIBLE + violation``) makes it apply these rules exactly. A feasible candidate's ISE
is far below ``INFEASIBLE``: it has settled within 2 s with at most 1 % overshoot and a tilt
below 55°, which bounds its ISE over 10 s by well under 100.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..errors import UserError

__all__ = ["INFEASIBLE", "StepBars", "missed_bars", "ranked_cost", "step_violation", "decode_cost"]

#: Offset of an infeasible candidate's ranked cost: any feasible ISE is far below it.
INFEASIBLE = 1.0e6

AXES = ("x", "y", "z", "psi")


@dataclass(frozen=True)
class StepBars:
    """The step bars of the backstepping issue (issue 3; docs/interpretations.md §2 for the tilt). Hashable."""

    overshoot_pct: float = 1.0
    settling_x_s: float = 2.0
    settling_y_s: float = 2.0
    settling_z_s: float = 1.5
    settling_psi_s: float = 2.0
    steady_state_error: float = 1.0e-3  # m for x, y, z; rad for ψ
    max_tilt_deg: float = 55.0

    def __post_init__(self) -> None:
        for name, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0):
                raise UserError(f"step bar {name} must be a positive number, got {v!r}")

    def settling(self, axis: str) -> float:
        return float(getattr(self, f"settling_{axis}_s"))

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def step_violation(
    step: dict[str, dict[str, np.ndarray]], max_tilt_deg: np.ndarray, bars: StepBars, t_end: float
) -> np.ndarray:
    """Total normalised violation (m,) of the bars; 0 exactly where every bar is met.

    step: ``{axis: {"overshoot_pct", "settling_s", "steady_state_error"}}`` with (m,) arrays
    (:func:`swarm_mj.metrics.step_metrics_batch`) for axes x, y, z, psi; max_tilt_deg (m,) the
    largest |roll| or |pitch|. Each bar contributes max(0, value − bar) / bar; a response
    still outside the band at the end (settling ``inf``) counts as settling at ``t_end``.
    """
    v = np.zeros_like(np.asarray(max_tilt_deg, dtype=float))
    for ax in AXES:
        m = step[ax]
        ts = np.minimum(m["settling_s"], t_end)
        v += np.maximum(0.0, m["overshoot_pct"] - bars.overshoot_pct) / bars.overshoot_pct
        v += np.maximum(0.0, ts - bars.settling(ax)) / bars.settling(ax)
        v += np.maximum(0.0, m["steady_state_error"] - bars.steady_state_error) / bars.steady_state_error
    v += np.maximum(0.0, max_tilt_deg - bars.max_tilt_deg) / bars.max_tilt_deg
    return np.where(np.isfinite(v), v, np.inf)


def missed_bars(step: dict[str, dict[str, float]], max_tilt_deg: float, bars: StepBars) -> list[str]:
    """The bars one response misses, in words (empty: all met); step as in :func:`step_violation`
    with floats, e.g. ``["y settling 2.05 s"]``."""
    miss = []
    for ax in AXES:
        m = step[ax]
        if m["overshoot_pct"] > bars.overshoot_pct:
            miss.append(f"{ax} overshoot {m['overshoot_pct']:.2f} %")
        if m["settling_s"] > bars.settling(ax):
            miss.append(f"{ax} settling {m['settling_s']:.2f} s")
        if m["steady_state_error"] > bars.steady_state_error:
            miss.append(f"{ax} steady-state error {m['steady_state_error']:.1e}")
    if max_tilt_deg > bars.max_tilt_deg:
        miss.append(f"tilt {max_tilt_deg:.1f}°")
    return miss


def ranked_cost(ise: np.ndarray, violation: np.ndarray) -> np.ndarray:
    """Deb's feasibility rules as one scalar (m,): ISE where feasible, else INFEASIBLE + violation.

    A diverged candidate (ISE ``inf``) stays ``inf``: worse than any infeasible one.
    """
    ise = np.asarray(ise, dtype=float)
    out = np.where(violation > 0.0, INFEASIBLE + violation, ise)
    return np.where(np.isfinite(ise), out, np.inf)


def decode_cost(cost: float) -> tuple[bool, float]:
    """(feasible, value) of a ranked cost: the ISE if feasible, else the violation (inf: diverged)."""
    if not math.isfinite(cost):
        return False, float("inf")
    if cost >= INFEASIBLE:
        return False, float(cost - INFEASIBLE)
    return True, float(cost)
