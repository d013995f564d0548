"""Labelling on Apache Beam (DirectRunner, 2 worker processes) gives the records of a local build.

apache-beam pins protobuf and pyarrow below the project's, so it lives in its own
environment: ``make test-beam`` makes ``.venv-beam`` (the beam extra, layered on ``.venv``)
and runs this file there (``.ci/run`` calls it after ``make test``). In an environment without
Beam the tests skip, unless ``RP_JAX_REQUIRE_BEAM=1`` (set by ``make test-beam``) makes the
missing package an error.

Each tiny synthetic dataset is built twice from one rendered world into two data dirs (so
the Beam build labels everything itself, reading no ground-truth cache of the other): once
as ``python -m rp_jax.datasets build ... --beam-pipeline-options=...`` runs it (the
features of every image first, then one job per block of a viewpoint's source images), once
locally (in one process, viewpoint by viewpoint), and the two are compared record for
record.
"""

from __future__ import annotations

import importlib.util
import os
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from rp_jax.datasets import loading
from rp_jax.datasets.__main__ import main as datasets_main
from tests.datasets._tiny import TINY, all_records, build_tiny

BEAM_OPTIONS = "runner=DirectRunner,direct_num_workers=2,direct_running_mode=multi_processing"
HAVE_BEAM = bool(os.environ.get("RP_JAX_REQUIRE_BEAM")) or (
    importlib.util.find_spec("apache_beam") is not None)


@pytest.mark.skipif(HAVE_BEAM, reason="apache-beam is installed here")
def test_without_beam_the_flag_says_what_to_install(tmp_path, capsys):
    code = datasets_main(["build", "webcam_clipart", "--size", "tiny", "--data-dir",
                          str(tmp_path), "--beam-pipeline-options", BEAM_OPTIONS])
    assert code == 2
    assert "needs apache-beam" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # stopped before rendering or building anything


@pytest.mark.slow
@pytest.mark.skipif(not HAVE_BEAM, reason="Beam has its own environment: make test-beam")
@pytest.mark.parametrize("name", ["webcam_clipart", "cmu_seasons"])
def test_beam_build_equals_the_local_build_record_for_record(name, tmp_path):
    world = tmp_path / "synthetic" / f"{name}_tiny"
    local = build_tiny(name, tmp_path / "local", synthetic_root=world)

    beam_dir = tmp_path / "beam"
    code = datasets_main(["build", name, "--size", "tiny", "--data-dir", str(beam_dir),
                          "--synthetic-root", str(world), "--beam-pipeline-options", BEAM_OPTIONS])
    assert code == 0
    beam = loading.get_builder(name, config=TINY, data_dir=beam_dir)
    assert beam.is_prepared()
    # Labelled by the pipeline, not read from the local build's ground-truth cache.
    caches = [Path(b._data_dir_root) / "downloads" / "groundtruth" / name / TINY
              for b in (local, beam)]
    assert caches[0] != caches[1] and any(caches[1].rglob("labels/*/*"))
    # The pipeline's unit is a block of a viewpoint's source images: a Webcam viewpoint
    # (10 images, 8 sources per block) was labelled as two blocks, maybe by two workers.
    blocks = Counter(f.parent.name for f in caches[1].glob("labels/*/*.blocks/*.npz"))
    if name == "webcam_clipart":
        assert blocks and set(blocks.values()) == {2}

    assert set(beam.info.splits) == set(local.info.splits)
    for split in local.info.splits:
        want, got = all_records(local, split), all_records(beam, split)
        assert len(got) == len(want) > 0
        for i, (a, b) in enumerate(zip(want, got)):
            assert a.keys() == b.keys()
            for key in a:
                np.testing.assert_array_equal(b[key], a[key], err_msg=f"{split}[{i}].{key}")
