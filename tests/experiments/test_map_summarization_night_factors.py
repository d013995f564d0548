"""Night queries re-rendered with one factor of the night capture taken away
(``experiments.map_summarization.night_factors``)."""

import json
from pathlib import Path

import numpy as np
import pytest

from experiments.map_summarization import night_factors as nf
from rp_jax.datasets import builder
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.layout import LayoutError
from tests.datasets._tiny import tiny_world_copy


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The command on the tiny world (its night traversal only), three frames."""
    tmp = tmp_path_factory.mktemp("night_factors")
    workdir = tmp / "run"
    # The session's tiny world (rendered once) where the command looks for it.
    tiny_world_copy(tmp_path_factory, "robotcar_seasons",
                    builder.synthetic_root(tmp / "data", "robotcar_seasons", "tiny", 0))
    code = nf.main(["--size", "tiny", "--frames", "3", "--workdir", str(workdir), "--quiet",
                    "--data-dir", str(tmp / "data")])
    assert code == 0
    return workdir, json.loads((workdir / "metrics.json").read_text())


def test_every_factor_is_measured_on_the_same_frames(tiny):
    workdir, out = tiny
    assert list(out["results"]) == ["night"]  # the tiny size renders no night-rain
    by_factor = out["results"]["night"]
    assert list(by_factor) == list(nf.FACTORS)
    for s in by_factor.values():
        assert s["frames"] == 3
        assert len(s["per_frame"]["redetected"]) == 3
        assert set(s["localized"]) == {"0.25m_2deg", "0.5m_5deg", "5m_10deg"}
    assert "| no motion blur and no sensor noise |" in (workdir / "report.md").read_text()


def test_the_first_row_is_the_layouts_own_night(tiny):
    _, out = tiny
    night = out["results"]["night"]
    # Re-rendered and through the layout's JPEG, the frames are the layout's images.
    assert night["as_taken"]["per_frame"]["equals_layout_image"] == [True, True, True]
    # The camera: the night's longest exposure; still, the same exposure and gain.
    assert night["as_taken"]["exposure_ms_median"] == pytest.approx(1000 / 11.1, rel=1e-3)
    assert night["still"]["per_frame"]["gain"] == night["as_taken"]["per_frame"]["gain"]
    # A blur-limited exposure: stopped at one pixel of blur 10 m away, at a lower gain.
    short = night["short_exposure"]
    job = nf.sample_jobs(nf.planned_world(Path("/nonexistent"), "tiny", 0), "night", 1)[0]
    limit_ms = 1000 * nf.BLUR_DISTANCE_M / (job.K[0, 0] * np.linalg.norm(job.velocity))
    assert short["exposure_ms_median"] == pytest.approx(limit_ms, rel=1e-6)
    # (at the tiny size's 128 pixels a pixel is wide: about 27 ms against the frame's 90)
    assert short["exposure_ms_median"] < night["as_taken"]["exposure_ms_median"] / 2
    assert short["gain_median"] < night["as_taken"]["gain_median"]
    # By day, the same views are taken in a fraction of a millisecond at a low gain.
    assert night["by_day"]["exposure_ms_median"] < 5
    assert night["by_day"]["gain_median"] < night["as_taken"]["gain_median"] / 100


def test_by_day_the_same_views_find_the_map_that_the_night_does_not(tiny):
    _, out = tiny
    night = out["results"]["night"]
    assert night["by_day"]["redetected_mean"] > night["as_taken"]["redetected_mean"] + 3


def test_each_variant_changes_its_frame_and_only_its_own_way():
    world = nf.planned_world(Path("/nonexistent"), "tiny", 0)
    job = nf.sample_jobs(world, "night", 1)[0]
    taken, meta = nf.render_variant(job, "night", "as_taken")
    still, still_meta = nf.render_variant(job, "night", "still")
    quiet, _ = nf.render_variant(job, "night", "noiseless")
    day, day_meta = nf.render_variant(job, "night", "by_day")
    assert not np.array_equal(taken, still) and not np.array_equal(taken, quiet)
    assert still_meta["gain"] == meta["gain"]
    assert day_meta["sun_elevation_deg"] > 0 > meta["sun_elevation_deg"]
    assert day_meta["gain"] < meta["gain"] / 100 and not np.array_equal(day, taken)
    # The same instant into the traversal, on the reference traversal's day.
    shifted = nf.by_day(job, "night")
    assert (shifted.when - rcs.traversal_start(rcs.REFERENCE_CONDITION)
            == job.when - rcs.traversal_start("night"))
    with pytest.raises(ValueError, match="unknown factor"):
        nf.render_variant(job, "night", "sunny")


def test_frames_are_spread_over_the_traversal():
    world = nf.planned_world(Path("/nonexistent"), "tiny", 0)
    every = [j for j in world.jobs if j.image_path.parent.parent.name == "night"]
    picked = nf.sample_jobs(world, "night", 3)
    assert picked[0] is every[0] and picked[-1] is every[-1] and len(picked) == 3
    assert len(nf.sample_jobs(world, "night", 10_000)) == len(every)
    with pytest.raises(LayoutError, match="no snow frame"):
        nf.sample_jobs(world, "snow", 3)


def test_a_layout_the_preset_did_not_write_is_refused(tmp_path):
    with pytest.raises(LayoutError, match="parameters.json"):
        nf.synthetic_world(tmp_path)
    (tmp_path / "_synthetic").mkdir()
    (tmp_path / "_synthetic" / "parameters.json").write_text(
        json.dumps({"preset": "cmu_seasons", "seed": 0, "size": "tiny"}))
    with pytest.raises(LayoutError, match="expected 'robotcar_seasons'"):
        nf.synthetic_world(tmp_path)


@pytest.mark.parametrize("flags, message", [
    (["--conditions", "night,midnight"], "--conditions 'night,midnight'"),
    (["--frames", "0"], "--frames >= 1"),
    (["--seeds", "0,1"], "--seeds and --factor go with --write-layouts"),
    (["--factor", "still"], "--seeds and --factor go with --write-layouts"),
    (["--manual-dir", "."], "a real download cannot be rendered again"),
])
def test_bad_flags_are_refused_before_any_work(tmp_path, capsys, flags, message):
    assert nf.main(["--size", "tiny", "--workdir", str(tmp_path / "w"), "--quiet",
                    "--data-dir", str(tmp_path / "data"), *flags]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "w").exists() and not (tmp_path / "data").exists()


def test_a_counterfactual_copy_changes_the_night_frames_and_nothing_else(tiny, tmp_path):
    _, out = tiny
    src = Path(out["world"]["root"])
    dst = tmp_path / "copy"
    n = nf.write_counterfactual_layout(src, dst, "still_noiseless", ["night"], progress=False)
    night = {p.relative_to(src) for p in (src / "images" / "night").rglob("*.jpg")}
    assert n == len(night) > 0
    for path in (p for p in src.rglob("*") if p.is_file()):
        rel = path.relative_to(src)
        copy = dst / rel
        assert copy.is_file(), rel
        if rel in night:
            assert copy.read_bytes() != path.read_bytes()
        elif rel.parts[0] == "segmentation" and rel.parts[1] == "night":
            pass  # rendered again: the same categories (nothing moves but the camera's noise)
        else:
            assert copy.read_bytes() == path.read_bytes(), rel
    record = json.loads((dst / nf.COUNTERFACTUAL_JSON).read_text())
    assert record["factor"] == "still_noiseless" and record["conditions"] == ["night"]
    # The copy reads as the layout it copies: the same captures and poses.
    assert ([c.image_path.relative_to(dst) for c in rcs.read_captures(dst, ["night"])]
            == [c.image_path.relative_to(src) for c in rcs.read_captures(src, ["night"])])
    # A second run finds it finished; another factor or a foreign folder is refused.
    assert nf.write_counterfactual_layout(src, dst, "still_noiseless", ["night"],
                                          progress=False) == 0
    with pytest.raises(ValueError, match="another counterfactual copy"):
        nf.write_counterfactual_layout(src, dst, "still", ["night"], progress=False)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(ValueError, match="not a counterfactual copy"):
        nf.write_counterfactual_layout(src, tmp_path / "mine", "still", ["night"],
                                       progress=False)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
