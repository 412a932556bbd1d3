"""A scenario's sensing record (docs/sensing.md): its ``[sensing]`` table, the alias ``[formation]
sensing_range``, and what ``Scenario.with_overrides(sensing=...)`` and ``--sensing PRESET`` change.

The alias (docs/sensing.md, "The alias"): a file that sets ``[formation] sensing_range = r`` and no
``[sensing] range_m`` reads as ``range_m = r``; ``[sensing] range_m = r`` (finite) is the rules'
``Scenario.sensing_range`` too; neither leaves the channel without a range (inf) and the rules with
their own 4 m (:class:`~swarm_mj.formation.rule_params.LayersParams`); both set is one error naming
``sensing.range_m``.
"""

from __future__ import annotations

import math
from typing import Any

from .errors import UserError
from .formation.rule_params import LayersParams
from .sensing.params import PRESETS, TABLE_KEYS, SensingParams, parse_sensing_table
from .table_fields import check_keys

#: What ``sensing=`` takes: a preset's name (``perfect``, ``mocap``, ``uwb``) or a whole record.
SensingLike = str | SensingParams


def _alias(formation: Any) -> float | None:
    """The ``[formation] sensing_range`` a file sets (its alias of ``range_m``), None where it does not."""
    if isinstance(formation, dict) and "sensing_range" in formation:
        return float(formation["sensing_range"])
    return None


def parse_scenario_sensing(data: dict, w: str, rules_range: float) -> tuple[SensingParams, float]:
    """``[sensing]`` (the ``perfect`` preset by default) with the alias applied: (the record, the rules'
    sensing range). ``w``: the file's prefix (``"x.toml: "``); ``rules_range``: the rules' range as
    ``[formation]`` gives it (its ``sensing_range``, else the rules' default). The ``[formation]`` table
    is read already (a dict, its ``sensing_range`` checked)."""
    table = check_keys(data.get("sensing", {}), set(TABLE_KEYS), f"{w}sensing")
    record = parse_sensing_table(table, f"{w}sensing", formation_sensing_range=_alias(data.get("formation")))
    if "range_m" in table and math.isfinite(record.range_m):
        rules_range = record.range_m
    return record, rules_range


def sensing_overrides(sc: Any, sensing: SensingLike, where: str = "sensing") -> dict[str, Any]:
    """The fields of ``sc`` (a :class:`~swarm_mj.scenario.Scenario`, not imported: scenario.py imports this
    module) that change when it flies ``sensing``, which stands for the file's whole
    ``[sensing]`` table: a preset's name is ``{preset = NAME}``, a record its
    :meth:`~swarm_mj.sensing.params.SensingParams.table`. The alias applies as in a file (``[formation]
    sensing_range`` is the channel's range where the record has none: inf); a record's finite
    ``range_m`` wins over the alias and is the rules' ``sensing_range`` too. ``raw`` follows (what a
    sweep's ``--param`` re-reads). Unknown preset: one :class:`UserError` line naming ``where``."""
    if isinstance(sensing, str):
        if sensing not in PRESETS:
            raise UserError(f"unknown sensing preset {sensing!r}; choose one of {', '.join(PRESETS)}", where=where)
        table: dict[str, Any] = {"preset": sensing}
    elif isinstance(sensing, SensingParams):
        table = sensing.table()
    else:
        raise UserError(f"must be a sensing preset's name or a SensingParams, got {sensing!r}", where=where)
    raw = dict(sc.raw) if isinstance(sc.raw, dict) else {}
    formation = raw.get("formation")
    alias = None if "range_m" in table else _alias(formation)
    record = parse_sensing_table(table, where, formation_sensing_range=alias)
    if math.isfinite(record.range_m):
        rules_range = record.range_m
    elif isinstance(raw.get("sensing"), dict) and "range_m" in raw["sensing"]:
        rules_range = LayersParams().sensing_range  # the replaced table gave the rules their range
    else:
        rules_range = sc.sensing_range
    if alias is None and isinstance(formation, dict) and "sensing_range" in formation:
        raw["formation"] = {k: v for k, v in formation.items() if k != "sensing_range"}  # the record's range wins
    out: dict[str, Any] = {"sensing": record, "sensing_range": rules_range}
    if raw:
        out["raw"] = {**raw, "sensing": table}
    return out
