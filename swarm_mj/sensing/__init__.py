"""Sensing and communication between the drones: each drone's own view (docs/sensing.md).

* :mod:`.params`: :class:`SensingParams`, the presets (``perfect``, ``mocap``, ``uwb``) and the
  ``[sensing]`` table's parser;
* :mod:`.channel`: the channel (broadcast rate, latency, loss, range, noise) as a record of arrays and
  a pure step, and :class:`Channel`, one run's channel with its seeded generator;
* :mod:`.margin`: the measurement-robust margin a barrier needs from these bounds.
"""

from __future__ import annotations

from .channel import (
    SENSING_STREAM,
    Channel,
    ChannelConfig,
    ChannelState,
    View,
    channel_config,
    channel_step,
    channel_tick,
    empty_state,
    senders_at,
    sensing_rng,
)
from .margin import Margin, age_bound, lost_in_a_row, noise_quantile, robust_margin
from .params import FIELDS, PRESETS, TABLE_KEYS, SensingParams, parse_sensing_table, sensing_preset

__all__ = [
    "FIELDS",
    "PRESETS",
    "SENSING_STREAM",
    "TABLE_KEYS",
    "Channel",
    "ChannelConfig",
    "ChannelState",
    "Margin",
    "SensingParams",
    "View",
    "age_bound",
    "channel_config",
    "channel_tick",
    "channel_step",
    "empty_state",
    "lost_in_a_row",
    "noise_quantile",
    "parse_sensing_table",
    "robust_margin",
    "senders_at",
    "sensing_preset",
    "sensing_rng",
]
