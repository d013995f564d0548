"""Tiny synthetic scenes for the ground-truth tests (Sec. III-D): textured images, captures."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import cv2
import numpy as np

from rp_jax.sources.capture import Camera, Capture

WIDTH, HEIGHT = 200, 150


def textured_image(seed: int = 0, width: int = WIDTH, height: int = HEIGHT) -> np.ndarray:
    """RGB uint8: random blobs of several sizes, blurred; rich in SIFT interest points."""
    rng = np.random.default_rng(seed)
    img = np.zeros((height, width, 3), np.float32)
    for sigma, amp in ((6.0, 120.0), (2.5, 80.0), (1.2, 40.0)):
        # Mostly shared across channels: texture must survive the conversion to gray.
        noise = rng.normal(0.0, 1.0, (height, width, 1)) + 0.3 * rng.normal(
            0.0, 1.0, (height, width, 3)
        )
        blurred = cv2.GaussianBlur(noise.astype(np.float32), (0, 0), sigma)
        img += amp * blurred / (blurred.std() + 1e-6)
    img = img - img.min()
    return np.clip(img / img.max() * 255.0, 0, 255).astype(np.uint8)


def shifted(
    image: np.ndarray, dx: float, dy: float, gain: float = 1.0, noise: float = 0.0, seed: int = 0
) -> np.ndarray:
    """Translate by (dx, dy) pixels, scale brightness and add Gaussian noise."""
    M = np.float32([[1, 0, dx], [0, 1, dy]])
    out = cv2.warpAffine(
        image,
        M,
        (image.shape[1], image.shape[0]),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REFLECT_101,
    )
    out = out.astype(np.float32) * gain
    if noise:
        out += np.random.default_rng(seed).normal(0.0, noise, out.shape)
    return np.clip(out, 0, 255).astype(np.uint8)


def make_capture(
    image_id: str,
    cycle: int,
    slot: int,
    viewpoint: str = "vp0",
    R=None,
    t=None,
    K=None,
    size=(WIDTH, HEIGHT),
) -> Capture:
    tz = dt.timezone(dt.timedelta(hours=-5))
    # Slot j at 08:30 + j hours of day 1 + cycle (a test schedule, not a paper one).
    when = dt.datetime(2021, 6, 1 + cycle, 8, 30, tzinfo=tz) + dt.timedelta(hours=slot)
    if K is None:
        K = np.array([[200.0, 0, size[0] / 2], [0, 200.0, size[1] / 2], [0, 0, 1]])
    cam = Camera("PINHOLE", size[0], size[1], K)
    return Capture(
        Path(f"/nonexistent/{viewpoint}/{image_id}.png"),
        when,
        cam,
        viewpoint,
        R=R,
        t=t,
        cycle=cycle,
        slot=slot,
        image_id=image_id,
    )


# Images of the tests are kept in a module-level registry so that the loader is a picklable
# module-level function (process pools) that needs no files on disk.
IMAGES: dict[str, np.ndarray | None] = {}


def load_from_registry(capture: Capture) -> np.ndarray | None:
    return IMAGES[f"{capture.viewpoint}/{capture.image_id}"]


def load_from_disk(capture: Capture) -> np.ndarray | None:
    """Loader for process pools started by spawn (no registry there): reads the PNG."""
    import cv2

    img = cv2.imread(str(capture.image_path), cv2.IMREAD_COLOR)
    return None if img is None else cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def to_disk(captures: list[Capture], folder: Path) -> list[Capture]:
    """Write the registry's images of ``captures`` as lossless PNGs (garbage for unreadable)."""
    import dataclasses

    import cv2

    out = []
    for c in captures:
        path = Path(folder) / c.viewpoint / f"{c.image_id}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        img = IMAGES[f"{c.viewpoint}/{c.image_id}"]
        if img is None:
            path.write_bytes(b"not a png")
        else:
            cv2.imwrite(str(path), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        out.append(dataclasses.replace(c, image_path=path))
    return out
