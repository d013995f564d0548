"""``python -m experiments.conditional``: the conditional predictor against the paper's (issue 17).

Cross-validates on the training viewpoints (``--cross-validate``; the only mode of this
release: nothing is measured on the test split yet): each fold trains the paper's predictor
and the conditional one (``--config.model.conditions=sun,weather,semantics``, or several
with ``--ablation time,sun,weather,sun+weather+semantics``) and scores their T-vectors
against y^j on the held-out viewpoints. Writes ``<workdir>/conditional.{json,md}`` and the
paper's own cross-validation under ``<workdir>/paper/``. Flags as every experiment's
(``--help``), plus ``--dataset`` (default webcam_clipart) and ``--ablation``.
"""

import argparse
import sys

from experiments import cli
from experiments.conditional.config import get_config


def _dataset(argv) -> str:
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--dataset", default="webcam_clipart")
    return pre.parse_known_args(argv)[0].dataset


def _flags(parser: argparse.ArgumentParser) -> None:
    from rp_jax.datasets import DATASET_NAMES

    parser.add_argument("--dataset", choices=DATASET_NAMES[:2], default="webcam_clipart",
                        help="which Sec. IV-A experiment's config and data (default "
                        "webcam_clipart)")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    dataset = _dataset(argv)
    config, workdir, args = cli.parse_flags(
        argv, "conditional", lambda size: get_config(f"{dataset}:{size}"), __doc__,
        cross_validation=True, default_size="small", add_flags=_flags)
    if args.workdir is None:  # runs/conditional_<dataset>_<size>
        workdir = workdir.with_name(workdir.name.replace("conditional", f"conditional_{dataset}"))
    prog = "python -m experiments.conditional"
    if not args.cross_validate:
        print(f"{prog}: error: this release measures on held-out training viewpoints only: "
              "give --cross-validate (and --folds N)", file=sys.stderr)
        return 2
    from rp_jax import platform, progress

    if args.quiet:
        progress.set_quiet()
    platform.configure_cpu()
    from experiments.conditional import crossval
    from experiments.sec4a import config as sec4a_config
    from rp_jax import train

    try:
        sec4a_config.validate(config)
    except train.ConfigError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    return crossval.run(config, workdir, args.ablation, args.folds, quiet=args.quiet,
                        prog=prog)


if __name__ == "__main__":
    sys.exit(main())
