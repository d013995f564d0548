"""Config of the Webcam Clip Art experiment (Sec. IV-A-1, Figs. 6a, 7).

    python -m experiments.webcam_clipart                 # synthetic world, full size
    python -m experiments.webcam_clipart --size tiny     # seconds, for tests

T = 21 timestamps every 30 min from 8:00 to 18:00, M = 4 days, 7 training and 1 test
viewpoint; the time input is the time of day (d = 2).

Full size: the number of epochs was chosen on a held-out training scene (1 of 7, with
``--config.input.validation_fraction=0.15 --config.train.num_epochs=8``: validation MSE lowest
at epoch 3 of 8, then rising as the network fits its 6 scenes), so the default run trains 3 epochs
on all 7 training scenes. Colour and zoom augmentation (``--config.input.augment.colour=0.15
--config.input.augment.zoom=0.3``) changed the MAE on 3 held-out training scenes (leave-one-out as
``--cross-validate``, world version 1) by -2.1 %, +0.5 % and +0.8 %, so they are left off.
Expected on the synthetic world (version 2): test MAE 0.117 against 0.192 for the per-slot
mean and 0.189 for the slot-conditioned mean.
"""

from experiments.sec4a import config as sec4a_config


def get_config(size: str = "full"):
    config = sec4a_config.get_config(size)
    config.input.dataset = "webcam_clipart"
    config.input.schedule = "webcam_clipart"  # T = 21
    config.model.time_fields = "time_of_day"  # d = 2 (hour, minute)
    if size == "full":
        config.train.num_epochs = 3  # chosen on a held-out training scene (see the docstring)
        config.input.validation_fraction = 0.0  # then train on all 7 training scenes
        config.train.keep_best = False
    return config
