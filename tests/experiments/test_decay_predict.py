"""experiments.decay --predict: the per-years-apart table and its arguments (the training
itself is tested in tests/conditional/test_decay.py)."""

import numpy as np
import pytest

from experiments.decay import predict


def test_bin_table_by_hand():
    outcome = np.array([[1, 0, -1, 1], [0, 0, 1, -1]], np.int8)
    years = np.array([[0.1, 0.9, 1.2, 6.0], [1.4, 0.4, 2.4, np.nan]])
    probability = np.array([[0.5, 0.25, 0.9, 0.9], [0.5, 0.5, 0.75, 0.1]])
    rows = predict.bin_table(probability, outcome, years, num_bins=3)
    assert [r["years_apart"] for r in rows] == [0, 1, 2, "all"]
    assert [r["pairs"] for r in rows] == [2, 2, 1, 5]  # unknown and 6 years out are left out
    np.testing.assert_allclose(rows[0]["observed"], 0.5)
    np.testing.assert_allclose(rows[0]["predicted"], 0.5)
    np.testing.assert_allclose(rows[1]["predicted"], 0.375)  # 0.25 and 0.5
    np.testing.assert_allclose(rows[1]["bce"], -(np.log(0.75) + np.log(0.5)) / 2)
    np.testing.assert_allclose(rows[2]["bce"], -np.log(0.75))
    np.testing.assert_allclose(rows[3]["observed"], 0.4)
    result = {"variants": {"no decay": {"bins": rows}, "decay basis": {"bins": rows}}}
    text = predict.markdown(result)
    assert "no decay: predicted %" in text and "| 1 | 2 | 0.0 | 37.5 |" in text


@pytest.mark.parametrize("argv, message", [
    (["--predict", "--num-epochs", "0"], "--num-epochs > 0"),
    (["--predict", "--points-per-image", "0"], "--points-per-image >= 1"),
])
def test_bad_predict_arguments_are_one_line_errors(argv, message, capsys):
    from experiments.decay.__main__ import main

    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2 and message in capsys.readouterr().err
