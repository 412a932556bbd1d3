"""Subcommands of ``swarm-mj`` (one module each: ``add_parser(sub)`` and ``main(args)``)."""

#: The anti-collision rules the command line offers: ``auto`` (the default: ``barrier`` where the
#: physics has downwash, ``layers`` under the paper's) and the keys of
#: ``swarm_mj.formation.anticollision.ANTI_COLLISION_RULES``, which a test keeps equal; written
#: here so that building the parser does not import the simulator.
RULE_NAMES = ("auto", "layers", "paper", "off", "jet-aware", "barrier", "stagger")
#: The physics presets (``swarm_mj.physics.aero.presets.AERO_MODELS``, kept equal by a test).
AERO_NAMES = ("paper", "realistic")
#: The sensing presets (``swarm_mj.sensing.params.PRESETS``' keys, kept equal by a test; docs/sensing.md).
SENSING_NAMES = ("perfect", "mocap", "uwb")

#: Exit statuses of every command (README, "Exit status"; ``swarm-mj run --help``'s epilog).
EXIT_OK = 0
EXIT_ERROR = 1  # a run stopped early (diverged), an output or the renderer failed
EXIT_USER = 2  # a user mistake: one line, before anything flies
EXIT_FLIGHT_FAILED = 3  # flew to the end, but a drone never took off, crashed or was lost; or no tune candidate flew
EXIT_INTERRUPTED = 130  # Ctrl-C

#: The exit statuses as ``--help`` epilogs print them.
EXIT_EPILOG = (
    "exit status: 0 the flight did what was asked; 1 the run stopped early (diverged) or an output failed; "
    "2 a user mistake (one line, nothing flown); 3 the run flew to its end but a drone never took off, "
    "crashed or was lost (one line says which); 130 interrupted."
)


def add_vehicle_argument(p, *, default: str = "the scenario's") -> None:  # noqa: ANN001 - an argparse parser
    """``--vehicle NAME|FILE`` and ``--gains FILE``, the same options in ``run``, ``video``, ``sweep`` and
    ``stress`` (the rule is :mod:`swarm_mj.choices`); ``default``: the vehicle flown without ``--vehicle``."""
    p.add_argument(
        "--vehicle",
        metavar="NAME|FILE",
        help=f"the drones flown: a bundled vehicle (paper, crazyflie21) or a vehicle file (default: {default}; "
        "docs/vehicles.md), with its own gains unless --gains or the scenario names some",
    )
    p.add_argument(
        "--gains",
        metavar="FILE",
        help="gains file (as written by 'swarm-mj tune'; default: the scenario's, else the vehicle's, else Table 4)",
    )


def add_sensing_argument(p) -> None:  # noqa: ANN001 - an argparse parser
    """``--sensing PRESET``, the same option in ``run``, ``video``, ``sweep`` and ``stress``: it replaces
    the scenario's ``[sensing]`` table as a whole (:func:`swarm_mj.scenario_sensing.sensing_overrides`)."""
    p.add_argument(
        "--sensing",
        choices=SENSING_NAMES,
        metavar="PRESET",
        help="what each drone knows of the others: perfect (default, the oracle), mocap, uwb; docs/sensing.md",
    )


def flown_scenario(args, scenario=None):  # noqa: ANN001, ANN201 - argparse args; a Scenario
    """The scenario ``args.scenario`` (or ``scenario``) with ``--vehicle``, ``--aero``, ``--gains`` and
    ``--sensing`` applied by the one rule of :func:`swarm_mj.scenario.flown` (errors name the options)."""
    from ..scenario import flown

    return flown(
        args.scenario if scenario is None else scenario,
        vehicle=getattr(args, "vehicle", None),
        aero=getattr(args, "aero", None),
        gains=getattr(args, "gains", None),
        sensing=getattr(args, "sensing", None),
        where=("--vehicle", "--aero", "--gains", "--sensing"),
    )
