"""Reading a TOML table's fields, one way: its keys (an unknown one is one line with a "did you mean",
:func:`~swarm_mj.errors.unknown_key`), numbers, choices, flags, sub-tables and vectors; each mistake is
one :class:`~swarm_mj.errors.UserError` naming the field. The readers of one field take the table, the
key, the default (None: required) and ``where``, the prefix of the field's name (``"x.toml: leader."``);
:func:`check_keys` and :func:`vec` take the name itself. The scenario's tables are read with them
(:func:`swarm_mj.scenario.parse_scenario`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import UserError, unknown_key


def check_keys(table: Any, allowed: set[str], where: str, see: str | None = None) -> dict:
    """``table`` is a table of keys among ``allowed``: the first unknown one is one short line with a "did
    you mean" (:func:`~swarm_mj.errors.unknown_key`; ``see``: where the docs list a long table's keys)."""
    if not isinstance(table, dict):
        raise UserError("must be a table", where=where)
    for key in table:
        if key not in allowed:
            raise unknown_key(key, allowed, where=where, see=see)
    return table


def finite(v: Any) -> bool:
    """A number ``v`` is finite: NaN and infinities are not, nor an integer beyond a float's range (TOML
    reads integers of any size, and ``np.isfinite`` takes none beyond int64's)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def number(
    table: dict,
    key: str,
    default: Any,
    where: str,
    *,
    positive: bool = False,
    minimum: float | None = None,
    integer: bool = False,
) -> Any:
    """``table[key]`` (``default`` where absent; None: the key is required): a finite number, an integer
    where ``integer``, positive or at least ``minimum`` where asked. ``where`` prefixes the key."""
    if key not in table:
        if default is None:
            raise UserError("missing field", where=f"{where}{key}")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise UserError(f"must be {'an integer' if integer else 'a number'}, got {v!r}", where=f"{where}{key}")
    if not finite(v):
        raise UserError(f"must be finite, got {v!r}", where=f"{where}{key}")
    if positive and v <= 0:
        raise UserError(f"must be positive, got {v!r}", where=f"{where}{key}")
    if minimum is not None and v < minimum:
        raise UserError(f"must be >= {minimum}, got {v!r}", where=f"{where}{key}")
    return v


def choice(
    table: dict,
    key: str,
    default: str | None,
    choices: Sequence[str],
    where: str,
    message: str = "must be one of {choices}, got {v!r}",
) -> str:
    """``table[key]`` (``default`` where absent; None: the key is required): a string among ``choices``;
    otherwise ``message`` with ``{v!r}`` the value and ``{choices}`` the choices joined. ``where`` prefixes
    the key."""
    if key not in table and default is None:
        raise UserError("missing field", where=f"{where}{key}")
    v = table.get(key, default)
    if not isinstance(v, str) or v not in choices:
        raise UserError(message.format(v=v, choices=", ".join(choices)), where=f"{where}{key}")
    return v


def flag(table: dict, key: str, default: bool, where: str) -> bool:
    """``table[key]`` (``default`` where absent): true or false. ``where`` prefixes the key."""
    v = table.get(key, default)
    if not isinstance(v, bool):
        raise UserError(f"must be true or false, got {v!r}", where=f"{where}{key}")
    return v


def subtable(table: dict, key: str, default: dict, where: str, message: str = "must be a table") -> dict:
    """``table[key]`` (``default`` where absent): a table, whose keys its reader checks. ``where`` prefixes
    the key."""
    v = table.get(key, default)
    if not isinstance(v, dict):
        raise UserError(message, where=f"{where}{key}")
    return v


def only_numbers(v: Any) -> bool:
    """A number or (nested) lists of numbers, no booleans or strings."""
    if isinstance(v, list):
        return all(only_numbers(x) for x in v)
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def vec(v: Any, n: int | None, where: str) -> np.ndarray:
    """``v`` as a float array: numbers, finite, ``n`` of them where ``n`` is given."""
    if not only_numbers(v):
        raise UserError(f"must be numbers, got {v!r}", where=where)
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"must be numbers, got {v!r}", where=where) from None
    if not np.isfinite(a).all():
        raise UserError("must be finite numbers", where=where)
    if n is not None and a.shape != (n,):
        raise UserError(f"must be a list of {n} numbers, got {v!r}", where=where)
    return a
