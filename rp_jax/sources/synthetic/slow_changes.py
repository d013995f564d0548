"""Slow changes of the synthetic world over the years: a long-term decay to learn (issue 17).

Beyond the paper: its Sec. VI leaves the long-term decay of repeatability to future work.
The world ``scene.build_scene`` draws is the same in every year but for weather, season,
light and traffic; a real street is not. Here, when a world asks for it
(``build_scene(..., slow_changes=SlowChanges("2012-01-01"))``; off by default), the world
rendered on a date is the world as built, aged from a reference date by these processes,
each at a published rate (sources beside the constants below):

========================  ==================  ===========================  =================
change                    element             model                        rate
========================  ==================  ===========================  =================
a new tenant: new shop    a facade with a     Poisson                      ln 2 / 10.7 years
windows, door and sign    shop front                                       (median stay)
repaint: walls (not bare  every facade        every 10 years, the first    1 / 10 years
brick) and trims                              at a uniform phase
traffic sign replaced     every sign post     every 15 years, ditto        1 / 15 years
tree dies, replanted at   every tree          Poisson                      3.5 % a year
3.0 m
tree grows (crown too),   every tree          0.33 m a year, linear        --
capped at 15 m
========================  ==================  ===========================  =================

Deterministic and apart: an element's events come from a random stream of its own,
``(world seed, STREAM, kind, element)``; what an event puts up (the new tenant's shop front,
the new paint, the new sign, the new tree) from the element's seed and the event's number.
The recipe's generator is never read, so the world built, and every world without slow
changes, is exactly what it was. Ages count from the reference date, by the local date of
the capture (a whole day is one state); on and before the reference date the world is as
built.

What changes is what the renderer draws (``SlowWorld.static_at``): the texture of a
facade, a sign or a tree, and a tree's size. Buildings, lamps, furniture and parking stay.
Not modelled (no rate found that fits this world): posters and graffiti (weeks, not
years), construction sites and whole new buildings.
"""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np

from rp_jax.sources.synthetic.quads import Material, QuadSet, TextureCache, sign_tex, tree_tex

__all__ = [
    "DAYS_PER_YEAR",
    "KINDS",
    "PLANTING_HEIGHT_M",
    "REPAINT_INTERVAL_YEARS",
    "SIGN_SERVICE_LIFE_YEARS",
    "SlowChanges",
    "SlowWorld",
    "TENANT_MEDIAN_STAY_YEARS",
    "TREE_GROWTH_M_PER_YEAR",
    "TREE_MAX_HEIGHT_M",
    "TREE_MORTALITY_PER_YEAR",
    "index_world",
    "years_since",
]

# ----------------------------------------------------------------------------- the rates

# Shop tenants. Xymax Real Estate Institute (2016), "How long will the tenants stay in the
# shopping center?", Kaplan-Meier over Japanese shopping centres: tenants stay 10.7 years
# until half have left (https://www.xymax.co.jp/english/research/release/160323.html).
# As a Poisson process (memoryless), half gone at 10.7 years is a rate of ln 2 / 10.7 =
# 6.5 % a year. The US BLS figures for new establishments are higher (annual survival
# 81-83 %, Knaup 2005, Monthly Labor Review; https://www.bls.gov/bdm/entrepreneurship/
# entrepreneurship.htm): a street's shops are not all new, so the slower rate is kept.
TENANT_MEDIAN_STAY_YEARS = 10.7
# Exterior repaint. "Most experts recommend repainting every 5-10 years" (e.g.
# https://bayareapaintersinc.com/post/how-often-should-you-repaint-the-exterior-of-your-house,
# https://www.wsindustries.com/blog/residential-painting-how-often-should-you-repaint-your-homes-exterior:
# stucco 5-10, painted brick 10-15); the long end of the range, as a fixed interval.
REPAINT_INTERVAL_YEARS = 10.0
# Traffic signs. In-service signs in Iowa were "predicted to have lives of at least 10
# years", about 5 years past their sheeting warranties (Sign life expectancy on low-volume
# roads in Iowa; https://discovery.researcher.life/article/sign-life-expectancy-on-low-
# volume-roads-in-iowa/b52ae9d5c6d732b78a0fdc593d742f31); FHWA's "expected sign life"
# method replaces a sign at that age (https://highways.dot.gov/safety/other/visibility/
# methods-maintaining-traffic-sign-retroreflectivity/chapter-4-management). 15 years:
# the at-least-10 plus the 5, on the slow side.
SIGN_SERVICE_LIFE_YEARS = 15.0
# Street-tree mortality. Roman and Scatena (2011), meta-analysis of 16 studies: street-tree
# annual survival 94.9-96.5 % (http://actrees.org/news/trees-in-the-news/research/
# street-tree-survival-rates-based-on-published-research-and-philadelphia-field-survey/);
# the low end of mortality. A dead tree is replaced at once (in the city the gap varies).
TREE_MORTALITY_PER_YEAR = 0.035
# Tree growth. Height gain per year: slow <= 12 in, medium 13-24 in, fast >= 25 in
# (https://biologyinsights.com/tree-growth-rates-how-fast-do-trees-grow-per-year); the
# slow end of medium, 13 in = 0.33 m, linear. The crown grows in proportion.
TREE_GROWTH_M_PER_YEAR = 0.33
# ... up to a medium tree's mature height: Arbor Day Foundation, medium trees 30-70 ft
# (http://arborday.org/trees/righttreeandplace/size.cfm); 15 m (49 ft), a tree already
# taller stays as it is.
TREE_MAX_HEIGHT_M = 15.0
# A replacement is planted as nursery stock: a 2-inch-caliper tree is at least 10 ft
# (3.0 m) tall (ANSI Z60.1's table, as quoted at
# https://morethingsjapanese.com/what-does-4-caliper-tree-mean/), with the crown-to-height
# ratio of the tree it replaces.
PLANTING_HEIGHT_M = 3.0
DAYS_PER_YEAR = 365.25

KINDS = ("tenant", "repaint", "sign", "tree_replacement", "tree_growth")
# Each kind's stream id, and the root of all of them (unused by any other stream of the world).
_KIND_CODE = {"tenant": 1, "repaint": 2, "sign": 3, "tree_replacement": 4}
STREAM = 1729
# Events are drawn once, this far ahead of the reference date.
HORIZON_YEARS = 200.0


@dataclasses.dataclass(frozen=True)
class SlowChanges:
    """A world's request for slow changes (hashable, so a ``SceneSpec`` can carry it).

    Attributes:
      reference_date: ISO date ``YYYY-MM-DD``; the world ``build_scene`` draws is the world
        on this date, and ages count from it.
      kinds: which of ``KINDS`` change (all by default).
    """

    reference_date: str
    kinds: tuple[str, ...] = KINDS

    def __post_init__(self):
        dt.date.fromisoformat(self.reference_date)  # ValueError on a bad date
        object.__setattr__(self, "kinds", tuple(self.kinds))
        unknown = sorted(set(self.kinds) - set(KINDS))
        if unknown:
            raise ValueError(f"SlowChanges: unknown kinds {unknown}; known: {', '.join(KINDS)}")

    @property
    def reference(self) -> dt.date:
        return dt.date.fromisoformat(self.reference_date)


def years_since(reference: dt.date, when: dt.date | dt.datetime) -> float:
    """The world's age in years (of ``DAYS_PER_YEAR``) on the local date of ``when``;
    0 on and before ``reference``."""
    day = when.date() if isinstance(when, dt.datetime) else when
    return max(0.0, (day - reference).days / DAYS_PER_YEAR)


def _stream(seed: int, kind: str, element: int, *more: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(
        [int(seed) & 0xFFFFFFFF, STREAM, _KIND_CODE[kind], int(element), *[int(m) for m in more]]
    )


def _event_times(seed: int, kind: str, element: int, mean_years: float, periodic: bool):
    """Ages (years after the reference date) of an element's events up to ``HORIZON_YEARS``.

    Poisson: exponential gaps of mean ``mean_years``. Periodic: every ``mean_years``, the
    first at a uniform phase (the last one fell uniformly within the interval before).
    """
    rng = np.random.default_rng(_stream(seed, kind, element))
    if periodic:
        return np.arange(rng.uniform(0.0, mean_years), HORIZON_YEARS, mean_years)
    times, t = [], 0.0
    while True:
        t += rng.exponential(mean_years)
        if t > HORIZON_YEARS:
            return np.array(times)
        times.append(t)


def _count(times: np.ndarray, age: float) -> int:
    """Events at or before ``age`` (the state's number: 0 = as built)."""
    return int(np.searchsorted(times, age, side="right"))


def _seed_of(seed: int, kind: str, element: int, n: int) -> int:
    """The seed of what the ``n``-th event of an element puts up."""
    return int(_stream(seed, kind, element, n).generate_state(1)[0] >> 2)


@dataclasses.dataclass
class _Facade:
    quad: int
    key: str
    tenants: np.ndarray  # event ages; empty without a shop front
    repaints: np.ndarray


@dataclasses.dataclass
class _Sign:
    quad: int
    key: str
    element: int
    replacements: np.ndarray


@dataclasses.dataclass
class _Tree:
    quads: tuple[int, int]
    element: int
    x: float
    y: float
    height: float
    radius: float
    key: str
    replacements: np.ndarray


@dataclasses.dataclass
class SlowWorld:
    """A built world's elements that change, with their event ages (``index_world``)."""

    config: SlowChanges
    seed: int
    static: QuadSet
    textures: TextureCache
    facades: list[_Facade]
    signs: list[_Sign]
    trees: list[_Tree]

    def age(self, when: dt.date | dt.datetime) -> float:
        return years_since(self.config.reference, when)

    def counts(self, when: dt.date | dt.datetime) -> dict[str, dict[int, int]]:
        """Events so far per kind and element (quad index of a facade or sign, the owner id
        of a tree); elements without an event are left out."""
        age = self.age(when)
        out: dict[str, dict[int, int]] = {k: {} for k in _KIND_CODE}
        for f in self.facades:
            for kind, times in (("tenant", f.tenants), ("repaint", f.repaints)):
                if _count(times, age):
                    out[kind][f.quad] = _count(times, age)
        for s in self.signs:
            if _count(s.replacements, age):
                out["sign"][s.quad] = _count(s.replacements, age)
        for t in self.trees:
            if _count(t.replacements, age):
                out["tree_replacement"][t.element] = _count(t.replacements, age)
        return out

    def tree_heights(self, when: dt.date | dt.datetime) -> np.ndarray:
        """(number of trees,) height in metres of every tree on the date."""
        return np.array([self._tree_state(t, self.age(when))[3] for t in self.trees])

    def _tree_state(self, t: _Tree, age: float) -> tuple[str, float, float, float]:
        """(texture key, planted height, planted crown radius, height now) of a tree."""
        n = _count(t.replacements, age)
        key, h0, r0, since = t.key, t.height, t.radius, age
        if n:
            h0 = PLANTING_HEIGHT_M
            r0 = t.radius / t.height * h0
            tseed = _seed_of(self.seed, "tree_replacement", t.element, n)
            key = f"tree:{tseed}:{h0:.2f}:{r0:.2f}"
            self.textures.register(
                key,
                tree_tex,
                dict(structure_seed=tseed, height=h0, radius=r0),
                depends=("foliage", "autumn", "snow"),
            )
            since = age - t.replacements[n - 1]
        height = h0
        if "tree_growth" in self.config.kinds:
            height = min(h0 + TREE_GROWTH_M_PER_YEAR * since, max(h0, TREE_MAX_HEIGHT_M))
        return key, h0, r0, height

    def static_at(self, when: dt.date | dt.datetime) -> QuadSet:
        """The static quads as they stand on the local date of ``when``.

        The same quads in the same order (indices into them, such as the scene's alpha
        casters, still hold); a changed element gets a texture key of its own, registered
        in the scene's texture cache, and a tree its grown size.
        """
        age = self.age(when)
        if age <= 0.0:
            return self.static
        s = self.static
        tex = list(s.tex)
        origin, u, v, shadow_pt = s.origin.copy(), s.u.copy(), s.v.copy(), s.shadow_pt.copy()
        for f in self.facades:
            n_tenant, n_paint = _count(f.tenants, age), _count(f.repaints, age)
            if n_tenant or n_paint:
                fn, kwargs, depends = self.textures.specs[f.key]
                key = f"{f.key}~t{n_tenant}p{n_paint}"
                self.textures.register(
                    key,
                    fn,
                    dict(kwargs, tenant=n_tenant or None, repaint=n_paint or None),
                    depends=depends,
                )
                tex[f.quad] = key
        for g in self.signs:
            n = _count(g.replacements, age)
            if n:
                key = f"{g.key}~{n}"
                self.textures.register(
                    key, sign_tex, dict(seed=_seed_of(self.seed, "sign", g.element, n))
                )
                tex[g.quad] = key
        for t in self.trees:
            key, h0, r0, height = self._tree_state(t, age)
            scale = height / h0
            w, h = (2 * r0 + 0.4) * scale, h0 * scale  # as ``scene._add_tree`` lays them out
            a, b = t.quads
            origin[a], u[a] = (t.x - w / 2, t.y, h), (w, 0.0, 0.0)
            origin[b], u[b] = (t.x, t.y - w / 2, h), (0.0, w, 0.0)
            v[a] = v[b] = (0.0, 0.0, -h)
            shadow_pt[a] = shadow_pt[b] = (t.x, t.y, 0.6 * h)
            tex[a] = tex[b] = key
        return dataclasses.replace(s, origin=origin, u=u, v=v, tex=tex, shadow_pt=shadow_pt)


def index_world(
    seed: int, static: QuadSet, textures: TextureCache, config: SlowChanges
) -> SlowWorld:
    """Finds a built world's facades, sign posts and trees and draws their events.

    Args:
      seed: the world's seed.
      static: the world's static quads as ``build_scene`` laid them out.
      textures: its texture cache (the changed textures are registered there).
      config: the reference date and the kinds that change.

    Returns:
      The ``SlowWorld``.
    """
    on = set(config.kinds)
    none = np.zeros(0)
    facades, signs, trees = [], [], []
    for q in np.flatnonzero(static.material == Material.FACADE):
        key = static.tex[q]
        shop = bool(textures.specs[key][1].get("shopfront", False))
        element = int(static.owner[q])
        facades.append(
            _Facade(
                quad=int(q),
                key=key,
                tenants=_event_times(
                    seed, "tenant", element, TENANT_MEDIAN_STAY_YEARS / np.log(2.0), periodic=False
                )
                if shop and "tenant" in on
                else none,
                repaints=_event_times(
                    seed, "repaint", element, REPAINT_INTERVAL_YEARS, periodic=True
                )
                if "repaint" in on
                else none,
            )
        )
    for q, key in enumerate(static.tex):
        if isinstance(key, str) and key.startswith("sign:"):
            element = int(key.rsplit(":", 1)[1])
            signs.append(
                _Sign(
                    quad=q,
                    key=key,
                    element=element,
                    replacements=_event_times(
                        seed, "sign", element, SIGN_SERVICE_LIFE_YEARS, periodic=True
                    )
                    if "sign" in on
                    else none,
                )
            )
    foliage = np.flatnonzero(static.material == Material.FOLIAGE)
    for element in np.unique(static.owner[foliage]):
        a, b = (int(q) for q in foliage[static.owner[foliage] == element])
        height = float(-static.v[a][2])
        width = float(np.linalg.norm(static.u[a]))
        key = static.tex[a]
        trees.append(
            _Tree(
                quads=(a, b),
                element=int(element),
                x=float(static.origin[a][0] + width / 2),
                y=float(static.origin[a][1]),
                height=height,
                radius=(width - 0.4) / 2,
                key=key,
                replacements=_event_times(
                    seed,
                    "tree_replacement",
                    int(element),
                    1.0 / TREE_MORTALITY_PER_YEAR,
                    periodic=False,
                )
                if "tree_replacement" in on
                else none,
            )
        )
    return SlowWorld(config, int(seed), static, textures, facades, signs, trees)
