"""Entry points that reproduce the paper's experiments (thin: the logic is in rp_jax)."""
