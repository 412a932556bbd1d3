"""A scenario table written as TOML text (:func:`scenario_toml`; the stress command writes the scenario
of each start with it). ``swarm_mj.scenario.load_scenario`` of the text gives the same scenario."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def _toml_scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        return ("inf" if f > 0 else "-inf") if math.isinf(f) else ("nan" if math.isnan(f) else repr(f))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_scalar(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scenario_toml(data: dict) -> str:
    """A scenario table (as :func:`swarm_mj.scenario.parse_scenario` reads it) as TOML text: scalars and lists at the
    top, then one ``[section]`` per sub-table (one level of nesting inside a section, written as
    an inline table). ``load_scenario`` of the text gives the same scenario."""
    top = [f"{k} = {_toml_scalar(v)}" for k, v in data.items() if not isinstance(v, dict)]
    out = top + [""]
    for k, v in data.items():
        if isinstance(v, dict):
            out.append(f"[{k}]")
            for kk, vv in v.items():
                if isinstance(vv, dict):
                    inner = ", ".join(f"{a} = {_toml_scalar(b)}" for a, b in vv.items())
                    out.append(f"{kk} = {{ {inner} }}")
                else:
                    out.append(f"{kk} = {_toml_scalar(vv)}")
            out.append("")
    return "\n".join(out)
