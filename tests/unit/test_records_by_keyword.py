"""Records are built by keyword (issue 48): no positional call of a record class with more than
:data:`MAX_POSITIONAL` fields anywhere in swarm_mj/, so that a reordered field can never pass a wrong
value silently. The records are found, not listed: every ``typing.NamedTuple`` and every dataclass
defined in swarm_mj/; a call is traced to its class through the imports (aliases and re-exports
included), ``cls(...)`` in a record's own classmethods, and ``Cls._make(...)`` (positional by nature)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "swarm_mj"
#: A record of more fields than this is built by keyword only.
MAX_POSITIONAL = 3


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_dataclass(node: ast.ClassDef) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name == "dataclass":
            return True
    return False


def _fields(node: ast.ClassDef) -> int | None:
    """The number of fields of a NamedTuple or dataclass class definition, else None."""
    named = any(getattr(b, "id", getattr(b, "attr", "")) == "NamedTuple" for b in node.bases)
    if not (named or _is_dataclass(node)):
        return None
    n = 0
    for stmt in node.body:
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
            if "ClassVar" not in ast.unparse(stmt.annotation):
                n += 1
    return n


class _Module:
    def __init__(self, path: Path, source: str | None = None) -> None:
        self.path = path
        self.name = _module_name(path)
        self.package = self.name if path.name == "__init__.py" else self.name.rpartition(".")[0]
        self.tree = ast.parse(path.read_text() if source is None else source, str(path))
        self.classes: dict[str, int] = {}  # record classes defined here: name -> fields
        self.names: dict[str, tuple[str, str]] = {}  # local name -> (module, name) imported
        self.modules: dict[str, str] = {}  # local name -> module imported
        for node in ast.walk(self.tree):
            if isinstance(node, ast.ClassDef) and (n := _fields(node)) is not None:
                self.classes[node.name] = n
            elif isinstance(node, ast.ImportFrom):
                base = self._resolve(node)
                for a in node.names:
                    self.names[a.asname or a.name] = (base, a.name)
                    self.modules[a.asname or a.name] = f"{base}.{a.name}"
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.asname:
                        self.modules[a.asname] = a.name

    def _resolve(self, node: ast.ImportFrom) -> str:
        if not node.level:
            return node.module or ""
        base = self.package.split(".")
        base = base[: len(base) - node.level + 1]
        return ".".join(base + ([node.module] if node.module else []))


def _modules() -> dict[str, _Module]:
    mods = [_Module(p) for p in sorted(PACKAGE.rglob("*.py"))]
    return {m.name: m for m in mods}


def _record(mods: dict[str, _Module], module: str | _Module, name: str, depth: int = 0) -> tuple[str, int] | None:
    """(qualified name, fields) of the record ``name`` means in ``module``, following imports."""
    mod = mods.get(module) if isinstance(module, str) else module
    if mod is None or depth > 10:
        return None
    if name in mod.classes:
        return f"{mod.name}.{name}", mod.classes[name]
    if name in mod.names:
        return _record(mods, *mod.names[name], depth + 1)
    return None


def _callee(mods: dict[str, _Module], mod: _Module, func: ast.expr) -> tuple[str, int] | None:
    if isinstance(func, ast.Name):
        return _record(mods, mod, func.id)
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
        target = mod.modules.get(func.value.id)
        return _record(mods, target, func.attr) if target else None
    return None


def positional(mods: dict[str, _Module]) -> list[tuple[_Module, ast.Call, str, int]]:
    """Every positional construction of a record: (module, call, the record's qualified name, its fields)."""
    found = []
    for mod in mods.values():
        record_classes = [n for n in ast.walk(mod.tree) if isinstance(n, ast.ClassDef) and n.name in mod.classes]
        for cls in record_classes:  # cls(...) in the record's own methods
            for node in ast.walk(cls):
                if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "cls" and node.args:
                    found.append((mod, node, f"{mod.name}.{cls.name}", mod.classes[cls.name]))
        for node in ast.walk(mod.tree):
            if not isinstance(node, ast.Call):
                continue
            func = node.func
            make = isinstance(func, ast.Attribute) and func.attr == "_make"
            rec = _callee(mods, mod, func.value if make else func)  # type: ignore[attr-defined]
            if rec is not None and (make or node.args):
                found.append((mod, node, *rec))
    return found


def positional_calls() -> list[str]:
    """Every positional construction of a record of more than MAX_POSITIONAL fields: 'path:line Class'."""
    rel = PACKAGE.parent
    return sorted(
        f"{m.path.relative_to(rel)}:{node.lineno} {name} ({n} fields)"
        for m, node, name, n in positional(_modules())
        if n > MAX_POSITIONAL
    )


def test_the_finder_sees_records_and_calls():
    """The walk finds the records of pipeline/records.py, the aero and formation records (through an
    alias: ``Rule as FormedRecord``), and flags a positional call, a ``_make`` and a ``cls(...)``."""
    mods = _modules()
    for module, name in [
        ("swarm_mj.pipeline.records", "Physics"),
        ("swarm_mj.pipeline.records", "Obs"),
        ("swarm_mj.physics.aero.downwash", "DownwashRecord"),
        ("swarm_mj.formation.barrier_params", "BarrierRecord"),
        ("swarm_mj.formation.layered", "FormedRecord"),
        ("swarm_mj.physics.sim", "Physics"),
    ]:
        assert _record(mods, module, name) is not None, (module, name)
    assert _record(mods, "swarm_mj.pipeline.records", "Physics")[1] == 33
    source = (
        "from typing import NamedTuple\n"
        "from .pipeline.records import Gains as G\n"
        "from .pipeline import records\n"
        "G(1, 2, 3)\n"  # line 4: positional, through an alias
        "records.Obs._make(x)\n"  # line 5: _make, through a module
        "G(a_pos=1)\n"  # keywords: fine
        "class P(NamedTuple):\n    a: int\n    b: int\n    c: int\n    d: int\n"
        "    @classmethod\n    def zero(cls):\n        return cls(0, 0, 0, 0)\n"  # line 14: cls(...)
    )
    probe = _Module(PACKAGE / "probe.py", source)
    found = positional({**mods, probe.name: probe})
    assert sorted((node.lineno, name, n) for m, node, name, n in found if m is probe) == [
        (4, "swarm_mj.pipeline.records.Gains", 14),
        (5, "swarm_mj.pipeline.records.Obs", 14),
        (14, "swarm_mj.probe.P", 4),
    ]


def test_records_are_built_by_keyword():
    bad = positional_calls()
    assert not bad, "records built from positional arguments (use Cls(field=...)):\n" + "\n".join(bad)
