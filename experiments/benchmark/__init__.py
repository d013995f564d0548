"""Speed of rp_jax against what users would otherwise write: PyTorch and OpenCV.

``python -m experiments.benchmark`` times the repeatability predictor (Sec. III-B, III-C:
train step and batched prediction) against the same network in PyTorch, the ground-truth
matcher (Sec. III-D) against ``cv2.BFMatcher``, and ground-truth labelling against the number
of images of a viewpoint; see ``stages.py`` for the method and ``report.py`` for the output.
"""
