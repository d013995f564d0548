"""The experiments of Sec. IV-A (repeatability prediction): the shared driver, its config
and cross-validation over training viewpoints; ``experiments.webcam_clipart`` and
``experiments.cmu_seasons`` are its two entry points."""
