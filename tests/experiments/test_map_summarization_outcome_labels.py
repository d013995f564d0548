"""The outcome scorer's labels: which slices give them (issue 26).

The labels themselves, on the tiny world, are tested where the experiment's fixture makes
them (``test_map_summarization.py``, ``test_map_summarization_conditions.py``).
"""

import pytest

from experiments.map_summarization import outcome_labels
from experiments.map_summarization.config import get_config


def test_training_slices_never_the_test_slice_nor_the_run_s_own():
    small = get_config("small")
    assert outcome_labels.training_slices(small) == [6, 7, 9]  # a run on the test slice 8
    small.map.slice = 6  # where recipes are chosen: trained without slice 6
    assert outcome_labels.training_slices(small) == [7, 9]
    tiny = get_config("tiny")  # the tiny world has slices 6 and 8 only
    assert outcome_labels.training_slices(tiny) == [6]
    tiny.map.slice = 6
    with pytest.raises(ValueError, match="no training slice"):
        outcome_labels.training_slices(tiny)


def test_training_slices_of_a_given_layout_are_the_folders_it_has(tmp_path):
    config = get_config("small")
    config.map.root = str(tmp_path)
    for s in (7, 8):
        (tmp_path / f"slice{s}").mkdir()
    assert outcome_labels.training_slices(config) == [7]  # no slice6 or slice9 folder
    (tmp_path / "slice7").rmdir()
    with pytest.raises(ValueError, match=f"outside slice 8 in {tmp_path}"):
        outcome_labels.training_slices(config)
