"""The appearance descriptor: what the sun, the clouds and the night do to an image."""

import numpy as np
import pytest

from rp_jax.conditional import appearance


def _scene(rng, h=96, w=160):
    """A textured street-like RGB image (float in [0, 1]): a bright sky above, texture below."""
    img = rng.uniform(0.2, 0.8, (h, w, 3))
    img[: h // 3] = [0.6, 0.7, 0.9]
    return img


def test_entries_and_determinism():
    rng = np.random.default_rng(0)
    img = (_scene(rng) * 255).astype(np.uint8)
    a = appearance.describe(img)
    assert list(a) == list(appearance.APPEARANCE_KEYS)
    assert all(np.isfinite(v) for v in a.values())
    assert a == appearance.describe(img.copy())
    # uint8 and float images of the same pixels describe alike.
    b = appearance.describe(img.astype(np.float32) / 255.0)
    np.testing.assert_allclose(list(a.values()), list(b.values()), atol=1e-6)


def test_darker_image_lower_luma_exposure_free_entries_unchanged():
    img = _scene(np.random.default_rng(1))
    bright, dark = appearance.describe(img), appearance.describe(img * 0.25)
    # Two stops darker: log2 of the mean luma falls by 2 (/ 8).
    assert dark["appearance_log_luma"] == pytest.approx(bright["appearance_log_luma"] - 0.25,
                                                        abs=1e-3)
    for k in ("appearance_contrast", "appearance_saturation", "appearance_luma_top_left"):
        assert dark[k] == pytest.approx(bright[k], abs=1e-3), k
    assert appearance.describe(img * 0.02)["appearance_dark_share"] > 0.9  # night


def test_flat_grey_light_against_hard_sunlit_shadows():
    rng = np.random.default_rng(2)
    grey = np.full((64, 64, 3), 0.5)
    flat = appearance.describe(grey)
    assert flat["appearance_contrast"] == pytest.approx(0.0, abs=1e-6)
    assert flat["appearance_saturation"] == pytest.approx(0.0, abs=1e-6)
    for k in ("top_left", "top_right", "bottom_left", "bottom_right"):
        assert flat[f"appearance_luma_{k}"] == pytest.approx(1.0, abs=1e-6)
    sunny = np.full((64, 64, 3), [0.9, 0.8, 0.5])  # warm sunlit wall ...
    sunny[:, 32:] *= 0.15  # ... half in a hard shadow
    sunny = np.clip(sunny + rng.normal(0, 0.01, sunny.shape), 0, 1)
    hard = appearance.describe(sunny)
    assert hard["appearance_contrast"] > 0.5 > flat["appearance_contrast"]
    assert hard["appearance_saturation"] > 0.3
    assert hard["appearance_luma_top_left"] > 1.5 > hard["appearance_luma_top_right"]
    assert hard["appearance_blue_minus_red"] < 0 < appearance.describe(
        np.full((8, 8, 3), [0.3, 0.4, 0.8]))["appearance_blue_minus_red"]


def test_clipped_share_and_grey_images():
    img = np.full((40, 40), 120, np.uint8)  # grey images become three equal channels
    img[:10] = 255
    a = appearance.describe(img)
    assert a["appearance_bright_share"] == pytest.approx(0.25, abs=0.02)
    assert a["appearance_saturation"] == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(ValueError, match="RGB image"):
        appearance.describe(np.zeros((1, 5, 3)))


def test_files_and_unknown(tmp_path):
    import cv2

    img = (_scene(np.random.default_rng(3)) * 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), img[..., ::-1])  # OpenCV writes BGR
    (tmp_path / "b.png").write_bytes(b"not an image")
    got = appearance.describe_files([tmp_path / "a.png", tmp_path / "b.png", tmp_path / "a.png"],
                                    readable=[True, True, False])
    expected = appearance.describe(img)
    for k in appearance.APPEARANCE_KEYS:
        assert got[k].shape == (3,) and got[k].dtype == np.float32
        assert got[k][0] == np.float32(expected[k])
        assert np.isnan(got[k][1]) and np.isnan(got[k][2])
