"""Speed of rp_jax against what users would otherwise write: PyTorch and OpenCV.

``python -m experiments.benchmark`` times the repeatability predictor (Sec. III-B, III-C:
train step and batched prediction) against the same network in PyTorch, the ground-truth
matcher (Sec. III-D) against ``cv2.BFMatcher``, ground-truth labelling against the number
of images of a viewpoint, map summarization (Sec. V-A) against K-cover, and per-query
localization (Sec. V-B) against plain OpenCV; see ``stages.py`` and ``mapsum_stages.py`` for
the method and ``report.py`` for the output.
"""
