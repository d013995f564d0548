"""rp_jax: Learning to Predict Repeatability of Interest Points (Doan et al.) in JAX/Flax."""

__version__ = "0.1.0"
