"""Output files: checked before a run, written atomically, strict JSON (one sanitiser).

Every file swarm-mj writes (summaries, gains files, sweep/stress JSON; recordings and videos
through :func:`replace_into`) goes through this module, so that:

* an output path is checked **before** anything is simulated (:func:`check_output_path`):
  its folder exists and is writable, it is not a folder, and a special file at the path
  (a FIFO, a device) is writable;
* a regular file is replaced atomically: the text goes to a temporary file in the target's
  folder, is flushed to disk and ``os.replace``-d over the target, so a reader (or an
  interruption) sees the old file or the new one, never half of one;
* what is **not** a regular file is never replaced: a FIFO or a character/block device
  (``/dev/stdout``, ``/dev/null``, ``/dev/full``) is written in place, ``-`` means standard
  output, and a symlink is written through to its target (atomically there). A failed
  write (e.g. ``ENOSPC`` on ``/dev/full``) raises :class:`~swarm_mj.errors.OutputError`
  (one line, exit status 1);
* JSON is strict: :func:`json_safe` turns NaN and ±inf into ``null`` (a formation that never
  settled, a metric with no finite value), numpy scalars and arrays into Python numbers and
  lists. It is the one sanitiser of the package.
"""

from __future__ import annotations

import datetime as _dt
import errno
import json
import math
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import OutputError, UserError

STDOUT = "-"


# --------------------------------------------------------------------------- strict JSON


def json_safe(o: Any, inf_as_string: bool = False) -> Any:
    """``o`` with every non-finite float made JSON (NaN -> ``None``; ±inf -> ``None``, or the strings
    ``"inf"``/``"-inf"`` with ``inf_as_string``, which the report and sweep results use so that their
    tables can tell "never settled" from "not measured") and numpy types made Python ones
    (arrays -> lists, tuples -> lists, Path and dates -> str): what ``json.dumps(...,
    allow_nan=False)`` accepts. The one sanitiser of every JSON file swarm-mj writes."""
    if isinstance(o, dict):
        return {
            str(k) if not isinstance(k, (str, int, float, bool)) and k is not None else k: json_safe(v, inf_as_string)
            for k, v in o.items()
        }
    if isinstance(o, (list, tuple)):
        return [json_safe(v, inf_as_string) for v in o]
    if isinstance(o, np.ndarray):
        return json_safe(o.tolist(), inf_as_string)
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        v = float(o)
        if math.isfinite(v):
            return v
        if inf_as_string and math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return None
    if isinstance(o, (Path, _dt.datetime, _dt.date, _dt.time)):
        return str(o)
    return o


def dumps_strict(data: Any, indent: int | None = 2, inf_as_string: bool = False) -> str:
    """Strict JSON text of ``data`` (see :func:`json_safe`), ending in a newline."""
    return json.dumps(json_safe(data, inf_as_string), indent=indent, allow_nan=False) + "\n"


# --------------------------------------------------------------------------- checks before a run


def _special(st: os.stat_result) -> bool:
    """A target that must be written in place, never replaced: FIFO, character or block device."""
    return stat.S_ISFIFO(st.st_mode) or stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)


def check_output_path(
    path: str | Path, option: str, suffixes: Sequence[str] | None = None, allow_stdout: bool = False
) -> Path:
    """Refuse, before anything runs, an output path that cannot be written.

    ``option`` names the option in the message (e.g. ``--summary``). A symlink is checked at
    its target. ``-`` is standard output when ``allow_stdout``. Raises :class:`UserError`.
    """
    s = str(path)
    if s == STDOUT and allow_stdout:
        return Path(s)
    if not s.strip():
        raise UserError(f"{option}: an empty file name")
    p = Path(s)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise UserError(f"{option} {s}: the file name must end in {' or '.join(suffixes)}")
    real = Path(os.path.realpath(p))
    try:
        st = os.stat(real)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise UserError(f"{option} {s}: cannot use this path: {exc.strerror or exc}") from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise UserError(f"{option} {s}: is a folder; give a file name")
        if _special(st):
            if not os.access(real, os.W_OK):
                raise UserError(f"{option} {s}: is not writable")
            return p
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"{option} {s}: is neither a regular file, a FIFO nor a device")
    folder = real.parent
    if not folder.exists():
        raise UserError(f"{option} {s}: folder {p.parent} does not exist")
    if not folder.is_dir():
        raise UserError(f"{option} {s}: {p.parent} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"{option} {s}: folder {p.parent} is not writable")
    return p


# --------------------------------------------------------------------------- writing


def _target(path: str | Path) -> tuple[Path, os.stat_result | None]:
    real = Path(os.path.realpath(Path(path)))  # a symlink is written through to its target
    try:
        return real, os.stat(real)
    except FileNotFoundError:
        return real, None


def _write_in_place(real: Path, data: bytes, shown: str) -> None:
    try:
        with open(real, "wb", buffering=0) as f:
            view = memoryview(data)
            while view:
                n = f.write(view)
                view = view[n:]
    except OSError as exc:
        raise OutputError(f"cannot write {shown}: {exc.strerror or exc}") from None


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path``: atomically for a regular file (temporary file in the same
    folder, fsync, ``os.replace``), in place for a FIFO or device, to stdout for ``-``, through
    a symlink to its target. Raises :class:`OutputError` on a write error."""
    shown = str(path)
    if shown == STDOUT:
        try:
            sys.stdout.flush()
            out = getattr(sys.stdout, "buffer", None)
            if out is not None:
                out.write(data)
            else:
                sys.stdout.write(data.decode("utf-8"))
            sys.stdout.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OutputError(f"cannot write to standard output: {exc.strerror or exc}") from None
        return
    real, st = _target(path)
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputError(f"cannot write {shown}: is a folder")
    if st is not None and not stat.S_ISREG(st.st_mode):
        _write_in_place(real, data, shown)
        return
    try:
        fd, tmp = tempfile.mkstemp(dir=real.parent, prefix=f".{real.name}.", suffix=".partial")
    except OSError as exc:
        raise OutputError(f"cannot write {shown}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if st is not None:
            os.chmod(tmp, stat.S_IMODE(st.st_mode))  # keep the replaced file's permissions
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)  # as open() would have created it
        os.replace(tmp, real)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {shown}: {exc.strerror or exc}") from None
        raise


def write_text_atomic(path: str | Path, text: str) -> None:
    """:func:`write_bytes_atomic` of UTF-8 text."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | Path, data: Any, inf_as_string: bool = False) -> None:
    """Strict JSON (:func:`dumps_strict`) written with :func:`write_bytes_atomic`."""
    write_text_atomic(path, dumps_strict(data, inf_as_string=inf_as_string))


def replace_into(tmp: str | Path, path: str | Path) -> None:
    """Move a finished temporary file ``tmp`` to ``path`` the way :func:`write_bytes_atomic`
    would: ``os.replace`` onto a regular file (or a symlink's target), a copy into a FIFO or
    device (then ``tmp`` is removed), never replacing what is not a regular file. For writers
    that must produce their own temporary file (recordings, videos)."""
    real, st = _target(path)
    if st is not None and not stat.S_ISREG(st.st_mode) and not stat.S_ISDIR(st.st_mode):
        try:
            with open(tmp, "rb") as src, open(real, "wb") as dst:
                shutil.copyfileobj(src, dst)
        except OSError as exc:
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
        finally:
            Path(tmp).unlink(missing_ok=True)
        return
    try:
        os.replace(tmp, real)
    except OSError as exc:
        if exc.errno == errno.EXDEV:  # a symlink into another file system: copy there, then replace
            try:
                write_bytes_atomic(real, Path(tmp).read_bytes())
            finally:
                Path(tmp).unlink(missing_ok=True)
            return
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
