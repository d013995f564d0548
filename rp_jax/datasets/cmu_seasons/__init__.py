"""TFDS builder of Extended CMU Seasons keypoint records (Sec. IV-A-1); see the README."""
