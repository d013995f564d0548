"""Parked cars stay as long as cars do on that kind of street (traffic.parked_car)."""

import numpy as np

from rp_jax.sources.synthetic import traffic


def _timeline(vegetation, hours, slot=3, seed=7, step_h=0.25):
    t0 = 40 * 365 * 24.0  # some instant in 2010, in hours of the UNIX clock
    steps = range(int(hours / step_h))
    return [traffic.parked_car(seed, slot, vegetation, t0 + k * step_h) for k in steps]


def _stays(timeline):
    """Lengths (in steps) of the runs of one identical car."""
    runs, cur, n = [], None, 0
    for c in timeline:
        if c is not None and c == cur:
            n += 1
        else:
            if cur is not None:
                runs.append(n)
            cur, n = c, 1
    if cur is not None:
        runs.append(n)
    return np.array(runs)


def test_a_stay_is_one_car_at_one_place():
    tl = _timeline(0.2, 48)
    assert any(c is not None for c in tl) and any(c is None for c in tl)
    # Asking at any instant of a stay gives the same car and offset (deterministic).
    assert tl == _timeline(0.2, 48)


def test_commercial_stays_hours_residential_stays_days():
    steps_per_h = 4
    commercial = np.concatenate([_stays(_timeline(0.2, 24 * 14, slot=s)) for s in range(8)])
    residential = np.concatenate([_stays(_timeline(0.8, 24 * 28, slot=s)) for s in range(8)])
    med_c = np.median(commercial) / steps_per_h
    med_r = np.median(residential) / steps_per_h
    assert 0.5 < med_c < 4.0, med_c  # hours
    assert med_r > 6.0 and med_r > 4 * med_c, (med_r, med_c)


def test_occupancy_follows_the_street():
    for veg in (0.2, 0.8):
        tl = _timeline(veg, 24 * 60, slot=1, step_h=1.0)
        occ = np.mean([c is not None for c in tl])
        assert abs(occ - traffic.parking_occupancy(veg)) < 0.15, (veg, occ)


def test_residents_park_their_own_car_again():
    tl = [c for c in _timeline(0.8, 24 * 90, slot=5, step_h=2.0) if c is not None]
    variants = [v for v, _ in tl]
    top = max(set(variants), key=variants.count)
    assert variants.count(top) / len(variants) > 0.3  # the resident's car, months apart
    assert len({round(dx, 3) for v, dx in tl if v == top}) > 1  # never parked twice exactly alike
