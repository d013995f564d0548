"""What a predictor says of real photographs: do people, vehicles and foliage score below
facades and ground?

No real photograph of a street with its categories labelled ships with the installed
packages, so each photograph here stands for one category as a whole (its dominant content),
from scikit-image's and matplotlib's sample data. They are used as they are, never to choose
or tune anything: this is a report of what the models say, whichever way it goes.

* people: ``astronaut.png`` (scikit-image; Eileen Collins, NASA) and ``grace_hopper.jpg``
  (matplotlib's sample data): portraits;
* vehicles: ``motorcycle_left.png`` / ``motorcycle_right.png`` (scikit-image; the
  Middlebury stereo pair: a motorcycle in a workshop);
* foliage: ``grass.png`` (scikit-image);
* facade: ``brick.png`` (scikit-image: a brick wall);
* ground: ``gravel.png`` (scikit-image).

Every image's SIFT keypoints (``rp_jax.keypoints.image_keypoints``, at most 500, the image
reduced to the model's training size) are scored as if captured at noon: the score of a
keypoint is its predicted repeatability averaged over the T timestamps.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

__all__ = ["CATEGORIES", "TRANSIENT", "category_scores", "photograph_paths"]

CATEGORIES = {
    "people": ("skimage:astronaut.png", "matplotlib:grace_hopper.jpg"),
    "vehicles": ("skimage:motorcycle_left.png", "skimage:motorcycle_right.png"),
    "foliage": ("skimage:grass.png",),
    "facade": ("skimage:brick.png",),
    "ground": ("skimage:gravel.png",),
}
TRANSIENT = ("people", "vehicles", "foliage")  # expected below the static categories
_NOON = dt.datetime(2024, 6, 1, 12, 0)


def photograph_paths() -> dict[str, list[Path]]:
    """Category -> the installed files (a missing file is left out)."""
    import matplotlib
    import skimage

    roots = {"skimage": Path(skimage.__file__).parent / "data",
             "matplotlib": Path(matplotlib.get_data_path()) / "sample_data"}
    out = {}
    for category, names in CATEGORIES.items():
        paths = [roots[pkg] / name for pkg, name in (n.split(":") for n in names)]
        out[category] = [p for p in paths if p.exists()]
    return out


def category_scores(predictor, paths: dict[str, list[Path]], *, max_keypoints: int = 500,
                    max_size: int | None = 640) -> dict:
    """Per category: keypoints and their mean score (repeatability averaged over the
    cycle's timestamps); ``transient_minus_static``: the mean of people, vehicles and
    foliage minus the mean of facade and ground (negative: as expected)."""
    from rp_jax import keypoints

    rows = {}
    for category, files in paths.items():
        scores = []
        for f in files:
            kp = keypoints.image_keypoints(predictor, f, _NOON, max_keypoints=max_keypoints,
                                           max_size=max_size)
            scores.append(kp.curves.mean(axis=1))
        s = np.concatenate(scores) if scores else np.zeros(0)
        rows[category] = {"images": [f.name for f in files], "keypoints": int(len(s)),
                          "mean_score": float(s.mean()) if len(s) else float("nan")}
    transient = [rows[c]["mean_score"] for c in TRANSIENT if c in rows]
    static = [rows[c]["mean_score"] for c in rows if c not in TRANSIENT]
    return {"categories": rows,
            "transient_minus_static": float(np.mean(transient) - np.mean(static))}
