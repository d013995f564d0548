"""Extended CMU Seasons keypoint records with repeatability labels (Sec. III-D, IV-A-1).

Slices 6, 7, 9 train and 8 test; T = 12 dates of one year (M = 1); viewpoints grouped by
ground-truth pose; an interest point is an inlier when its match agrees with the known
poses (epipolar and triangulation checks). Category ids (Fig. 9) come from the
``segmentation/`` maps when present. Reading, splitting and labelling live in
``rp_jax.sources``, ``data_specs/cmu_seasons.json`` and ``rp_jax.groundtruth``.
"""

from typing import ClassVar

import tensorflow_datasets as tfds

from rp_jax.datasets import builder


class Builder(builder.RepeatabilityBuilder):
    """TFDS builder ``cmu_seasons`` (configs synthetic, synthetic_small/_tiny, real)."""

    DATASET = "cmu_seasons"
    BUILDER_CONFIGS = builder.builder_configs(records_per_image=32)
    VERSION = tfds.core.Version("1.5.0")
    RELEASE_NOTES: ClassVar[dict[str, str]] = {
        "1.5.0": "A viewpoint's records come from at most 84 source images (the paper's M = 4 days"
        " x T = 21 timestamps), spread over its timestamps and cycles and each matched "
        "against every image of the viewpoint, so labelling costs 84 x n image pairs "
        "instead of n^2; a source's labels are those all-pairs matching gives it. "
        "Viewpoints of more than 84 images (real downloads) keep fewer records than "
        "before; every synthetic viewpoint has at most 84 images, so its records are "
        "unchanged.",
        "1.4.0": "Synthetic world version 4: parked cars stay as long as cars do on their "
        "street (hours on commercial streets, overnight and days on residential ones, a "
        "resident's own car back at its slot) instead of changing every 4 hours, and "
        "window glass mirrors the sky (Fresnel reflectance of glass), so the synthetic "
        "pixels and records change.",
        "1.3.0": "Real layouts: the query ground truth the release ships in "
        "slice{N}/camera-poses/*.txt is read, so the posed queries (the other dates) join "
        "the viewpoints, and the original CMU Seasons' ..._rect.jpg names are read. "
        "Synthetic world version 3: the reference traversal is recorded as the real one "
        "is described (Apr 4, 2011, sunny, no foliage; it fills the paper's Apr 21 slot) and "
        "every traversal starts between 9:00 and 16:00 local time (9:30-14:30 before), so "
        "the synthetic records change; query poses are also written to camera-poses/. "
        "Brick walls, lawns, lawn paths and flat roofs are textured with real photographs of "
        "brick, grass and gravel (scikit-image's, CC0; windows, signs and snow where they were), "
        "so the synthetic pixels and records change.",
        "1.2.0": "Synthetic world version 2: foliage moves in the wind, so tree crowns differ "
        "between frames (an older rendering is rendered again).",
        "1.1.0": "Synthetic world: snow lies on facade ledges; the full synthetic world is 20 "
        "capture positions per slice at half the real resolution (a run in minutes), and 32 "
        "of each image's interest points become records (the paper's 61,726 points). "
        "Ground-truth caches hold no patches and follow changes of the image files.",
        "1.0.0": "Initial release: SIFT interest points on undistorted images, pose-based "
        "verification, y^j over the paper's 12 dates.",
    }
    MANUAL_DOWNLOAD_INSTRUCTIONS = """\
    Download Extended CMU Seasons (visuallocalization.net) and extract slices 6-9 into
    manual_dir (default <data_dir>/downloads/manual/, or --manual-dir):

        <manual_dir>/intrinsics.txt
        <manual_dir>/slice{N}/database/img_<i>_<c0|c1>_<unix_us>us.jpg
        <manual_dir>/slice{N}/query/img_<i>_<c0|c1>_<unix_us>us.jpg
        <manual_dir>/slice{N}/ground-truth-database-images-slice{N}.txt
        <manual_dir>/slice{N}/camera-poses/*.txt                          query poses
        <manual_dir>/segmentation/slice{N}/<database|query>/<stem>.png     optional

    The release has poses for about half of the queries (camera-poses/); query images
    without a ground-truth pose cannot be grouped into viewpoints and are skipped.
    """
