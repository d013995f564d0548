"""TFDS builder of Oxford RobotCar keypoint records (Sec. IV-B-1); see the README."""
