"""The bad-input suite (issue 14): one row per case, from the command or call a user makes.

Each row makes its own tiny input in a temporary folder, runs the command (exit status and
stderr) or the library call (exception and message), and checks three promises:

* the exit status or exception is the one expected (never a wrong result with exit 0);
* the message names the bad thing (a file and line, an argument and its range, a flag);
* the inputs are unchanged (checksums of the input folders before and after).

The silent wrong results and the data loss of the issue's first section are rows here;
each also has its own regression test beside the module it fixes.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import hashlib
import json
import re
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

# --------------------------------------------------------------------------- tiny inputs


def _checksums(root: Path) -> dict[str, str]:
    """Every file's sha256 and every folder, under ``root``: a new empty folder is a change."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "folder" for p in sorted(root.rglob("*"))}


def _webcam_download(root: Path, scenes: dict[str, list[str]], seed: int = 0,
                     sizes: dict[str, tuple[int, int]] | None = None) -> Path:
    """A real Webcam Clip Art layout: scene -> frame stems, textured static frames."""
    rng = np.random.default_rng(seed)
    sizes = sizes or {}
    for scene, stems in scenes.items():
        base = cv2.GaussianBlur(rng.integers(0, 255, (72, 96, 3), np.uint8), (0, 0), 1.5)
        (root / scene).mkdir(parents=True, exist_ok=True)
        for k, stem in enumerate(stems):
            frame = np.clip(base.astype(int) + 4 * k, 0, 255).astype(np.uint8)
            if stem in sizes:
                frame = cv2.resize(frame, sizes[stem])
            assert cv2.imwrite(str(root / scene / f"{stem}.png"), frame)
    return root


DAYS = ["20100601_080000", "20100601_083000", "20100602_080000"]


def _cmu_download_with_nan_pose(root: Path) -> Path:
    from tests.sources.test_cmu_seasons import _layout

    root.mkdir(parents=True)
    entries, _, _ = _layout(root)
    gt = root / "slice7" / "ground-truth-database-images-slice7.txt"
    lines = gt.read_text().splitlines()
    lines[1] = f"{entries[1][0]} 1 0 0 0 nan 0 0"
    gt.write_text("\n".join(lines) + "\n")
    return root


@functools.lru_cache(maxsize=1)
def _predictor():
    """A predictor of zero weights (validation needs neither training nor initialisation)."""
    from rp_jax import predict
    from tests.test_train import SCHEDULE, small_config

    config = small_config()
    shapes = predict._abstract_params(config, SCHEDULE.num_timestamps)
    return predict.Predictor(_zeros(shapes), config, SCHEDULE, batch_size=8)


def _zeros(tree):
    import jax

    return jax.tree.map(lambda s: np.zeros(s.shape, s.dtype), tree)


def _predictor_call(patches=None, xy=None, times=None, **kwargs):
    rng = np.random.default_rng(0)
    patches = rng.integers(0, 256, (2, 64, 64, 3), np.uint8) if patches is None else patches
    xy = np.full((2, 2), 0.5, np.float32) if xy is None else xy
    times = [dt.datetime(2020, 5, 3, 9, 0)] * 2 if times is None else times
    return lambda: _predictor()(patches, xy, times, **kwargs)


# --------------------------------------------------------------------------- the table


@dataclasses.dataclass(frozen=True)
class Case:
    """One bad input.

    Attributes:
      name: what is wrong, in a user's words.
      make: ``tmp_path -> (run, inputs)``: ``run()`` makes the call or runs the command
        (returning its exit status), ``inputs`` the folders that must not change.
      expect: the exit status, or the exception type the call raises.
      names: regexes the message (stderr, or the exception) must match: the bad thing.
    """

    name: str
    make: Callable[[Path], tuple[Callable[[], object], list[Path]]]
    expect: int | type[BaseException]
    names: tuple[str, ...]


def _datasets_build(name: str, manual: Path, tfds_dir: Path) -> Callable[[], int]:
    from rp_jax.datasets import __main__ as datasets_cli

    return lambda: datasets_cli.main(["build", name, "--manual-dir",
                                      str(manual), "--data-dir", str(tfds_dir), "--workers", "1"])


def _second_download(tmp: Path):
    a = _webcam_download(tmp / "A", {"houseA": DAYS, "houseB": DAYS}, seed=0)
    b = _webcam_download(tmp / "B", {"houseA": DAYS, "houseB": DAYS}, seed=1)
    assert _datasets_build("webcam_clipart", a, tmp / "tfds")() == 0
    return _datasets_build("webcam_clipart", b, tmp / "tfds"), [a, b]


def _lost_test_scene(tmp: Path):
    root = _webcam_download(tmp / "dl", {"a": DAYS, "b": DAYS, "c": ["IMG_0001", "IMG_0002"]})
    return _datasets_build("webcam_clipart", root, tmp / "tfds"), [root]


def _mixed_sizes(tmp: Path):
    root = _webcam_download(tmp / "dl", {"a": DAYS, "b": DAYS},
                            sizes={"20100601_083000": (48, 36)})
    return _datasets_build("webcam_clipart", root, tmp / "tfds"), [root]


def _cmu_nan_pose(tmp: Path):
    root = _cmu_download_with_nan_pose(tmp / "dl")
    return _datasets_build("cmu_seasons", root, tmp / "tfds"), [root]


def _synthetic_over_a_download(tmp: Path):
    from rp_jax.sources.synthetic import __main__ as synthetic_cli

    root = _cmu_download_with_nan_pose(tmp / "copy")  # any download: it must stay as it is
    return (lambda: synthetic_cli.main(["cmu_seasons", str(root), "--size", "tiny",
                                        "--workers", "1", "--quiet"])), [root]


def _synthetic_other_seed(tmp: Path):
    from rp_jax.sources.synthetic import __main__ as synthetic_cli
    from rp_jax.sources.synthetic import presets

    root = tmp / "world"
    (root / "_synthetic").mkdir(parents=True)
    (root / "_synthetic" / "generation.json").write_text(json.dumps(
        {"generator": "rp_jax.sources.synthetic", "preset": "webcam_clipart", "size": "tiny",
         "seed": 0, "world": presets.world_version("webcam_clipart"), "frames": 1}))
    _webcam_download(root, {"scene_00": DAYS[:1]})
    return (lambda: synthetic_cli.main(["webcam_clipart", str(root), "--size", "tiny",
                                        "--seed", "1", "--quiet"])), [root]


def _train(tmp: Path, **overrides):
    from rp_jax import train
    from tests.test_train import small_config, task

    return lambda: train.train_and_evaluate(small_config(**overrides), tmp / "run", task(64, 0),
                                            progress=False)


def _nan_learning_rate(tmp: Path):
    return _train(tmp, learning_rate=float("nan")), []


def _nan_inputs(tmp: Path):
    from rp_jax import train
    from rp_jax.datasets import input_pipeline as ip
    from tests.test_train import small_config, task

    src = task(64, 0)
    bad = ip.ArraySource(dict(src.arrays, xy_normalized=np.full_like(
        src.arrays["xy_normalized"], np.nan)), ip.MODEL_KEYS)
    return (lambda: train.train_and_evaluate(small_config(), tmp / "run", bad,
                                             progress=False)), []


def _another_epoch_count(tmp: Path):
    _train(tmp, num_epochs=1)()
    return _train(tmp, num_epochs=2), []


def _empty_cmu_folder(tmp: Path):
    from rp_jax.sources import cmu_seasons

    (tmp / "empty").mkdir()
    return (lambda: cmu_seasons.read(tmp / "empty")), [tmp / "empty"]


def _exit_status(main: Callable[[list[str]], int], argv: list[str]) -> Callable[[], int]:
    """``main(argv)``'s exit status, also when it exits through ``SystemExit`` (argparse)."""
    def run() -> int:
        try:
            return main(argv)
        except SystemExit as e:
            return e.code if isinstance(e.code, int) else 1
    return run


def _experiment(name: str, *flags: str, workdir: str = "run"):
    """``python -m experiments.<name> --size tiny ...`` in-process, in ``tmp``: the rows of
    a config field out of range or a bad workdir. ``inputs`` is the whole of ``tmp``: the
    command must fail before it builds, trains or creates anything."""
    def make(tmp: Path):
        import importlib

        main = importlib.import_module(f"experiments.{name}.__main__").main \
            if name == "map_summarization" else _sec4a_main(name)
        argv = ["--size", "tiny", "--workdir", str(tmp / workdir),
                f"--config.input.data_dir={tmp / 'tfds'}", *[f.format(tmp=tmp) for f in flags]]
        return _exit_status(main, argv), [tmp]
    return make


def _sec4a_main(name: str) -> Callable[[list[str]], int]:
    import importlib

    from experiments import cli

    module = importlib.import_module(f"experiments.{name}.__main__")
    return lambda argv: cli.main(argv, name, module.get_config, module.__doc__)


def _data_dir_a_file(tmp: Path):
    from rp_jax.datasets import __main__ as datasets_cli

    (tmp / "tfds").write_text("not a folder")
    return _exit_status(datasets_cli.main, ["build", "webcam_clipart", "--size", "tiny",
                                            "--data-dir", str(tmp / "tfds")]), [tmp]


def _data_dir_under_a_file(tmp: Path):
    from rp_jax.datasets import __main__ as datasets_cli

    (tmp / "notes").write_text("not a folder")
    return _exit_status(datasets_cli.main, ["build", "webcam_clipart", "--size", "tiny",
                                            "--data-dir", str(tmp / "notes" / "tfds")]), [tmp]


def _decay_workdir_under_a_file(tmp: Path):
    from experiments.decay import __main__ as decay_cli

    (tmp / "notes").write_text("not a folder")
    return _exit_status(decay_cli.main, ["--size", "tiny", "--workdir",
                                         str(tmp / "notes" / "run")]), [tmp]


def _experiment_data_dir_a_file(tmp: Path):
    (tmp / "notes").write_text("not a folder")
    return _experiment("webcam_clipart", "--config.input.data_dir={tmp}/notes")(tmp)


def _demo(*flags: str):
    def make(tmp: Path):
        from experiments import demo

        return _exit_status(demo.main, ["--workdir", str(tmp / "run"), *flags]), [tmp]
    return make


def _workdir_a_file(tmp: Path):
    (tmp / "run").write_text("my notes")
    return _experiment("webcam_clipart")(tmp)


def _workdir_under_a_file(name: str):
    def make(tmp: Path):
        (tmp / "notes").write_text("my notes")
        return _experiment(name, workdir="notes/run")(tmp)
    return make


def _workdir_of_another_experiment(tmp: Path):
    from experiments.cmu_seasons.config import get_config

    (tmp / "run").mkdir()
    (tmp / "run" / "config.json").write_text(json.dumps(get_config("tiny").to_dict(),
                                                        default=list))
    return _experiment("webcam_clipart")(tmp)


def _bad_image(kind: str):
    def make(tmp: Path):
        root = _webcam_download(tmp / "dl", {"a": DAYS, "b": DAYS})
        path = root / "a" / f"{DAYS[1]}.png"
        data = path.read_bytes()
        path.write_bytes({"zero-byte": b"", "corrupt": b"\x89PNG garbage" * 8,
                          "truncated": data[: len(data) // 2]}[kind])
        return _datasets_build("webcam_clipart", root, tmp / "tfds"), [root]
    return make


def _webcam_one_level_too_deep(tmp: Path):
    _webcam_download(tmp / "dl" / "scenes", {"a": DAYS, "b": DAYS})
    return _datasets_build("webcam_clipart", tmp / "dl", tmp / "tfds"), [tmp / "dl"]


def _cmu_zero_quaternion(tmp: Path):
    from tests.sources.test_cmu_seasons import _layout

    root = tmp / "dl"
    root.mkdir()
    entries, _, _ = _layout(root)
    gt = root / "slice7" / "ground-truth-database-images-slice7.txt"
    lines = gt.read_text().splitlines()
    lines[1] = f"{entries[1][0]} 0 0 0 0 1 2 3"
    gt.write_text("\n".join(lines) + "\n")
    return _datasets_build("cmu_seasons", root, tmp / "tfds"), [root]


def _robotcar_ins(edit: Callable[[list[str]], None]):
    def make(tmp: Path):
        from rp_jax.sources import robotcar
        from tests.sources.test_robotcar import _layout

        root = tmp / "dl"
        _layout(root)
        ins = root / "2015-02-13-09-16-26" / "gps" / "ins.csv"
        lines = ins.read_text().splitlines()
        edit(lines)
        ins.write_text("\n".join(lines) + "\n")
        return (lambda: robotcar.read(root)), [root]
    return make


def _nan_northing(lines: list[str]) -> None:
    row = lines[2].split(",")
    row[5] = "nan"
    lines[2] = ",".join(row)


def _renamed_northing(lines: list[str]) -> None:
    lines[0] = lines[0].replace("northing", "north")


def _mismatched_checkpoint(tmp: Path):
    from rp_jax import predict

    _train(tmp, num_epochs=1)()
    path = tmp / "run" / "config.json"
    config = json.loads(path.read_text())
    config["model"]["encoder_features"] = 16
    path.write_text(json.dumps(config))
    return (lambda: predict.load(tmp / "run")), [tmp / "run"]


def _call(fn: Callable[[], object]):
    return lambda tmp: (fn, [])


def _folds(n: int):
    from experiments.sec4a import crossval

    return lambda: crossval.viewpoint_folds(np.array(["a", "b", "b"]), num_folds=n)


def _cases() -> list[Case]:
    from rp_jax import train
    from rp_jax.sources.layout import LayoutError

    pix = np.array([[600.0, 100.0]] * 2, np.float32)
    return [
        # Issue 14, item 1: a second download is not read as the first.
        Case("a second download into a built data dir", _second_download, 2,
             (r"built from .*/A \(6 files", r"not from .*/B", r"--data-dir")),
        # Item 2: the predictor mis-scales nothing and accepts nothing out of range.
        Case("float patches in 0-255", _call(_predictor_call(
            patches=np.full((2, 64, 64, 3), 200.0, np.float32))), ValueError,
            (r"float patches must be in \[0, 1\]", r"200")),
        Case("integer patches above 255", _call(_predictor_call(
            patches=np.full((2, 64, 64, 3), 300, np.int32))), ValueError,
            (r"integer patches must be in \[0, 255\]", r"300")),
        Case("pixel xy without image_size", _call(_predictor_call(xy=pix)), ValueError,
             (r"xy must be normalised to \[0, 1\]", r"600", r"image_size")),
        Case("swapped image_size", _call(_predictor_call(xy=pix, image_size=(480, 640))),
             ValueError, (r"x must be in \[0, 480\]", r"600", r"\(H, W\)")),
        Case("a time outside the schedule", _call(_predictor_call(
            times=[dt.datetime(2020, 5, 3, 3, 0)] * 2)), ValueError,
            (r"times", r"08:00\.\.18:00", r"03:00")),
        # Item 3: the synthetic generator overwrites nothing it did not write.
        Case("the synthetic generator over a download", _synthetic_over_a_download, 2,
             (r"not written by the synthetic generator", r"intrinsics\.txt", r"--overwrite")),
        Case("the synthetic generator over another seed", _synthetic_other_seed, 2,
             (r"seed 0 \(asked 1\)", r"mix two worlds", r"--overwrite")),
        # Item 5: mixed sizes in one static viewpoint.
        Case("a webcam scene of two image sizes", _mixed_sizes, 2,
             (r"2 sizes", r"1 at 48x36 \(20100601_083000\.png\)")),
        # Item 6: no model of another epoch count, no training on NaN.
        Case("a trained workdir asked for another epoch count", _another_epoch_count,
             train.WorkdirMismatchError,
             (r"train\.num_epochs=1, asked train\.num_epochs=2", r"--workdir")),
        Case("a NaN learning rate", _nan_learning_rate, train.ConfigError,
             (r"config\.train\.learning_rate=nan: expected a finite number > 0",)),
        Case("NaN inputs", _nan_inputs, train.NonFiniteLossError,
             (r"training loss is nan at epoch 1, step 1", r"no checkpoint")),
        # Item 7: no input dropped in silence.
        Case("a NaN in a CMU pose line", _cmu_nan_pose, 2,
             (r"ground-truth-database-images-slice7\.txt:2:", r"NaN")),
        Case("a test scene whose names are no times", _lost_test_scene, 2,
             (r"split 'test' \(c\) lost all its viewpoints",)),
        Case("--folds above the training viewpoints", _call(_folds(99)), ValueError,
             (r"num_folds=99", r"only 2 viewpoints \(a, b\)")),
        Case("an empty folder as a CMU download", _empty_cmu_folder, LayoutError,
             (r"no intrinsics\.txt", r"slice\{N\}/database")),
        # Tracebacks that became one line, exit 2, before any build or training (each was a
        # traceback after the dataset was built, or a wrong result with exit 0).
        *[Case(f"--config.{flag}", _experiment("webcam_clipart", f"--config.{flag}"), 2,
               (rf"config\.{re.escape(shown)}: expected {expected}",))
          for flag, shown, expected in (
              ("input.batch_size=0", "input.batch_size=0", "an integer >= 1"),
              ("model.time_encoding=bogus", "model.time_encoding='bogus'",
               r"one of \['raw', 'cyclic'\]"),
              ("train.num_epochs=0", "train.num_epochs=0", "an integer >= 1"),
              ("input.validation_fraction=1.5", "input.validation_fraction=1.5",
               r"a number in \[0, 1\)"),
              ("input.validation_fraction=-0.1", "input.validation_fraction=-0.1",
               r"a number in \[0, 1\)"),
              ("train.learning_rate=-1", "train.learning_rate=-1.0", "a finite number > 0"),
              ("eval.knn_k=0", "eval.knn_k=0", "an integer >= 1"),
              ("input.schedule=cmu_seasons", "input.schedule='cmu_seasons'",
               "'webcam_clipart'"),
              ("model.dtype=float16", "model.dtype='float16'", "one of"),
              ("model.encoder_features=0", "model.encoder_features=0", "an integer >= 1"),
              ("input.augment.contrast=2", "input.augment.contrast=2.0",
               r"a number in \[0, 1\)"),
              ("train.num_devices=-1", "train.num_devices=-1", "an integer >= 0"),
              ("eval.every_epochs=0", "eval.every_epochs=0", "an integer >= 1"),
              ("seed=-1", "seed=-1", "an integer >= 0"),
              ("input.batch_size=33", "input.batch_size=33", "a multiple of the 2 devices"),
          )],
        Case("a CMU run with a bad field", _experiment("cmu_seasons", "--config.train.grad_clip=0"),
             2, (r"config\.train\.grad_clip=0\.0: expected a finite number > 0",)),
        Case("more devices than there are", _experiment("webcam_clipart",
                                                        "--config.train.num_devices=99"), 2,
             (r"config\.train\.num_devices=99 but only 2 local devices",)),
        Case("a --data-dir that is a file", _data_dir_a_file, 2,
             (r"--data-dir .*tfds is a file, not a folder; expected the TFDS data directory",)),
        Case("a --data-dir under a file", _data_dir_under_a_file, 2,
             (r"--data-dir .*notes/tfds cannot be created: .*notes is a file",)),
        Case("a decay workdir under a file", _decay_workdir_under_a_file, 2,
             (r"--workdir .*notes/run cannot be created: .*notes is a file",)),
        Case("a TFDS data_dir that is a file", _experiment_data_dir_a_file, 2,
             (r"config\.input\.data_dir='.*notes': expected a folder \(created if absent\)",)),
        Case("the demo with num_epochs=0", _demo("--config.train.num_epochs=0"), 2,
             (r"config\.train\.num_epochs=0: expected an integer >= 1",)),
        Case("a workdir that is a file", _workdir_a_file, 2,
             (r"run is a file, not a folder", r"--workdir")),
        Case("a workdir under a file", _workdir_under_a_file("webcam_clipart"), 2,
             (r"--workdir .*notes/run cannot be created: .*notes is a file",)),
        Case("a map-summarization workdir under a file", _workdir_under_a_file(
            "map_summarization"), 2, (r"--workdir .*notes/run cannot be created: .*notes is",)),
        Case("a workdir of another experiment", _workdir_of_another_experiment, 2,
             (r"dataset: 'cmu_seasons' there, 'webcam_clipart' asked", r"new --workdir")),
        Case("map summarization on an empty --manual-dir",
             _experiment("map_summarization", "--manual-dir={tmp}"), 2,
             (r"config\.map\.robotcar_dir: .*robotcar is not a folder",
              r"DIR/robotcar and DIR/cmu_seasons")),
        Case("map summarization on an unknown query date",
             _experiment("map_summarization", "--config.map.query_dates=('2099-01-01',)"), 2,
             (r"config\.map\.query_dates", r"not there: \['2099-01-01'\]", r"2010-09-01")),
        Case("map summarization on a query date that is no date",
             _experiment("map_summarization", "--config.map.query_dates=('March 4',)"), 2,
             (r"ISO dates such as", r"'March 4' is not one")),
        Case("map summarization on a missing slice",
             _experiment("map_summarization", "--config.map.slice=99"), 2,
             (r"config\.map\.slice=99", r"no slice99")),
        Case("map summarization on a map root without the slice",
             _experiment("map_summarization", "--config.map.root={tmp}"), 2,
             (r"config\.map\.slice=8: expected a slice of .*; it has none",)),
        Case("map summarization on a map root that does not exist",
             _experiment("map_summarization", "--config.map.root={tmp}/nowhere"), 2,
             (r"config\.map\.root='.*/nowhere': expected an Extended CMU Seasons layout; "
              r".*/nowhere is no folder",)),
        Case("map summarization pruning 150 %",
             _experiment("map_summarization", "--config.map.ratios=(1.5,)"), 2,
             (r"config\.map\.ratios=\(1\.5,\)", r"\(0, 1\)")),
        # Bad data: an unreadable image is skipped and named (a correct result, exit 0); a
        # bad pose line or layout is an error naming the file and line.
        *[Case(f"a {kind} image", _bad_image(kind), 0,
               (rf"unreadable image .*a/{DAYS[1]}\.png", r"skipped"))
          for kind in ("zero-byte", "corrupt", "truncated")],
        Case("a webcam download one folder too deep", _webcam_one_level_too_deep, 2,
             (r"dl is not a Webcam Clip Art layout: no scene folder with time-named images",
              r"Expected <root>/<scene>/YYYYMMDD_HHMMSS\.jpg")),
        Case("a zero quaternion in a CMU pose line", _cmu_zero_quaternion, 2,
             (r"ground-truth-database-images-slice7\.txt:2: a quaternion of norm 0",)),
        Case("a NaN in a RobotCar INS row", _robotcar_ins(_nan_northing), LayoutError,
             (r"gps/ins\.csv:3: non-finite pose value \(northing=nan\)",)),
        Case("a RobotCar INS file with a wrong header", _robotcar_ins(_renamed_northing),
             LayoutError, (r"gps/ins\.csv: header lacks \['northing'\]",)),
        Case("a checkpoint that does not match its config.json", _mismatched_checkpoint,
             ValueError, (r"checkpoint \d+ in .*run/checkpoints does not match the config",
                          r"encoder_features': 16")),
    ]


CASES = _cases()


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input(case: Case, tmp_path, capsys, caplog):
    run, inputs = case.make(tmp_path)
    before = {str(p): _checksums(p) for p in inputs}
    capsys.readouterr()
    caplog.clear()
    if isinstance(case.expect, int):
        assert run() == case.expect
        message = capsys.readouterr().err + caplog.text  # a read summary is a warning
    else:
        with pytest.raises(case.expect) as err:
            run()
        message = str(err.value)
    for pattern in case.names:
        assert re.search(pattern, message), f"{case.name}: {pattern!r} not in:\n{message}"
    assert {str(p): _checksums(p) for p in inputs} == before, f"{case.name} changed its inputs"


@pytest.mark.parametrize("size", ["tiny", "small", "full"])
def test_every_default_config_is_valid(size, tmp_path):
    """The validation refuses no config an experiment ships (with a fresh workdir)."""
    from experiments.cmu_seasons.config import get_config as cmu
    from experiments.map_summarization.config import get_config as mapsum
    from experiments.map_summarization.config import validate as validate_mapsum
    from experiments.sec4a.config import validate
    from experiments.webcam_clipart.config import get_config as webcam

    for get_config in (webcam, cmu):
        validate(get_config(size), tmp_path / "run")
    config = mapsum(size)
    config.map.candidates = ("rp_cmu",)  # a recipe with the CMU predictor: its config too
    validate_mapsum(config, tmp_path / "run")
