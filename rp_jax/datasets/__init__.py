"""rp_jax.datasets: TFDS keypoint records and the input pipeline (Sec. III-D, Sec. IV-A).

One TFDS builder per dataset (``webcam_clipart``, ``cmu_seasons``, ``robotcar`` and its
whole-day variant ``robotcar_day``; configs
``synthetic``, ``synthetic_small``, ``synthetic_tiny``, ``real``) in ``<name>/``, their
shared logic in ``builder``, the record in ``features``, ``loading.load`` for experiments
and ``python -m rp_jax.datasets build|curves`` on the command line.

Importing this package is light (no TFDS): import the submodules you need.
"""

DATASET_NAMES = ("webcam_clipart", "cmu_seasons", "robotcar", "robotcar_day")
CONFIG_NAMES = ("synthetic", "synthetic_small", "synthetic_tiny", "real")
