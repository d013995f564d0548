"""The synthetic world: a deterministic 3D street of textured planar quads (Sec. IV-A stand-in).

The paper learns repeatability from fixed viewpoints observed over a daily cycle (Webcam
Clip Art) or a yearly one (Extended CMU Seasons, Oxford RobotCar). Their images cannot be
downloaded here, so the project renders a street world with the same ingredients: building
facades (windows, doors, signs), road, sidewalks, grass, trees, street furniture, parked
and passing cars, pedestrians, sky. This module builds that world's geometry; ``render``
draws it under the real sun and weather of a capture instant.

World frame (metres): **x east along the street, y north across it, z up.** The street's
centreline is the x axis; the street runs from ``x = 0`` to ``x = length_m`` and the world
extends ``MARGIN_M`` beyond both ends (with a closing building across the street there).
Right-hand traffic: the eastbound lane is at ``y < 0``, westbound at ``y > 0``.

Every surface is a textured *quad* (``quads``: materials, quads, the texture cache).
Everything is deterministic from ``(seed, kwargs)``. What moves (parked
cars with the street's dwell times, passing cars, people) is placed per capture instant by
``rp_jax.sources.synthetic.traffic``.

Why ``build_scene`` is one 380-line recipe: its random draws, in their order, *are* the world
(every facade, tree and slot of a seed). Cutting it into helpers that draw from the same
generator would be easy to get subtly wrong and would move every rendered pixel of every
dataset; it stays whole, and the geometry types it builds live in ``quads``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic import ground_textures as gt
from rp_jax.sources.synthetic import slow_changes as slow_changes_lib
from rp_jax.sources.synthetic import textures as tx
from rp_jax.sources.synthetic.conditions import CLIMATES
from rp_jax.sources.synthetic.quads import (
    Material,
    QuadBuilder,
    QuadSet,
    TextureCache,
    box_quads,
    plain_tex,
    sign_tex,
    tree_tex,
)
from rp_jax.sources.synthetic.slow_changes import SlowChanges, SlowWorld

__all__ = ["MARGIN_M", "Scene", "build_scene"]

MARGIN_M = 40.0  # world beyond each end of the street
GROUND_TILE_M = 10.0


# ---------------------------------------------------------------- the scene


@dataclasses.dataclass
class Scene:
    """A deterministic synthetic street.

    Attributes:
      seed, kind, length_m, latitude, longitude, vegetation: as given to ``build_scene``.
      road_half_width: metres from the centreline to each curb.
      sidewalk_width: metres.
      lanes_y: y of each lane's centre: ``eastbound``, ``westbound`` (travel) and
        ``parking_south``, ``parking_north``.
      sidewalk_y: y of the middle of the south and north sidewalks.
      facade_y: (south, north) y of the nearest building front on each side (signed).
      x_range: (x_min, x_max) extent of the world along the street.
      static: the static quads.
      buildings: (B, 2, 3) box corners (lo, hi) of every building (shadow casters).
      furniture_boxes: (F, 2, 3) boxes of poles, bins... (shadow casters).
      alpha_casters: indices into ``static`` of cut-out quads casting textured shadows.
      lamps: (L, 3) positions of street-lamp heads.
      parking_slots: (S, 4) rows (x, y, direction, slot id).
      textures: the lazily generated texture cache.
      slow_changes: the world's slow changes over the years (``slow_changes.SlowWorld``),
        None (the default) for a world that stays as built.
      climate: as given to ``build_scene`` (``conditions.CLIMATES``).
    """

    seed: int
    kind: str
    length_m: float
    latitude: float
    longitude: float
    vegetation: float
    road_half_width: float
    sidewalk_width: float
    lanes_y: dict
    sidewalk_y: tuple
    facade_y: tuple
    x_range: tuple
    static: QuadSet
    buildings: np.ndarray
    furniture_boxes: np.ndarray
    alpha_casters: np.ndarray
    lamps: np.ndarray
    parking_slots: np.ndarray
    textures: TextureCache
    n_planes: int
    slow_changes: SlowWorld | None = None
    climate: str = "latitude"

    @property
    def drivable_y(self) -> dict:
        """Lane centres a preset can place a vehicle camera in (alias of ``lanes_y``)."""
        return self.lanes_y

    def street_axis(self) -> tuple[np.ndarray, np.ndarray]:
        """(origin, unit direction) of the street centreline: ((0, 0, 0), (1, 0, 0))."""
        return np.zeros(3), np.array([1.0, 0.0, 0.0])

    def centerline(self, n: int = 2) -> np.ndarray:
        """(n, 3) points along the centreline from x=0 to x=length_m."""
        return np.stack([np.linspace(0, self.length_m, n), np.zeros(n), np.zeros(n)], -1)


def _add_tree(
    qb: QuadBuilder,
    tc: TextureCache,
    x: float,
    y: float,
    height: float,
    radius: float,
    tseed: int,
    owner: int,
) -> list[int]:
    key = f"tree:{tseed}:{height:.2f}:{radius:.2f}"
    tc.register(
        key,
        tree_tex,
        dict(structure_seed=tseed, height=height, radius=radius),
        depends=("foliage", "autumn", "snow"),
    )
    w = 2 * radius + 0.4
    centre = np.array([x, y, height * 0.6])
    start = len(qb.rows)
    qb.add(
        (x - w / 2, y, height),
        (w, 0, 0),
        (0, 0, -height),
        key,
        categories.VEGETATION,
        Material.FOLIAGE,
        -1,
        centre,
        owner,
    )
    qb.add(
        (x, y - w / 2, height),
        (0, w, 0),
        (0, 0, -height),
        key,
        categories.VEGETATION,
        Material.FOLIAGE,
        -1,
        centre,
        owner,
    )
    return [start, start + 1]


def build_scene(
    seed: int,
    *,
    kind: str = "street",
    length_m: float = 60.0,
    latitude: float = 40.44,
    longitude: float = -79.99,
    vegetation: float = 0.5,
    lanes: int = 2,
    building_height: tuple[float, float] | None = None,
    slow_changes: SlowChanges | None = None,
    climate: str = "latitude",
    **kwargs,
) -> Scene:
    """Builds a deterministic synthetic street.

    Args:
      seed: the world's seed; the same (seed, kwargs) gives the same world.
      kind: only ``"street"`` (a straight street along +x) for now.
      length_m: street length; the world extends ``MARGIN_M`` beyond both ends.
      latitude, longitude: degrees; set the sun and the seasons.
      vegetation: 0 urban (shops, narrow sidewalks, few trees) .. 1 suburban/park-like
        (houses with front lawns, many trees).
      lanes: travel lanes (2 or 4).
      building_height: optional (min, max) metres overriding the style's heights.
      slow_changes: optional ``slow_changes.SlowChanges``: the world built is the world on
        its reference date, and new tenants, repaints, new signs and growing and replanted
        trees change it after (from streams of their own: the world built is the same).
      climate: its temperatures, snow and whether rain freezes (``conditions.CLIMATES``:
        "latitude", as the presets' worlds were first rendered, or "local", the place's
        own climate normals where ``conditions.CLIMATE_NORMALS`` has them).
      **kwargs: reserved; unknown keys raise.

    Returns:
      The ``Scene``.
    """
    if kind != "street":
        raise ValueError(f"build_scene: unknown kind {kind!r}; expected 'street'")
    if kwargs:
        raise TypeError(f"build_scene: unexpected arguments {sorted(kwargs)}")
    if climate not in CLIMATES:
        raise ValueError(f"build_scene: climate must be one of {CLIMATES}, got {climate!r}")
    rng = np.random.default_rng([seed, 1])
    veg = float(np.clip(vegetation, 0.0, 1.0))
    tc = TextureCache()
    qb = QuadBuilder()
    lane_w, park_w = 3.4, 2.4
    road_half = lanes / 2 * lane_w + park_w
    sidewalk = rng.uniform(2.5, 4.0) if veg < 0.6 else rng.uniform(1.8, 2.6)
    yard = veg * rng.uniform(4.0, 9.0)
    x_lo, x_hi = -MARGIN_M, length_m + MARGIN_M
    outer = road_half + sidewalk + yard + 30.0
    plane = [1]  # plane 0 is the ground

    def new_plane() -> int:
        plane[0] += 1
        return plane[0] - 1

    # Ground: tiles of road, two sidewalks, two yard strips, each GROUND_TILE_M long.
    n_tiles = int(np.ceil((x_hi - x_lo) / GROUND_TILE_M))
    strips = [
        ("road", -road_half, road_half, tx.TEXEL_M),
        ("sidewalk_s", -road_half - sidewalk, -road_half, tx.TEXEL_M),
        ("sidewalk_n", road_half, road_half + sidewalk, tx.TEXEL_M),
        ("yard_s", -outer, -road_half - sidewalk, 0.05),
        ("yard_n", road_half + sidewalk, outer, 0.05),
    ]
    crosswalk_tile = int(rng.integers(0, n_tiles)) if rng.random() < 0.5 else -1
    for i in range(n_tiles):
        x0 = x_lo + i * GROUND_TILE_M
        for name, ya, yb, texel in strips:
            key = f"ground:{name}:{i}"
            if name == "road":
                tc.register(
                    key,
                    gt.ground_texture,
                    dict(
                        seed=int(seed * 7919 + i),
                        kind="road",
                        length_m=GROUND_TILE_M,
                        width_m=yb - ya,
                        lanes=lanes + 2,
                        crosswalk=i == crosswalk_tile,
                        texel=texel,
                    ),
                    # Only a lawn's colour follows the season: a road or sidewalk tile is
                    # the same texture all year, so it is not drawn again at each season.
                    depends=("snow", "snow_pattern"),
                )
            else:
                gkind = (
                    "sidewalk"
                    if name.startswith("sidewalk")
                    else ("grass" if veg >= 0.3 else "sidewalk")
                )
                tc.register(
                    key,
                    gt.ground_texture,
                    dict(
                        seed=int(seed * 7919 + i * 13 + len(name)),
                        kind=gkind,
                        length_m=GROUND_TILE_M,
                        width_m=yb - ya,
                        texel=texel,
                    ),
                    depends=(("season", "snow", "snow_pattern") if gkind == "grass"
                             else ("snow", "snow_pattern")),
                )
            if name == "sidewalk_s":  # curb (texture top rows) must face the road (north)
                qb.add(
                    (x0, yb, 0),
                    (GROUND_TILE_M, 0, 0),
                    (0, -(yb - ya), 0),
                    key,
                    categories.GROUND,
                    Material.GROUND,
                    0,
                )
            elif name == "sidewalk_n":  # flip so that the curb rows lie at the road side (south)
                qb.add(
                    (x0 + GROUND_TILE_M, ya, 0),
                    (-GROUND_TILE_M, 0, 0),
                    (0, yb - ya, 0),
                    key,
                    categories.GROUND,
                    Material.GROUND,
                    0,
                )
            else:
                qb.add(
                    (x0, yb, 0),
                    (GROUND_TILE_M, 0, 0),
                    (0, -(yb - ya), 0),
                    key,
                    categories.GROUND,
                    Material.GROUND,
                    0,
                )

    # Buildings on both sides, fronts facing the street.
    buildings = []
    urban = veg < 0.5
    styles = (
        ["brick", "plaster", "concrete", "brick"]
        if urban
        else ["siding", "brick", "plaster", "siding"]
    )
    bid = 0
    facade_min = [np.inf, np.inf]
    for side, sgn in ((0, -1.0), (1, 1.0)):
        x = x_lo + rng.uniform(-5, 0)
        while x < x_hi:
            if urban:
                w = rng.uniform(7, 18)
                floors = int(rng.integers(2, 7))
                floor_h = rng.uniform(3.0, 3.6)
                gap = rng.uniform(0, 1.5) if rng.random() < 0.3 else 0.0
                setback = (
                    road_half
                    + sidewalk
                    + yard
                    + (rng.uniform(0, 1.5) if rng.random() < 0.3 else 0.0)
                )
            else:
                w = rng.uniform(8, 13)
                floors = int(rng.integers(1, 3))
                floor_h = rng.uniform(2.8, 3.2)
                gap = rng.uniform(3, 8)
                setback = road_half + sidewalk + yard + rng.uniform(0, 3)
            h = floors * floor_h + rng.uniform(0.3, 1.2)
            if building_height is not None:
                h = rng.uniform(*building_height)
                floors = max(1, int(h / floor_h))
            depth = rng.uniform(10, 18)
            style = str(rng.choice(styles))
            bseed = int(rng.integers(1 << 30))
            x0, x1 = x, x + w
            if sgn > 0:
                lo, hi = (x0, setback, 0.0), (x1, setback + depth, h)
                front = "-y"
            else:
                lo, hi = (x0, -setback - depth, 0.0), (x1, -setback, h)
                front = "+y"
            facade_min[side] = min(facade_min[side], setback)
            fkey, skey, rkey = f"facade:{bid}", f"side:{bid}", f"roof:{bid}"
            tc.register(
                fkey,
                tx.facade_texture,
                dict(
                    seed=bseed,
                    width_m=w,
                    height_m=h,
                    floor_h=floor_h,
                    style=style,
                    shopfront=urban and rng.random() < 0.7,
                ),
                depends=("snow", "snow_pattern"),
            )
            tc.register(
                skey,
                tx.side_wall_texture,
                dict(seed=bseed + 1, width_m=depth, height_m=h, style=style),
            )
            tc.register(
                rkey,
                tx.roof_texture,
                dict(seed=bseed + 2, width_m=w, depth_m=depth),
                depends=("snow", "snow_pattern"),
            )
            tex = {front: fkey, "+x": skey, "-x": skey, "+z": rkey}
            faces = (front, "+x", "-x", "+z")
            box_quads(
                qb,
                lo,
                hi,
                tex,
                categories.BUILDING,
                Material.WALL,
                receivers={front: new_plane(), "+x": new_plane(), "-x": new_plane()},
                owner=bid,
                faces=faces,
            )
            # the front is a FACADE
            qb.rows[-4] = qb.rows[-4][:5] + (Material.FACADE,) + qb.rows[-4][6:]
            buildings.append((lo, hi))
            bid += 1
            x = x1 + gap
    # Buildings closing both ends of the street, facing along it.
    for xe, front in ((x_lo - 12.0, "+x"), (x_hi, "-x")):
        lo, hi = (xe, -outer, 0.0), (xe + 12.0, outer, rng.uniform(9, 18))
        fkey = f"facade:{bid}"
        tc.register(
            fkey,
            tx.facade_texture,
            dict(
                seed=int(rng.integers(1 << 30)),
                width_m=2 * outer,
                height_m=hi[2],
                floor_h=3.3,
                style="brick",
                shopfront=False,
                texel=0.05,
            ),
            depends=("snow", "snow_pattern"),
        )
        box_quads(
            qb,
            lo,
            hi,
            {front: fkey},
            categories.BUILDING,
            Material.WALL,
            receivers={front: new_plane()},
            owner=bid,
            faces=(front,),
        )
        qb.rows[-1] = qb.rows[-1][:5] + (Material.FACADE,) + qb.rows[-1][6:]
        buildings.append((lo, hi))
        bid += 1

    # Trees along the curb and in front yards.
    alpha = []
    obj = 10_000
    tree_step = 18.0 - 10.0 * veg
    for sgn in (-1.0, 1.0):
        x = x_lo + rng.uniform(0, tree_step)
        while x < x_hi:
            if rng.random() < 0.35 + 0.6 * veg:
                y = sgn * (road_half + min(1.0, sidewalk * 0.35))
                hgt, rad = rng.uniform(5, 10), rng.uniform(1.6, 3.2)
                alpha += _add_tree(qb, tc, x, y, hgt, rad, int(rng.integers(1 << 30)), obj)
                obj += 1
            if yard > 2.5 and rng.random() < veg * 0.6:
                y = sgn * (road_half + sidewalk + rng.uniform(1.5, yard - 0.5))
                hgt, rad = rng.uniform(4, 11), rng.uniform(1.5, 3.5)
                alpha += _add_tree(
                    qb, tc, x + rng.uniform(-3, 3), y, hgt, rad, int(rng.integers(1 << 30)), obj
                )
                obj += 1
            x += tree_step * rng.uniform(0.7, 1.3)

    # Street furniture: lamps, sign posts, bins, hydrants.
    furniture = []
    lamps = []
    tc.register("pole", plain_tex, dict(seed=3, colour=(0.22, 0.24, 0.23), w=16, h=256, bands=2))
    tc.register("lamp_head", plain_tex, dict(seed=4, colour=(0.85, 0.82, 0.7), w=32, h=16, aux=255))
    tc.register("bin", plain_tex, dict(seed=5, colour=(0.12, 0.25, 0.15), w=32, h=48, bands=3))
    tc.register("hydrant", plain_tex, dict(seed=6, colour=(0.75, 0.15, 0.1), w=16, h=32, bands=1))
    lamp_step = rng.uniform(22, 32)
    for k, x in enumerate(np.arange(x_lo + rng.uniform(0, lamp_step), x_hi, lamp_step)):
        sgn = -1.0 if k % 2 == 0 else 1.0
        y = sgn * (road_half + 0.5)
        lo, hi = (x - 0.08, y - 0.08, 0.0), (x + 0.08, y + 0.08, 6.5)
        box_quads(qb, lo, hi, {"*": "pole"}, categories.OTHER, owner=obj)
        furniture.append((lo, hi))
        hy = y - sgn * 1.2
        hlo, hhi = (x - 0.3, min(y, hy) - 0.15, 6.3), (x + 0.3, max(y, hy) + 0.15, 6.55)
        box_quads(
            qb,
            hlo,
            hhi,
            {"*": "lamp_head"},
            categories.OTHER,
            Material.LAMP,
            owner=obj,
            emit={f: 1.0 for f in ("+x", "-x", "+y", "-y")},
        )
        furniture.append((hlo, hhi))
        lamps.append((x, hy, 6.25))
        obj += 1
    for k in range(int((x_hi - x_lo) / 9)):
        x = x_lo + rng.uniform(0, x_hi - x_lo)
        sgn = float(rng.choice([-1.0, 1.0]))
        y = sgn * (road_half + rng.uniform(0.4, 0.9))
        r = rng.random()
        if r < 0.35:  # sign post with a two-sided sign
            lo, hi = (x - 0.04, y - 0.04, 0.0), (x + 0.04, y + 0.04, 2.8)
            box_quads(qb, lo, hi, {"*": "pole"}, categories.OTHER, owner=obj)
            furniture.append((lo, hi))
            key = f"sign:{seed}:{k}"
            tc.register(key, sign_tex, dict(seed=int(seed * 31 + k)))
            sw, sh = rng.uniform(0.45, 0.8), rng.uniform(0.45, 0.8)
            face = -sgn  # facing the road
            if face > 0:
                qb.add(
                    (x - sw / 2, y + 0.05, 2.8),
                    (sw, 0, 0),
                    (0, 0, -sh),
                    key,
                    categories.OTHER,
                    Material.WALL,
                    -1,
                    None,
                    obj,
                )
            else:
                qb.add(
                    (x + sw / 2, y - 0.05, 2.8),
                    (-sw, 0, 0),
                    (0, 0, -sh),
                    key,
                    categories.OTHER,
                    Material.WALL,
                    -1,
                    None,
                    obj,
                )
        elif r < 0.7:
            lo, hi = (x - 0.3, y - 0.3, 0.0), (x + 0.3, y + 0.3, 1.0)
            box_quads(qb, lo, hi, {"*": "bin"}, categories.OTHER, owner=obj)
            furniture.append((lo, hi))
        else:
            lo, hi = (x - 0.12, y - 0.12, 0.0), (x + 0.12, y + 0.12, 0.7)
            box_quads(qb, lo, hi, {"*": "hydrant"}, categories.OTHER, owner=obj)
            furniture.append((lo, hi))
        obj += 1

    # Parking slots along both curbs.
    slots = []
    park_y = road_half - park_w / 2
    sid = 0
    for sgn in (-1.0, 1.0):
        for x in np.arange(x_lo + 3, x_hi - 3, 6.0):
            slots.append((x + rng.uniform(-0.4, 0.4), sgn * park_y, sgn, sid))
            sid += 1

    static = qb.build()
    slow_world = None
    if slow_changes is not None:

        slow_world = slow_changes_lib.index_world(seed, static, tc, slow_changes)
    return Scene(
        seed=seed,
        kind=kind,
        length_m=float(length_m),
        latitude=float(latitude),
        longitude=float(longitude),
        vegetation=veg,
        road_half_width=road_half,
        sidewalk_width=sidewalk,
        lanes_y={
            "eastbound": -lane_w / 2 * (lanes // 2),
            "westbound": lane_w / 2 * (lanes // 2),
            "parking_south": -park_y,
            "parking_north": park_y,
        },
        sidewalk_y=(-(road_half + sidewalk / 2), road_half + sidewalk / 2),
        facade_y=(-facade_min[0], facade_min[1]),
        x_range=(x_lo, x_hi),
        static=static,
        buildings=np.array(buildings, np.float64).reshape(-1, 2, 3),
        furniture_boxes=np.array(furniture, np.float64).reshape(-1, 2, 3),
        alpha_casters=np.array(alpha, np.int64),
        lamps=np.array(lamps, np.float64).reshape(-1, 3),
        parking_slots=np.array(slots, np.float64).reshape(-1, 4),
        textures=tc,
        n_planes=plane[0],
        slow_changes=slow_world,
        climate=climate,
    )
