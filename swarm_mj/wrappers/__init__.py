"""Gymnasium and PettingZoo faces of :class:`~swarm_mj.env.SwarmEnv` (docs/design.md, "env").

* :class:`SwarmGymEnv` (``swarm_mj.wrappers.gymnasium``): the whole swarm as one
  ``gymnasium.Env``; also registered as ``"swarm_mj/Swarm-v0"``.
* :class:`SwarmParallelEnv` (``swarm_mj.wrappers.pettingzoo``): one agent per drone,
  a PettingZoo ``ParallelEnv``.
* :class:`SwarmVectorEnv` (``swarm_mj.wrappers.vector``): m independent swarms in batched
  MuJoCo models, a Gymnasium ``VectorEnv`` (auto-reset, per-copy seeds and termination).

Both need the ``gym`` extra (``pip install swarm-mj[gym]``). The names are imported
lazily, so ``import swarm_mj.wrappers`` works without it and only fails, with a clear
message, when a wrapper is used.
"""

from __future__ import annotations

__all__ = ["SwarmGymEnv", "SwarmParallelEnv", "SwarmVectorEnv"]

_WHERE = {"SwarmGymEnv": ".gymnasium", "SwarmParallelEnv": ".pettingzoo", "SwarmVectorEnv": ".vector"}


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    try:
        module = importlib.import_module(_WHERE[name], __name__)
    except ModuleNotFoundError as exc:
        if exc.name in ("gymnasium", "pettingzoo"):
            raise ModuleNotFoundError(f"{name} needs {exc.name}: pip install 'swarm-mj[gym]'", name=exc.name) from exc
        raise
    return getattr(module, name)
