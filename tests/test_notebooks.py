"""Every notebook runs headless at reduced size (GLINT_NB_SMALL=1) and raises nothing."""
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="needs nbformat (the dev extra; absent on the GPU machine)")
NotebookClient = pytest.importorskip("nbclient", reason="needs nbclient (the dev extra)").NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, monkeypatch):
    monkeypatch.setenv("GLINT_NB_SMALL", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors


def test_notebooks_follow_the_skeleton():
    assert len(NOTEBOOKS) >= 2
    for path in NOTEBOOKS:
        text = "\n".join(c.source for c in nbformat.read(path, as_version=4).cells if c.cell_type == "markdown")
        for heading in ("**What you will learn**", "## Setup", "## Parameters", "## Steps", "## See also"):
            assert heading in text, f"{path.name}: missing '{heading}'"
        assert not any(c.get("outputs") for c in nbformat.read(path, as_version=4).cells if c.cell_type == "code"), \
            f"{path.name}: commit notebooks without outputs"
