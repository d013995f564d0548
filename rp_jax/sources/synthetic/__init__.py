"""The synthetic world: rendered stand-ins for the paper's datasets (Sec. IV).

The paper's datasets (Webcam Clip Art, Extended CMU Seasons, Oxford RobotCar) cannot be
downloaded here. This package renders a street world under real sun, weather and seasons
(``scene``, ``render``, ``sun``, ...) and writes it in each real dataset's on-disk layout
(``presets``, ``write_layout``, ``route``), so ``rp_jax.sources`` reads it like the real data.

Entry points::

    python -m rp_jax.sources.synthetic webcam_clipart OUT_DIR --size tiny
    python -m rp_jax.sources.synthetic contact-sheet OUT.png

    from rp_jax.sources.synthetic import generate
    generate("cmu_seasons", Path("data/cmu"), size="small", seed=0)
"""

from rp_jax.sources.synthetic.presets import PRESET_NAMES, SIZES, generate

__all__ = ["PRESET_NAMES", "SIZES", "generate"]
