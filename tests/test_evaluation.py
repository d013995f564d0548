"""Tests of rp_jax.evaluation: metrics and baselines against hand computations."""

import numpy as np
import pytest

from rp_jax import evaluation as ev


def test_masked_errors_hand_case():
    pred = np.array([[0.5, 0.0], [1.0, 0.2]])
    label = np.array([[0.0, 0.0], [0.5, 0.9]])
    mask = np.array([[True, True], [True, False]])
    e = ev.masked_errors(pred, label, mask)
    assert e["mse"] == pytest.approx((0.25 + 0.25) / 2)
    assert e["mae"] == pytest.approx((0.5 + 0 + 0.5) / 3)


def test_average_curve_and_corr():
    label = np.array([[0.0, 1.0, 0.0], [0.2, 0.8, 9.0]])
    mask = np.array([[True, True, True], [True, True, False]])
    np.testing.assert_allclose(ev.average_curve(label, mask), [0.1, 0.9, 0.0])
    gap = ev.average_curve(label, np.array([[True, False, True], [True, False, False]]))
    assert np.isnan(gap[1]) and gap[0] == 0.1
    assert ev.curve_corr(label * 0.5 + 0.1, label, mask) == pytest.approx(1.0)
    assert np.isnan(ev.curve_corr(np.ones_like(label), label, mask))


def test_curves_by_source_slot_average_each_sources_points_only():
    # Two points detected at slot 0 (by day), one at slot 2 (at night); T = 3.
    label = np.array([[0.9, 0.4, 0.0], [0.7, 0.2, 0.1], [0.0, 0.3, 0.8]])
    mask = np.array([[True, True, True], [True, False, True], [True, True, True]])
    m = ev.curves_by_source_slot(label, mask, np.array([0, 0, 2]))
    np.testing.assert_allclose(m[0], [0.8, 0.4, 0.05])  # slot 1 of the 2nd point unobserved
    assert np.isnan(m[1]).all()  # no point detected at slot 1
    np.testing.assert_allclose(m[2], [0.0, 0.3, 0.8])
    # Its rows weighted by their observed points give back the average curve.
    counts = np.array([[2, 1, 2], [0, 0, 0], [1, 1, 1]])
    np.testing.assert_allclose(np.nansum(m * counts, 0) / counts.sum(0),
                               ev.average_curve(label, mask))


def test_slot_conditioned_mean_uses_capture_slot_and_falls_back():
    label = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.6, 0.2]])
    mask = np.ones_like(label, bool)
    slot = np.array([0, 1, 1])
    pred = ev.slot_conditioned_mean(label, mask, slot, np.array([1, 0, 2]))
    np.testing.assert_allclose(pred[0], [0.0, 0.8, 0.1])
    np.testing.assert_allclose(pred[1], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(pred[2], label.mean(0))  # slot 2 unseen: per-slot mean


def test_descriptor_knn_finds_neighbours():
    rng = np.random.default_rng(0)
    centres = rng.normal(size=(2, 16)) * 10
    desc = np.concatenate([centres[0] + rng.normal(size=(5, 16)),
                           centres[1] + rng.normal(size=(5, 16))])
    label = np.concatenate([np.tile([1.0, 0.0], (5, 1)), np.tile([0.0, 1.0], (5, 1))])
    pred = ev.descriptor_knn(desc, label, np.ones_like(label, bool), centres, k=3, block=1)
    np.testing.assert_allclose(pred, [[1.0, 0.0], [0.0, 1.0]])


def test_descriptor_knn_on_threads_equals_one_thread_and_a_brute_force_by_hand():
    rng = np.random.default_rng(1)
    desc = rng.normal(size=(300, 8)).astype(np.float32)
    label = rng.random((300, 5)).astype(np.float32)
    mask = rng.random((300, 5)) > 0.3
    queries = rng.normal(size=(37, 8)).astype(np.float32)
    one = ev.descriptor_knn(desc, label, mask, queries, k=4, block=5, workers=1)
    many = ev.descriptor_knn(desc, label, mask, queries, k=4, block=5, workers=3)
    np.testing.assert_array_equal(one, many)
    for i in (0, 18, 36):  # the last block holds 2 queries
        nn = np.argsort(((desc - queries[i]) ** 2).sum(1))[:4]
        expected = (label[nn] * mask[nn]).sum(0) / np.maximum(mask[nn].sum(0), 1)
        np.testing.assert_allclose(one[i], expected, rtol=1e-6)


def test_per_group_errors():
    pred = np.zeros((4, 2))
    label = np.array([[1.0, 1.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    out = ev.per_group_errors(pred, label, np.ones_like(label, bool), np.array([0, 0, 1, 5]),
                              {"building": (0,), "vegetation": (1,), "vehicle": (2,)})
    assert set(out) == {"building", "vegetation"}
    assert out["building"]["count"] == 2 and out["building"]["mae"] == pytest.approx(0.5)
