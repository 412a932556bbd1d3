"""Every function of swarm_mj/ with more than LIMIT parameters (the team rule: at most 20).

Usage: python tools/max_params.py [LIMIT]; prints path:line name count for each, exit 1 if any.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path


def too_many(root: Path, limit: int) -> list[tuple[str, int, str, int]]:
    """(path, line, function name, parameter count) of each function over ``limit`` parameters."""
    out = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                a = node.args
                count = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
                if count > limit:
                    out.append((str(path), node.lineno, getattr(node, "name", "<lambda>"), count))
    return out


def main() -> int:
    limit = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    root = Path(__file__).resolve().parent.parent / "swarm_mj"
    found = too_many(root, limit)
    for path, line, name, count in found:
        print(f"{path}:{line} {name} {count}")
    print(f"{len(found)} function(s) with more than {limit} parameters under {root}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
