"""The 64x64x3 patch around an interest point and its border rule (Sec. III-B)."""

import numpy as np

from rp_jax.groundtruth.patches import PATCH_SIZE, extract_patches


def _ramp(h=100, w=120):
    yy, xx = np.mgrid[0:h, 0:w]
    return np.stack([xx % 256, yy % 256, (xx + yy) % 256], -1).astype(np.uint8)


def test_interior_patch_is_centred_on_rounded_keypoint():
    img = _ramp()
    p = extract_patches(img, np.array([[60.4, 50.6]], np.float32))
    assert p.shape == (1, PATCH_SIZE, PATCH_SIZE, 3) and p.dtype == np.uint8
    # Centre (60, 51): element [32, 32] is that pixel; the patch spans x 28..91, y 19..82.
    np.testing.assert_array_equal(p[0, 32, 32], img[51, 60])
    np.testing.assert_array_equal(p[0], img[19:83, 28:92])


def test_border_patch_is_reflect_padded_not_dropped():
    img = _ramp()
    xy = np.array([[0.0, 0.0], [119.0, 99.0], [5.2, 98.7]], np.float32)
    p = extract_patches(img, xy)
    assert p.shape[0] == 3  # every keypoint keeps a patch
    # Top-left corner: reflection without repeating the edge (BORDER_REFLECT_101):
    # patch column 32 - k is image column k.
    np.testing.assert_array_equal(p[0, 32, 32], img[0, 0])
    np.testing.assert_array_equal(p[0, 32, 32 - 5], img[0, 5])
    np.testing.assert_array_equal(p[0, 32 - 7, 32], img[7, 0])
    # Bottom-right corner: patch row 32 + k is image row 99 - k.
    np.testing.assert_array_equal(p[1, 32 + 4, 32], img[95, 119])
    np.testing.assert_array_equal(p[1, 32, 32 + 3], img[99, 116])


def test_tiny_image_and_grayscale():
    img = np.arange(20 * 10, dtype=np.uint8).reshape(10, 20)
    p = extract_patches(img, np.array([[3.0, 4.0]]))
    assert p.shape == (1, 64, 64, 3)
    np.testing.assert_array_equal(p[0, 32, 32], [img[4, 3]] * 3)
    assert extract_patches(img, np.zeros((0, 2))).shape == (0, 64, 64, 3)
