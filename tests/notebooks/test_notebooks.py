"""The notebooks run top to bottom (short horizons: ``CMANIP_NOTEBOOK_QUICK=1``)."""

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"


@pytest.mark.notebook
@pytest.mark.parametrize("name", ["mpf_walkthrough", "closed_loop_episode",
                                  "latdespot_walkthrough", "configest_walkthrough"])
def test_notebook_runs(name, monkeypatch):
    monkeypatch.setenv("CMANIP_NOTEBOOK_QUICK", "1")
    notebook = nbformat.read(NOTEBOOKS / f"{name}.ipynb", as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(NOTEBOOKS)}}).execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    assert any(o.output_type == "stream" for o in outputs)
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the plots were drawn
