"""Config of the Webcam Clip Art experiment (Sec. IV-A-1, Figs. 6a, 7).

    python -m experiments.webcam_clipart                 # synthetic world, full size
    python -m experiments.webcam_clipart --size tiny     # seconds, for tests

T = 21 timestamps every 30 min from 8:00 to 18:00, M = 4 days, 7 training and 1 test
viewpoint; the time input is the time of day (d = 2).
"""

from rp_jax.configs import experiment


def get_config(size: str = "full"):
    config = experiment.get_config(size)
    config.dataset = "webcam_clipart"
    config.schedule = "webcam_clipart"  # T = 21
    config.time_fields = "time_of_day"  # d = 2 (hour, minute)
    return config
