"""The cmu_seasons TFDS builder on a tiny synthetic world (Sec. IV-A-1, Fig. 9).

Its own module: rendering and pose-verified labelling of the CMU world take the longest of
the three builders (about 30 s on the shared 2-core machine).
"""

from __future__ import annotations

import pytest

pytest.importorskip("tensorflow_datasets")

from rp_jax.datasets import loading
from rp_jax.schedule import load_spec, preset
from tests.datasets._tiny import TINY, all_records, check_records


def test_cmu_seasons_tiny_splits_by_slice(tmp_path):
    b = loading.get_builder("cmu_seasons", config=TINY, data_dir=tmp_path / "tfds", workers=1)
    b.download_and_prepare()
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
