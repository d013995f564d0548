"""The ground truth's file cache (rp_jax/groundtruth/cache.py)."""

import threading

import numpy as np

from rp_jax.groundtruth import cache


def test_npz_round_trip_and_one_reader_at_a_time(tmp_path):
    path = tmp_path / "features.npz"
    arrays = {"xy": np.arange(168, dtype=np.float32).reshape(84, 2),
              "desc": np.ones((84, 128), np.float32)}
    cache.save_npz(path, arrays)
    got = cache.load_npz(path)
    assert set(got) == set(arrays) and all(np.array_equal(got[k], arrays[k]) for k in arrays)
    # Reads are serialised (CPython 3.11's ast.literal_eval, which NumPy parses each array's
    # header with, is not thread-safe): a read waits while another holds the lock.
    read = []
    with cache._NPZ_READ:
        thread = threading.Thread(target=lambda: read.append(cache.load_npz(path)))
        thread.start()
        thread.join(timeout=0.5)
        assert thread.is_alive() and not read
    thread.join(timeout=10)
    assert not thread.is_alive() and np.array_equal(read[0]["xy"], arrays["xy"])
