"""rp_jax.sources.synthetic."""
