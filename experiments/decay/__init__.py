"""Beyond the paper (issue 17): is there a long-term decay of repeatability to learn?

``python -m experiments.decay --size small`` renders the synthetic Webcam scenes on the
same days of six years with the world's slow changes on (``webcam_years``) and off
(``webcam_years_frozen``), labels both with the ground truth's per-image outcomes, and
reports the inlier fraction against the years between a point's image and the target
image (``measure``).
"""
