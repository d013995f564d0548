"""What a built real dataset was built from, so that another download is never read as it.

A real build (``--manual-dir``) reads the download in ``manual_dir``, and TFDS keys what it
builds by the data directory alone: without more, building webcam_clipart/real from a
second download B into a data directory already holding it built from A prints "already
built" and A's counts, and an experiment on B trains and tests on A's records.

So ``prepare`` writes, next to the built records, ``built_from.json``: a fingerprint of the
layout it was built from (every file's path relative to the root, its size and mtime;
hashed) and of the labelling (the builder's version and config, the ground-truth settings,
the data spec). A later ``prepare`` with a ``manual_dir`` recomputes both and refuses, naming
what differs and what to do, when they are not the same.

A synthetic build records the same way which world it read (the rendered layout's marker:
preset, size, seed and world version) and its labelling. Its records are the tool's own,
made again at will, so a later ``prepare`` builds it again, saying why, when this code
renders another version of that world or labels otherwise (a build older than these
records, too): without that, a world made right (say, a city's climate) kept feeding the
old records to every experiment run in a data directory that had built them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import logging
import os
import shutil
from pathlib import Path

from rp_jax import files
from rp_jax.sources.layout import LayoutError

__all__ = [
    "BUILT_FROM_JSON",
    "BuiltFromAnotherLayoutError",
    "build_lock",
    "labelling_fingerprint",
    "layout_fingerprint",
    "prepare",
    "record_synthetic",
    "synthetic_staleness",
]

log = logging.getLogger(__name__)

BUILT_FROM_JSON = "built_from.json"


class BuiltFromAnotherLayoutError(LayoutError):
    """A built real dataset was built from another layout or labelling than the one given.

    A ``LayoutError``, so that every command reports it in one line (exit status 2).
    """


def layout_fingerprint(root: str | os.PathLike) -> dict:
    """Files, bytes and a digest of (relative path, size, mtime in ns) of every file.

    Hidden files and folders (names starting with ``.``) are left out: they are not part
    of a dataset's layout (``.DS_Store``, editor files).
    """
    root = Path(root).absolute()
    h = hashlib.sha256()
    n_files, total = 0, 0
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for name in sorted(filenames):
            if name.startswith("."):
                continue
            path = Path(dirpath) / name
            try:
                st = path.stat()
            except OSError:  # a dangling link: not a file of the layout
                continue
            rel = path.relative_to(root).as_posix()
            h.update(f"{rel}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
            n_files += 1
            total += st.st_size
    return {"root": str(root), "files": n_files, "bytes": total, "digest": h.hexdigest()}


# Fields of data_specs/<name>.json that the labelling never reads (the camera's place, for the
# sun of the conditional predictor's sidecar): adding one leaves every build valid.
SPEC_FIELDS_NOT_LABELLING = ("location", "location_note")


def labelling_fingerprint(builder) -> dict:
    """What turns the layout into records: builder version and config, ground truth, spec."""
    from rp_jax.datasets import registry
    from rp_jax.schedule import load_spec

    cfg = builder.builder_config
    payload = {
        "dataset": builder.DATASET,
        "version": str(builder.VERSION),
        "config": {
            "name": cfg.name,
            "max_keypoints": cfg.max_keypoints,
            "records_per_image": cfg.records_per_image,
            "seed": cfg.seed,
        },
        "ground_truth": dataclasses.asdict(
            registry.get(builder.DATASET).ground_truth(cfg.max_keypoints)),
        "data_spec": {k: v for k, v in load_spec(builder.DATASET).items()
                      if k not in SPEC_FIELDS_NOT_LABELLING},
    }
    text = json.dumps(payload, sort_keys=True, default=str)
    return {"digest": hashlib.sha256(text.encode()).hexdigest(), **payload}


def _path(builder) -> Path:
    return Path(builder.data_dir) / BUILT_FROM_JSON


@contextlib.contextmanager
def _local_build_messages(builder):
    """TFDS's download messages ("Downloading and preparing dataset Unknown size ...", in bold
    on stdout) and its own bars say nothing true of a build that downloads nothing; the
    labelling's own progress (``rp_jax.progress``) and one log line say what happens."""
    import tensorflow_datasets as tfds

    log.info("building %s/%s in %s (labelled here; nothing is downloaded)", builder.name,
             builder.builder_config.name, builder.data_dir)
    builder._log_download_bytes = builder._log_download_done = lambda: None
    tfds.disable_progress_bar()  # its bars redraw with control codes, even in a log
    try:
        yield
    finally:
        del builder._log_download_bytes, builder._log_download_done


@contextlib.contextmanager
def build_lock(builder):
    """Hold the build of ``builder``'s dataset/config/version (one process at a time) and
    remove the partial builds (TFDS's ``incomplete.*`` folders) that killed builds left.

    TFDS builds into ``<config>/incomplete.XXXXXX_<version>/`` and renames it when done; a
    build killed meanwhile leaves it for ever (one of 7 MB was found). Every build here takes
    this lock (``rp_jax.workdir_lock``: ``fcntl.flock`` on ``<config>/.<version>.build.lock``,
    released by the kernel when its holder dies, the file naming its holder), so under the
    lock no other build is writing one: each such folder of this version is stale and is
    removed. Other versions' folders are not touched. A second build of the same version
    waits for the first, saying whom it waits for (process id and start time), then finds
    the dataset built: the data directory is a cache shared by runs, unlike a workdir.
    """
    from rp_jax import workdir_lock

    data_dir = Path(builder.data_dir)
    lock = data_dir.parent / f".{data_dir.name}.build.lock"
    with workdir_lock.hold_file(lock, lambda who: f"{data_dir} is being built by {who}",
                                wait=True):
        for stale in sorted(data_dir.parent.glob(f"incomplete.*_{data_dir.name}")):
            if stale.is_dir() and not stale.is_symlink():
                log.warning("removing %s, the partial build of a killed run", stale)
                shutil.rmtree(stale)
        yield


def _check(builder, manual_dir: Path) -> None:
    path = _path(builder)
    where = f"{builder.name}/{builder.builder_config.name} in {builder.data_dir}"
    if not path.is_file():
        log.warning(
            "%s was built before builds recorded their layout: it cannot be checked against "
            "%s; delete %s to rebuild it from there", where, manual_dir, builder.data_dir
        )
        return
    built = json.loads(path.read_text())
    layout = layout_fingerprint(manual_dir)
    labelling = labelling_fingerprint(builder)
    old_layout, old_labelling = built.get("layout", {}), built.get("labelling", {})
    remedy = (
        f"give another TFDS data directory (--data-dir) for this one, or delete "
        f"{builder.data_dir} to rebuild it there"
    )
    if old_layout.get("digest") != layout["digest"]:
        same_root = old_layout.get("root") == layout["root"]
        raise BuiltFromAnotherLayoutError(
            f"{where} was built from {old_layout.get('root')} ({old_layout.get('files')} files, "
            f"{old_layout.get('bytes')} bytes), not from {layout['root']} ({layout['files']} "
            f"files, {layout['bytes']} bytes"
            + ("; the same folder, but its files changed since" if same_root else "")
            + f"): {remedy}"
        )
    if old_labelling.get("digest") != labelling["digest"]:
        raise BuiltFromAnotherLayoutError(
            f"{where} was labelled with other settings "
            f"({_labelling_changes(old_labelling, labelling)} differ): {remedy}"
        )


def _labelling_changes(old: dict, new: dict) -> str:
    """The fields of two ``labelling_fingerprint`` records that differ, in words."""
    changed = sorted(k for k in new if k != "digest"
                     and old.get(k) != json.loads(json.dumps(new[k], default=str)))
    return ", ".join(changed) or "unknown"


def record_synthetic(builder, marker: dict) -> None:
    """Write, beside a synthetic build's records, the marker of the world it read and its
    labelling (``RepeatabilityBuilder`` does, at the end of every build)."""
    _record(builder, synthetic=marker)


def synthetic_staleness(builder) -> str | None:
    """Why a built synthetic dataset is not what this code would build now, in words;
    None when it is (or when the build is not a synthetic one)."""
    from rp_jax.sources.synthetic import presets

    if builder.builder_config.source == "real":
        return None
    try:
        built = json.loads(_path(builder).read_text())
    except (OSError, json.JSONDecodeError):
        built = {}
    marker = built.get("synthetic") if isinstance(built, dict) else None
    if not isinstance(marker, dict):
        return "it was built before builds recorded the synthetic world they read"
    preset = marker.get("preset")
    want = presets.world_version(preset)
    if marker.get("world", 1) != want:
        return (f"it was built from version {marker.get('world', 1)} of the synthetic "
                f"{preset} world; this code renders version {want}")
    labelling = labelling_fingerprint(builder)
    old = built.get("labelling") or {}
    if old.get("digest") != labelling["digest"]:
        return f"it was labelled with other settings ({_labelling_changes(old, labelling)} differ)"
    return None


def _record(builder, **built_from: dict) -> None:
    """``built_from.json``: what the build read (``layout=`` a download's fingerprint or
    ``synthetic=`` a world's marker) and its labelling."""
    payload = {**built_from, "labelling": labelling_fingerprint(builder)}
    files.write_json(_path(builder), payload, sort_keys=True, default=str)


def _manual_dir(builder, manual_dir) -> Path:
    """The folder a real build reads: the one given, else TFDS's default manual dir."""
    if manual_dir is not None:
        return Path(manual_dir).absolute()
    return (Path(builder._data_dir_root) / "downloads" / "manual").absolute()


def prepare(builder, manual_dir: str | os.PathLike | None = None, *, beam_options=None) -> bool:
    """Build ``builder`` unless built; a real build records and checks what it was built from.

    Args:
      builder: a ``RepeatabilityBuilder`` (``loading.get_builder``).
      manual_dir: the download a real config reads (default: TFDS's
        ``<data_dir>/downloads/manual``).
      beam_options: Apache Beam ``PipelineOptions``: label the viewpoints in a Beam pipeline
        (``builder.beam_pipeline_options``); None: in local processes.

    One build of a dataset/config/version at a time (``build_lock``), which first removes
    the partial builds of killed runs.

    Returns:
      True if it was built now, False if it was already built.

    Raises:
      BuiltFromAnotherLayoutError: a real dataset already built there was built from
        another layout (other files, sizes or times) or with other labelling settings.
    """
    import tensorflow_datasets as tfds

    real = builder.builder_config.source == "real"
    if builder.is_prepared():
        if real:
            _check(builder, _manual_dir(builder, manual_dir))
            return False
        if (stale := synthetic_staleness(builder)) is None:
            return False
        log.warning("%s/%s in %s: %s; building it again", builder.name,
                    builder.builder_config.name, builder.data_dir, stale)
        with build_lock(builder):
            if builder.is_prepared() and synthetic_staleness(builder) is not None:
                from rp_jax.datasets import builder_sidecar_dir

                shutil.rmtree(builder.data_dir)
                # The per-pair outcomes written beside it are the old records' rows.
                shutil.rmtree(builder_sidecar_dir(builder), ignore_errors=True)
    # Fingerprinted before the build: what was there when it was read.
    layout = layout_fingerprint(_manual_dir(builder, manual_dir)) if real else None
    dl = tfds.download.DownloadConfig(manual_dir=None if manual_dir is None else str(manual_dir),
                                      beam_options=beam_options)
    with build_lock(builder), _local_build_messages(builder):
        if builder.is_prepared():  # built by another process while this one waited
            return False
        builder.download_and_prepare(download_config=dl)
    if layout is not None:
        _record(builder, layout=layout)
    return True
