"""rp_jax.mapsum."""
