"""TFDS builder of Webcam Clip Art keypoint records (Sec. IV-A-1); see the README."""
