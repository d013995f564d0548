"""What the ``python -m rp_jax.keypoints / mapsum / localize`` commands share.

Each command is thin (hloc's style: parse flags, call one library function, print what it
wrote). They share the project's one flag vocabulary (``rp_jax.command_line``: ``--predictor``
is a trained predictor, ``--model`` a COLMAP model, ``--out`` the output, ``--quiet`` no
progress) and one rule for bad input: a single line
``<command>: error: <what, naming the file or flag>`` on stderr and exit status 2 (argparse's
own status for a bad flag), never a traceback. Their ``--out`` is a ``files.OutputFolder``:
a file the user put there is never replaced without ``--overwrite``, and a failed run leaves
nothing of itself behind.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

from rp_jax import time_fields
from rp_jax.files import FolderNotWritableError, OutputExistsError
from rp_jax.schedule import OutsideScheduleError
from rp_jax.sources.capture_times import TIME_FORMATS_HELP, NoCaptureTimeError, parse_datetime
from rp_jax.sources.layout import LayoutError

__all__ = [
    "DateOnly",
    "FALLBACK_MAX_SIZE",
    "INPUT_ERRORS",
    "InputError",
    "OVERWRITE_HELP",
    "TIME_INPUTS",
    "check_time_has_what_the_model_reads",
    "datetime_flag",
    "load_predictor",
    "model_about",
    "run_command",
    "time_inputs",
    "wrap_hint",
]

EXIT_BAD_INPUT = 2
OVERWRITE_HELP = ("replace files in --out that this command did not write (without it such a "
                  "file stops the run before any work; the command's own outputs of an earlier "
                  "run are replaced either way)")


class InputError(ValueError):
    """Bad input to a command: a missing folder, an unreadable file, a flag that does not fit."""


# What a command reports in one line (exit 2); anything else is a bug and keeps its traceback.
INPUT_ERRORS = (InputError, LayoutError, NoCaptureTimeError, FileNotFoundError,
                OutsideScheduleError, OutputExistsError, FolderNotWritableError)


class DateOnly(dt.datetime):
    """A time flag given as a date alone (``2024-06-01``): midnight, and known to be so."""


_DATE_ALONE = re.compile(r"\d{4}-\d{2}-\d{2}|\d{8}")


def datetime_flag(text: str) -> dt.datetime:
    """argparse ``type=`` for a time flag (bad text: argparse's one-line error, exit 2).

    A date alone gives a ``DateOnly`` (midnight), which ``check_time_has_what_the_model_reads``
    refuses for a model that reads the time of day.
    """
    try:
        when = parse_datetime(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"unreadable time {text!r}; expected {TIME_FORMATS_HELP}"
        ) from None
    if _DATE_ALONE.fullmatch(str(text).strip()):
        return DateOnly(when.year, when.month, when.day, tzinfo=when.tzinfo)
    return when


# What each of the paper's time inputs (Sec. III-B) reads, in words.
TIME_INPUTS = time_fields.READS
# --max-size of a workdir that does not say its training resolution: the longer side of
# Extended CMU Seasons' 1024x768 images.
FALLBACK_MAX_SIZE = 1024


def time_inputs(config) -> str:
    """Which parts of a time the predictor of ``config`` reads, in words."""
    fields = config.model.time_fields
    return TIME_INPUTS.get(fields, f"the time fields {fields!r}")


def check_time_has_what_the_model_reads(flag: str, when: dt.datetime | None, config) -> None:
    """Refuse a date alone (``DateOnly``) for a model that reads the time of day.

    Raises:
      InputError: naming the flag, the date and what the model reads.
    """
    if isinstance(when, DateOnly) and config.model.time_fields != "day_of_year":
        raise InputError(f"{flag} {when:%Y-%m-%d}: a date without a time of day, but the model "
                         f"reads {time_inputs(config)}; give the hour too, e.g. "
                         f'"{when:%Y-%m-%d} 09:30"')


def wrap_hint(err: Exception) -> str:
    """``rp_jax.predict.at_time``'s outside-the-schedule message in the commands' words."""
    return str(err).replace("pass wrap=True", "give --wrap")


def model_about(path: str | os.PathLike) -> dict:
    """What a model says about itself: its ``model.json`` (a shipped model's, or one in a
    workdir), or {} when it has none."""
    from rp_jax import shipped

    if not Path(path).exists() and str(path) in shipped.names():
        about = shipped.MODELS_DIR / str(path) / "model.json"
    else:
        about = Path(path) / "model.json"
    try:
        return json.loads(about.read_text())
    except (OSError, ValueError):
        return {}


def load_predictor(path: str | os.PathLike, flag: str = "--predictor"):
    """``rp_jax.predict.load`` with its failures as an ``InputError`` naming the flag."""
    from rp_jax import (
        predict,  # JAX: imported once the command has configured the CPU
        shipped,
    )

    if not Path(path).exists() and str(path) in shipped.names():
        return predict.load(str(path))  # a model shipped in the package, by name
    path = Path(path)
    if not path.is_dir():
        raise InputError(f"{flag} {path}: no such folder (expected a trained workdir with "
                         "config.json, schedule.json and checkpoints/, or a shipped model: "
                         f"{', '.join(shipped.names())})")
    try:
        return predict.load(path)
    except (ValueError, KeyError, TypeError, OSError) as err:
        raise InputError(f"{flag} {path}: unreadable model: {err}") from err


def run_command(prog: str, body: Callable[[], int]) -> int:
    """Run a command's body; an input error becomes one line on stderr and exit status 2."""
    try:
        return body()
    except INPUT_ERRORS as err:
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f"{prog}: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
