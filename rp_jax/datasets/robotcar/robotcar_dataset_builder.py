"""Oxford RobotCar keypoint records with repeatability labels (Sec. III-D, Sec. IV-B-1).

The 9 traversals of the paper's Table I (T = 9 hourly timestamps 9:00-17:00, M = 1) at the
listed viewpoints (5 m, 45 deg of yaw); all viewpoints are in ``train`` (the paper uses
them to summarise maps). Reading and labelling live in ``rp_jax.sources.robotcar`` and
``rp_jax.groundtruth``.
"""

from typing import ClassVar

import tensorflow_datasets as tfds

from rp_jax.datasets import builder


class Builder(builder.RepeatabilityBuilder):
    """TFDS builder ``robotcar`` (configs synthetic, synthetic_small/_tiny, real)."""

    DATASET = "robotcar"
    BUILDER_CONFIGS = builder.builder_configs()
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
        "1.3.0": "Synthetic world version 3 (an older rendering is rendered again): brick "
        "walls, lawns, lawn paths and flat roofs are textured with real photographs of brick, "
        "grass and gravel (scikit-image's, CC0; windows, signs and snow where they were), so "
        "the synthetic pixels and records change.",
        "1.2.0": "Synthetic world version 2: foliage moves in the wind, so tree crowns differ "
        "between frames (an older rendering is rendered again).",
        "1.1.0": "Synthetic world: snow lies on facade ledges on snowy days. Ground-truth "
        "caches hold no patches and follow changes of the image files.",
        "1.0.0": "Initial release: SIFT interest points on demosaiced images, pose-based "
        "verification, y^j over the 9 hourly timestamps.",
    }
    MANUAL_DOWNLOAD_INSTRUCTIONS = """\
    Download the 9 traversals of the paper's Table I from the Oxford RobotCar dataset
    (stereo centre images and gps/ins.csv, or rtk.csv) and the SDK's models/ and
    extrinsics/ folders into manual_dir (default <data_dir>/downloads/manual/):

        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/stereo/centre/<unix_us>.png
        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/stereo.timestamps
        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/gps/ins.csv
        <manual_dir>/models/stereo_narrow_left.txt (+ _distortion_lut.bin)
        <manual_dir>/extrinsics/stereo.txt, ins.txt
        <manual_dir>/viewpoints.csv          viewpoint,latitude,longitude,yaw_deg
    """
