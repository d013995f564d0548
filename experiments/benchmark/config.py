"""What the benchmark measures: the problem sizes, the variants of the model stages (each in
its own worker process), and the prefix of the worker protocol's lines (``worker.py``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

__all__ = [
    "OURS_DEFAULT",
    "PEER_DEFAULT",
    "PROTOCOL_PREFIX",
    "SIZES",
    "STAGE_VARIANTS",
    "VARIANTS",
    "Variant",
]

PROTOCOL_PREFIX = "@@BENCH "  # stdout lines of the worker protocol start with this

# Problem sizes. ``tiny`` is for tests (seconds); ``full`` is the real measurement.
SIZES: dict[str, dict[str, Any]] = {
    "tiny": {
        "train_batch": 16,
        "train_steps": 2,
        "predict_batch": 32,
        "predict_steps": 2,
        "num_records": 64,
        "schedule": "webcam_clipart",
        "match_images": 3,
        "match_keypoints": 120,
        # Labelling's matching as a viewpoint grows (each size in a fresh process); sizes
        # above match_scaling_measured_max are extrapolated from the largest measured one.
        "match_scaling_images": (3, 5, 9),
        "match_scaling_measured_max": 5,
        "gt_images": (3, 4, 6),
        "gt_image_size": (200, 150),
        "gt_keypoints": 150,
        # Map summarization (Sec. V-A): map sizes, pruned fraction, grid cell, T.
        "sum_points": (1_000, 10_000),
        "sum_headline_points": 10_000,
        "sum_ratio": 0.5,
        "sum_cell_size_m": 10.0,
        "sum_timestamps": 24,
        "kcover_budget_s": 60.0,
        # Localization (Sec. V-B).
        "loc_points": 1_500,
        "loc_images": 8,
        "loc_street_m": 36.0,
        "loc_queries": 3,
        "loc_words": 16,
        "loc_retrieved": 3,
    },
    "full": {
        # The project's defaults: batch 256 for training, 512 for prediction.
        "train_batch": 256,
        "train_steps": 6,
        "predict_batch": 512,
        "predict_steps": 6,
        "num_records": 2048,
        "schedule": "webcam_clipart",
        # One viewpoint of 8 images at the ground truth's 1000 interest points per image.
        "match_images": 8,
        "match_keypoints": 1000,
        # Issue 16: 84, 168, 336 and 1,000 images per viewpoint. 1,000 images are ~500,000
        # image pairs (and 13 GB of PairwiseMatches): measured up to the max, extrapolated
        # (seconds per pair, bytes per output element) above.
        "match_scaling_images": (84, 168, 336, 1000),
        "match_scaling_measured_max": 168,
        "gt_images": (21, 42, 84),
        "gt_image_size": (640, 480),
        "gt_keypoints": 1000,
        # Maps of 10^4 .. 10^7 points; the goal: 10^6 points in under a second.
        "sum_points": (10_000, 100_000, 1_000_000, 10_000_000),
        "sum_headline_points": 1_000_000,
        "sum_ratio": 0.5,
        "sum_cell_size_m": 10.0,  # experiments/map_summarization's config.map.cell_size_m
        "sum_timestamps": 24,  # hourly (Sec. V: T = 24 hours/day)
        "kcover_budget_s": 60.0,  # skip K-cover at a size once the previous took longer
        # A 200 m street, a database image every 5 m, ~3,000 keypoints per query.
        "loc_points": 20_000,
        "loc_images": 40,
        "loc_street_m": 200.0,
        "loc_queries": 20,
        "loc_words": 64,
        "loc_retrieved": 5,  # experiments/map_summarization's config.map.num_retrieved
    },
}


@dataclasses.dataclass(frozen=True)
class Variant:
    """One configuration measured in its own process.

    Attributes:
      name: its key in the report.
      impl: ``"jax"`` (ours) or ``"torch"`` (the peer).
      num_devices: forced XLA host devices (jax); the batch is sharded over them.
      ynn: XLA's YNNPACK fusion flag (``rp_jax.platform.YNN_FLAG``) set (jax).
      dtype: patch-encoder dtype (``config.model.dtype``, jax).
      compile: ``torch.compile`` the module (torch).
      predictor_api: predict through ``rp_jax.predict.Predictor`` as shipped (jax, predict).
      malloc: ``rp_jax.platform.tune_malloc()`` in the worker (what ``configure_cpu`` does;
        jax or torch).
      conv1: ``RepeatabilityPredictor.conv1_path`` (jax); empty: the model's default.
      autocast: run the step under ``torch.autocast("cpu", dtype=torch.bfloat16)`` (torch).
      description: one line for the report.
    """

    name: str
    impl: str
    num_devices: int = 1
    ynn: bool = False
    dtype: str = "float32"
    compile: bool = False
    predictor_api: bool = False
    malloc: bool = False
    conv1: str = ""
    autocast: bool = False
    description: str = ""


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("jax_1dev", "jax", 1, False, description="JAX, 1 CPU device (JAX's default)"),
        Variant(
            "jax_2dev", "jax", 2, False, description="JAX, 2 forced host devices, batch sharded"
        ),
        Variant(
            "jax_2dev_ynn",
            "jax",
            2,
            True,
            conv1="space_to_depth",
            description="JAX, 2 devices + YNN fusion flag, conv1 after the space-to-depth "
            "transpose, glibc's default malloc (the previous default)",
        ),
        Variant(
            "jax_2dev_ynn_image",
            "jax",
            2,
            True,
            description="JAX, 2 devices + YNN (rp_jax.platform.configure_cpu defaults), conv1 as "
            "a 12x12 stride-4 convolution of the image (model default)",
        ),
        Variant(
            "jax_2dev_ynn_bf16",
            "jax",
            2,
            True,
            "bfloat16",
            description="JAX, configure_cpu defaults, bfloat16 patch encoder",
        ),
        Variant(
            "jax_2dev_ynn_malloc_s2d",
            "jax",
            2,
            True,
            malloc=True,
            conv1="space_to_depth",
            description="JAX, 2 devices + YNN + tune_malloc, conv1 after the space-to-depth "
            "transpose",
        ),
        Variant(
            "jax_2dev_ynn_malloc",
            "jax",
            2,
            True,
            malloc=True,
            description="JAX, 2 devices + YNN + tune_malloc (rp_jax.platform.configure_cpu("
            "malloc=True), what the Sec. IV-A commands train with), conv1 as a 12x12 stride-4 "
            "convolution of the image (model default)",
        ),
        Variant(
            "jax_2dev_ynn_malloc_bf16",
            "jax",
            2,
            True,
            "bfloat16",
            malloc=True,
            description="JAX, configure_cpu(malloc=True), bfloat16 patch encoder",
        ),
        Variant(
            "jax_predictor_api",
            "jax",
            2,
            True,
            predictor_api=True,
            description="rp_jax.predict.Predictor as shipped, after configure_cpu()",
        ),
        Variant("torch_eager", "torch", description="PyTorch 2 threads, eager"),
        Variant(
            "torch_eager_malloc",
            "torch",
            malloc=True,
            description="PyTorch 2 threads, eager, with rp_jax.platform.tune_malloc()",
        ),
        Variant(
            "torch_bf16",
            "torch",
            autocast=True,
            description="PyTorch 2 threads, eager, torch.autocast('cpu', bfloat16)",
        ),
        Variant(
            "torch_compile", "torch", compile=True, description="PyTorch 2 threads, torch.compile"
        ),
    )
}
# Which variant stands for "ours" and for "peer" in the top-level ratio: what a user gets
# by default from each (configure_cpu() and the model's defaults; eager mode in PyTorch).
OURS_DEFAULT = "jax_2dev_ynn_image"
PEER_DEFAULT = "torch_eager"
_MODEL_VARIANTS = [
    "jax_1dev",
    "jax_2dev_ynn",
    "jax_2dev_ynn_image",
    "jax_2dev_ynn_malloc",
    "jax_2dev_ynn_bf16",
]
_PEERS = ["torch_eager", "torch_eager_malloc", "torch_bf16"]
STAGE_VARIANTS = {
    "train": _MODEL_VARIANTS + _PEERS,
    "predict": _MODEL_VARIANTS + ["jax_predictor_api"] + _PEERS,
}
