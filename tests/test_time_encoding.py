"""Tests of rp_jax.time_encoding (the time input of Sec. III-B)."""

import datetime as dt

import jax
import numpy as np
import pytest

from rp_jax import time_encoding as te


def _enc(times, **kw):
    f = te.fields_from_datetimes(times)
    return np.asarray(te.encode(f["hour"], f["minute"], f["day"], f["month"], **kw))


@pytest.mark.parametrize("fields,d", [("time_of_day", 2), ("day_of_year", 2), ("hour_of_year", 4)])
@pytest.mark.parametrize("encoding", ["raw", "cyclic"])
def test_dimensions_match_paper(fields, d, encoding):
    out = _enc([dt.datetime(2020, 3, 4, 12, 30)] * 3, fields=fields, encoding=encoding)
    assert out.shape == (3, d) and out.dtype == np.float32


def test_raw_values_are_normalised_paper_fields():
    out = _enc([dt.datetime(2020, 7, 16, 18, 30)], fields="hour_of_year", encoding="raw")[0]
    np.testing.assert_allclose(out, [18 / 24, 30 / 60, 15 / 31, 6 / 12], rtol=1e-6)


def test_cyclic_is_continuous_across_midnight_and_new_year():
    minute = dt.timedelta(minutes=1)
    for a in (dt.datetime(2020, 5, 3, 23, 59), dt.datetime(2020, 12, 31, 23, 59)):
        e = _enc([a, a + minute], fields="hour_of_year", encoding="cyclic")
        assert np.abs(e[0] - e[1]).max() < 0.02  # one minute / one day apart: nearly equal
    raw = _enc([dt.datetime(2020, 5, 3, 23, 59), dt.datetime(2020, 5, 4, 0, 0)],
               fields="time_of_day", encoding="raw")
    assert np.abs(raw[0] - raw[1]).max() > 0.9  # the raw encoding jumps, as documented


def test_cyclic_is_unit_circle_and_distinguishes_times():
    times = [dt.datetime(2020, 1, 1, h, 0) for h in range(24)]
    e = _enc(times, fields="time_of_day", encoding="cyclic")
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, rtol=1e-5)
    assert len({tuple(np.round(r, 4)) for r in e}) == 24


def test_jittable_and_validates():
    f = jax.jit(lambda h, m, d, mo: te.encode(h, m, d, mo, fields="hour_of_year"))
    assert f(np.array([1]), np.array([2]), np.array([3]), np.array([4])).shape == (1, 4)
    with pytest.raises(ValueError, match="unknown time fields"):
        te.num_features("minute_of_week")
    with pytest.raises(ValueError, match="unknown time encoding"):
        te.encode(1, 2, 3, 4, encoding="fourier")


@pytest.mark.parametrize("fields", ["time_of_day", "day_of_year", "hour_of_year"])
@pytest.mark.parametrize("encoding", ["raw", "cyclic"])
def test_numpy_fields_are_encoded_in_numpy_as_jax_encodes_them(fields, encoding, caplog):
    """Times a user asks about (NumPy fields) compile nothing and equal the training step's
    encoding (JAX, under jit) to float32 rounding."""
    rng = np.random.default_rng(0)
    n = 997  # a size no other test encodes, so a JAX path would have to compile
    fields_ = [rng.integers(0, 24, n), rng.integers(0, 60, n), rng.integers(1, 32, n),
               rng.integers(1, 13, n)]
    with caplog.at_level("WARNING"), jax.log_compiles(True):
        out = te.encode(*fields_, fields=fields, encoding=encoding)
    assert not [r for r in caplog.records if "Compiling" in r.getMessage()]
    assert isinstance(out, np.ndarray) and out.dtype == np.float32
    traced = jax.jit(lambda *f: te.encode(*f, fields=fields, encoding=encoding))(*fields_)
    assert isinstance(traced, jax.Array)
    np.testing.assert_allclose(out, np.asarray(traced), atol=2e-6)
