"""Detection with a per-image cap keeping the strongest responses (Sec. III-D)."""

import cv2
import numpy as np
import pytest

from rp_jax.groundtruth import features
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


def _sift_detect_then_compute(gray, max_keypoints):
    """The two-call reference: detect, keep the strongest, describe them (its own pyramid)."""
    det = cv2.SIFT_create()
    kps = det.detect(gray, None)
    order = np.argsort(-np.array([k.response for k in kps], np.float32), kind="stable")
    kps, desc = det.compute(gray, [kps[i] for i in order[:max_keypoints]])
    return np.array([k.pt for k in kps], np.float32), desc


@pytest.mark.parametrize("seed", [0, 5])
@pytest.mark.parametrize("cap", [3, 60, 400])
def test_sift_in_one_pass_equals_detect_then_compute(seed, cap):
    gray = cv2.cvtColor(textured_image(seed), cv2.COLOR_RGB2GRAY)
    blurred = cv2.GaussianBlur(gray, (0, 0), 3)  # its strongest points sit above octave -1
    for image in (gray, blurred):
        xy, desc = _sift_detect_then_compute(image, cap)
        f = detect_and_describe(image, max_keypoints=cap)
        np.testing.assert_array_equal(f.xy, xy)
        np.testing.assert_array_equal(f.descriptor, desc)


def test_sift_one_pass_declines_without_an_octave_minus_one_point():
    # Where no kept point lies on the doubled image, OpenCV's compute() builds another
    # pyramid; the one-pass path must then hand over to the two-call path.
    gray = cv2.cvtColor(textured_image(0), cv2.COLOR_RGB2GRAY)
    det = cv2.SIFT_create()
    assert features._sift_in_one_pass(det, gray, 3) is None  # its 3 strongest: octave 1
    assert features._sift_in_one_pass(det, gray, 100_000) is not None
    blurred = cv2.GaussianBlur(gray, (0, 0), 3)  # no point at octave -1 at all
    assert features._sift_in_one_pass(det, blurred, 100_000) is None
