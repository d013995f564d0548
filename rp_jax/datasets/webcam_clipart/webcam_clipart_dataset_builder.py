"""Webcam Clip Art keypoint records with repeatability labels (Sec. III-D, Sec. IV-A-1).

8 static webcam scenes (7 train, 1 test), T = 21 timestamps every 30 min 8:00-18:00,
M = 4 days; an interest point is an inlier in another image when its match lies within
5 px (static camera). The reading, splitting and labelling live in ``rp_jax.sources``,
``data_specs/webcam_clipart.json`` and ``rp_jax.groundtruth``; this file only names them.
"""

from typing import ClassVar

import tensorflow_datasets as tfds

from rp_jax.datasets import builder


class Builder(builder.RepeatabilityBuilder):
    """TFDS builder ``webcam_clipart`` (configs synthetic, synthetic_small/_tiny, real)."""

    DATASET = "webcam_clipart"
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
        "1.3.0": "File names on their own clock, as the real releases (AMOS: UTC; the author's "
        "sample: US/Eastern whatever the camera's zone): the reader converts them to the "
        "camera's zone for the slots and reads the author's MATLAB v7.3 .mat sun angles. "
        "Synthetic world version 3 names its frames in UTC (image_id changes; an older "
        "rendering is rendered again) and writes a v7.3 .mat per frame; times and slots are "
        "as before. "
        "Brick walls, lawns, lawn paths and flat roofs are textured with real photographs of "
        "brick, grass and gravel (scikit-image's, CC0; windows, signs and snow where they were), "
        "so the synthetic pixels and records change.",
        "1.2.0": "Synthetic world version 2: foliage moves in the wind, so tree crowns differ "
        "between frames (an older rendering is rendered again).",
        "1.1.0": "Synthetic world: snow lies on facade ledges on snowy days. Ground-truth "
        "caches hold no patches and follow changes of the image files.",
        "1.0.0": "Initial release: SIFT interest points, static-camera verification (5 px), "
        "y^j over the 21 half-hourly timestamps.",
    }
    MANUAL_DOWNLOAD_INSTRUCTIONS = """\
    Download Webcam Clip Art (Lalonde et al.) and place the 8 chosen scenes in manual_dir
    (default <data_dir>/downloads/manual/, or --manual-dir):

        <manual_dir>/<scene>/YYYYMMDD_HHMMSS.jpg      (or <manual_dir>/images/<scene>/...)
        <manual_dir>/<scene>/YYYYMMDD_HHMMSS.mat      optional sun angles (MATLAB v5 or v7.3)
        <manual_dir>/<scene>/scene.json               optional {"timezone": "America/...",
                                                      "name_timezone": "America/New_York",
                                                      "latitude": .., "longitude": ..}
        <manual_dir>/<scene>/metadata.csv             optional name,datetime overrides
        <manual_dir>/segmentation/<scene>/<stem>.png  optional category maps

    timezone is the camera's zone (slots are read on its wall clock); name_timezone the
    zone the file names are written in (default data_specs' default_name_timezone,
    US/Eastern as in the author's sample; "UTC" for AMOS). With latitude/longitude the
    sun angles of the .mat files are checked against the times read (a warning if off).

    Name the train and test scenes in data_specs/webcam_clipart.json (splits.real); if
    they are not named, the last scene in sorted order is the test scene.
    """
