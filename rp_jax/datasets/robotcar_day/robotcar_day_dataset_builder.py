"""Oxford RobotCar keypoint records over the whole day (Sec. III-D, beyond Sec. IV-B-1).

The paper's RobotCar RP covers 9:00-17:00 (Table I: T = 9). This dataset is the same
recipe (viewpoints within 5 m and 45 deg of yaw, pose-verified SIFT interest points, M = 1)
over T = 24 hourly timestamps 0:00-23:00, one traversal per hour, so a map can be
summarized for a dawn, dusk or night query. One viewpoint in four is held out as ``test``
(``data_specs/robotcar_day.json``): the daily curve of Sec. IV-A is read there. Reading
lives in ``rp_jax.sources.robotcar.read_day``, the synthetic world in the
``robotcar_day`` preset.
"""

from typing import ClassVar

import tensorflow_datasets as tfds

from rp_jax.datasets import builder


class Builder(builder.RepeatabilityBuilder):
    """TFDS builder ``robotcar_day`` (configs synthetic, synthetic_small/_tiny, real)."""

    DATASET = "robotcar_day"
    BUILDER_CONFIGS = builder.builder_configs()
    VERSION = tfds.core.Version("1.0.0")
    RELEASE_NOTES: ClassVar[dict[str, str]] = {
        "1.0.0": "Initial release: the RobotCar recipe over 24 hourly timestamps, nights "
        "rendered in physical units by the synthetic world.",
    }
    MANUAL_DOWNLOAD_INSTRUCTIONS = """\
    Download RobotCar traversals at the hours of the day you want covered (one per hour
    for every slot; stereo centre images and gps/ins.csv, or rtk.csv) and the SDK's
    models/ and extrinsics/ folders into manual_dir, laid out as for ``robotcar``:

        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/stereo/centre/<unix_us>.png
        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/stereo.timestamps
        <manual_dir>/<YYYY-MM-DD-HH-MM-SS>/gps/ins.csv
        <manual_dir>/models/stereo_narrow_left.txt (+ _distortion_lut.bin)
        <manual_dir>/extrinsics/stereo.txt, ins.txt
        <manual_dir>/viewpoints.csv          viewpoint,latitude,longitude,yaw_deg

    Each image goes to the slot of its local (Europe/London) hour.
    """
