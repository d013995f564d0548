"""Detection with a per-image cap keeping the strongest responses (Sec. III-D)."""

import cv2
import numpy as np
import pytest

from rp_jax.groundtruth.features import detect_and_describe
from tests.groundtruth._scenes import textured_image


@pytest.mark.parametrize("detector,width,dtype", [("sift", 128, np.float32), ("orb", 32, np.uint8)])
def test_cap_keeps_strongest(detector, width, dtype):
    img = textured_image(0)
    full = detect_and_describe(img, detector=detector, max_keypoints=100_000)
    capped = detect_and_describe(img, detector=detector, max_keypoints=50)
    assert len(full) > 50 and len(capped) <= 50
    assert capped.descriptor.shape == (len(capped), width) and capped.descriptor.dtype == dtype
    assert np.all(np.diff(capped.response) <= 0)  # strongest first
    assert capped.response.min() >= np.sort(full.response)[::-1][49] - 1e-12


def test_flat_image_has_no_points_and_bad_input_is_named():
    flat = np.full((60, 80, 3), 128, np.uint8)
    f = detect_and_describe(flat)
    assert len(f) == 0 and f.descriptor.shape == (0, 128)
    with pytest.raises(ValueError, match="uint8"):
        detect_and_describe(flat.astype(np.float32))
    with pytest.raises(ValueError, match="unknown detector"):
        detect_and_describe(flat, detector="nope")


@pytest.mark.skipif(hasattr(cv2, "AKAZE_create"), reason="this OpenCV ships AKAZE")
def test_akaze_missing_is_explained():
    with pytest.raises(ValueError, match="AKAZE is not available"):
        detect_and_describe(textured_image(0), detector="akaze")
