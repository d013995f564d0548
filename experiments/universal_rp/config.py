"""Config of the many-worlds experiment (``python -m experiments.universal_rp``).

The training and the model are the Webcam Clip Art experiment's (``experiments.webcam_clipart``:
T = 21 slots 8:00-18:00, the time of day as input, 3 epochs at full size); ``universal``
names the worlds:

* ``train_seeds``: world seeds of ``webcam_worlds`` (8 webcams each, cities of
  ``plan_worlds.WORLD_CITIES``) whose webcams train;
* ``unseen_seeds``: world seeds of ``webcam_worlds_unseen`` (4 webcams each, cities of
  ``plan_worlds.UNSEEN_CITIES``): the held-out worlds, never trained or chosen on;
* ``curve``: the learning curve's numbers of training webcams, each the first n of one
  seeded shuffle of all training webcams (``order_seed``), so a larger set holds the smaller;
* ``shipped``: shipped models also judged on the held-out worlds (the 7-scene RP).

Full size: 6 training worlds (48 webcams) and 5 held-out worlds (20 webcams); the curve at
7 (the paper's number of training webcams), 20 and 48.
"""

import ml_collections

from experiments.webcam_clipart import config as webcam_config

_WORLDS = {
    # size: (training world seeds, held-out world seeds, curve)
    "tiny": ((1,), (1,), (1, 2)),
    "small": ((1, 2, 3), (1, 2, 3), (4, 12, 24)),
    "full": ((1, 2, 3, 4, 5, 6), (1, 2, 3, 4, 5), (7, 20, 48)),
}


def get_config(size: str = "full") -> ml_collections.ConfigDict:
    config = webcam_config.get_config(size)
    config.input.validation_fraction = 0.0  # the recipe is the webcam experiment's, unchosen
    config.train.keep_best = False
    train_seeds, unseen_seeds, curve = _WORLDS[size]
    config.universal = ml_collections.ConfigDict({
        "size": size,
        "train_preset": "webcam_worlds",
        "train_seeds": train_seeds,
        "unseen_preset": "webcam_worlds_unseen",
        "unseen_seeds": unseen_seeds,
        "curve": curve,
        "order_seed": 0,
        "shipped": ("webcam_clipart-synthetic",),
    })
    return config


def train_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """The training config (the webcam experiment's fields, without ``universal``)."""
    fields = config.to_dict()
    fields.pop("universal", None)
    return ml_collections.ConfigDict(fields)
