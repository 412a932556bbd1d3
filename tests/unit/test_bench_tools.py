"""The benchmark tools of issue 30: tools/accuracy.py keeps docs/physics_step.md's hand-written tail,
and tools/bench_step_contacts.py's summary counts what each run reports. tools/bench_peers.py's crazyflow
flight: tests/integration/test_bench_tools_runs.py. tools/golden.py's comparison (issue 48)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parents[2] / "tools"


def _tool(name: str):
    spec = importlib.util.spec_from_file_location(f"_test_tool_{name}", TOOLS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(TOOLS))
    try:
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(TOOLS))
    return mod


def test_accuracy_docs_keep_the_hand_written_tail(tmp_path):
    acc = _tool("accuracy")
    page = tmp_path / "physics_step.md"
    assert acc.keep_hand_written(str(page), "generated\n") == "generated\n"  # no file yet
    page.write_text("old generated\n\n" + acc.KEPT_MARK + "\n\n## Measured by hand\n")
    out = acc.keep_hand_written(str(page), "new generated\n")
    assert out == "new generated\n\n" + acc.KEPT_MARK + "\n\n## Measured by hand\n"
    page.write_text("old generated, no mark\n")
    assert acc.keep_hand_written(str(page), "new\n") == "new\n"


def test_the_repository_page_has_the_mark():
    acc = _tool("accuracy")
    text = (TOOLS.parent / "docs" / "physics_step.md").read_text()
    assert text.count(acc.KEPT_MARK) == 1


def test_step_contacts_summary_sums_each_step():
    sc = _tool("bench_step_contacts")
    rows = [
        {"seed": 0, "timestep_s": 0.005, "contacts": 3, "contact_steps": 10, "pairs": 2, "stopped": True},
        {"seed": 0, "timestep_s": 0.01, "contacts": 2, "contact_steps": 4, "pairs": 2, "stopped": True},
        {"seed": 1, "timestep_s": 0.005, "contacts": 0, "contact_steps": 0, "pairs": 0, "stopped": False},
        {"seed": 1, "timestep_s": 0.01, "contacts": 1, "contact_steps": 1, "pairs": 1, "stopped": False},
    ]
    s = sc.summarize(rows)
    assert s["5 ms"] == {
        "starts": 2,
        "seeds_with_contact": [0],
        "contacts": 3,
        "contact_steps": 10,
        "pairs": 2,
        "stopped": 1,
    }
    assert s["10 ms"]["seeds_with_contact"] == [0, 1] and s["10 ms"]["contact_steps"] == 5


def test_golden_compare_finds_a_changed_number_and_ignores_timing(tmp_path):
    """tools/golden.py (issue 48's bit-for-bit bar): a number moved by more than 1e-9 is a difference,
    one within it or a timing key is not, a missing summary is one, and a new key in NEW is allowed."""
    golden = _tool("golden")
    base, new = tmp_path / "base", tmp_path / "new"
    base.mkdir()
    new.mkdir()
    summary = {"drones": {"leader": {"rmse": [0.25, 1.0e-3]}}, "wall_time_s": 2.0, "rule": "layers"}
    (base / "a.json").write_text(golden.json.dumps(summary))
    (base / "b.json").write_text(golden.json.dumps(summary))
    same = {**summary, "drones": {"leader": {"rmse": [0.25 + 1e-12, 1.0e-3]}}, "wall_time_s": 9.0, "extra": 1}
    (new / "a.json").write_text(golden.json.dumps(same))
    assert golden.compare(base, new) == ["b.json: not written"]
    moved = {**summary, "drones": {"leader": {"rmse": [0.25, 1.1e-3]}}}
    (new / "b.json").write_text(golden.json.dumps(moved))
    assert golden.compare(base, new) == ["b.json.drones.leader.rmse[1]: 0.001 vs 0.0011"]
    assert golden.differences({"rule": "layers"}, {"rule": "barrier"}) == [".rule: 'layers' vs 'barrier'"]
