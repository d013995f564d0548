"""Config of the whole-day RobotCar experiment (Sec. IV-A's evaluation, Sec. IV-B-1's RP).

    python -m experiments.robotcar_day                 # synthetic world, small (default)
    python -m experiments.robotcar_day --size tiny     # seconds, for tests

T = 24 hourly timestamps 0:00-23:00, M = 1 (one traversal per hour), one viewpoint in four
held out as test (``data_specs/robotcar_day.json``); the time input is the time of day
(d = 2), as the paper's RobotCar RP. The epochs are those of the map-summarization RobotCar
RP at each size (``experiments.map_summarization.config``): this predictor is the one the
RobotCar-Seasons-like map summarization uses.
"""

from experiments.sec4a import config as sec4a_config


def get_config(size: str = "small"):
    config = sec4a_config.get_config(size)
    config.input.dataset = "robotcar_day"
    config.input.schedule = "robotcar_day"  # T = 24
    config.model.time_fields = "time_of_day"  # d = 2 (hour, minute)
    config.train.num_epochs = {"tiny": 2, "small": 3, "full": 5}[size]
    return config
