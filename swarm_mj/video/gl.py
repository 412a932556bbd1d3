"""OpenGL for headless rendering: which backend MuJoCo uses (MUJOCO_GL), EGL probing, one-line failures.

MuJoCo reads ``MUJOCO_GL`` once, when it is imported (docs/libraries.md): ``swarm_mj`` sets it to
``egl`` on Linux when libEGL can be opened (else ``disable``), unless the user set it. A backend
the user chose that cannot load (``MUJOCO_GL=osmesa`` without libOSMesa) makes ``import mujoco``
itself fail with an AttributeError deep in PyOpenGL; :func:`import_mujoco` (called by the command
line before any command runs) catches that, imports MuJoCo with rendering off so that the
simulation still flies and its recording is written, and remembers why, so that the first
renderer asked for raises one :class:`~swarm_mj.errors.RenderError` line (exit status 1).

This module does not import mujoco at the top, so that :func:`import_mujoco` can run first.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..errors import RenderError

if TYPE_CHECKING:
    import mujoco

# What to install when EGL is missing (Debian 12 / Ubuntu package names):
#   libegl1          libEGL.so.1, the GLVND EGL loader PyOpenGL opens
#   libegl-mesa0     Mesa's EGL driver (the vendor libEGL loads, 50_mesa.json)
#   libgl1-mesa-dri  Mesa's DRI drivers, among them swrast (llvmpipe) for CPU rendering
#   libopengl0       libOpenGL.so.0, the GL entry points PyOpenGL loads with EGL
EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0"


#: (MUJOCO_GL value, exception) when MuJoCo could not be imported with the backend the user chose.
IMPORT_FAILURE: tuple[str, BaseException] | None = None


def import_mujoco() -> None:
    """Import MuJoCo; if the chosen MUJOCO_GL backend cannot load, import it with rendering off.

    Simulation never needs OpenGL, so a run still flies; rendering then fails in one line
    (:func:`describe_import_failure`). A no-op when MuJoCo is already imported.
    """
    global IMPORT_FAILURE
    if "mujoco" in sys.modules:
        return
    try:
        import mujoco  # noqa: F401

        return
    except Exception as exc:  # noqa: BLE001 - e.g. AttributeError from PyOpenGL without libOSMesa
        backend = os.environ.get("MUJOCO_GL", "").strip().lower()
        if backend in ("", "disable", "disabled", "off", "false", "0"):
            raise  # not a rendering backend problem
        IMPORT_FAILURE = (backend, exc)
    for name in [m for m in sys.modules if m.split(".")[0] in ("mujoco", "OpenGL")]:
        del sys.modules[name]  # the half-imported backend
    os.environ["MUJOCO_GL"] = "disable"
    os.environ.pop("PYOPENGL_PLATFORM", None)
    import mujoco  # noqa: F401,F811


def describe_import_failure() -> str:
    """One line: MuJoCo could not load the MUJOCO_GL backend the user chose, and what to do."""
    assert IMPORT_FAILURE is not None
    backend, exc = IMPORT_FAILURE
    text = re.sub(r"\s+", " ", " ".join(str(a) for a in getattr(exc, "args", ()) if a)).strip()
    head = f"cannot render: MuJoCo could not load MUJOCO_GL={backend} ({type(exc).__name__}: {text})"
    if backend == "egl":
        return f"{head}; fix: apt-get install {EGL_PACKAGES} (Debian/Ubuntu) or install a GPU driver with EGL"
    hint = {
        "osmesa": "its library libOSMesa is not installed (apt-get install libosmesa6)",
        "glfw": "GLFW needs a display",
    }.get(backend, "it did not load")
    return f"{head}: {hint}; for headless rendering set MUJOCO_GL=egl (apt-get install {EGL_PACKAGES})"


def mujoco_gl_backend() -> str:
    """The OpenGL backend MuJoCo chose when it was imported (MUJOCO_GL read at that time)."""
    try:
        from mujoco.rendering.classic import gl_context

        return str(getattr(gl_context, "_MUJOCO_GL", os.environ.get("MUJOCO_GL", ""))).strip().lower()
    except Exception:  # pragma: no cover - another mujoco layout
        return os.environ.get("MUJOCO_GL", "").strip().lower()


def libegl_loadable() -> bool:
    """Whether the dynamic loader can open libEGL.so.1 (Debian package libegl1)."""
    import ctypes

    try:
        ctypes.CDLL("libEGL.so.1")
    except OSError:
        return False
    return True


HEADLESS_BACKENDS = ("egl", "disable", "disabled", "off", "false", "0")


def describe_gl_failure(exc: BaseException) -> str:
    """One line: why the renderer could not start, and what to do about it."""
    backend = mujoco_gl_backend()
    text = " ".join(str(a) for a in getattr(exc, "args", ()) if a) or type(exc).__name__
    text = re.sub(r"\s+", " ", text).strip()
    low = text.lower()
    fix = (
        f"fix: apt-get install {EGL_PACKAGES} (Debian/Ubuntu; Mesa renders on the CPU) or install a GPU driver with EGL"
    )
    head = "headless rendering needs EGL (MUJOCO_GL=egl) and it failed"
    if (
        sys.platform.startswith("linux")
        and backend in HEADLESS_BACKENDS
        and ("unable to load egl library" in low or not libegl_loadable())
    ):
        return f"{head}: the EGL library libEGL.so.1 is not installed; {fix}"
    if backend != "egl":
        return (
            f"cannot render: MuJoCo was imported with MUJOCO_GL={backend or '(unset)'} and that failed "
            f"({type(exc).__name__}: {text}); for headless rendering set MUJOCO_GL=egl before anything "
            f"imports mujoco (or import swarm_mj first), and {fix}"
        )
    if "egl device display" in low or "eglquerydevicesext" in low or "eglgetplatformdisplayext" in low:
        cause = "EGL found no driver that can render (Mesa's EGL and DRI drivers, or a GPU driver)"
    elif "pyopengl" in low or "no module named 'opengl'" in low:
        cause = "PyOpenGL is missing"
        fix = "fix: pip install pyopengl"
    else:
        cause = f"{type(exc).__name__}: {text}"
    return f"{head}: {cause}; {fix}"


def _default_renderer_factory(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    import mujoco

    return mujoco.Renderer(model, height=height, width=width, max_geom=20000)


# Replaced in tests to simulate a machine without EGL.
renderer_factory: Callable[[mujoco.MjModel, int, int], mujoco.Renderer] = _default_renderer_factory


def open_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A :class:`mujoco.Renderer` of ``width`` x ``height``, or :class:`RenderError` in one line.

    Grows the model's offscreen buffer when the image is larger than it. Mesa's own
    warnings are silenced (``EGL_LOG_LEVEL=fatal`` unless set): the error says it all.
    """
    import mujoco

    if IMPORT_FAILURE is not None:
        raise RenderError(describe_import_failure())
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), int(width))
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), int(height))
    os.environ.setdefault("EGL_LOG_LEVEL", "fatal")
    try:
        renderer = renderer_factory(model, width, height)
    except (ImportError, OSError, RuntimeError, AttributeError, mujoco.FatalError) as exc:
        raise RenderError(describe_gl_failure(exc)) from exc
    except Exception as exc:  # e.g. a GLError from PyOpenGL: still a renderer that cannot start
        if type(exc).__module__.startswith("OpenGL"):
            raise RenderError(describe_gl_failure(exc)) from exc
        raise
    return renderer
