"""TFDS builder of RobotCar keypoint records over the whole day (T = 24); see the README."""
