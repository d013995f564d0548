"""rp_jax.localize."""
