"""``swarm-mj list``: the bundled scenarios with a one-line description."""

from __future__ import annotations

import argparse
import tomllib


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list the bundled scenarios")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..scenario import bundled_scenarios

    found = bundled_scenarios()
    width = max((len(n) for n in found), default=0)
    for name, path in found.items():
        try:
            desc = tomllib.loads(path.read_text()).get("description", "")
        except (tomllib.TOMLDecodeError, OSError) as exc:
            desc = f"(unreadable: {exc})"
        print(f"{name:<{width}}  {desc}")
    return 0
