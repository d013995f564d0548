"""Ground-truth repeatability labels of interest points (Sec. III-D of the paper).

OpenCV/NumPy only (no jax): detection (``features``), 64x64x3 patches (``patches``),
vectorised nearest-neighbour + ratio-test matching (``matching``), geometric verification
(``verification``, ``triangulation``), the repeatability vector y^j and its mask
(``labels``), the source images whose points become records (``sources``), streamed in
blocks (``source_labels``, ``blocks``), and the cached, resumable per-viewpoint pipeline
(``viewpoint``).
"""

from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.groundtruth.labels import repeatability_labels
from rp_jax.groundtruth.viewpoint import (
    OUTCOME_KEYS,
    RECORD_KEYS,
    TIME_FIELDS,
    attach_patches,
    label_viewpoint,
    label_viewpoint_block,
    label_viewpoint_outcomes,
    label_viewpoints,
    load_records,
    viewpoint_block_count,
)

__all__ = [
    "OUTCOME_KEYS",
    "RECORD_KEYS",
    "TIME_FIELDS",
    "GroundTruthConfig",
    "attach_patches",
    "label_viewpoint",
    "label_viewpoint_block",
    "label_viewpoint_outcomes",
    "label_viewpoints",
    "load_records",
    "repeatability_labels",
    "viewpoint_block_count",
]
