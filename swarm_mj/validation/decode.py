"""Decoder of the Crazyflie uSD-card-deck binary log (the Neural-Swarm raw logs; docs/validation.md).

Format (established from the logs and from the dataset's own decoder, docs/validation.md, "Data"):

* header: one byte ``n`` (the number of logged variables), then ``n`` names each ended by ``,``,
  each name carrying its C type in brackets (``tick(I)``, ``stateEstimateZ.x(h)``: ``struct``
  codes, little-endian), then a 4-byte CRC-32;
* then blocks: one byte ``k`` (records in the block), ``k`` records of the ``n`` values, a 4-byte
  CRC-32.

The CRC-32 (zlib's) is stored so that the CRC of the checked bytes *followed by the stored CRC*
is 0xFFFFFFFF: a block checks when ``crc32(count byte + records + CRC) == 0xFFFFFFFF``.
"""

from __future__ import annotations

import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import UserError

#: CRC-32 residue of a checked span that includes its own stored CRC.
CRC_RESIDUE = 0xFFFFFFFF
_NAME = re.compile(r"^(?P<name>.+)\((?P<code>[bBhHiIlLqQfd])\)$")


@dataclass
class RawLog:
    """One decoded log: ``columns`` maps each logged variable's name (without its type) to its
    values, as logged (raw integers or floats); ``crc_errors`` counts blocks whose CRC fails
    (header included); ``n_blocks`` the blocks read."""

    path: Path
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    crc_errors: int = 0
    n_blocks: int = 0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0


def _crc_ok(chunk: bytes) -> bool:
    return (zlib.crc32(chunk) & 0xFFFFFFFF) == CRC_RESIDUE


def decode_bytes(data: bytes, path: Path | str = "<bytes>") -> RawLog:
    """Decode the bytes of one uSD log (module docstring). Blocks whose CRC fails are dropped and
    counted; a truncated last block is dropped and counted. Raises :class:`UserError` for a file
    that is not such a log (empty, no well-formed header)."""
    path = Path(path)
    if len(data) < 2:
        raise UserError(f"{path}: not a Crazyflie uSD log (file too short)")
    n = data[0]
    names: list[str] = []
    codes: list[str] = []
    idx = 1
    for _ in range(n):
        end = data.find(b",", idx)
        if end < 0 or end - idx > 200:
            raise UserError(f"{path}: not a Crazyflie uSD log (bad header)")
        try:
            token = data[idx:end].decode("ascii")
        except UnicodeDecodeError:
            raise UserError(f"{path}: not a Crazyflie uSD log (bad header)") from None
        m = _NAME.match(token.strip())
        if not m:
            raise UserError(f"{path}: not a Crazyflie uSD log (bad variable {token!r} in the header)")
        names.append(m["name"])
        codes.append(m["code"])
        idx = end + 1
    if n == 0 or idx + 4 > len(data):
        raise UserError(f"{path}: not a Crazyflie uSD log (bad header)")
    log = RawLog(path=path)
    if not _crc_ok(data[: idx + 4]):
        log.crc_errors += 1
    offset = idx + 4
    record = struct.Struct("<" + "".join(codes))
    rows: list[bytes] = []
    while offset < len(data):
        k = data[offset]
        end = offset + 1 + k * record.size
        if end + 4 > len(data):
            log.crc_errors += 1  # truncated last block
            break
        log.n_blocks += 1
        if _crc_ok(data[offset : end + 4]):
            rows.append(data[offset + 1 : end])
        else:
            log.crc_errors += 1
        offset = end + 4
    dtype = np.dtype([(f"f{i}", "<" + c) for i, c in enumerate(codes)])
    table = np.frombuffer(b"".join(rows), dtype=dtype)
    for i, name in enumerate(names):
        log.columns[name] = np.array(table[f"f{i}"])
    return log


def decode(path: str | Path) -> RawLog:
    """Decode the uSD log file at ``path`` (:func:`decode_bytes`)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise UserError(f"{p}: cannot read the log: {e.strerror or e}") from None
    return decode_bytes(data, p)
