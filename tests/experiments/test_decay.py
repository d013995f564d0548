"""Tests of the decay measurement (experiments.decay): its counting, its intervals, and a
tiny run end to end."""

import json

import numpy as np
import pytest

from experiments.decay import measure
from rp_jax.groundtruth.labels import OUTCOME_INLIER as IN
from rp_jax.groundtruth.labels import OUTCOME_MISS as MISS
from rp_jax.groundtruth.labels import OUTCOME_UNKNOWN as UNK

YEAR = measure.SECONDS_PER_YEAR


def _outcomes():
    """Four images of one scene: two a week apart, one a year later, one two years later at
    another slot; three points of image 0, two of image 2."""
    return {
        "outcome": np.array(
            [
                [UNK, IN, MISS, IN],
                [UNK, IN, IN, MISS],
                [UNK, MISS, UNK, IN],  # image 2 unreadable for this point: unknown
                [IN, MISS, UNK, MISS],
                [MISS, MISS, UNK, IN],
            ],
            np.int8,
        ),
        "row_image": np.array([0, 0, 0, 2, 2], np.int32),
        "image_unix_time": np.array([0.0, 7 * 86400.0, 1.0 * YEAR, 2.0 * YEAR]),
        "image_slot": np.array([10, 10, 10, 4], np.int32),
        "image_id": np.array(["s/a.jpg", "s/b.jpg", "s/c.jpg", "s/d.jpg"]),
    }


def test_image_bin_counts_by_hand():
    ids, hits, trials = measure.image_bin_counts(_outcomes(), num_bins=3)
    assert list(ids) == ["s/a.jpg", "s/c.jpg"]
    # Image 0's points: bin 0 = image 1 (3 known, 2 inliers), bin 1 = image 2 (2 known,
    # 1 inlier); image 3 is at another slot.
    assert hits[0].tolist() == [2, 1, 0] and trials[0].tolist() == [3, 2, 0]
    # Image 2's points: image 1 is 1 - 7/365.25 years away (bin 1), image 0 a year (bin 1).
    assert hits[1].tolist() == [0, 1, 0] and trials[1].tolist() == [0, 4, 0]
    # Every slot: image 3 joins (2 years from image 0, 1 from image 2).
    _, hits_all, trials_all = measure.image_bin_counts(_outcomes(), num_bins=3, same_slot=False)
    assert trials_all[0].tolist() == [3, 2, 3] and hits_all[0].tolist() == [2, 1, 2]
    assert trials_all[1].tolist() == [0, 6, 0] and hits_all[1].tolist() == [0, 2, 0]


def test_bootstrap_interval_brackets_the_fraction_and_pairs_cancel():
    rng = np.random.default_rng(3)
    trials = rng.integers(20, 60, (40, 3))
    hits = rng.binomial(trials, [0.6, 0.4, 0.2])
    fraction, low, high = measure.bootstrap_fraction(hits, trials, resamples=500)
    assert np.allclose(fraction, hits.sum(0) / trials.sum(0))
    assert np.all(low <= fraction) and np.all(fraction <= high) and np.all(high - low < 0.1)
    ids = np.array([f"s/{i}.jpg" for i in range(40)])
    difference, d_low, d_high = measure.bootstrap_difference(
        (ids, hits, trials), (ids[::-1], hits[::-1], trials[::-1]), resamples=200
    )
    assert np.allclose(difference, 0) and np.allclose(d_low, 0) and np.allclose(d_high, 0)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_tiny_run_measures_a_decay(tmp_path):
    result = measure.run(tmp_path, size="tiny", workers=1, resamples=200, progress=False)
    written = json.loads((tmp_path / "decay.json").read_text())
    assert written == json.loads(json.dumps(result))
    tables = (tmp_path / "decay.md").read_text().split("\n\n")
    assert len(tables) == 2
    assert len(tables[0].splitlines()) == 2 + measure.NUM_BINS  # header, rule, the bins
    assert len(tables[1].splitlines()) == 2 + len(measure.CATEGORIES)
    assert set(result["by_category"]) == set(measure.CATEGORIES)
    rows = result["bins"]
    assert [r["years_apart"] for r in rows] == list(range(measure.NUM_BINS))
    for r in rows:
        for world in ("off", "on"):
            w = r[world]
            assert w["outcomes"] > 0 and 0.0 <= w["inlier_fraction"] <= 1.0
            assert w["low"] <= w["inlier_fraction"] <= w["high"]
    # Both worlds are the same in their first days; five years on, the changing one has
    # fewer of its points repeat.
    last = rows[-1]
    assert last["on"]["inlier_fraction"] < last["off"]["inlier_fraction"]
    assert result["rates"]["tree_mortality_per_year"] == 0.035
    import cv2

    for figure in ("decay.png", "years.png"):
        image = cv2.imread(str(tmp_path / figure))
        assert image is not None and image.std() > 10, figure  # written, not blank
    # An ablation reuses the frozen world and names its own outputs.
    grown = measure.run(tmp_path, size="tiny", workers=1, resamples=50, progress=False,
                        kinds=("tree_growth",))
    assert grown["kinds"] == ["tree_growth"] and result["kinds"] == list(measure.slow_changes.KINDS)
    assert (tmp_path / "decay-tree_growth.json").is_file()
    assert (tmp_path / "layouts" / "webcam_years-tree_growth").is_dir()
    assert grown["bins"][0]["off"] == {**result["bins"][0]["off"],
                                       **{k: grown["bins"][0]["off"][k] for k in ("low", "high")}}


@pytest.mark.parametrize("argv, message", [
    (["--kinds", "tenant,bogus"], "--kinds tenant,bogus: unknown bogus"),
    (["--workers", "0"], "--workers 0: expected an integer >= 1"),
    (["--resamples", "0"], "--resamples 0: expected an integer >= 1"),
])
def test_bad_arguments_are_one_line_errors(argv, message, capsys):
    from experiments.decay.__main__ import main

    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2 and message in capsys.readouterr().err
