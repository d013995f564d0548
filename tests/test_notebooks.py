"""The notebooks run top to bottom at tiny size (so they cannot rot).

The quickstart puts a shipped model on a photo, then renders a tiny synthetic world, builds
labels, trains and predicts; the exploration notebook then loads the quickstart's workdir. The
own-data notebook puts a shipped model on a photo through a day, summarizes a tiny rendered
COLMAP map for a time and localizes queries against it.
"""

import os
from pathlib import Path

import pytest

from tests.datasets._tiny import tiny_data_copy

NOTEBOOKS = Path(__file__).resolve().parent.parent / "notebooks"


def _execute(name: str, env: dict, cwd: Path):
    # Jupyter's client is imported by the tests that use it, not by every test process at
    # collection (0.3 s of CPU).
    import nbformat
    from nbclient import NotebookClient

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


def _with_tiny_world(tmp_path_factory, name: str, work: Path, world: str) -> None:
    """``work/tfds`` and ``work/<world>`` as the notebook would make them: copies of the
    session's tiny build and world of ``name`` (rendered and labelled once for every test
    that reads them; tests/datasets/ tests the builds). The notebook's ``generate`` then
    finds every frame (it skips existing ones) and its experiment the dataset built."""
    data = tiny_data_copy(tmp_path_factory, [name], work)
    (data.parent / "synthetic" / f"{name}_tiny").rename(work / world)


@pytest.mark.slow
def test_quickstart_then_explore(tmp_path, tmp_path_factory):
    work = tmp_path / "qs"
    _with_tiny_world(tmp_path_factory, "webcam_clipart", work, "synthetic/webcam_clipart")
    env = {"RP_JAX_NOTEBOOK_SIZE": "tiny", "RP_JAX_NOTEBOOK_DIR": str(work),
           "RP_JAX_WORKDIR": str(work / "run"), "RP_JAX_TFDS_DIR": str(work / "tfds"),
           "RP_JAX_NO_CPU_SETUP": "1"}
    nb = _execute("quickstart.ipynb", env, tmp_path)
    outputs = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                      for o in c.get("outputs", []))
    assert "test_mae" in outputs and "repeatability at 17:15" in outputs
    assert "Why this tiny run is not a result" in "".join(c.source for c in nb.cells)
    assert (work / "run" / "metrics.json").exists()
    nb = _execute("explore_predictions.ipynb", env, tmp_path)
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert len(images) >= 2


@pytest.mark.slow
def test_own_data(tmp_path, tmp_path_factory):
    _with_tiny_world(tmp_path_factory, "cmu_seasons", tmp_path / "od", "cmu_world")
    env = {"RP_JAX_NOTEBOOK_DIR": str(tmp_path / "od"), "RP_JAX_NO_CPU_SETUP": "1"}
    nb = _execute("own_data.ipynb", env, tmp_path)
    outputs = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                      for o in c.get("outputs", []))
    assert "keypoints; curves" in outputs and "points for 2011-07-28 15:00" in outputs
    assert "queries against" in outputs
    assert (tmp_path / "od" / "summary_jul28" / "model").is_dir()
    assert (tmp_path / "od" / "localized" / "submission.txt").exists()


@pytest.mark.parametrize("name", ["quickstart.ipynb", "explore_predictions.ipynb",
                                  "own_data.ipynb"])
def test_committed_with_outputs_small_and_colab_ready(name):
    """As committed: figures visible on the repository page, under 1 MB, and a first code
    cell that installs the package in Colab and does nothing elsewhere."""
    path = NOTEBOOKS / name
    assert path.stat().st_size < 1_000_000
    import nbformat

    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.get("execution_count") for c in code), "saved without running every cell"
    images = [o for c in code for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(images) >= 2
    assert not [o for c in code for o in c.get("outputs", []) if o.output_type == "error"]
    first = code[0].source
    assert 'if "google.colab" in sys.modules:' in first and "pip" in first
    # Outside Colab the cell does nothing: running it here installs nothing and raises nothing.
    exec(compile(first, name, "exec"), {})  # noqa: S102
    if name == "explore_predictions.ipynb":
        # The keypoints are drawn on the image itself.
        assert any("ax.imshow(image)" in c.source and "ax.scatter" in c.source for c in code)
