"""Subcommands of ``swarm-mj`` (one module each: ``add_parser(sub)`` and ``main(args)``)."""

#: The anti-collision rules the command line offers: ``auto`` (the default: ``jet-aware`` where the
#: physics has downwash, ``layers`` under the paper's) and the keys of
#: ``swarm_mj.formation.anticollision.ANTI_COLLISION_RULES``, which a test keeps equal; written
#: here so that building the parser does not import the simulator.
RULE_NAMES = ("auto", "layers", "paper", "off", "jet-aware", "barrier", "barrier-lanes")
#: The physics presets (``swarm_mj.physics.aero.presets.AERO_MODELS``, kept equal by a test).
AERO_NAMES = ("paper", "realistic")
