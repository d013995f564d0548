"""The outcome scorers of a run (experiments.map_summarization.outcome_scorer): settings and
the ensemble's score."""

import datetime as dt
from pathlib import Path

import jax
import numpy as np
import pytest

from experiments.map_summarization import outcome_scorer as eo
from experiments.map_summarization.config import get_config
from rp_jax.mapsum.outcome_scorer import (
    OutcomeScorer,
    Standardizer,
    create_train_state,
    score_points,
)


def test_members_come_from_the_config():
    config = get_config("tiny")
    assert eo.settings_of(config).members == config.map.outcome_members
    config.map.outcome_members = 3
    assert eo.settings_of(config).members == 3


def test_an_ensemble_scores_the_mean_probability_of_its_members():
    rng = np.random.default_rng(0)
    when = dt.datetime(2010, 6, 1, 12, tzinfo=dt.UTC)
    nowhere = Path("/nonexistent")
    n_point, n_query = 5, eo.query_table([when], [nowhere]).shape[1]
    net = OutcomeScorer(hidden=8, depth=1, time_aware=True)
    members = [jax.device_get(create_train_state(net, n_point, n_query, seed=s).params)
               for s in (0, 1)]
    table = rng.normal(size=(30, n_point)).astype(np.float32)
    pstd = Standardizer.fit(table)
    qstd = Standardizer(np.zeros(n_query), np.ones(n_query))
    scorers = eo.OutcomeScorers(eo.ScorerSettings(members=2), {"outcome": net},
                                {"outcome": members}, {"outcome": (pstd, qstd)},
                                np.ones(n_point, bool), {})
    got = scorers.point_scores("outcome", table, when)
    qrow = qstd(eo.query_table([when], [nowhere]))[0]
    each = [score_points(net, p, pstd(table), qrow) for p in members]
    assert not np.allclose(each[0], each[1])  # two members that differ
    np.testing.assert_allclose(got, (each[0] + each[1]) / 2, rtol=1e-6)


def test_validation_refuses_a_bad_field_before_any_work(tmp_path):
    config = get_config("tiny")
    config.map.outcome_members = 0
    with pytest.raises(ValueError, match="outcome_members"):
        eo.validate(config, tmp_path / "run", slice_id=6, progress=False)
    assert not (tmp_path / "run" / "outcome_labels").exists()
