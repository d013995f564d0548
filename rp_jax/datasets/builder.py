"""Shared logic of the three TFDS builders (Sec. III-D, Sec. IV-A-1, Sec. IV-B-1).

A builder reads a layout with its ``rp_jax.sources`` reader, groups the captures by
viewpoint, splits the viewpoints as ``data_specs/<name>.json`` says, and has
``rp_jax.groundtruth`` label each viewpoint: the points of at most
``sources_per_viewpoint`` source images (84 by default), each matched against every image
of its viewpoint, so a viewpoint of n images costs 84 x n image pairs
(``rp_jax.groundtruth.sources``). The unit of work is a block of a viewpoint's source
images (``BlockJob``), after the features of every image are detected and cached
(``FeatureJob``); both are cached under ``<download_dir>/groundtruth/<name>/<config>/``, so
an interrupted build resumes at the blocks it had not finished. It writes one record per
interest point (``features``) as array_record; no TensorFlow is needed to write or read
(``builder.as_data_source(split)``).

Configs: ``synthetic`` (default; renders the synthetic world at full size into
``<data_dir>/../synthetic/<name>`` when absent, then labels it), ``synthetic_small``,
``synthetic_tiny`` (tests, quick runs) and ``real`` (reads ``manual_dir``).

Scaling out: ``cache_job_features(FeatureJob)`` and ``label_block_examples(BlockJob)`` are
pure, picklable functions; under Apache Beam (``python -m rp_jax.datasets build ...
--beam-pipeline-options=...``, or ``DownloadConfig(beam_options=...)``) the builder maps
the first over every viewpoint's images and, once all features are cached (a side input
waits for them), the second over every (viewpoint, block of sources), so one large viewpoint
is spread over all workers. TFDS orders the records by key either way, so both builds hold
the same records in the same order (tests/datasets/test_beam.py).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import inspect
import json
import logging
import os
import types
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import tensorflow_datasets as tfds
from etils import epath
from tensorflow_datasets.core import utils as tfds_utils

from rp_jax.datasets import CONFIG_NAMES, DATASET_NAMES, registry
from rp_jax.datasets import features as features_lib
from rp_jax.groundtruth import (
    GroundTruthConfig,
    attach_patches,
    label_viewpoint,
    label_viewpoint_block,
    label_viewpoints,
    viewpoint_block_count,
)
from rp_jax.groundtruth.blocks import cache_features
from rp_jax.groundtruth.viewpoint import FEATURE_JOB_IMAGES
from rp_jax.schedule import preset
from rp_jax.sources.capture import Capture
from rp_jax.sources.layout import LayoutError

__all__ = [
    "CONFIG_NAMES",
    "DATASET_NAMES",
    "DEFAULT_SOURCES_PER_VIEWPOINT",
    "BlockJob",
    "FeatureJob",
    "RepeatabilityBuilder",
    "RepeatabilityConfig",
    "ViewpointJob",
    "beam_pipeline_options",
    "block_jobs",
    "builder_configs",
    "cache_job_features",
    "feature_jobs",
    "label_block_examples",
    "label_viewpoint_examples",
    "synthetic_root",
    "viewpoint_jobs",
]

log = logging.getLogger(__name__)

_GENERATION_JSON = Path("_synthetic") / "generation.json"  # written by synthetic.generate


# ----------------------------------------------------------------------------- configs


@dataclasses.dataclass(eq=False)
class RepeatabilityConfig(tfds.core.BuilderConfig):
    """A BuilderConfig: which layout is read and how many interest points per image.

    Attributes:
      source: ``"synthetic"`` (rendered by ``rp_jax.sources.synthetic``) or ``"real"``
        (the downloaded dataset in ``manual_dir``).
      size: synthetic size, ``"full"``, ``"small"`` or ``"tiny"`` (ignored for real).
      seed: synthetic world seed.
      max_keypoints: interest points per image (strongest first), see GroundTruthConfig;
        all of them take part in matching.
      records_per_image: how many of an image's interest points become records (a seeded
        random choice; 0 = all). Matching against every keypoint keeps the labels right,
        while the dataset stays near the paper's size (72,160 training points from 7
        Webcam Clip Art viewpoints, about 120 per image).
      sources_per_viewpoint: how many images of a viewpoint give records (source images,
        spread over its timestamps and cycles, each matched against every image;
        ``GroundTruthConfig.max_sources``); 0 = every image (all pairs, n^2).
    """

    source: str = "synthetic"
    size: str = "full"
    seed: int = 0
    max_keypoints: int = 1000
    records_per_image: int = 0
    sources_per_viewpoint: int = 0


# The paper's Webcam Clip Art viewpoint gives records from M = 4 days x T = 21 timestamps =
# 84 images (Sec. IV-A-1; 72,160 training points from 7 viewpoints: about 120 per image),
# while a real viewpoint holds about 10,000 images: 84 source images keep the records at
# the paper's number whatever a viewpoint's size, and make its cost linear in it. Every
# synthetic viewpoint has at most 84 images, so all of them are sources there.
DEFAULT_SOURCES_PER_VIEWPOINT = 84


def builder_configs(records_per_image: int = 120,
                    sources_per_viewpoint: int = DEFAULT_SOURCES_PER_VIEWPOINT,
                    ) -> list[RepeatabilityConfig]:
    """The four configs every builder offers, ``synthetic`` first (the default).

    ``records_per_image`` (synthetic full/small and real) keeps a dataset near the paper's
    size: 120 for Webcam Clip Art (72,160 training points from 7 viewpoints), 32 for
    Extended CMU Seasons (45,870 + 15,856 points from about 1,900 images).
    ``sources_per_viewpoint`` (every config): ``DEFAULT_SOURCES_PER_VIEWPOINT``.
    """
    return [
        RepeatabilityConfig(
            name="synthetic",
            source="synthetic",
            size="full",
            records_per_image=records_per_image,
            sources_per_viewpoint=sources_per_viewpoint,
            description="The synthetic world at the paper's scale (rendered if absent).",
        ),
        RepeatabilityConfig(
            name="synthetic_small",
            source="synthetic",
            size="small",
            max_keypoints=500,
            records_per_image=records_per_image,
            sources_per_viewpoint=sources_per_viewpoint,
            description="A smaller synthetic world for a quick look (minutes).",
        ),
        RepeatabilityConfig(
            name="synthetic_tiny",
            source="synthetic",
            size="tiny",
            max_keypoints=150,
            sources_per_viewpoint=sources_per_viewpoint,
            description="A tiny synthetic world for tests (seconds).",
        ),
        RepeatabilityConfig(
            name="real",
            source="real",
            records_per_image=records_per_image,
            sources_per_viewpoint=sources_per_viewpoint,
            description="The real dataset, downloaded by hand into manual_dir.",
        ),
    ]


# ----------------------------------------------------------------------------- labelling


@dataclasses.dataclass(frozen=True)
class ViewpointJob:
    """Everything needed to label one viewpoint; picklable (Beam, processes).

    Attributes:
      dataset: one of ``DATASET_NAMES`` (selects the reader's ``load_image`` etc.).
      viewpoint: the viewpoint id.
      captures: its captures, (cycle, slot) assigned.
      num_timestamps: T of the dataset's schedule.
      config: ground-truth settings.
      cache_dir: per-viewpoint cache (resume), or None.
    """

    dataset: str
    viewpoint: str
    captures: tuple[Capture, ...]
    num_timestamps: int
    config: GroundTruthConfig
    cache_dir: str | None = None
    records_per_image: int = 0
    seed: int = 0

    def label_kwargs(self) -> dict:
        """Keyword arguments of ``groundtruth.label_viewpoint(s)`` for this dataset."""
        dataset = registry.get(self.dataset)
        return {
            "load_image": dataset.load_image,
            "num_timestamps": self.num_timestamps,
            "config": self.config,
            "cache_dir": self.cache_dir,
            "camera_of": dataset.camera_of,
            "load_category": dataset.load_category,
        }


def select_records(records: Mapping[str, np.ndarray], per_image: int, seed: int = 0) -> dict:
    """Keep at most ``per_image`` rows of each image, a seeded random choice (0 = all rows).

    The choice depends only on (seed, viewpoint, image id, its row count), so a rebuild or a
    Beam run picks the same records.
    """
    n = len(records["image_id"])
    if per_image <= 0 or n == 0:
        return dict(records)
    keep = np.zeros(n, bool)
    image_ids = np.asarray(records["image_id"]).astype(str)
    viewpoints = np.asarray(records["viewpoint"]).astype(str)
    for image_id in np.unique(image_ids):
        rows = np.flatnonzero(image_ids == image_id)
        if len(rows) <= per_image:
            keep[rows] = True
            continue
        key = f"{viewpoints[rows[0]]}|{image_id}".encode()
        digest = int.from_bytes(hashlib.sha1(key).digest()[:4], "little")
        rng = np.random.default_rng([seed, digest])
        keep[np.sort(rng.choice(rows, per_image, replace=False))] = True
    return {k: np.asarray(v)[keep] for k, v in records.items()}


def label_viewpoint_examples(job: ViewpointJob) -> list[tuple[str, dict]]:
    """``(key, example)`` of the interest points of one viewpoint (pure; Beam-mappable).

    Patches are cut for the selected records only (the caches hold none).
    """
    kwargs = job.label_kwargs()
    records = label_viewpoint(list(job.captures), **kwargs, with_patches=False)
    records = select_records(records, job.records_per_image, job.seed)
    records = attach_patches(records, job.captures, kwargs["load_image"])
    return list(features_lib.records_to_examples(records))


@dataclasses.dataclass(frozen=True)
class FeatureJob:
    """Detect and cache the features of images ``start:stop`` of a viewpoint (picklable)."""

    job: ViewpointJob
    start: int
    stop: int


@dataclasses.dataclass(frozen=True)
class BlockJob:
    """Label block ``block`` of a viewpoint's source images (picklable; Beam, processes)."""

    job: ViewpointJob
    block: int


def feature_jobs(jobs: Sequence[ViewpointJob]) -> list[FeatureJob]:
    """The ``FeatureJob`` s of every viewpoint, ``FEATURE_JOB_IMAGES`` images each."""
    return [FeatureJob(j, s, min(len(j.captures), s + FEATURE_JOB_IMAGES))
            for j in jobs for s in range(0, len(j.captures), FEATURE_JOB_IMAGES)]


def block_jobs(jobs: Sequence[ViewpointJob]) -> list[BlockJob]:
    """The ``BlockJob`` s of every viewpoint (``groundtruth.viewpoint_block_count``)."""
    return [BlockJob(j, k) for j in jobs
            for k in range(viewpoint_block_count(len(j.captures), j.config))]


def cache_job_features(job: FeatureJob) -> int:
    """Detect and cache a ``FeatureJob`` 's features (pure; Beam-mappable); returns how many
    images were readable."""
    kwargs = job.job.label_kwargs()
    if kwargs["cache_dir"] is None:
        return 0  # nothing to share: each block detects what it needs
    return cache_features(
        job.job.captures[job.start:job.stop], load_image=kwargs["load_image"],
        config=kwargs["config"], cache_dir=kwargs["cache_dir"],
        load_category=kwargs["load_category"])


def label_block_examples(job: BlockJob, features_done: int = 0) -> list[tuple[str, dict]]:
    """``(key, example)`` of the selected interest points of one block of a viewpoint's
    source images (pure; Beam-mappable). The blocks of a viewpoint together give the
    examples of ``label_viewpoint_examples``: the selection is per image.

    ``features_done``: ignored; the Beam pipeline passes the feature jobs' total as a side
    input so that no block starts before every image's features are cached.
    """
    kwargs = job.job.label_kwargs()
    captures = list(job.job.captures)
    records = label_viewpoint_block(captures, job.block, **kwargs)
    records = select_records(records, job.job.records_per_image, job.job.seed)
    records = attach_patches(records, captures, kwargs["load_image"])
    return list(features_lib.records_to_examples(records))


def viewpoint_jobs(
    name: str,
    captures: Sequence[Capture],
    viewpoint_ids: Sequence[str],
    *,
    config: GroundTruthConfig,
    cache_dir: str | Path | None,
    records_per_image: int = 0,
    seed: int = 0,
) -> list[ViewpointJob]:
    """One ``ViewpointJob`` per viewpoint id (captures grouped by ``capture.viewpoint``)."""
    by_viewpoint: dict[str, list[Capture]] = {}
    for c in captures:
        by_viewpoint.setdefault(c.viewpoint, []).append(c)
    T = preset(name).num_timestamps
    return [
        ViewpointJob(
            name,
            vp,
            tuple(by_viewpoint[vp]),
            T,
            config,
            None if cache_dir is None else str(cache_dir),
            records_per_image,
            seed,
        )
        for vp in viewpoint_ids
    ]


# ----------------------------------------------------------------------------- synthetic


def synthetic_root(data_dir_root: str | Path, name: str, size: str, seed: int = 0) -> Path:
    """Where a synthetic layout goes: ``<data_dir>/../synthetic/<name>[_<size>][_seed<s>]``."""
    folder = name if size == "full" else f"{name}_{size}"
    if seed:
        folder += f"_seed{seed}"
    return Path(data_dir_root).resolve().parent / "synthetic" / folder


def ensure_synthetic(name: str, root: Path, *, size: str, seed: int, workers: int | None) -> Path:
    """Render the synthetic preset into ``root`` unless a finished one is there.

    ``generate`` is itself resumable (existing frames are skipped); its
    ``_synthetic/generation.json`` marks a finished layout.

    Raises:
      ValueError: ``root`` holds a synthetic layout of another preset, size or seed.
    """
    from rp_jax.sources.synthetic import generate, presets

    marker = root / _GENERATION_JSON
    if marker.is_file():
        done = json.loads(marker.read_text())
        want = {"preset": name, "size": size, "seed": seed}
        have = {k: done.get(k) for k in want}
        if have != want:
            raise ValueError(
                f"{root} holds the synthetic layout {have}, not {want}; "
                "remove it or choose another synthetic_root"
            )
        if not presets.discard_older_world(root, done):
            return root

    log.info("rendering the synthetic %s world (%s) into %s", name, size, root)
    return generate(name, root, size=size, seed=seed, workers=workers)


# ----------------------------------------------------------------------------- TF-free writing


class _NeverRaised(Exception):
    """Stands in for ``tf.errors.ResourceExhaustedError`` (Python I/O raises OSError)."""


# What TFDS's shuffler needs of TensorFlow: local file I/O.
_PYTHON_FILE_IO = types.SimpleNamespace(
    io=types.SimpleNamespace(
        gfile=types.SimpleNamespace(
            GFile=lambda path, mode: open(os.fspath(path), mode),  # noqa: SIM115
            exists=lambda path: os.path.exists(os.fspath(path)),
            remove=lambda path: os.remove(os.fspath(path)),
        )
    ),
    errors=types.SimpleNamespace(ResourceExhaustedError=_NeverRaised),
)


def _tensorflow_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("tensorflow") is not None


def _raise_open_file_limit(wanted: int) -> None:
    try:
        import resource
    except ImportError:  # not POSIX
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < wanted:
        new = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
        resource.setrlimit(resource.RLIMIT_NOFILE, (new, hard))


@contextlib.contextmanager
def tf_free_shuffler():
    """Let TFDS write splits larger than its 1 GB in-memory buffer without TensorFlow.

    Past ``MAX_MEM_BUFFER_SIZE`` TFDS's shuffler spills examples to 1000 bucket files
    through ``tf.io.gfile`` (``tensorflow_datasets/core/shuffle.py``), the only step of a
    generator build that needs TensorFlow. Without TensorFlow, this points that module's
    ``tf`` at Python's local file I/O for the duration (local data dirs only), and raises
    the open-file limit for the buckets. With TensorFlow installed it does nothing.
    """
    if _tensorflow_installed():
        yield
        return
    from tensorflow_datasets.core import shuffle

    _raise_open_file_limit(shuffle.BUCKETS_NUMBER + 256)
    previous = shuffle.tf
    shuffle.tf = _PYTHON_FILE_IO
    try:
        yield
    finally:
        shuffle.tf = previous


# ----------------------------------------------------------------------------- builder


def _no_bucket() -> None:
    """``DatasetInfo.initialize_from_bucket`` of builders that nothing on GCS describes."""


def beam_pipeline_options(text: str):
    """Beam ``PipelineOptions`` from ``"runner=DirectRunner,direct_num_workers=2"`` (the
    spelling of ``tfds build --beam_pipeline_options``); needs ``pip install rp_jax[beam]``."""
    beam = tfds.core.lazy_imports.apache_beam
    flags = [f"--{item.strip()}" for item in text.split(",") if item.strip()]
    return beam.options.pipeline_options.PipelineOptions(flags=flags)


def _default_workers() -> int:
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    return max(1, min(2, cores))


class RepeatabilityBuilder(tfds.core.GeneratorBasedBuilder, skip_registration=True):
    """Base of the three builders; a subclass sets ``DATASET`` and the TFDS class fields.

    Extra constructor arguments (also through ``tfds.builder(name, ...)``):
      synthetic_root: where the synthetic layout is (or is rendered); default
        ``synthetic_root(data_dir, name, size, seed)``.
      workers: processes labelling viewpoints in parallel (default min(2, cores)).
      file_format: default ``"array_record"`` (random access, no TensorFlow).
    """

    DATASET: str = ""
    BUILDER_CONFIGS = builder_configs()
    DEFAULT_CONFIG_NAME = "synthetic"

    def __init__(
        self,
        *,
        synthetic_root: str | Path | None = None,
        workers: int | None = None,
        file_format=None,
        **kwargs,
    ):
        self._synthetic_root = None if synthetic_root is None else Path(synthetic_root)
        self._workers = workers or _default_workers()
        self._use_beam = False
        super().__init__(file_format=file_format or "array_record", **kwargs)
        self._original_state.update(
            synthetic_root=synthetic_root, workers=workers, file_format=file_format
        )

    @tfds_utils.classproperty
    @classmethod
    def code_path(cls) -> epath.Path:
        # TFDS's own lookup imports ``importlib_resources`` (not installed here) for a
        # builder defined in a package; the file of the class is all it needs.
        return epath.Path(inspect.getfile(cls))

    # -- TFDS hooks

    def _info(self) -> tfds.core.DatasetInfo:
        T = preset(self.DATASET).num_timestamps
        info = self.dataset_info_from_configs(
            features=features_lib.features_dict(T),
            supervised_keys=None,
            metadata=tfds.core.MetadataDict(
                schedule=preset(self.DATASET).to_dict(),
                num_timestamps=T,
            ),
        )
        # TFDS asks GCS for pre-computed info of every builder not yet built, and first makes
        # an empty /tmp/tmp*tfds folder it never removes (one per build and per experiment
        # run). Nothing of these datasets is on GCS: skip the look-up.
        info.initialize_from_bucket = _no_bucket
        return info

    def is_prepared(self) -> bool:
        """TFDS's answer, without its "Variant folder ... has no dataset_info.json" warning
        for a dataset not built yet (every first build and every load check said it)."""
        return (Path(self.data_path) / "dataset_info.json").exists() and super().is_prepared()

    def _download_and_prepare(self, dl_manager, download_config, **kwargs):
        # Beam is used only when asked for (tfds build --beam_pipeline_options=...).
        self._use_beam = bool(download_config.beam_runner or download_config.beam_options)
        with tf_free_shuffler():
            out = super()._download_and_prepare(dl_manager, download_config, **kwargs)
        if self.builder_config.source != "real":
            # Which synthetic world the records come from, beside them (TFDS builds in a
            # temporary folder that becomes ``data_dir``): ``provenance.prepare`` builds
            # again what a world or labelling of this code would not give.
            from rp_jax.datasets import provenance
            from rp_jax.sources.synthetic import output_folder

            provenance.record_synthetic(
                self, output_folder.folder_parameters(self.synthetic_layout_root()) or {})
        return out

    def synthetic_layout_root(self) -> Path:
        """Where this synthetic config's layout is (rendered or not)."""
        cfg = self.builder_config
        return self._synthetic_root or synthetic_root(
            self._data_dir_root, self.DATASET, cfg.size, cfg.seed
        )

    def layout_root(self, dl_manager) -> Path:
        """The folder read: ``manual_dir`` (real) or the synthetic layout (rendered if absent)."""
        cfg = self.builder_config
        if cfg.source == "real":
            try:
                return Path(dl_manager.manual_dir)
            except AssertionError as err:  # TFDS: absent or empty, with the instructions
                raise LayoutError(str(err)) from err
        return ensure_synthetic(self.DATASET, self.synthetic_layout_root(), size=cfg.size,
                                seed=cfg.seed, workers=self._workers)

    def cache_dir(self, dl_manager) -> Path:
        """Per-viewpoint ground-truth cache of this dataset and config (resume)."""
        return (
            Path(dl_manager.download_dir) / "groundtruth" / self.DATASET / self.builder_config.name
        )

    def _split_generators(self, dl_manager):
        return {
            split: self._generate_examples(jobs)
            for split, jobs in self.split_jobs(dl_manager).items()
        }

    def local_download_manager(self, manual_dir: str | Path | None = None):
        """What ``layout_root`` and ``cache_dir`` read of a download manager, without TFDS's
        (no build): ``<data_dir>/downloads`` and the manual dir (default under it)."""
        download_dir = Path(self._data_dir_root) / "downloads"
        return types.SimpleNamespace(
            download_dir=download_dir,
            manual_dir=Path(manual_dir) if manual_dir else download_dir / "manual",
        )

    def split_jobs(self, dl_manager) -> dict[str, list[ViewpointJob]]:
        """Split -> the ``ViewpointJob`` of each of its viewpoints, as a build labels them
        (``rp_jax.datasets.outcomes`` reads the same jobs for the per-pair outcomes)."""
        cfg = self.builder_config
        root = self.layout_root(dl_manager)
        dataset = registry.get(self.DATASET)
        try:
            captures = dataset.read(root)
        except LayoutError as err:
            if cfg.source == "real":
                raise LayoutError(f"{err}\n\n{self.MANUAL_DOWNLOAD_INSTRUCTIONS}") from err
            raise
        if not captures:
            raise LayoutError(
                f"{root}: the {self.DATASET} reader found no usable capture "
                "(see the read summary logged above)"
            )
        splits = dataset.splits(cfg.source, {c.viewpoint for c in captures},
                                found=dataset.layout_viewpoints(root))
        gt_config = dataclasses.replace(dataset.ground_truth(cfg.max_keypoints),
                                        max_sources=cfg.sources_per_viewpoint)
        cache = self.cache_dir(dl_manager)
        log.info("%s/%s: %s", self.DATASET, cfg.name, {s: len(v) for s, v in splits.items()})
        return {
            split: viewpoint_jobs(self.DATASET, captures, vps, config=gt_config, cache_dir=cache,
                                  records_per_image=cfg.records_per_image, seed=cfg.seed)
            for split, vps in splits.items()
        }

    def _generate_examples(self, jobs: Sequence[ViewpointJob]):
        if self._use_beam:
            return _beam_labelling(jobs)
        return self._generate_locally(jobs)

    def _generate_locally(self, jobs: Sequence[ViewpointJob]):
        if not jobs:
            return
        kwargs = jobs[0].label_kwargs()
        by_viewpoint = {j.viewpoint: list(j.captures) for j in jobs}
        select = functools.partial(
            select_records, per_image=jobs[0].records_per_image, seed=jobs[0].seed
        )
        for _, records in label_viewpoints(
            by_viewpoint, workers=self._workers, select=select, **kwargs
        ):
            yield from features_lib.records_to_examples(records)


def _beam_labelling(jobs: Sequence[ViewpointJob]):
    """The Beam transform of a split: every image's features, then every block of sources.

    Reshuffle after each Create: else a runner fuses the work into Create, and the one
    worker that made the list does all of it. The blocks take the feature jobs' total as a
    side input, which a runner computes before the step that reads it, so no block detects
    an image that a feature job is still detecting.
    """
    beam = tfds.core.lazy_imports.apache_beam

    class _Labelling(beam.PTransform):
        def expand(self, root):
            features = (
                root
                | "feature jobs" >> beam.Create(feature_jobs(jobs))
                | "spread feature jobs" >> beam.Reshuffle()
                | "detect" >> beam.Map(cache_job_features)
                | "all features" >> beam.CombineGlobally(sum)
            )
            return (
                root
                | "block jobs" >> beam.Create(block_jobs(jobs))
                | "spread block jobs" >> beam.Reshuffle()
                | "label blocks" >> beam.FlatMap(
                    label_block_examples, features_done=beam.pvalue.AsSingleton(features))
            )

    return _Labelling()
