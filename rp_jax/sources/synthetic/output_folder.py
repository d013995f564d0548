"""Which folders the synthetic generator may write into: its own, made with the same parameters.

The generator writes a real dataset's layout (``intrinsics.txt``, pose files, images) and
skips frames whose files exist, so that a killed render resumes. Pointed at a copy of a
download it would overwrite the user's files; pointed at its own folder rendered with
another seed it would keep the old frames beside the new ones, one layout of two worlds
that the builders read without a word. ``claim`` decides before anything is written:

* a new or empty folder: claimed; its marker ``_synthetic/parameters.json`` names every
  parameter that makes the output (generator, preset, size, seed, world version) and is
  written before the first frame, so a killed render is still recognised as ours;
* a folder with a marker of the same parameters: resumed;
* a folder with a marker of other parameters: refused, or with ``overwrite`` deleted (the
  marker proves it is the generator's own output) and rendered anew;
* a non-empty folder without a marker: refused, or with ``overwrite`` every frame is
  rendered anew over the files there (the caller asked for it); it gets its marker when
  that render has finished (``mark``).
"""

from __future__ import annotations

import json
import logging
import shutil
from collections.abc import Mapping
from pathlib import Path

__all__ = [
    "GENERATOR",
    "PARAMETERS_JSON",
    "OutputFolderError",
    "claim",
    "folder_parameters",
    "mark",
]

log = logging.getLogger(__name__)

GENERATOR = "rp_jax.sources.synthetic"
PARAMETERS_JSON = Path("_synthetic") / "parameters.json"  # written when a render starts
_GENERATION_JSON = Path("_synthetic") / "generation.json"  # written when it has finished
_MAP_SUBSET_JSON = Path("_synthetic") / "map_subset.json"  # map_layout's partial render
# Parameters compared between a folder and a render (others, e.g. frames, are outcomes).
_COMPARED = ("preset", "size", "seed", "world")


class OutputFolderError(ValueError):
    """The folder holds files the generator did not write, or a render of other parameters."""


def folder_parameters(out_dir: Path) -> dict | None:
    """The parameters a folder was rendered with, from its marker; None if it has none.

    A marker of an older version may lack ``world`` (version 1); the map-only render of
    ``map_layout`` is a ``cmu_seasons`` render.
    """
    out_dir = Path(out_dir)
    for rel in (_GENERATION_JSON, PARAMETERS_JSON, _MAP_SUBSET_JSON):
        path = out_dir / rel
        if not path.is_file():
            continue
        try:
            marker = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if not isinstance(marker, dict):
            continue
        if rel == _MAP_SUBSET_JSON:
            marker = {"preset": "cmu_seasons", **marker}
        return {**marker, "world": marker.get("world", 1)}
    return None


def _some_files(out_dir: Path, n: int = 5) -> list[str]:
    names = []
    for p in sorted(out_dir.rglob("*")):
        if p.is_file():
            names.append(str(p.relative_to(out_dir)))
            if len(names) == n:
                break
    return names


def _write_marker(out_dir: Path, parameters: Mapping) -> None:
    from rp_jax.sources.synthetic import write_layout

    (out_dir / PARAMETERS_JSON).parent.mkdir(parents=True, exist_ok=True)
    write_layout.write_text_atomic(out_dir / PARAMETERS_JSON,
                              json.dumps(dict(parameters), indent=2, sort_keys=True) + "\n")


def mark(out_dir: Path, parameters: Mapping) -> None:
    """Write the marker naming ``parameters`` (a finished render of a claimed folder)."""
    _write_marker(Path(out_dir), parameters)


def claim(out_dir: Path, parameters: Mapping, *, overwrite: bool = False) -> bool:
    """Make ``out_dir`` the generator's folder for a render of ``parameters``, or refuse.

    Args:
      out_dir: the folder the render writes (created if absent).
      parameters: every parameter that makes the output: ``generator``, ``preset``,
        ``size``, ``seed``, ``world`` (written to the marker as given).
      overwrite: write into a folder of other parameters (deleted first) or one the
        generator did not write (its files are overwritten).

    Returns:
      True when existing files must be rendered anew (a foreign folder, ``overwrite``);
      False when the render may skip the frames already there.

    Raises:
      OutputFolderError: without ``overwrite``, a non-empty folder with no marker, or one
        whose marker names other parameters; the message names them and what to do.
    """
    out_dir = Path(out_dir)
    if not out_dir.exists() or not any(out_dir.iterdir()):
        out_dir.mkdir(parents=True, exist_ok=True)
        _write_marker(out_dir, parameters)
        return False
    have = folder_parameters(out_dir)
    if have is not None:
        differ = {k: (have.get(k), parameters.get(k)) for k in _COMPARED
                  if have.get(k) != parameters.get(k)}
        if not differ:
            if not (out_dir / PARAMETERS_JSON).is_file():
                _write_marker(out_dir, parameters)
            return False
        what = ", ".join(f"{k} {old!r} (asked {new!r})" for k, (old, new) in differ.items())
        if not overwrite:
            raise OutputFolderError(
                f"{out_dir} holds a synthetic render of other parameters: {what}; rendering "
                "into it would mix two worlds in one layout. Choose another folder, or pass "
                "--overwrite (overwrite=True) to delete it and render anew"
            )
        log.warning("%s: deleting the synthetic render of other parameters (%s)", out_dir, what)
        shutil.rmtree(out_dir)
        out_dir.mkdir(parents=True)
        _write_marker(out_dir, parameters)
        return False
    if not overwrite:
        files = _some_files(out_dir)
        raise OutputFolderError(
            f"{out_dir} is not empty and was not written by the synthetic generator (no "
            f"{PARAMETERS_JSON}; it holds {', '.join(files)}, ...): rendering would overwrite "
            "files of the same names (intrinsics.txt, pose files, images). Choose a new or "
            "empty folder, or pass --overwrite (overwrite=True) to write over them"
        )
    log.warning("%s: not written by the synthetic generator; overwriting its files (--overwrite)",
                out_dir)
    # No marker until the render has finished: a killed one is still not ours, and its
    # re-run (with --overwrite again) renders every frame anew instead of keeping files.
    return True
