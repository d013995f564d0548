"""``python -m experiments.universal_rp``: the RP trained on many synthetic worlds and judged
on held-out worlds (beyond the paper: its conclusion's "universal RP").

Renders the training worlds (``webcam_worlds``) and the held-out worlds
(``webcam_worlds_unseen``), labels each into its own dataset, trains the RP on 7, 20 and 48
webcams (full size) and writes metrics.json, report.md and scaling_curve.png into the workdir.
Flags (``--help``): --workdir, --size tiny|small|full, --worlds-dir (where the worlds and
their datasets go; default data/ of the checkout), --config.FIELD=VALUE, --print-config,
--quiet.
"""

import sys
from pathlib import Path

from experiments import cli
from experiments.universal_rp.config import get_config


def _add_flags(parser) -> None:
    parser.add_argument("--worlds-dir", type=Path, default=None, metavar="DIR",
                        help="where the worlds are rendered (DIR/synthetic/<world>) and their "
                        "datasets built (DIR/worlds_tfds/<world>); default: the folder above "
                        "the TFDS data directory (data/ of the checkout)")


def main(argv=None) -> int:
    config, workdir, args = cli.parse_flags(argv, "universal_rp", get_config, __doc__,
                                            add_flags=_add_flags)
    prog = "python -m experiments.universal_rp"
    if args.manual_dir is not None:
        print(f"{prog}: error: --manual-dir: this experiment renders its own worlds",
              file=sys.stderr)
        return 2
    if args.data_dir is not None:
        print(f"{prog}: error: --data-dir: each world's dataset is built under --worlds-dir "
              "(DIR/worlds_tfds/<world>)", file=sys.stderr)
        return 2
    from rp_jax import platform, progress, train, workdir_lock

    if args.quiet:
        progress.set_quiet()
    platform.configure_cpu(malloc=True)
    from experiments.universal_rp import experiment

    try:
        with workdir_lock.hold(workdir):
            metrics = experiment.run(config, workdir, data_root=args.worlds_dir,
                                     progress=not args.quiet)
    except (train.ConfigError, train.WorkdirMismatchError, workdir_lock.FolderBusyError,
            ValueError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    last = metrics["curve"][-1]
    s = last["summary"]
    print(f"wrote {Path(workdir)}/metrics.json, report.md and {metrics['figures'][0]}")
    print(f"{last['scenes']} training webcams: MAE {s['rp_mae_mean']:.4f} on "
          f"{len(last['worlds'])} held-out worlds against {s['best_baseline_mae_mean']:.4f} for "
          f"the best baseline ({100 * s['gain_over_best_baseline_mean']:+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
