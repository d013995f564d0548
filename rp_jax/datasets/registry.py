"""What the project knows about each dataset, in one object per dataset (Sec. IV-A-1, IV-B-1).

A ``Dataset`` bundles a dataset's reader (``rp_jax.sources.<name>``: reading the layout,
the pixels and category maps the ground truth is built on, the camera of those pixels),
how its interest points are verified (Sec. III-D: a static camera for Webcam Clip Art,
known poses for Extended CMU Seasons and Oxford RobotCar) and how its viewpoints are split
(``data_specs/<name>.json``). The TFDS builders, the experiment drivers and the figures
ask ``registry.get(name)`` instead of switching on the name.

Every function a ``Dataset`` holds is a module-level function, so a labelling job that
names its dataset pickles to worker processes and Beam workers.
"""

from __future__ import annotations

import dataclasses
import logging
import types
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax.datasets import DATASET_NAMES
from rp_jax.groundtruth import GroundTruthConfig
from rp_jax.schedule import load_spec
from rp_jax.sources import cmu_seasons, robotcar, webcam_clipart
from rp_jax.sources.capture import Capture
from rp_jax.sources.layout import LayoutError

__all__ = ["DATASETS", "Dataset", "get"]

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class Dataset:
    """One dataset: its reader, its verification and its splits.

    Attributes:
      name: one of ``DATASET_NAMES``.
      reader: the ``rp_jax.sources`` module that reads its real layout (and the synthetic
        one, which has the same layout).
      verification: ``"static"`` (an inlier moves < ``inlier_pixel_threshold`` px, Sec.
        IV-A-1) or ``"pose"`` (epipolar and triangulation checks with known poses).
      read_layout: ``root -> captures`` with (cycle, slot) and viewpoint assigned.
      camera_of: ``capture -> 3x3 K`` of the pixels ``reader.load_image`` returns, or None
        where no camera is needed (static verification) or the capture's own K is right.
      split_of: ``(source, viewpoints) -> {split: viewpoints}``, before the lost-split check.
      layout_viewpoints: ``root -> viewpoints`` the layout holds before the reader drops
        any (None where viewpoints exist only after reading, e.g. RobotCar's pose groups;
        CMU Seasons gives its ``slice<N>/`` folders).
      split_on_layout: the splits are chosen on the layout's viewpoints, not the ones read
        (Webcam Clip Art: a scene whose images were all dropped is not replaced by another
        held-out scene); otherwise ``layout_viewpoints`` only checks that no split is lost.
    """

    name: str
    reader: types.ModuleType
    verification: str
    read_layout: Callable[[Path], list[Capture]]
    camera_of: Callable[[Capture], np.ndarray] | None
    split_of: Callable[[str, Sequence[str]], dict[str, list[str]]]
    layout_viewpoints: Callable[[Path], list[str] | None]
    split_on_layout: bool = False

    @property
    def load_image(self) -> Callable[[Capture], np.ndarray | None]:
        return self.reader.load_image

    @property
    def load_category(self) -> Callable[[Capture], np.ndarray | None]:
        return self.reader.load_category

    def read(self, root: str | Path) -> list[Capture]:
        """Read a layout with the dataset's reader.

        Raises:
          LayoutError: ``root`` is not in the expected layout (the message lists the paths).
        """
        return self.read_layout(Path(root))

    def ground_truth(self, max_keypoints: int) -> GroundTruthConfig:
        """How this dataset's interest points are verified (Sec. IV-A-1, IV-B-1)."""
        if self.verification == "static":
            threshold = float(load_spec(self.name).get("inlier_pixel_threshold", 5.0))
            return GroundTruthConfig(verification="static", static_pixel_threshold=threshold,
                                     max_keypoints=max_keypoints)
        return GroundTruthConfig(verification="pose", max_keypoints=max_keypoints)

    def splits(self, source: str, viewpoints: Iterable[str], *,
               found: Iterable[str] | None = None) -> dict[str, list[str]]:
        """Viewpoint ids of each split, as ``data_specs/<name>.json`` says (Sec. IV-A-1).

        Webcam Clip Art: listed scenes (7 train / 1 test; for a real layout with no list, the
        last scene in sorted order is the test scene). CMU Seasons: slices 6, 7, 9 train and
        8 test. RobotCar: all train; its whole day: one viewpoint in four test. Empty splits
        are dropped.

        Args:
          source: ``"synthetic"`` or ``"real"``.
          viewpoints: the viewpoints of the captures the reader kept.
          found: the viewpoints the layout held before the reader dropped any
            (``layout_viewpoints``). Given, the splits are chosen on them (a scene whose
            images were all dropped is not replaced by another held-out scene), and a split
            that had viewpoints there but keeps none raises ``LayoutError``.
        """
        viewpoints = sorted(set(viewpoints))
        expected = None if found is None else self.split_of(source, sorted(set(found)))
        if expected is not None and self.split_on_layout:
            kept = set(viewpoints)
            out = {split: [v for v in vps if v in kept] for split, vps in expected.items()}
        else:
            out = self.split_of(source, viewpoints)
        if expected is not None:
            lost = {split: vps for split, vps in expected.items() if vps and not out.get(split)}
            if lost:
                what = "; ".join(f"{split!r} ({', '.join(vps)})" for split, vps in lost.items())
                raise LayoutError(
                    f"{self.name}: split {what} lost all its viewpoints: the reader dropped "
                    "every image of them (the read summary logged above names the files and "
                    "why: no capture time, unreadable, no pose, outside every viewpoint or "
                    f"timestamp); fix those files, or list the splits in "
                    f"data_specs/{self.name}.json"
                )
        return {split: vps for split, vps in out.items() if vps}


# ----------------------------------------------------------------------------- Webcam Clip Art


def _webcam_splits(source: str, scenes: Sequence[str]) -> dict[str, list[str]]:
    spec = load_spec("webcam_clipart")["splits"]
    lists = spec.get(source) or {}
    if lists.get("train") is None or lists.get("test") is None:
        # The paper does not name its scenes: hold out the last scene (7 train / 1 test).
        ordered = sorted(scenes)
        held_out = ordered[-1:] if len(ordered) > 1 else []
        log.warning(
            "data_specs/webcam_clipart.json names no %s scenes; test = %s, train = the other %d",
            source, held_out, len(ordered) - len(held_out),
        )
        return {"train": [s for s in ordered if s not in held_out], "test": held_out}
    known = set(lists["train"]) | set(lists["test"])
    unknown = sorted(set(scenes) - known)
    if unknown:
        raise ValueError(
            f"scenes {unknown} are in no split of data_specs/webcam_clipart.json "
            f"(splits.{source}: train {lists['train']}, test {lists['test']})"
        )
    return {split: [s for s in lists[split] if s in scenes] for split in ("train", "test")}


def _webcam_layout_viewpoints(root: Path) -> list[str]:
    return sorted(webcam_clipart.find_scenes(root))


# ----------------------------------------------------------------------------- CMU Seasons


def _cmu_slices(root: Path, splits: Mapping[str, Sequence[int]]) -> list[int]:
    wanted = sorted({int(n) for ns in splits.values() for n in ns})
    if not root.is_dir():
        return wanted  # the reader raises LayoutError naming what it expected
    found = cmu_seasons.find_slices(root)
    present = [n for n in wanted if n in found]
    if not present:
        return wanted  # ditto, listing the slices found
    missing = [n for n in wanted if n not in found]
    if missing:
        log.info("%s: slices %s absent (a reduced layout); reading %s", root, missing, present)
    return present


def _cmu_read(root: Path) -> list[Capture]:
    return cmu_seasons.read(root, slices=_cmu_slices(root, load_spec("cmu_seasons")["splits"]))


def _slice_of(viewpoint: str) -> int:
    head = viewpoint.split("/", 1)[0]
    if not head.startswith("slice") or not head[5:].isdigit():
        raise ValueError(f"CMU viewpoint id {viewpoint!r} is not 'slice<N>/...'")
    return int(head[5:])


def _cmu_splits(source: str, viewpoints: Sequence[str]) -> dict[str, list[str]]:
    spec = load_spec("cmu_seasons")["splits"]
    return {split: [v for v in viewpoints if _slice_of(v) in set(slices)]
            for split, slices in spec.items()}


def _cmu_layout_viewpoints(root: Path) -> list[str]:
    """``slice<N>/`` of the slices whose ``database`` folder holds images."""
    wanted = _cmu_slices(root, load_spec("cmu_seasons")["splits"])
    found = cmu_seasons.find_slices(root) if root.is_dir() else {}
    return [
        f"slice{n}/"
        for n in wanted
        if n in found
        and (found[n] / "database").is_dir()
        and any(p.is_file() for p in (found[n] / "database").iterdir())
    ]


# ----------------------------------------------------------------------------- RobotCar


def _robotcar_splits(source: str, viewpoints: Sequence[str]) -> dict[str, list[str]]:
    return {"train": list(viewpoints)}


def _no_layout_viewpoints(root: Path) -> None:
    return None


def _robotcar_day_splits(source: str, viewpoints: Sequence[str]) -> dict[str, list[str]]:
    """Every ``test_every``-th viewpoint in sorted order from ``test_offset`` is ``test``
    (``data_specs/robotcar_day.json``), the others ``train``."""
    spec = load_spec("robotcar_day")["splits"]
    ordered = sorted(viewpoints)
    test = ordered[int(spec["test_offset"])::int(spec["test_every"])]
    return {"train": [v for v in ordered if v not in test], "test": test}


DATASETS: dict[str, Dataset] = {
    "webcam_clipart": Dataset(
        "webcam_clipart", webcam_clipart, "static", webcam_clipart.read, None,
        _webcam_splits, _webcam_layout_viewpoints, split_on_layout=True,
    ),
    "cmu_seasons": Dataset(
        "cmu_seasons", cmu_seasons, "pose", _cmu_read, cmu_seasons.camera_matrix,
        _cmu_splits, _cmu_layout_viewpoints,
    ),
    "robotcar": Dataset(
        "robotcar", robotcar, "pose", robotcar.read, None, _robotcar_splits,
        _no_layout_viewpoints,
    ),
    "robotcar_day": Dataset(
        "robotcar_day", robotcar, "pose", robotcar.read_day, None, _robotcar_day_splits,
        _no_layout_viewpoints,
    ),
}
assert tuple(DATASETS) == DATASET_NAMES


def get(name: str) -> Dataset:
    """The ``Dataset`` called ``name``; ValueError naming the known ones otherwise."""
    try:
        return DATASETS[name]
    except KeyError:
        raise ValueError(f"unknown dataset {name!r}; known: {', '.join(DATASET_NAMES)}") from None
