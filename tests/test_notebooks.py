"""The notebooks run top to bottom at tiny size (so they cannot rot).

The quickstart renders a tiny synthetic world, builds labels, trains and predicts; the
exploration notebook then loads the quickstart's workdir.
"""

import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"


def _execute(name: str, env: dict, cwd: Path):
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": str(cwd)}}).execute()
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return nb


@pytest.mark.slow
def test_quickstart_then_explore(tmp_path):
    work = tmp_path / "qs"
    env = {"RP_JAX_NOTEBOOK_SIZE": "tiny", "RP_JAX_NOTEBOOK_DIR": str(work),
           "RP_JAX_WORKDIR": str(work / "run"), "RP_JAX_TFDS_DIR": str(work / "tfds"),
           "RP_JAX_NO_CPU_SETUP": "1"}
    nb = _execute("quickstart.ipynb", env, tmp_path)
    outputs = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                      for o in c.get("outputs", []))
    assert "test_mae" in outputs and "repeatability at 17:15" in outputs
    assert (work / "run" / "metrics.json").exists()
    nb = _execute("explore_predictions.ipynb", env, tmp_path)
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert len(images) >= 2
