"""The keypoint record as TFDS features (Sec. III-D; ARCHITECTURE.md "Interfaces").

One record per interest point of one image: its 64x64x3 patch, its position, the capture
time of its image, and its ground-truth repeatability vector y^j over the T timestamps of
a cycle with the mask of the timestamps that had images. Keys are flat so that a record
feeds ``input_pipeline.MODEL_KEYS`` directly (``patch``, ``xy_normalized``, ``hour``,
``minute``, ``day``, ``month``, ``label``, ``label_mask``).

``records_to_examples`` turns the column arrays of ``rp_jax.groundtruth.label_viewpoint``
into TFDS examples; it holds no labelling logic.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np

__all__ = [
    "DESCRIPTOR_SIZE",
    "FEATURE_KEYS",
    "PATCH_SHAPE",
    "TEXT_KEYS",
    "example_key",
    "features_dict",
    "records_to_examples",
]

PATCH_SHAPE = (64, 64, 3)
DESCRIPTOR_SIZE = 128  # SIFT, the paper's detector/descriptor (Sec. III-D)
# The time of capture on the camera's local wall clock, one int32 feature each.
TIME_KEYS = ("year", "month", "day", "hour", "minute", "utc_offset_minutes")
TEXT_KEYS = ("viewpoint", "image_id")
FEATURE_KEYS = (
    "patch",
    "xy",
    "xy_normalized",
    "image_size",
    *TIME_KEYS,
    "cycle",
    "slot",
    "label",
    "label_mask",
    "category",
    "descriptor",
    "viewpoint",
    "image_id",
    "keypoint_id",
)


def features_dict(num_timestamps: int):
    """The ``tfds.features.FeaturesDict`` of a keypoint record with T = ``num_timestamps``.

    ``patch`` is a zlib-encoded uint8 tensor rather than an ``Image``: PNG encoding in TFDS
    needs TensorFlow, which this project does not install; array_record compresses too.
    """
    import tensorflow_datasets as tfds

    tensor = tfds.features.Tensor
    scalar = {k: np.int32 for k in (*TIME_KEYS, "cycle", "slot", "category", "keypoint_id")}
    return tfds.features.FeaturesDict(
        {
            "patch": tensor(
                shape=PATCH_SHAPE,
                dtype=np.uint8,
                encoding="zlib",
                doc="64x64x3 RGB patch centred on the interest point",
            ),
            "xy": tensor(shape=(2,), dtype=np.float32, doc="pixel position (x right, y down)"),
            "xy_normalized": tensor(shape=(2,), dtype=np.float32, doc="(x / W, y / H)"),
            "image_size": tensor(shape=(2,), dtype=np.int32, doc="(W, H) of the image"),
            **scalar,
            "label": tensor(
                shape=(num_timestamps,),
                dtype=np.float32,
                doc="ground-truth repeatability y^j at the T timestamps",
            ),
            "label_mask": tensor(
                shape=(num_timestamps,),
                dtype=np.bool_,
                doc="True where timestamp j had an image (m_{k,j} > 0)",
            ),
            "descriptor": tensor(shape=(DESCRIPTOR_SIZE,), dtype=np.float32, doc="SIFT"),
            "viewpoint": tfds.features.Text(),
            "image_id": tfds.features.Text(),
        }
    )


def example_key(viewpoint: str, image_id: str, keypoint_id: int) -> str:
    """The unique TFDS key of an interest point."""
    return f"{viewpoint}|{image_id}|{int(keypoint_id)}"


def records_to_examples(records: Mapping[str, np.ndarray]) -> Iterator[tuple[str, dict]]:
    """Yield ``(key, example)`` for every row of ``label_viewpoint``'s column arrays.

    Args:
      records: ``rp_jax.groundtruth.RECORD_KEYS`` arrays with one row per interest point
        (``time`` is [N, 6] in ``TIME_KEYS`` order).

    Raises:
      ValueError: if the descriptors are not 128-wide (the records were built with a
        detector other than SIFT) or ``time`` has the wrong width.
    """
    n = len(records["xy"])
    if n == 0:
        return
    descriptor = np.asarray(records["descriptor"], np.float32)
    if descriptor.shape[1:] != (DESCRIPTOR_SIZE,):
        raise ValueError(
            f"descriptors of shape {descriptor.shape[1:]}; the keypoint record stores "
            f"{DESCRIPTOR_SIZE}-d SIFT descriptors (GroundTruthConfig(detector='sift'))"
        )
    time = np.asarray(records["time"], np.int32)
    if time.shape != (n, len(TIME_KEYS)):
        raise ValueError(f"time of shape {time.shape}, expected ({n}, {len(TIME_KEYS)})")
    patch = np.asarray(records["patch"], np.uint8)
    xy = np.asarray(records["xy"], np.float32)
    xy_normalized = np.asarray(records["xy_normalized"], np.float32)
    image_size = np.asarray(records["image_size"], np.int32)
    label = np.asarray(records["label"], np.float32)
    label_mask = np.asarray(records["label_mask"], bool)
    ints = {
        k: np.asarray(records[k], np.int32) for k in ("cycle", "slot", "category", "keypoint_id")
    }
    for i in range(n):
        viewpoint, image_id = str(records["viewpoint"][i]), str(records["image_id"][i])
        example = {
            "patch": patch[i],
            "xy": xy[i],
            "xy_normalized": xy_normalized[i],
            "image_size": image_size[i],
            **{k: int(time[i, c]) for c, k in enumerate(TIME_KEYS)},
            **{k: int(v[i]) for k, v in ints.items()},
            "label": label[i],
            "label_mask": label_mask[i],
            "descriptor": descriptor[i],
            "viewpoint": viewpoint,
            "image_id": image_id,
        }
        yield example_key(viewpoint, image_id, ints["keypoint_id"][i]), example
