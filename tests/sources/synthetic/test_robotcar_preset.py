"""The ``robotcar`` preset (the paper's Table I traversals, Sec. IV-B-1) in Oxford's climate."""

from rp_jax.sources.synthetic import conditions, presets
from rp_jax.sources.synthetic.plan_robotcar import ROBOTCAR_LOCATION


def _traversal_days(seed, tmp_path):
    plan = presets.plan("robotcar", tmp_path / str(seed), size="full", seed=seed)
    return plan.jobs, sorted({(j.scene, j.when.date()) for j in plan.jobs},
                             key=lambda sd: sd[1])


def test_table_one_traversals_are_driven_in_oxfords_climate(tmp_path):
    lat, lon = ROBOTCAR_LOCATION
    snowy_in = {"local": 0, "latitude": 0}
    for seed in range(3):
        jobs, days = _traversal_days(seed, tmp_path)
        assert {dict(j.scene.extra).get("climate") for j in jobs} == {"local"}
        assert len(days) == 9
        for scene, day in days:
            for climate in snowy_in:
                level = conditions.snow_state(scene.seed, day, lat, lon, climate=climate)[0]
                snowy_in[climate] += level > 0
    # None of the nine days has snow lying in Oxford's climate (Table I's traversals are
    # not snow traversals); the latitude's laid it on four of them.
    assert snowy_in["local"] == 0
    assert snowy_in["latitude"] >= 3 * 3
