"""What moves in the synthetic street: parked cars, passing cars and people (Sec. IV-A stand-in).

The static world is ``scene.build_scene``; this module places, for one capture instant, the
objects that come and go: parked cars stay in their curb slots for the street's dwell times
(``parked_car``, an alternating renewal process whose parameters and sources are written
below), passing cars are spawned per 60 s window at a traffic rate that follows the hour,
and people walk along both sidewalks. Everything is deterministic from the scene's seed and
the instant, so two renderings of the same instant agree and a test can ask where a car was.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections import OrderedDict

import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic import object_textures as ot
from rp_jax.sources.synthetic.quads import (
    Material,
    QuadBuilder,
    QuadSet,
    TextureCache,
    box_quads,
)
from rp_jax.sources.synthetic.scene import Scene

__all__ = [
    "N_CAR_VARIANTS",
    "N_PEOPLE_VARIANTS",
    "OWN_CAR_LENGTH_M",
    "OWN_CAR_WIDTH_M",
    "PassingCar",
    "add_car",
    "car_headlamps",
    "headlamps",
    "passing_cars",
    "dynamic_quads",
    "parked_car",
    "parking_occupancy",
    "street_type",
]


def _car_face(
    seed: int,
    face: str,
    length: float,
    width: float,
    body_h: float,
    cabin_h: float,
    _memo: OrderedDict = OrderedDict(),  # noqa: B006
) -> np.ndarray:
    key = (seed, length, width, body_h, cabin_h)
    if key not in _memo:
        _memo[key] = ot.car_textures(seed, length, width, body_h, cabin_h)
        if len(_memo) > 64:
            _memo.popitem(last=False)
    return _memo[key][face]



# ---------------------------------------------------------------- cars and people


N_CAR_VARIANTS = 48  # distinct car models x paints (textures are cached per variant)
N_PEOPLE_VARIANTS = 64
_CAR_SHAPES = [
    (4.4, 1.8, 0.85, 0.5),
    (4.8, 1.85, 0.9, 0.55),
    (4.2, 1.75, 0.8, 0.5),
    (5.0, 1.95, 1.05, 0.75),
]


def add_car(
    qb: QuadBuilder,
    tc: TextureCache,
    x: float,
    y: float,
    direction: float,
    variant: int,
    owner: int,
    moving: bool,
) -> list[tuple]:
    """Adds a car (body box + cabin box) centred at (x, y) heading ``direction`` (+1 east, -1 west).

    Returns:
      The car's two shadow-casting boxes.
    """
    length, width, body_h, cabin_h = _CAR_SHAPES[variant % len(_CAR_SHAPES)]
    seed = 1000 + variant
    faces = (
        "side_l",
        "side_r",
        "front",
        "back",
        "top",
        "cabin_side_l",
        "cabin_side_r",
        "cabin_front",
        "cabin_back",
        "cabin_top",
    )
    keys = {}
    for f in faces:
        key = f"car:{variant}:{f}"
        tc.register(
            key,
            _car_face,
            dict(seed=seed, face=f, length=length, width=width, body_h=body_h, cabin_h=cabin_h),
        )
        keys[f] = key
    z0 = 0.18
    lo, hi = (x - length / 2, y - width / 2, z0), (x + length / 2, y + width / 2, z0 + body_h)
    # Heading east: front is +x, left side is +y.
    if direction > 0:
        tex = {
            "+x": keys["front"],
            "-x": keys["back"],
            "+y": keys["side_l"],
            "-y": keys["side_r"],
            "+z": keys["top"],
        }
    else:
        tex = {
            "-x": keys["front"],
            "+x": keys["back"],
            "-y": keys["side_l"],
            "+y": keys["side_r"],
            "+z": keys["top"],
        }
    emit = {"+x": 2.0, "-x": 2.0} if moving else None
    box_quads(qb, lo, hi, tex, categories.VEHICLE, Material.CAR, owner=owner, emit=emit)
    cl = length * 0.55
    cx = x - direction * length * 0.05
    clo, chi = (
        (cx - cl / 2, y - width * 0.45, z0 + body_h),
        (cx + cl / 2, y + width * 0.45, z0 + body_h + cabin_h),
    )
    if direction > 0:
        ctex = {
            "+x": keys["cabin_front"],
            "-x": keys["cabin_back"],
            "+y": keys["cabin_side_l"],
            "-y": keys["cabin_side_r"],
            "+z": keys["cabin_top"],
        }
    else:
        ctex = {
            "-x": keys["cabin_front"],
            "+x": keys["cabin_back"],
            "-y": keys["cabin_side_l"],
            "+y": keys["cabin_side_r"],
            "+z": keys["cabin_top"],
        }
    box_quads(qb, clo, chi, ctex, categories.VEHICLE, Material.CAR, owner=owner)
    return [(lo, hi), (clo, chi)]


def _car_instance(
    tc: TextureCache, x: float, y: float, direction: float, variant: int, owner: int, moving: bool
) -> tuple[QuadSet, np.ndarray]:
    """A car's quads and boxes from a cached template at the origin, moved to (x, y)."""
    key = (variant, direction > 0, moving)
    if key not in tc.car_templates:
        qb = QuadBuilder()
        boxes = add_car(qb, tc, 0.0, 0.0, direction, variant, 0, moving)
        tc.car_templates[key] = (qb.build(), np.array(boxes, np.float64))
    tpl, boxes = tc.car_templates[key]
    off = np.array([x, y, 0.0])
    q = dataclasses.replace(
        tpl,
        origin=tpl.origin + off,
        shadow_pt=tpl.shadow_pt + off,
        owner=np.full(tpl.n, owner, np.int32),
    )
    return q, boxes + off


def _hash_rng(*parts: int) -> np.random.Generator:
    return np.random.default_rng([int(p) & 0xFFFFFFFF for p in parts])


# ---------------------------------------------------------------- parked cars: dwell times

# How long a car stays in a curb slot depends on the street. Stays are lognormal with these
# medians (hours) and log-sd; the slot's occupancy is the street's (``parking_occupancy``); a
# slot alternates stays and empty gaps (an alternating renewal process), simulated within
# blocks of PARKING_BLOCK_H hours from a stationary start. Sources and assumptions:
# * commercial, median 1.5 h: a downtown length-of-stay survey of two-hour curb spaces
#   (City of Charlottesville parking study, weblink.charlottesville.org doc 791732: most
#   stays about 1 h or less, 20 % about 2 h, 15 % 3 h or more, 5 % 4 h or more, mean 1.6 h).
#   This lognormal's mean is 2.1 h and 19 % of its stays pass 3 h, a heavier tail than
#   that survey's (noted, not refitted: fitting it would change every rendering);
# * residential, median 14 h: a resident's overnight stay, from about 18:00 to 08:00 (an
#   assumption from the working day, not a survey), log-sd 1.0 so that some cars stay days;
# * RESIDENT_CAR_SHARE and PARK_JITTER_M: assumptions (half the residential stays by the
#   household's own car; a car stops within +-0.4 m of a slot's centre along the curb).
PARKING_STAY_MEDIAN_H = {"commercial": 1.5, "residential": 14.0}
PARKING_STAY_LOG_SD = {"commercial": 0.8, "residential": 1.0}
PARKING_BLOCK_H = {"commercial": 24.0, "residential": 7 * 24.0}
RESIDENT_CAR_SHARE = 0.5  # residential stays by the resident's own car (same car, same slot)
PARK_JITTER_M = 0.4  # a car parks within this distance of the slot's centre, along the curb


def street_type(vegetation: float) -> str:
    """"commercial" (urban shops, ``vegetation < 0.5`` as in ``build_scene``) or "residential"."""
    return "commercial" if vegetation < 0.5 else "residential"


def parking_occupancy(vegetation: float) -> float:
    """Share of time a curb slot holds a car (denser in urban streets)."""
    return 0.35 + 0.3 * (1.0 - vegetation)


def parked_car(scene_seed: int, slot: int, vegetation: float, t_hours: float):
    """The car in a curb slot at an instant: ``(variant, offset_m)`` or None when empty.

    Args:
      scene_seed: the world's seed.
      slot: the slot id.
      vegetation: the street's vegetation (its type, ``street_type``).
      t_hours: the instant in hours on a continuous clock (e.g. UNIX seconds / 3600).

    Deterministic in its arguments; the same stay gives the same car at the same place at
    every instant it covers, so a parked car matches across the captures of its stay.
    """
    kind = street_type(vegetation)
    median, sd = PARKING_STAY_MEDIAN_H[kind], PARKING_STAY_LOG_SD[kind]
    block_h = PARKING_BLOCK_H[kind]
    occ = parking_occupancy(vegetation)
    mean_stay = median * float(np.exp(0.5 * sd * sd))
    mean_gap = mean_stay * (1.0 - occ) / occ
    block = int(np.floor(t_hours / block_h))
    r = _hash_rng(scene_seed, 24, slot, block)
    resident = int(_hash_rng(scene_seed, 25, slot).integers(0, N_CAR_VARIANTS))
    clock = block * block_h
    occupied = r.random() < occ
    # Stationary start: a stay in progress has a residual part of a stay left.
    remaining = (median * np.exp(sd * r.normal()) * r.random()) if occupied else (
        r.exponential(mean_gap))
    k = 0
    while True:
        if occupied and clock + remaining > t_hours:
            own = kind == "residential" and r.random() < RESIDENT_CAR_SHARE
            variant = resident if own else int(r.integers(0, N_CAR_VARIANTS))
            return variant, float(r.uniform(-PARK_JITTER_M, PARK_JITTER_M))
        if not occupied and clock + remaining > t_hours:
            return None
        # Draws a stay's car only when it is the one returned; skip its draws otherwise.
        if occupied:
            r.random(), r.integers(0, N_CAR_VARIANTS), r.uniform()
        clock += remaining
        occupied = not occupied
        remaining = median * np.exp(sd * r.normal()) if occupied else r.exponential(mean_gap)
        k += 1
        if k > 10_000:  # cannot happen with positive stays; guards against a bad config
            raise RuntimeError("parked_car: no end to the renewal process")


def _traffic_rate(hour: float) -> float:
    """Cars per second per lane at a local hour: quiet at night, busy in the day."""
    day = np.exp(-0.5 * ((hour - 8.5) / 1.5) ** 2) + np.exp(-0.5 * ((hour - 17.5) / 2.0) ** 2)
    return 0.01 + 0.04 * (6 < hour < 22) + 0.06 * day


@dataclasses.dataclass(frozen=True)
class PassingCar:
    """A car driving through the street at an instant: centre (x, y), ``direction`` (+1
    east, -1 west) and its model (``variant``)."""

    x: float
    y: float
    direction: float
    variant: int

    @property
    def length(self) -> float:
        return _CAR_SHAPES[self.variant % len(_CAR_SHAPES)][0]

    @property
    def width(self) -> float:
        return _CAR_SHAPES[self.variant % len(_CAR_SHAPES)][1]


def passing_cars(scene: Scene, when: dt.datetime) -> list[PassingCar]:
    """The cars driving through the street at ``when``: spawned per 60 s window at the
    hour's rate (``_traffic_rate``), each at its own constant speed, in both lanes."""
    hour = when.hour + when.minute / 60.0 + when.second / 3600.0
    t = when.timestamp()
    x_lo, x_hi = scene.x_range
    span = x_hi - x_lo
    win = 60.0
    k_now = int(np.floor(t / win))
    out = []
    for lane, direction in (("eastbound", 1.0), ("westbound", -1.0)):
        y = scene.lanes_y[lane]
        n_back = int(np.ceil(span / 7.0 / win)) + 1
        for k in range(k_now - n_back, k_now + 1):
            r = _hash_rng(scene.seed, 22, int(direction > 0), k)
            rate = _traffic_rate(((k * win - t) / 3600.0 + hour) % 24)
            for _ in range(int(r.poisson(rate * win))):
                t0, v, variant = (
                    k * win + r.random() * win,
                    r.uniform(7.0, 13.0),
                    int(r.integers(0, N_CAR_VARIANTS)),
                )
                if t < t0:
                    continue
                d = v * (t - t0)
                if d > span:
                    continue
                x = x_lo + d if direction > 0 else x_hi - d
                out.append(PassingCar(float(x), float(y), direction, variant))
    return out


# Where a car's dipped headlamps sit: at the front, this far in from its sides and this high
# above the road, within UN ECE Regulation 48's installation limits (the illuminating
# surface's outer edge at most 400 mm from the car's side, 500-1,200 mm above the road).
HEADLAMP_INSET_M = 0.25
HEADLAMP_HEIGHT_M = 0.65


# The camera's own car (RobotCar's Nissan LEAF: 4.45 m long, 1.77 m wide), centred on the
# vehicle frame's origin.
OWN_CAR_LENGTH_M, OWN_CAR_WIDTH_M = 4.45, 1.77


def car_headlamps(x: float, y: float, heading: float, length: float, width: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A car's two headlamps: ``(positions (2, 3), forward directions (2, 3))`` of a car
    centred at (x, y) heading ``heading`` (radians from +x, counter-clockwise)."""
    fwd = np.array([np.cos(heading), np.sin(heading), 0.0])
    left = np.array([-fwd[1], fwd[0], 0.0])
    front = np.array([x, y, HEADLAMP_HEIGHT_M]) + fwd * length / 2
    pos = np.stack([front + side * (width / 2 - HEADLAMP_INSET_M) * left for side in (1.0, -1.0)])
    return pos, np.stack([fwd, fwd])


def headlamps(cars: list[PassingCar]) -> tuple[np.ndarray, np.ndarray]:
    """Every car's two headlamps: ``(positions (2N, 3), forward directions (2N, 3))``."""
    lamps = [car_headlamps(c.x, c.y, 0.0 if c.direction > 0 else np.pi, c.length, c.width)
             for c in cars]
    if not lamps:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.concatenate([p for p, _ in lamps]), np.concatenate([f for _, f in lamps])


def dynamic_quads(scene: Scene, when: dt.datetime) -> tuple[QuadSet, list, list[int]]:
    """Parked cars (stays of the street's dwell times), passing cars and people (per instant).

    Args:
      scene: the world.
      when: tz-aware capture instant (local hours come from its own clock).

    Returns:
      (quads, boxes, alpha_idx): the quads, their shadow-casting boxes, and indices (into
      the returned quads) of people cut-outs casting textured shadows.
    """
    qb = QuadBuilder()
    tc = scene.textures
    boxes = []
    alpha = []
    cars: list[QuadSet] = []
    hour = when.hour + when.minute / 60.0 + when.second / 3600.0
    obj = 50_000
    # Parked cars: each slot alternates stays and gaps with the street's dwell times.
    t_hours = when.timestamp() / 3600.0
    for x, y, sgn, sid in scene.parking_slots:
        car = parked_car(scene.seed, int(sid), scene.vegetation, t_hours)
        if car is not None:
            variant, dx = car
            q, b = _car_instance(tc, x + dx, y, -sgn, variant, obj, moving=False)
            cars.append(q)
            boxes += list(b)
        obj += 1
    for car in passing_cars(scene, when):
        q, b = _car_instance(tc, car.x, car.y, car.direction, car.variant, obj, moving=True)
        cars.append(q)
        boxes += list(b)
        obj += 1
    # People walking along both sidewalks, spawned per 120 s window.
    t = when.timestamp()
    x_lo, x_hi = scene.x_range
    span = x_hi - x_lo
    pwin = 120.0
    k_now = int(np.floor(t / pwin))
    rate = 0.004 + 0.03 * (7 < hour < 21)
    for side, ys in enumerate(scene.sidewalk_y):
        n_back = int(np.ceil(span / 1.0 / pwin)) + 1
        for k in range(k_now - n_back, k_now + 1):
            r = _hash_rng(scene.seed, 23, side, k)
            for _ in range(int(r.poisson(rate * pwin))):
                t0, v = k * pwin + r.random() * pwin, r.uniform(1.0, 1.6) * r.choice([-1.0, 1.0])
                pid = int(r.integers(0, N_PEOPLE_VARIANTS))
                yoff = r.uniform(-0.35, 0.35) * scene.sidewalk_width
                if t < t0:
                    continue
                d = abs(v) * (t - t0)
                if d > span:
                    continue
                x = x_lo + d if v > 0 else x_hi - d
                key = f"person:{pid}"
                tc.register(key, ot.person_texture, dict(seed=9000 + pid))
                y = ys + yoff
                # Facing the street: the cut-out lies in the xz-plane, two-sided.
                alpha.append(len(qb.rows))
                qb.add(
                    (x - 0.35, y, 1.75),
                    (0.7, 0, 0),
                    (0, 0, -1.75),
                    key,
                    categories.OTHER,
                    Material.CUTOUT,
                    -1,
                    (x, y, 1.0),
                    obj,
                )
                obj += 1
    people = qb.build()
    # People first so that ``alpha`` indexes stay valid.
    return QuadSet.concat([people] + cars), boxes, alpha
