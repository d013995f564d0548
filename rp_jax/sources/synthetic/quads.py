"""The building blocks of the synthetic world: materials, textured quads, the lazy texture
cache, and the textures that the street (``scene``) and its slow changes over the years
(``slow_changes``) both make (trees, signs, plain objects).

A quad: ``origin`` (top-left corner of its texture), ``u`` (texture columns, to the right as
seen from the front) and ``v`` (texture rows, downwards); a point of texture coordinate
(a, b) in [0, 1]^2 lies at ``origin + a u + b v`` and the outward normal is ``unit(v x u)``
(the world frame: ``scene``'s docstring).
"""

from __future__ import annotations

import dataclasses
import enum
from collections import OrderedDict
from collections.abc import Callable

import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic import object_textures as ot
from rp_jax.sources.synthetic import textures as tx

__all__ = [
    "Material",
    "QuadBuilder",
    "QuadSet",
    "TextureCache",
    "TextureState",
    "box_quads",
    "plain_tex",
    "sign_tex",
    "tree_tex",
]


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


class QuadBuilder:
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
    qb: QuadBuilder,
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


def tree_tex(
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
        _memo[key] = ot.tree_structure(structure_seed, height, radius)
    return ot.tree_texture(_memo[key], foliage, autumn, snow)


def plain_tex(
    seed: int, colour, w: int = 16, h: int = 64, aux: int = 0, bands: int = 0, snow: int = 0
):
    del snow
    return ot.plain_texture(seed, colour, w, h, aux, bands)


def sign_tex(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rgb = tx.sign_texture(rng, 64, 64)
    import cv2  # local: only the sign border needs it

    cv2.rectangle(rgb, (1, 1), (62, 62), (0.95, 0.95, 0.95), 2)
    return tx.finish(rgb, np.zeros((64, 64), np.uint8), blur=0.5)
