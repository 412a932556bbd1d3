"""``swarm-mj`` command line: thin — parse, call, print (docs/design.md, "Commands").

Each subcommand lives in ``swarm_mj/commands/<name>.py`` with ``add_parser(subparsers)``
and ``main(args) -> int``. Errors: a :class:`~swarm_mj.errors.UserError` prints one line
and exits 2; a divergence or missing renderer prints one line and exits 1; Ctrl-C exits 130.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import signal
import sys
from collections.abc import Iterator

from . import __version__
from .errors import SwarmError

COMMANDS = ["run", "list", "tune", "video", "sweep", "stress", "report", "view", "warm-up", "validate", "export"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="swarm-mj",
        description="MuJoCo quadrotor swarm: backstepping control, FPA gain tuning, pentagon formation, "
        "anti-collision and wind. Try: swarm-mj run circle",
    )
    parser.add_argument("--version", action="version", version=f"swarm-mj {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = name.replace("-", "_")  # warm-up: commands/warm_up.py
        try:
            mod = importlib.import_module(f".commands.{module}", __package__)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.endswith(f"commands.{module}"):
                continue  # subcommand not shipped in this build
            raise
        mod.add_parser(sub)
    return parser


@contextlib.contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Ctrl-C while modules load (C extensions such as MuJoCo's must not be interrupted half-way)
    is held until the block ends, then raised as KeyboardInterrupt."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield  # ignored (a worker) or handled by someone else
        return
    caught: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if caught:
        raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    try:
        with _sigint_deferred():
            parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 0
        with _sigint_deferred():
            from .video.gl import import_mujoco

            import_mujoco()  # a MUJOCO_GL backend that cannot load: fly anyway, fail rendering in one line
    except KeyboardInterrupt:  # Ctrl-C while the program loads
        print("swarm-mj: interrupted", file=sys.stderr)
        return 130
    try:
        return int(args.func(args) or 0)
    except SwarmError as exc:
        print(f"swarm-mj: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("swarm-mj: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
