"""rp_jax.datasets: TFDS keypoint records and the input pipeline (Sec. III-D, Sec. IV-A).

One TFDS builder per dataset (``webcam_clipart``, ``cmu_seasons``, ``robotcar`` and its
whole-day variant ``robotcar_day``; configs
``synthetic``, ``synthetic_small``, ``synthetic_tiny``, ``real``) in ``<name>/``, their
shared logic in ``builder``, the record in ``features``, ``loading.load`` for experiments
and ``python -m rp_jax.datasets build|curves`` on the command line.

Importing this package is light (no TFDS): import the submodules you need.
"""

from pathlib import Path

DATASET_NAMES = ("webcam_clipart", "cmu_seasons", "robotcar", "robotcar_day")
CONFIG_NAMES = ("synthetic", "synthetic_small", "synthetic_tiny", "real")
# A build's per-pair outcomes (``outcomes``) live beside its records, in
# ``<data_dir>/rp_jax_outcomes/<dataset>/<config>/<version>``: written by ``outcomes``,
# dropped with the records by a rebuild (``provenance``).
SIDECAR_ROOT = "rp_jax_outcomes"


def sidecar_dir(data_dir: str | Path, dataset: str, config: str, version: str) -> Path:
    """The per-pair outcomes of ``dataset``/``config`` at TFDS ``version`` in ``data_dir``."""
    return Path(data_dir) / SIDECAR_ROOT / dataset / config / str(version)


def builder_sidecar_dir(builder) -> Path:
    """``sidecar_dir`` of a TFDS builder's dataset, config and version."""
    return sidecar_dir(builder._data_dir_root, builder.DATASET, builder.builder_config.name,
                       builder.version)
