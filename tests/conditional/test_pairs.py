"""Records + sidecar -> pair arrays -> batches: tables stored once, capture = own image."""

import numpy as np

from rp_jax.conditional import inputs, pairs


def _side(n_images, rows, rng):
    time = np.zeros((n_images, 6), np.int32)
    time[:, 1], time[:, 2], time[:, 3], time[:, 4] = 6, 3, np.arange(8, 8 + n_images), 30
    out = {
        "outcome": rng.integers(-1, 2, (rows, n_images)).astype(np.int8),
        "row_image": rng.integers(0, n_images, rows).astype(np.int32),
        "keypoint_id": np.arange(rows, dtype=np.int32),
        "image_id": np.array([f"im{i}" for i in range(n_images)]),
        "image_readable": np.ones(n_images, bool),
        "image_time": time,
        "image_slot": np.arange(n_images, dtype=np.int32) % 3,
    }
    for key in inputs.SUN_KEYS + inputs.WEATHER_KEYS[:-1]:
        out[f"image_{key}"] = rng.uniform(0, 1, n_images).astype(np.float32)
    out["image_weather"] = rng.integers(0, 5, n_images).astype(np.int8)
    out["image_readable"][-1] = False
    return out


def test_from_records_and_batch():
    rng = np.random.default_rng(0)
    sidecar = {"b": _side(4, 3, rng), "a": _side(6, 5, rng)}
    # Records of both viewpoints, interleaved; rows say which sidecar row each one is.
    viewpoint = np.array(["b", "a", "a", "b", "a"])
    rows = np.array([2, 4, 0, 0, 1])
    columns = {"viewpoint": viewpoint, "patch": rng.integers(0, 255, (5, 64, 64, 3)),
               "xy_normalized": rng.uniform(0, 1, (5, 2)), "category": np.arange(5) - 1,
               "label": rng.uniform(0, 1, (5, 3))}
    arrays = pairs.from_records(columns, sidecar, rows)
    assert arrays.viewpoints == ["a", "b"] and len(arrays) == 5
    assert arrays.tables["slot"].shape == (2, 6)  # padded to the widest viewpoint
    np.testing.assert_array_equal(arrays.tables["valid"][1], [1, 1, 1, 0, 0, 0])
    for r in range(5):
        side, row = sidecar[viewpoint[r]], rows[r]
        n = len(side["image_id"])
        np.testing.assert_array_equal(arrays.points["outcome"][r, :n], side["outcome"][row])
        assert (arrays.points["outcome"][r, n:] == -1).all()
        own = side["row_image"][row]
        assert arrays.points["own"][r] == own
        assert arrays.points["capture_hour"][r] == side["image_time"][own, 3]
        assert arrays.points["capture_cloud_cover"][r] == side["image_cloud_cover"][own]

    b = pairs.batch(arrays, np.array([3, 1]), size=4)
    assert b["mask"].tolist() == [True, True, False, False]
    assert b["target"]["hour"].shape == (4, 6) and b["capture"]["hour"].shape == (4,)
    np.testing.assert_array_equal(b["target"]["hour"][0, :4], [8, 9, 10, 11])  # viewpoint b
    assert b["own_target"][0].sum() == 1 and b["own_target"][0, arrays.points["own"][3]]
    np.testing.assert_array_equal(b["label"][:2], columns["label"][[3, 1]])
