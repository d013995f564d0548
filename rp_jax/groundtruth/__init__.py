"""rp_jax.groundtruth."""
