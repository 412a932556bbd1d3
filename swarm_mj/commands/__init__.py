"""Subcommands of ``swarm-mj`` (one module each: ``add_parser(sub)`` and ``main(args)``)."""
