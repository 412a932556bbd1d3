"""MuJoCo's own ``mj_step``, callable from a compiled kernel (the chunk driver, docs/design.md).

A control loop that calls ``mujoco.mj_step`` from Python pays the interpreter between every
physics step. :func:`step_call` is a Numba intrinsic that calls the C function ``mj_step(m, d)``
of the ``libmujoco`` the Python bindings loaded, given its address and the addresses of the
``mjModel`` and ``mjData`` (``MjModel._address``, ``MjData._address``). It is the same function on
the same memory, so the physics is MuJoCo's, bit for bit (a test steps both ways and compares).
The addresses are arguments, not constants, so a kernel that uses it stays in Numba's cache.

:func:`ncon_view` gives a one-element int32 view of ``mjData.ncon`` (the contact count a kernel must
read after each step to hand contacts back to Python); its offset is taken from the struct
layout and verified against ``MjData.ncon`` on a probe model with and without contacts. Anything
unexpected (no Numba, a library not found, a layout that does not verify) makes :func:`available`
False, and the caller flies the per-step Python path instead.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import os
from collections.abc import Iterator

import mujoco
import numpy as np

from .. import _jit

__all__ = ["available", "mj_step_address", "ncon_view", "profiler_paused", "step_call", "timer_pause", "timer_resume"]

if _jit.AVAILABLE:  # pragma: no branch - numba is a dependency
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def step_call(typingctx, fn, m, d):  # noqa: ARG001
        """``fn(m, d)`` for the C function at address ``fn`` taking two pointers (``mj_step``)."""
        if not all(isinstance(x, types.Integer) for x in (fn, m, d)):
            return None
        sig = types.void(fn, m, d)

        def codegen(context, builder, signature, args):  # noqa: ARG001
            f, pm, pd = args
            vp = ir.IntType(8).as_pointer()
            fnty = ir.FunctionType(ir.VoidType(), [vp, vp])
            callee = builder.inttoptr(f, fnty.as_pointer())
            builder.call(callee, [builder.inttoptr(pm, vp), builder.inttoptr(pd, vp)])
            return context.get_dummy_value()

        return sig, codegen

else:  # pragma: no cover

    def step_call(fn, m, d):  # type: ignore[misc]
        raise RuntimeError("mj_step from a kernel needs numba")


def _library_paths() -> list[str]:
    here = os.path.dirname(mujoco.__file__)
    names = ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll")
    return sorted(p for pat in names for p in glob.glob(os.path.join(here, pat)))


@functools.cache
def mj_step_address() -> int | None:
    """The address of ``mj_step`` in the libmujoco next to the bindings (None if not found)."""
    for path in _library_paths():
        try:
            lib = ctypes.CDLL(path)
            return int(ctypes.cast(lib.mj_step, ctypes.c_void_p).value or 0) or None
        except (OSError, AttributeError):
            continue
    return None


@functools.cache
def _time_callback() -> ctypes.c_void_p | None:
    """MuJoCo's global ``mjcb_time`` (a function pointer) in the libmujoco the bindings loaded, or None."""
    for path in _library_paths():
        try:
            return ctypes.c_void_p.in_dll(ctypes.CDLL(path), "mjcb_time")
        except (OSError, ValueError):
            continue
    return None


def timer_pause() -> int | None:
    """Switch MuJoCo's profiling timers off; returns what :func:`timer_resume` restores.

    MuJoCo times each stage of ``mj_step`` (``mjData.timer``) only while the global callback
    ``mjcb_time`` is set, and the Python bindings set it (to a steady clock) whenever an ``MjData``
    is made. Its clock reads cost about a tenth of a six-drone step (measured: 46.8 against 42.0 µs,
    docs/design.md, "Start-up and the step's own cost"); they change nothing in the physics. So the
    simulator's steps run with it unset and leave ``mjData.timer`` as it was.
    """
    cb = _time_callback()
    if cb is None:
        return None
    saved = cb.value
    cb.value = None
    return saved


def timer_resume(saved: int | None) -> None:
    """Put back the ``mjcb_time`` that :func:`timer_pause` returned (a no-op for None)."""
    cb = _time_callback()
    if cb is not None and saved is not None:
        cb.value = saved


@contextlib.contextmanager
def profiler_paused() -> Iterator[None]:
    """MuJoCo's profiling timers off inside the block (:func:`timer_pause`), restored after."""
    saved = timer_pause()
    try:
        yield
    finally:
        timer_resume(saved)


def _ncon_offset_unchecked(data: mujoco.MjData) -> int:
    """Byte offset of ``ncon`` in mjData: the field right after the ``timer`` array (mjdata.h)."""
    timer = data.timer.duration  # (mjNTIMER,) a view into the struct, one mjTimerStat per stride
    return int(timer.ctypes.data - data._address + len(timer) * timer.strides[0])


def _view(data: mujoco.MjData, offset: int) -> np.ndarray:
    return np.ctypeslib.as_array((ctypes.c_int32 * 1).from_address(data._address + offset))


@functools.cache
def _ncon_offset() -> int | None:
    """The verified offset: on a probe model, the view reads ``MjData.ncon`` with 0 and with 2 contacts."""
    xml = """<mujoco><worldbody><geom type="plane" size="1 1 .1"/>
      <body pos="0 0 .05"><freejoint/><geom size=".1"/></body>
      <body pos="0 0 .5"><freejoint/><geom size=".1"/></body></worldbody></mujoco>"""
    try:
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        off = _ncon_offset_unchecked(d)
        seen = []
        for z in (0.5, 0.12):  # apart: 1 contact (sphere on the plane); touching: 2
            d.qpos[9] = z
            mujoco.mj_forward(m, d)
            seen.append((int(_view(d, off)[0]), int(d.ncon)))
        d.qpos[2], d.qpos[9] = 0.8, 0.4  # both in the air, apart: none
        mujoco.mj_forward(m, d)
        seen.append((int(_view(d, off)[0]), int(d.ncon)))
    except Exception:  # noqa: BLE001 - any surprise: no chunk driver
        return None
    ok = all(a == b for a, b in seen) and sorted({b for _, b in seen}) == [0, 1, 2]
    return off if ok else None


def ncon_view(data: mujoco.MjData) -> np.ndarray | None:
    """A live (1,) int32 view of ``data.ncon`` (keep ``data`` alive while it is used), or None."""
    off = _ncon_offset()
    return None if off is None else _view(data, off)


def available() -> bool:
    """A kernel can step MuJoCo here: Numba compiles, ``mj_step`` is found, ``ncon`` verifies."""
    return _jit.AVAILABLE and mj_step_address() is not None and _ncon_offset() is not None
