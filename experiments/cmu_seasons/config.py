"""Config of the Extended CMU Seasons experiment (Sec. IV-A-1, Figs. 6b, 8, 9).

    python -m experiments.cmu_seasons                 # synthetic world, full size
    python -m experiments.cmu_seasons --size tiny     # seconds, for tests

T = 12 dates per year (Mar 04 ... Dec 21), M = 1 year, slices 6, 7, 9 train and 8 test;
the time input is the day of the year (d = 2).
"""

from experiments.sec4a import config as sec4a_config


def get_config(size: str = "full"):
    config = sec4a_config.get_config(size)
    config.input.dataset = "cmu_seasons"
    config.input.schedule = "cmu_seasons"  # T = 12
    config.model.time_fields = "day_of_year"  # d = 2 (day, month)
    return config
