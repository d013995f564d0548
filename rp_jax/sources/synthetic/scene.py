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

Every surface is a *quad*: ``origin`` (top-left corner of its texture), ``u`` (texture
columns, to the right as seen from the front) and ``v`` (texture rows, downwards). A point
of texture coordinate (a, b) in [0, 1]^2 lies at ``origin + a u + b v`` and the outward
normal is ``unit(v x u)``. Everything is deterministic from ``(seed, kwargs)``; parked cars
come and go with the street's dwell times (``parked_car``), passing cars and people per
capture instant.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import enum
from collections import OrderedDict
from collections.abc import Callable

import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic import textures as tx

__all__ = [
    "Material",
    "QuadSet",
    "Scene",
    "TextureState",
    "build_scene",
    "box_quads",
    "MARGIN_M",
    "dynamic_quads",
    "add_car",
]

MARGIN_M = 40.0  # world beyond each end of the street
GROUND_TILE_M = 10.0


class Material(enum.IntEnum):
    """How the renderer reads a quad's aux channel and lights it."""

    WALL = 0  # opaque, aux unused
    FACADE = 1  # aux: window id (glass), lit at night per window
    GROUND = 2  # aux: snow susceptibility; wet when it rains
    ROOF = 3  # aux: snow susceptibility
    FOLIAGE = 4  # aux: alpha; translucent lighting, two-sided
    CUTOUT = 5  # aux: alpha (people), two-sided
    LAMP = 6  # aux: emission, on at night
    CAR = 7  # aux: emission of head/tail lights (moving cars at dusk/night)


@dataclasses.dataclass(frozen=True)
class TextureState:
    """The per-capture state that changes textures: season and snow (from ``conditions``)."""

    season: int = 1  # grass colour: 0 winter, 1 spring/summer, 2 late summer, 3 autumn
    snow: int = 0  # 0..4
    snow_pattern: int = 0  # the snow pack's pattern id (``conditions.snow_state``), 0 without snow
    foliage: float = 1.0  # quantised leaf density
    autumn: float = 0.0  # quantised autumn colour


@dataclasses.dataclass
class QuadSet:
    """Structure-of-arrays of quads (N of them)."""

    origin: np.ndarray  # (N, 3)
    u: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3)
    tex: list  # N texture keys
    category: np.ndarray  # (N,) uint8
    material: np.ndarray  # (N,) int8
    receiver: np.ndarray  # (N,) int32 plane id receiving exact cast shadows, -1: object-level
    shadow_pt: np.ndarray  # (N, 3) point tested for object-level shadow
    owner: np.ndarray  # (N,) int32 building id (window lighting) or object id
    emit: np.ndarray  # (N,) float32 emission switch class: 0 none, 1 lamp, 2 moving-car light

    @property
    def n(self) -> int:
        return len(self.tex)

    @property
    def normal(self) -> np.ndarray:
        nrm = np.cross(self.v, self.u)
        return nrm / np.linalg.norm(nrm, axis=1, keepdims=True)

    @staticmethod
    def empty() -> QuadSet:
        z3 = np.zeros((0, 3))
        return QuadSet(
            z3,
            z3,
            z3,
            [],
            np.zeros(0, np.uint8),
            np.zeros(0, np.int8),
            np.zeros(0, np.int32),
            z3,
            np.zeros(0, np.int32),
            np.zeros(0, np.float32),
        )

    @staticmethod
    def concat(sets: list[QuadSet]) -> QuadSet:
        sets = [s for s in sets if s.n]
        if not sets:
            return QuadSet.empty()
        return QuadSet(
            *(
                np.concatenate([getattr(s, f) for s in sets])
                if f != "tex"
                else sum((s.tex for s in sets), [])
                for f in (
                    "origin",
                    "u",
                    "v",
                    "tex",
                    "category",
                    "material",
                    "receiver",
                    "shadow_pt",
                    "owner",
                    "emit",
                )
            )
        )


class _QuadBuilder:
    def __init__(self):
        self.rows = []

    def add(
        self, origin, u, v, tex, category, material, receiver=-1, shadow_pt=None, owner=-1, emit=0.0
    ):
        origin, u, v = (np.asarray(a, np.float64) for a in (origin, u, v))
        sp = origin + 0.5 * u + 0.5 * v if shadow_pt is None else np.asarray(shadow_pt, np.float64)
        self.rows.append((origin, u, v, tex, category, material, receiver, sp, owner, emit))

    def build(self) -> QuadSet:
        if not self.rows:
            return QuadSet.empty()
        cols = list(zip(*self.rows))
        return QuadSet(
            np.array(cols[0]),
            np.array(cols[1]),
            np.array(cols[2]),
            list(cols[3]),
            np.array(cols[4], np.uint8),
            np.array(cols[5], np.int8),
            np.array(cols[6], np.int32),
            np.array(cols[7]),
            np.array(cols[8], np.int32),
            np.array(cols[9], np.float32),
        )


_FACE_NORMAL = {
    "+x": np.array([1.0, 0, 0]),
    "-x": np.array([-1.0, 0, 0]),
    "+y": np.array([0, 1.0, 0]),
    "-y": np.array([0, -1.0, 0]),
    "+z": np.array([0, 0, 1.0]),
}


def box_quads(
    qb: _QuadBuilder,
    lo,
    hi,
    tex: dict,
    category: int,
    material: int = Material.WALL,
    receivers: dict | None = None,
    owner: int = -1,
    emit: dict | None = None,
    faces=("+x", "-x", "+y", "-y", "+z"),
) -> None:
    """Adds the outward faces of an axis-aligned box [lo, hi] (no bottom face).

    Args:
      qb: the builder.
      lo, hi: box corners.
      tex: texture key per face name (``"+x"``, ``"-x"``, ``"+y"``, ``"-y"``, ``"+z"``), or
        ``"*"`` for all.
      category: category id of every face.
      material: material of every face (``"+z"`` faces of buildings are given ROOF by callers).
      receivers: optional plane id per face (exact cast shadows).
      owner: building / object id.
      emit: optional emission class per face.
      faces: which faces to add.
    """
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    geo = {
        "+x": ((x1, y0, z1), (0, dy, 0), (0, 0, -dz)),
        "-x": ((x0, y1, z1), (0, -dy, 0), (0, 0, -dz)),
        "+y": ((x1, y1, z1), (-dx, 0, 0), (0, 0, -dz)),
        "-y": ((x0, y0, z1), (dx, 0, 0), (0, 0, -dz)),
        "+z": ((x0, y1, z1), (dx, 0, 0), (0, -dy, 0)),
    }
    receivers = receivers or {}
    emit = emit or {}
    for f in faces:
        o, u, v = geo[f]
        key = tex.get(f, tex.get("*"))
        mat = (
            material
            if not (
                f == "+z"
                and material in (Material.FACADE, Material.WALL)
                and category == categories.BUILDING
            )
            else Material.ROOF
        )
        o, u, v = (np.asarray(a, np.float64) for a in (o, u, v))
        sp = o + 0.5 * u + 0.5 * v + 0.05 * _FACE_NORMAL[f]  # just outside the face
        qb.add(o, u, v, key, category, mat, receivers.get(f, -1), sp, owner, emit.get(f, 0.0))


# ---------------------------------------------------------------- texture cache


class TextureCache:
    """Lazily generated textures with their mip pyramids, bounded by bytes (LRU)."""

    def __init__(self, max_bytes: int = 600 << 20):
        self.specs: dict[str, tuple[Callable, dict, tuple]] = {}
        self._cache: OrderedDict = OrderedDict()
        self._bytes = 0
        self.max_bytes = max_bytes
        # Car templates built from this cache's textures, keyed (variant, direction, moving);
        # they live and die with the cache (a global keyed by id() outlived it).
        self.car_templates: dict = {}

    def register(self, key: str, fn: Callable, kwargs: dict, depends: tuple = ()) -> None:
        """Declares texture ``key`` = ``fn(**kwargs, **state parts named in depends)``."""
        if key not in self.specs:
            self.specs[key] = (fn, kwargs, depends)

    def pyramid(self, key: str, state: TextureState) -> list[np.ndarray]:
        """Mip pyramid of texture ``key`` for a texture state (generated on first use)."""
        fn, kwargs, depends = self.specs[key]
        parts = tuple(getattr(state, d) for d in depends)
        ck = (key, parts)
        hit = self._cache.get(ck)
        if hit is not None:
            self._cache.move_to_end(ck)
            return hit
        tex = fn(**kwargs, **dict(zip(depends, parts)))
        pyr = tx.mip_pyramid(tex)
        nbytes = sum(p.nbytes for p in pyr)
        self._cache[ck] = pyr
        self._bytes += nbytes
        while self._bytes > self.max_bytes and len(self._cache) > 1:
            _, old = self._cache.popitem(last=False)
            self._bytes -= sum(p.nbytes for p in old)
        return pyr


def _tree_tex(
    structure_seed: int,
    height: float,
    radius: float,
    foliage: float,
    autumn: float,
    snow: int,
    _memo: dict = {},  # noqa: B006 - a deliberate process-wide memo
) -> np.ndarray:
    key = (structure_seed, height, radius)
    if key not in _memo:
        _memo[key] = tx.tree_structure(structure_seed, height, radius)
    return tx.tree_texture(_memo[key], foliage, autumn, snow)


def _plain(
    seed: int, colour, w: int = 16, h: int = 64, aux: int = 0, bands: int = 0, snow: int = 0
):
    del snow
    return tx.plain_texture(seed, colour, w, h, aux, bands)


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
        _memo[key] = tx.car_textures(seed, length, width, body_h, cabin_h)
        if len(_memo) > 64:
            _memo.popitem(last=False)
    return _memo[key][face]


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
    qb: _QuadBuilder,
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
        _tree_tex,
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
      **kwargs: reserved; unknown keys raise.

    Returns:
      The ``Scene``.
    """
    if kind != "street":
        raise ValueError(f"build_scene: unknown kind {kind!r}; expected 'street'")
    if kwargs:
        raise TypeError(f"build_scene: unexpected arguments {sorted(kwargs)}")
    rng = np.random.default_rng([seed, 1])
    veg = float(np.clip(vegetation, 0.0, 1.0))
    tc = TextureCache()
    qb = _QuadBuilder()
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
                    tx.ground_texture,
                    dict(
                        seed=int(seed * 7919 + i),
                        kind="road",
                        length_m=GROUND_TILE_M,
                        width_m=yb - ya,
                        lanes=lanes + 2,
                        crosswalk=i == crosswalk_tile,
                        texel=texel,
                    ),
                    depends=("season", "snow", "snow_pattern"),
                )
            else:
                gkind = (
                    "sidewalk"
                    if name.startswith("sidewalk")
                    else ("grass" if veg >= 0.3 else "sidewalk")
                )
                tc.register(
                    key,
                    tx.ground_texture,
                    dict(
                        seed=int(seed * 7919 + i * 13 + len(name)),
                        kind=gkind,
                        length_m=GROUND_TILE_M,
                        width_m=yb - ya,
                        texel=texel,
                    ),
                    depends=("season", "snow", "snow_pattern"),
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
    tc.register("pole", _plain, dict(seed=3, colour=(0.22, 0.24, 0.23), w=16, h=256, bands=2))
    tc.register("lamp_head", _plain, dict(seed=4, colour=(0.85, 0.82, 0.7), w=32, h=16, aux=255))
    tc.register("bin", _plain, dict(seed=5, colour=(0.12, 0.25, 0.15), w=32, h=48, bands=3))
    tc.register("hydrant", _plain, dict(seed=6, colour=(0.75, 0.15, 0.1), w=16, h=32, bands=1))
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
            tc.register(key, _sign_tex, dict(seed=int(seed * 31 + k)))
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
    )


def _sign_tex(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rgb = tx.sign_texture(rng, 64, 64)
    import cv2  # local: only the sign border needs it

    cv2.rectangle(rgb, (1, 1), (62, 62), (0.95, 0.95, 0.95), 2)
    return tx._finish(rgb, np.zeros((64, 64), np.uint8), blur=0.5)


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
    qb: _QuadBuilder,
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
        qb = _QuadBuilder()
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


def dynamic_quads(scene: Scene, when: dt.datetime) -> tuple[QuadSet, list, list[int]]:
    """Parked cars (stays of the street's dwell times), passing cars and people (per instant).

    Args:
      scene: the world.
      when: tz-aware capture instant (local hours come from its own clock).

    Returns:
      (quads, boxes, alpha_idx): the quads, their shadow-casting boxes, and indices (into
      the returned quads) of people cut-outs casting textured shadows.
    """
    qb = _QuadBuilder()
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
    # Passing cars: spawned per 60 s window, moving at constant speed through the street.
    t = when.timestamp()
    x_lo, x_hi = scene.x_range
    span = x_hi - x_lo
    win = 60.0
    k_now = int(np.floor(t / win))
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
                q, b = _car_instance(tc, x, y, direction, variant, obj, moving=True)
                cars.append(q)
                boxes += list(b)
                obj += 1
    # People walking along both sidewalks, spawned per 120 s window.
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
                tc.register(key, tx.person_texture, dict(seed=9000 + pid))
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
