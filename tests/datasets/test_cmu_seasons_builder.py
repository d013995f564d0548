"""The cmu_seasons TFDS builder on a tiny synthetic world (Sec. IV-A-1, Fig. 9).

Its own module: rendering and pose-verified labelling of the CMU world take the longest of
the three builders (about 30 s on the shared 2-core machine).
"""

from __future__ import annotations

import pytest

pytest.importorskip("tensorflow_datasets")

from rp_jax.schedule import load_spec, preset
from tests.datasets._tiny import all_records, build_tiny, check_records, shared_data_dir


def test_cmu_seasons_tiny_splits_by_slice(tmp_path_factory):
    b = build_tiny("cmu_seasons", shared_data_dir(tmp_path_factory))
    spec = load_spec("cmu_seasons")["splits"]
    assert set(b.info.splits) == {"train", "test"}
    for split in ("train", "test"):
        records = all_records(b, split)
        assert records
        slices = {int(r["viewpoint"].decode().split("/")[0][5:]) for r in records}
        assert slices <= set(spec[split])
        check_records(records, 12, preset("cmu_seasons"))
        # Category ids from the (undistorted) segmentation maps.
        assert any(r["category"] >= 0 for r in records)
