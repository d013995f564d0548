"""``python -m experiments.conditional``: the conditional predictor against the paper's (issue 17).

Cross-validates on the training viewpoints (``--cross-validate``; the only mode of this
release: nothing is measured on the test split yet): each fold trains the paper's predictor
and the conditional one (``--config.model.conditions=sun,weather,semantics``, or several
with ``--ablation time,sun,weather,sun+weather+semantics``) and scores their T-vectors
against y^j on the held-out viewpoints. Writes ``<workdir>/conditional.{json,md}`` and the
paper's own cross-validation under ``<workdir>/paper/``. Flags as every experiment's
(``--help``), plus ``--dataset`` (default webcam_clipart) and ``--ablation``; a seed other
than 0 (``--config.seed=N``) has its own default workdir (``..._seed<N>``), and
``--combine-seeds DIR,DIR,...`` combines finished seeds' runs (``experiments.conditional.seeds``).
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
    parser.add_argument("--combine-seeds", default=None, metavar="DIR,DIR,...",
                        help="train nothing: combine the finished runs in these workdirs "
                        "(one per seed, their conditional.json) into "
                        "<workdir>/conditional_seeds.{json,md} (default workdir: the first)")


def default_workdir(workdir, dataset: str, seed: int):
    """``runs/conditional_<dataset>_<size>``, with ``_seed<N>`` for a seed other than 0: one
    workdir per seed (a workdir holding another seed's run is refused, not mixed)."""
    name = workdir.name.replace("conditional", f"conditional_{dataset}")
    return workdir.with_name(name + (f"_seed{seed}" if seed else ""))


def _combine_seeds(args, prog: str) -> int:
    from experiments.conditional import seeds

    dirs = [d.strip() for d in args.combine_seeds.split(",") if d.strip()]
    out = args.workdir or dirs[0]
    try:
        combined = seeds.write(dirs, out)
    except ValueError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    print(seeds.markdown(combined))
    print(f"wrote {out}/conditional_seeds.json and conditional_seeds.md")
    return 0


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    dataset = _dataset(argv)
    config, workdir, args = cli.parse_flags(
        argv, "conditional", lambda size: get_config(f"{dataset}:{size}"), __doc__,
        cross_validation=True, default_size="small", add_flags=_flags)
    if args.workdir is None:  # runs/conditional_<dataset>_<size>[_seed<N>]
        workdir = default_workdir(workdir, dataset, int(config.seed))
    prog = "python -m experiments.conditional"
    if args.combine_seeds:
        return _combine_seeds(args, prog)
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
