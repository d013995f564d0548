"""Readers of the real dataset layouts, yielding ``Capture`` records, and the synthetic world."""

from rp_jax.sources.capture import Camera, Capture

__all__ = ["Camera", "Capture"]
