"""Both Sec. IV-A experiments run end to end at tiny size from their command lines."""

import json
import shlex
import sys

import cv2
import numpy as np
import pytest

from experiments import cli
from experiments.cmu_seasons.config import get_config as cmu_config
from experiments.robotcar_day.config import get_config as robotcar_day_config
from experiments.webcam_clipart.config import get_config as webcam_config
from rp_jax.sources.synthetic.presets import world_version
from tests.datasets._tiny import tiny_data_copy

KEYS = {"test_mse", "test_mae", "curve_corr", "baselines", "counts", "timings", "curves", "figures"}
BASELINES = {"per_slot_mean", "slot_conditioned_mean", "descriptor_knn"}


def _not_blank(path):
    img = cv2.imread(str(path))
    assert img is not None, f"{path} is not a readable PNG"
    assert img.shape[0] > 200 and img.shape[1] > 200
    assert img.std() > 10, f"{path} looks blank"


@pytest.mark.slow
@pytest.mark.parametrize(
    "name,get_config,figures",
    [
        ("webcam_clipart", webcam_config,
         {"fig6_average_repeatability.png", "fig7_examples.png", "learning_curve.png"}),
        (
            "cmu_seasons",
            cmu_config,
            {"fig6_average_repeatability.png", "fig7_examples.png", "fig9_categories.png",
             "learning_curve.png"},
        ),
        ("robotcar_day", robotcar_day_config,
         {"fig6_average_repeatability.png", "fig6_by_source_time.png", "fig7_examples.png"}),
    ],
)
def test_experiment_tiny(tmp_path, tmp_path_factory, monkeypatch, name, get_config, figures):
    workdir = tmp_path / "run"
    # The session's tiny build of the dataset (rendered and labelled once for every test
    # that reads it; its build is tested in tests/datasets/): the run reads it as on its
    # own second run, and trains, predicts and reports from the command line.
    data_dir = tiny_data_copy(tmp_path_factory, [name], tmp_path / "data")
    argv = ["--size", "tiny", "--workdir", str(workdir), "--data-dir", str(data_dir)]
    # As if run as `python -m experiments.<name> ARGV`: the report must record that command.
    monkeypatch.setattr(sys, "orig_argv", ["/venv/bin/python3", "-m", f"experiments.{name}", *argv])
    assert cli.main(argv, name, get_config, "") == 0
    metrics = json.loads((workdir / "metrics.json").read_text())
    assert KEYS <= set(metrics)
    assert set(metrics["baselines"]) == BASELINES
    T = len(metrics["schedule"]["labels"])
    for m in [metrics, *metrics["baselines"].values()]:
        mae, mse_slot, mse = m["test_mae"], m["test_mse_per_slot"], m["test_mse"]
        # Per valid entry the error e lies in [-1, 1], so mean e^2 <= mean |e| and, by Jensen,
        # (mean |e|)^2 <= mean e^2; a no-error score would mean the labels leaked.
        assert 0.0 < mae and mae**2 <= mse_slot * (1 + 1e-9) and mse_slot <= mae * (1 + 1e-9), m
        # The paper's loss sums over a point's valid slots (at least its own, at most T).
        assert mse_slot * (1 - 1e-9) <= mse <= T * mse_slot * (1 + 1e-9), m
    assert metrics["counts"]["train"] > 0 and metrics["counts"]["test"] > 0
    assert len(metrics["curves"]["gt"]) == len(metrics["schedule"]["labels"])
    # The workdir says which records its model learnt: a run after the world moves on
    # refuses it instead of loading it (tests/experiments/test_records.py).
    trained_on = json.loads((workdir / "trained_on.json").read_text())
    assert trained_on["dataset"] == name and trained_on["world"] == world_version(name)
    # What the points detected at each timestamp keep at every other: a T x T map each.
    by_source = metrics["by_source_slot"]
    assert np.asarray(by_source["gt"], float).shape == (T, T) == np.asarray(
        by_source["pred"], float).shape
    if name == "robotcar_day":  # driven at 1:00 and 13:00 only: the other rows are empty
        detected = [s for s in range(T) if any(v is not None for v in by_source["gt"][s])]
        assert detected == [1, 13]
    if name == "cmu_seasons":
        assert "per_category" in metrics and "building" in metrics["per_category"]
    assert figures <= set(metrics["figures"])
    for f in figures:
        _not_blank(workdir / f)
    report = (workdir / "report.md").read_text()
    assert "| RP (ours) |" in report and "per slot mean" in report
    _check_provenance(report, f"python -m experiments.{name} {shlex.join(argv)}")


def _check_provenance(report: str, command: str) -> None:
    """The report says how it was made: the command, the code, the package versions."""
    assert "## Provenance" in report and f"- Command: `{command}`" in report
    assert "- Code: git " in report or "- Code: rp_jax " in report
    for package in ("jax", "flax", "optax", "numpy", "opencv", "tensorflow-datasets"):
        assert f" {package} " in report.split("## Provenance")[1], package


def test_cli_rejects_bad_arguments(tmp_path, capsys):
    with pytest.raises(SystemExit):
        cli.parse(["--size", "huge"], "webcam_clipart", webcam_config, "")
    for argv, message in ((["--config.num_epoch=3"], "--config.num_epoch: no such field"),
                          (["--config.train.num_epochs=three"],
                           "--config.train.num_epochs=three: invalid")):
        with pytest.raises(SystemExit) as exit_info:
            cli.parse(argv, "webcam_clipart", webcam_config, "")
        assert exit_info.value.code == 2 and message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.parse(["--manual-dir", str(tmp_path / "missing")], "webcam_clipart", webcam_config, "")
    with pytest.raises(SystemExit):
        cli.parse(["--frobnicate"], "webcam_clipart", webcam_config, "")
    with pytest.raises(SystemExit):
        cli.parse(["--config", str(tmp_path / "none.py")], "webcam_clipart", webcam_config, "")
    config, workdir = cli.parse(
        [
            "--config.train.num_epochs=3",
            "--config.model.encoder_channels=(8, 8, 16)",
            "--config.input.augment.flip=no",  # the earlier parser's yes/no for a bool
            "--manual-dir",
            str(tmp_path),
        ],
        "cmu_seasons",
        cmu_config,
        "",
    )
    assert config.train.num_epochs == 3 and tuple(config.model.encoder_channels) == (8, 8, 16)
    assert config.input.augment.flip is False
    assert config.input.data_config == "real" and workdir.name == "cmu_seasons_real"
    assert config.input.manual_dir == str(tmp_path.absolute()) and config.input.data_dir == ""


def test_cli_data_dir_is_the_tfds_folder_and_old_spellings_warn(tmp_path, capsys):
    # --data-dir is the TFDS data directory, as in python -m rp_jax.datasets and TFDS.
    config, workdir = cli.parse(["--size", "tiny", "--data-dir", str(tmp_path / "tfds")],
                                "webcam_clipart", webcam_config, "")
    assert config.input.data_dir == str(tmp_path / "tfds")
    assert config.input.data_config == "synthetic_tiny"
    assert config.input.manual_dir == "" and workdir.name == "webcam_clipart_tiny"
    assert capsys.readouterr().err == ""
    # Released spellings work one more release, with a warning on stderr.
    config, _ = cli.parse(["--tfds-dir", str(tmp_path / "tfds")], "webcam_clipart",
                          webcam_config, "")
    assert config.input.data_dir == str(tmp_path / "tfds")
    assert "--tfds-dir is deprecated" in capsys.readouterr().err
    download = tmp_path / "download"
    (download / "scene_00").mkdir(parents=True)  # files, no built dataset: the old meaning
    config, workdir = cli.parse(["--data-dir", str(download)], "webcam_clipart", webcam_config,
                                "")
    assert config.input.data_config == "real"
    assert config.input.manual_dir == str(download.absolute())
    assert config.input.data_dir == "" and workdir.name == "webcam_clipart_real"
    err = capsys.readouterr().err
    assert "is deprecated" in err and f"use --manual-dir {download}" in err
    # A TFDS data directory holding other TFDS datasets is one, not a download.
    other = tmp_path / "tensorflow_datasets"
    (other / "mnist" / "3.0.1").mkdir(parents=True)
    (other / "mnist" / "3.0.1" / "dataset_info.json").write_text("{}")
    config, _ = cli.parse(["--data-dir", str(other)], "webcam_clipart", webcam_config, "")
    assert config.input.data_dir == str(other) and config.input.data_config == "synthetic"
    assert capsys.readouterr().err == ""


def test_cli_config_file_and_print_config(tmp_path, capsys):
    # --config FILE[:ARG] is ml_collections.config_flags' own; --size is the ARG of the default.
    path = "experiments/cmu_seasons/config.py"
    config, workdir = cli.parse(["--config", f"{path}:tiny", "--config.seed=7"],
                                "webcam_clipart", webcam_config, "")
    assert config.input.dataset == "cmu_seasons" and config.input.data_config == "synthetic_tiny"
    assert config.seed == 7 and workdir.name == "webcam_clipart_cmu_seasons_tiny"
    config, _ = cli.parse(["--config", path, "--size", "small"], "webcam_clipart",
                          webcam_config, "")
    assert config.input.data_config == "synthetic_small"
    with pytest.raises(SystemExit) as exit_info:
        cli.parse(["--size", "tiny", "--config.train.num_epochs", "5", "--print-config"],
                  "webcam_clipart", webcam_config, "")
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "\ntrain:\n" in out and "  num_epochs: 5\n" in out
    assert "\ninput:\n" in out and "  data_config: synthetic_tiny\n" in out


def test_cli_reads_a_field_named_before_the_grouping_with_a_warning(capsys):
    # Config fields moved into groups (input/model/train/eval); the old names keep working
    # for one release, as the old flag spellings do.
    config, _ = cli.parse(["--size", "tiny", "--config.num_epochs=4", "--config.augment.flip=no",
                           "--noconfig.keep_best", "--config.knn_k", "3"],
                          "webcam_clipart", webcam_config, "")
    assert config.train.num_epochs == 4 and config.input.augment.flip is False
    assert config.train.keep_best is False and config.eval.knn_k == 3
    err = capsys.readouterr().err
    for old, new in (("--config.num_epochs", "--config.train.num_epochs"),
                     ("--config.augment.flip", "--config.input.augment.flip"),
                     ("--noconfig.keep_best", "--noconfig.train.keep_best"),
                     ("--config.knn_k", "--config.eval.knn_k")):
        assert f"{old} is deprecated" in err and f"use {new}" in err
    with pytest.raises(SystemExit) as exit_info:  # a name that never was a field stays an error
        cli.parse(["--config.num_epoch=3"], "webcam_clipart", webcam_config, "")
    assert exit_info.value.code == 2
    help_text = cli.build_parser("webcam_clipart", "").format_help()
    assert "--config FILE[:ARG]" in help_text and "--config.FIELD=VALUE" in help_text


def test_split_validation_holds_out_whole_viewpoints():
    from experiments.records import split_validation

    vps = np.array(["a", "a", "b", "c", "c", "d"])
    mask = split_validation(vps, 0.25, seed=0)
    held = set(vps[mask])
    assert len(held) == 1 and not (held & set(vps[~mask]))
    assert not split_validation(np.array(["a", "a"]), 0.5, seed=0).any()


def test_cross_validate_flag_needs_two_training_viewpoints(tmp_path, tmp_path_factory, capsys):
    # The tiny synthetic world has one training scene: a clear error, not a traceback.
    data_dir = tiny_data_copy(tmp_path_factory, ["webcam_clipart"], tmp_path / "data")
    argv = ["--size", "tiny", "--workdir", str(tmp_path / "run"),
            "--data-dir", str(data_dir), "--cross-validate"]
    assert cli.main(argv, "webcam_clipart", webcam_config, "") == 2
    assert "at least 2 training viewpoints" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.parse_flags(["--folds", "3"], "webcam_clipart", webcam_config, "",
                        cross_validation=True)
    with pytest.raises(SystemExit):  # not a flag of the map-summarization experiment
        cli.parse(["--cross-validate"], "map_summarization", webcam_config, "")
