"""The outcome scorers of a run (experiments.map_summarization.outcome_scorer): settings and
the ensemble's score."""

import datetime as dt
from pathlib import Path

import jax
import numpy as np
import pytest

from experiments.map_summarization import outcome_labels
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
    n_point, n_query = 5, outcome_labels.query_table([when], [nowhere]).shape[1]
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
    qrow = qstd(outcome_labels.query_table([when], [nowhere]))[0]
    each = [score_points(net, p, pstd(table), qrow) for p in members]
    assert not np.allclose(each[0], each[1])  # two members that differ
    np.testing.assert_allclose(got, (each[0] + each[1]) / 2, rtol=1e-6)


def test_validation_refuses_a_bad_field_before_any_work(tmp_path):
    config = get_config("tiny")
    config.map.outcome_members = 0
    with pytest.raises(ValueError, match="outcome_members"):
        eo.validate(config, tmp_path / "run", slice_id=6, progress=False)
    assert not (tmp_path / "run" / "outcome_labels").exists()


@pytest.mark.parametrize("flags, says", [
    (["--validation-seeds", "x"], "argument --validation-seeds: 'x': expected comma-separated"),
    (["--validate-slice", "8"], "slice 8 is the test slice"),
])
def test_the_command_refuses_bad_flags_naming_them_before_any_work(tmp_path, capsys, flags,
                                                                    says):
    code = None
    try:
        code = eo.main(["--workdir", str(tmp_path / "run"), "--quiet", *flags])
    except SystemExit as e:  # argparse's own errors
        code = e.code
    assert code == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_table_of_another_width_is_refused_naming_both():
    when = dt.datetime(2010, 6, 1, 12, tzinfo=dt.UTC)
    n_query = outcome_labels.query_table([when], [Path("/nonexistent")]).shape[1]
    net = OutcomeScorer(hidden=8, depth=1, time_aware=True)
    params = jax.device_get(create_train_state(net, 4, n_query, seed=0).params)
    std = (Standardizer(np.zeros(4), np.ones(4)), Standardizer(np.zeros(n_query),
                                                               np.ones(n_query)))
    scorers = eo.OutcomeScorers(eo.ScorerSettings(), {"outcome": net}, {"outcome": [params]},
                                {"outcome": std}, np.ones(4, bool), {})
    with pytest.raises(ValueError, match="a table of 6 point features, trained on 4"):
        scorers.point_scores("outcome", np.zeros((3, 6), np.float32), when)


def test_the_query_table_reads_the_sun_at_the_given_place():
    from rp_jax.mapsum.outcome_scorer import QUERY_FEATURES
    from rp_jax.sources.synthetic.plan_robotcar import ROBOTCAR_LOCATION

    when = [dt.datetime(2014, 12, 16, 17, 0, tzinfo=dt.UTC)]  # dusk in Oxford
    nowhere = [Path("/nonexistent")]
    cmu = outcome_labels.query_table(when, nowhere)
    oxford = outcome_labels.query_table(when, nowhere, ROBOTCAR_LOCATION)
    sun = [i for i, n in enumerate(QUERY_FEATURES) if n.startswith("sun_")]
    assert sun and not np.allclose(cmu[:, sun], oxford[:, sun])
    rest = [i for i in range(len(QUERY_FEATURES)) if i not in sun]
    np.testing.assert_array_equal(cmu[:, rest], oxford[:, rest])  # the clock is the same
    # 17:00 UTC in mid-December: the sun is down in Oxford (sets near 15:55 UTC).
    assert oxford[0, QUERY_FEATURES.index("sun_elevation")] < 0


def test_stacked_groups_offset_their_point_rows():
    from rp_jax.mapsum.localization_outcomes import OutcomeLabels

    def group(points, pairs, name):
        n = len(pairs)
        lab = OutcomeLabels(query=np.zeros(n, np.int64), point=np.asarray(pairs, np.int64),
                            candidate=np.ones(n, bool), inlier=np.ones(n, bool),
                            pose_correct=np.ones(1, bool), localized=np.ones(1, bool),
                            names=np.array(["q"]), times=np.array(["t"]),
                            group=np.array([name]))
        return lab, np.zeros((points, 3), np.float32), np.zeros((1, 2), np.float32)

    stack = eo.stack_groups([group(4, [0, 3], "a"), group(2, [1], "b")])
    assert stack.points.shape == (6, 3) and stack.queries.shape == (2, 2)
    assert stack.pair_point.tolist() == [0, 3, 5]


def test_reads_rp_says_whether_the_scorers_learned_with_rp_columns():
    from experiments.map_summarization.outcome_scorer import OutcomeScorers
    from rp_jax.mapsum.outcome_scorer import point_feature_names

    def scorers(rp: dict) -> OutcomeScorers:
        columns = np.ones(len(point_feature_names(rp)), bool)
        return OutcomeScorers(None, {}, {}, {}, columns, {})

    assert not scorers({}).reads_rp
    assert scorers({"robotcar": 9}).reads_rp and scorers({"robotcar": 24}).reads_rp
