"""The frames of the map-summarization experiment, rendered in the Extended CMU layout."""

import datetime as dt
import json

import pytest

from rp_jax.sources.synthetic import map_layout, presets


def test_available_query_dates_of_the_presets():
    tiny = map_layout.available_query_dates("tiny", 0, 8)
    assert tiny == [dt.date(2010, 9, 1), dt.date(2011, 7, 28)]  # Apr 21 is the reference
    small = map_layout.available_query_dates("small", 0, 8)
    assert len(small) == 11 and presets.REFERENCE_DATE not in small


def test_ensure_layout_rejects_a_date_without_queries(tmp_path):
    with pytest.raises(ValueError, match="query dates are"):
        map_layout.ensure_cmu_map_layout(
            tmp_path,
            size="tiny",
            seed=0,
            slice_id=8,
            query_dates=[dt.date(2011, 3, 4)],
            progress=False,
        )


def test_ensure_layout_renders_an_older_world_again(tmp_path, monkeypatch):
    root = tmp_path / "cmu"
    (root / presets.SYNTHETIC_DIR).mkdir(parents=True)
    (root / "stale.jpg").write_bytes(b"old pixels")
    old = {"size": "tiny", "seed": 0, "slice": 8, "query_dates": ["2010-09-01"]}  # world 1
    (root / presets.SYNTHETIC_DIR / "map_subset.json").write_text(json.dumps(old))
    rendered = []

    def fake_run_jobs(jobs, **kwargs):
        rendered.append((len(jobs), (root / "stale.jpg").exists()))
        raise RuntimeError("stop after the render call")

    monkeypatch.setattr(presets, "run_jobs", fake_run_jobs)
    with pytest.raises(RuntimeError, match="stop after"):
        map_layout.ensure_cmu_map_layout(
            root,
            size="tiny",
            seed=0,
            slice_id=8,
            query_dates=[dt.date(2010, 9, 1)],
            progress=False,
        )
    assert not (root / "stale.jpg").exists()  # the version-1 frames are gone
    # The render was reached (Sep 01 has tiny queries): 8 reference frames + 8 queries.
    assert rendered == [(16, False)]


def test_cmu_reference_traversal_as_the_real_one_is_described():
    import zoneinfo

    tz = zoneinfo.ZoneInfo(presets.CMU_TIMEZONE)
    plan = presets.plan("cmu_seasons", "/nonexistent", size="small", seed=0)
    ref = [j for j in plan.jobs if j.keypoints_path is not None]
    other = [j for j in plan.jobs if j.keypoints_path is None]
    assert {j.when.astimezone(tz).date() for j in ref} == {dt.date(2011, 4, 4)}
    assert {j.weather for j in ref} == {"clear"} and {j.weather for j in other} == {None}
    hours = [j.when.astimezone(tz).hour + j.when.astimezone(tz).minute / 60 for j in plan.jobs]
    assert 9.0 <= min(hours) and max(hours) < 16.2  # a traversal lasts a few seconds
    assert max(hours) - min(hours) > 4.0  # the traversals span the hours of the day
