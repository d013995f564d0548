"""The suite's test processes keep what collection made out of the cyclic garbage
collector's sight (``gc.freeze`` in tests/conftest.py), unless ``RP_JAX_TEST_GC=default``."""

import gc

from tests import conftest


def test_what_collection_made_is_frozen_in_a_test_process():
    if conftest._collector_left_as_it_is():
        assert gc.get_freeze_count() == 0
    else:
        # JAX, TensorFlow Datasets, OpenCV, the package and the tests' modules: far more than this.
        assert gc.get_freeze_count() > 50_000


def test_the_hook_freezes_unless_told_to_leave_the_collector_alone(monkeypatch):
    monkeypatch.setenv("RP_JAX_TEST_GC", "default")
    before = gc.get_freeze_count()
    young = [[] for _ in range(1000)]  # objects the collector tracks
    conftest.pytest_collection_finish(None)
    assert gc.get_freeze_count() == before
    monkeypatch.delenv("RP_JAX_TEST_GC")
    try:
        conftest.pytest_collection_finish(None)
        assert gc.get_freeze_count() >= before + len(young)
    finally:
        if before == 0:  # a run that keeps the collector as it is goes on as it was
            gc.unfreeze()
