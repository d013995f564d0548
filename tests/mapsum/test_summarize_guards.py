"""``python -m rp_jax.mapsum summarize`` as a user meets it (issue 27, findings 3, 6 and 8).

A user's own file in ``--out`` is kept, a pruning ratio that keeps all or nothing is
refused, and a query time the predictor cannot read is refused before any work, leaving no
``--out`` behind. On the tiny textured-plane scene of tests/_own_data.py.
"""

import pytest

from rp_jax.mapsum import __main__ as command
from tests._own_data import make_predictor, make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"), n_db=4)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return make_predictor(tmp_path_factory.mktemp("predictor"))


def _summarize(scene, out, *extra):
    return command.main(["summarize", "--model", str(scene.model), "--images", str(scene.images),
                         "--out", str(out), *extra])


@pytest.mark.parametrize("ratio", ["1", "0", "1.5", "-0.1"])
def test_a_ratio_outside_0_1_is_refused(scene, tmp_path, capsys, ratio):
    """--ratio 1 wrote an empty map with exit status 0."""
    out = tmp_path / "o"
    assert _summarize(scene, out, "--method", "random", "--ratio", ratio) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--ratio {float(ratio):g}" in err
    assert "strictly between 0 and 1" in err and not out.exists()


def test_a_users_summary_json_is_kept(scene, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "summary.json").write_text('{"mine": true}\n')
    argv = ["--method", "random", "--ratio", "0.5", "--partition", "none"]
    assert _summarize(scene, out, *argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "summary.json" in err and "--overwrite" in err
    assert (out / "summary.json").read_text() == '{"mine": true}\n'
    assert _summarize(scene, out, *argv, "--overwrite") == 0
    assert '"mine"' not in (out / "summary.json").read_text()
    assert _summarize(scene, out, *argv) == 0  # its own outputs: replaced without asking
    assert (out / "model").is_dir() and (out / "localization.npz").is_file()


def test_query_times_the_predictor_cannot_read(scene, model, tmp_path, capsys):
    base = ["--predictor", str(model), "--ratio", "0.5"]
    out = tmp_path / "o"
    # 22:00 lies outside the 08:00-18:00 schedule: refused at once, with no --out left.
    assert _summarize(scene, out, *base, "--at", "2011-04-04 22:00") == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "--at 2011-04-04T22:00:00 lies outside" in captured.err
    assert "wrap=True" not in captured.err and not out.exists()
    # A date alone is midnight: refused for a predictor that reads the time of day.
    assert _summarize(scene, out, *base, "--at", "2011-04-04") == 2
    err = capsys.readouterr().err
    assert "a date without a time of day" in err and "the time of day (hour and minute)" in err
    assert not out.exists()
