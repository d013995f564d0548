import numpy as np
import pytest

from rp_jax.sources.synthetic import frame_jobs, photometry, presets, road_lighting


def test_the_class_is_the_highest_whose_average_and_lowest_point_are_both_met():
    assert road_lighting.lighting_class(6.0, 1.2) == "P4"
    assert road_lighting.lighting_class(8.0, 1.2) == "P4"  # P3's average, not its lowest
    assert road_lighting.lighting_class(8.0, 1.6) == "P3"
    assert road_lighting.lighting_class(20.0, 5.0) == "P1"
    assert road_lighting.lighting_class(1.0, 0.1) is None
    averages = [a for a, _ in road_lighting.P_CLASSES.values()]
    assert averages == sorted(averages, reverse=True)


def test_the_calculation_grid_follows_en_13201_3():
    grid = road_lighting.calculation_grid(10.0, 25.0, -5.8, 5.8)
    xs, ys = np.unique(grid[:, 0]), np.unique(grid[:, 1])
    assert len(xs) == 10 and len(ys) == 8  # 10 along up to 30 m; across at most 1.5 m apart
    np.testing.assert_allclose(np.diff(xs), 2.5)
    np.testing.assert_allclose([xs[0], ys[0]], [11.25, -5.8 + 11.6 / 16])
    assert len(np.unique(road_lighting.calculation_grid(0.0, 40.0, 0.0, 3.0)[:, 0])) == 14
    assert len(np.unique(road_lighting.calculation_grid(0.0, 40.0, 0.0, 3.0)[:, 1])) == 3
    with pytest.raises(ValueError, match="spacing_m"):
        road_lighting.calculation_grid(0.0, 0.0, 0.0, 3.0)


def test_road_illuminance_is_the_inverse_square_law_with_the_cosine():
    intensity, h = 790.0, 6.25
    lamps = np.array([[0.0, 0.0, h]])
    d = np.array([0.0, 5.0, 15.0])
    E = road_lighting.road_illuminance(np.stack([d, np.zeros(3)], 1), lamps, intensity)
    np.testing.assert_allclose(E, intensity * h / (h * h + d * d) ** 1.5, rtol=0.02)


def test_the_arrangement_rule_by_road_width():
    assert road_lighting.arrangement_for(5.0, 6.25) == "single-sided"
    assert road_lighting.arrangement_for(8.0, 6.25) == "staggered"
    assert road_lighting.arrangement_for(11.6, 6.25) == "opposite"


def _street(preset: str, seed: int, tmp_path):
    job = presets.plan(preset, tmp_path, size="full", seed=seed).jobs[0]
    return frame_jobs.scene_of(job.scene), photometry.named(job.lighting)


@pytest.mark.parametrize("preset,seeds", [("robotcar_seasons", range(10)),
                                          ("robotcar_day", range(3))])
def test_the_physical_nights_light_their_street_to_class_p4(preset, seeds, tmp_path):
    # What photometry.EN_13201 and docs/synthetic_world.md say of the RobotCar-like worlds'
    # lamps (the conditions run's ten worlds, and the whole-day RP's): class P4 of
    # EN 13201-2 on the carriageway, not over-lit, in a staggered pair of rows (where the
    # design rule would put opposite rows on a street this wide).
    for seed in seeds:
        scene, lighting = _street(preset, seed, tmp_path)
        assert lighting is photometry.EN_13201
        check = road_lighting.check_street(scene.lamps, scene.road_half_width,
                                           lighting.lamp_intensity_cd)
        assert check.lighting_class == "P4" and not check.overlit, (seed, check)
        assert 2 * 22.0 <= check.spacing_m <= 2 * 32.0
        assert (check.arrangement, check.rule_arrangement) == ("staggered", "opposite")


def test_a_street_too_short_to_compute_away_from_its_ends_is_refused():
    lamps = np.array([[0.0, -5.0, 6.25], [25.0, 5.0, 6.25], [50.0, -5.0, 6.25]])
    with pytest.raises(ValueError, match="too short a street"):
        road_lighting.check_street(lamps, 5.8, 790.0)
    lamps = np.array([[x, -5.0 if k % 2 else 5.0, 6.25] for k, x in enumerate(range(0, 150, 25))])
    check = road_lighting.check_street(lamps, 5.8, 790.0)
    assert check.arrangement == "staggered" and check.spacing_m == 50.0
