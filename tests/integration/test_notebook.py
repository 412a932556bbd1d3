"""examples/quickstart.ipynb runs headless from top to bottom (issue 19), with nbclient and the
ipykernel of the running interpreter (its environment, PYTHONPATH included, is the kernel's)."""

from __future__ import annotations

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "quickstart.ipynb"


@pytest.mark.slow
def test_quickstart_notebook_runs_headless(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # raises CellExecutionError on the first failing cell
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    text = "".join(o.get("text", "") for o in outputs if o.get("output_type") == "stream")
    assert "scenario circle" in text and "minimum separation" in text
    assert any("image/png" in o.get("data", {}) for o in outputs), "no matplotlib figure"
    rrd = tmp_path / "circle.rrd"
    assert rrd.exists() and rrd.read_bytes()[:4] == b"RRF2"
    # the inline viewer where rerun-notebook is installed, else the line that says how to open it
    assert "swarm-mj view circle.rrd --web" in text or any(
        "application/vnd.jupyter.widget-view+json" in o.get("data", {}) for o in outputs
    )
