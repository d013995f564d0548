"""The MSE of Sec. III-C against a hand computation."""

import numpy as np

from rp_jax import losses


def test_mse_matches_hand_computation():
    pred = np.array([[0.5, 0.2], [1.0, 0.0]], np.float32)
    label = np.array([[0.0, 0.2], [0.5, 0.5]], np.float32)
    # (1/N) sum_i ||y_i - y_hat_i||^2 = ((0.25 + 0) + (0.25 + 0.25)) / 2
    assert np.isclose(losses.mse(pred, label), 0.375)


def test_masks_drop_missing_slots_and_padding():
    pred = np.array([[0.5, 0.2], [1.0, 0.0], [9.0, 9.0]], np.float32)
    label = np.array([[0.0, 0.2], [0.5, 0.5], [0.0, 0.0]], np.float32)
    label_mask = np.array([[True, True], [True, False], [True, True]])
    example_mask = np.array([True, True, False])
    # Slot 2 of point 2 has no images; point 3 is padding: (0.25 + 0.25) / 2.
    assert np.isclose(losses.mse(pred, label, label_mask, example_mask), 0.25)
    # MAE over the 3 valid entries: (0.5 + 0 + 0.5) / 3.
    assert np.isclose(losses.mae(pred, label, label_mask, example_mask), 1 / 3)
