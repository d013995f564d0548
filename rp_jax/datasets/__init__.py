"""rp_jax.datasets."""
