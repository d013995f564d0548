"""The one flag vocabulary of every ``python -m`` command of the project.

A flag means the same thing in every command that has it. The data flags take TFDS's own
words (``tfds build --data_dir ... --manual_dir ...``; ``tfds.download.DownloadConfig``),
the config flags those of the Flax examples (``ml_collections.config_flags``):

``--data-dir DIR``      the TFDS data directory: where built datasets are kept (TFDS's
                        ``data_dir``). Never the download.
``--manual-dir DIR``    the real dataset you downloaded, in its real layout (TFDS's
                        ``manual_dir``); giving it selects the real data.
``--size tiny|small|full``  the size of the synthetic world (used without ``--manual-dir``).
``--workdir DIR``       the run directory of a training experiment (resumes if present).
``--out PATH``          where a command writes what it makes.
``--config FILE[:ARG]`` an ``ml_collections`` config file (``get_config(ARG)``);
``--config.FIELD=VALUE`` overrides one field; ``--print-config`` prints the resolved
                        config and exits.
``--predictor MODEL``   a trained repeatability predictor (a workdir, or a shipped model's
                        name); ``--model`` is a COLMAP model (the 3D map), as in COLMAP/hloc.
``--quiet``             no progress output (``rp_jax.progress``).

Old spellings keep working for one release and print a deprecation warning on stderr
(``deprecated_alias``).
"""

from __future__ import annotations

import argparse
import sys

__all__ = [
    "DATA_DIR_HELP",
    "MANUAL_DIR_HELP",
    "SIZE_HELP",
    "VOCABULARY",
    "add_config_file",
    "add_data_dir",
    "add_manual_dir",
    "add_quiet",
    "add_size",
    "check_writable_folder",
    "deprecated_alias",
    "deprecation_warning",
]

# What each shared flag means, as --help says it (a test checks every command against this).
VOCABULARY = {
    "--data-dir": "TFDS data directory",
    "--manual-dir": "real dataset you downloaded",
    "--size": "synthetic world",
    "--quiet": "no progress output",
    "--predictor": "trained predictor",
}
DATA_DIR_HELP = ("TFDS data directory: where built datasets are kept (TFDS's data_dir; "
                 "default: $RP_JAX_DATA_DIR, else {default})")
MANUAL_DIR_HELP = ("the real dataset you downloaded, in its real layout (TFDS's manual_dir); "
                   "giving it selects the real data instead of the synthetic world")
SIZE_HELP = ("size of the synthetic world: tiny (tests, seconds), small (minutes), full (the "
             "largest, see the README) (default {default})")

def deprecation_warning(prog: str, old: str, new: str) -> None:
    """One line on stderr: ``old`` still works this release; say ``new``."""
    print(f"{prog}: warning: {old} is deprecated and will be removed in the next release; "
          f"use {new}", file=sys.stderr)


class _DeprecatedAlias(argparse.Action):
    """Stores like the new flag and warns on stderr; hidden from --help."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        deprecation_warning(parser.prog, option_string, self.new)
        setattr(namespace, self.dest, values)


def deprecated_alias(parser, old: str, new: str, *, dest: str, **kwargs) -> None:
    """Accept ``old`` (hidden from --help) as a deprecated spelling of ``new``."""
    parser.add_argument(old, dest=dest, action=_DeprecatedAlias, new=new, help=argparse.SUPPRESS,
                        default=argparse.SUPPRESS, **kwargs)


def add_data_dir(parser, default: str, **kwargs) -> None:
    """``--data-dir DIR``: the TFDS data directory (``default`` is said in --help)."""
    from pathlib import Path

    parser.add_argument("--data-dir", type=Path, default=None, metavar="DIR",
                        help=DATA_DIR_HELP.format(default=default), **kwargs)


def add_manual_dir(parser, extra: str = "", **kwargs) -> None:
    """``--manual-dir DIR``: the real download, in its real layout."""
    from pathlib import Path

    parser.add_argument("--manual-dir", type=Path, default=None, metavar="DIR",
                        help=MANUAL_DIR_HELP + extra, **kwargs)


def add_size(parser, default: str, choices=("tiny", "small", "full")) -> None:
    """``--size``: the synthetic world's size."""
    parser.add_argument("--size", choices=choices, default=default,
                        help=SIZE_HELP.format(default=default))


def add_config_file(parser, default: str) -> None:
    """``--config FILE[:ARG]`` (an ml_collections config file) and ``--print-config``."""
    parser.add_argument("--config", dest="config_file", metavar="FILE[:ARG]", default=None,
                        help="ml_collections config file whose get_config(ARG) gives the config "
                        f"(default: {default})")
    parser.add_argument("--print-config", action="store_true",
                        help="print the resolved config (after every flag) and exit")


def add_quiet(parser) -> None:
    """``--quiet``: no progress output."""
    parser.add_argument("--quiet", action="store_true",
                        help="no progress output (off a terminal, progress is one plain line "
                        "per stage or per 10 %%)")


def check_writable_folder(parser, flag: str, path) -> None:
    """Stop through ``parser.error`` (exit 2), before any work, when ``path`` (``--workdir``,
    ``--out``) cannot be a folder this process writes in (``rp_jax.files.folder_problem``)."""
    from rp_jax.files import folder_problem

    problem = folder_problem(path)
    if problem is not None:
        parser.error(f"{flag} {path} {problem}; give a folder you may write in (it is created "
                     "if absent)")
