"""Real photographs of brick, grass and gravel as the synthetic world's surface materials.

Procedural noise (``textures.py``) has the right layout but not the local statistics of a
camera's view of a real material: the tonal spread of fired bricks, the width and
brightness of mortar joints, the clumps of a lawn, the shadows between stones. The patches
a repeatability predictor learns from are a few pixels across, so where a real photograph
of the material can be had offline, the world is textured with it, resampled to the
renderer's texel size (area average: what a camera integrates over a texel's footprint).

The photographs
---------------
scikit-image ships three photographs of surfaces inside its wheel, in ``skimage/data/``
(``skimage.data.brick()``, ``.grass()``, ``.gravel()``): 512 x 512, 8-bit grayscale. Those
functions read the files shipped in the package (they pass scikit-image's hash registry,
so its fetcher never downloads); this module reads the same files with
``importlib.resources`` and OpenCV, avoiding ``skimage.io``'s plugin scan. Nothing else in
the wheel is a surface photograph (``camera``, ``astronaut``, ``coffee``, ``chelsea``,
``rocket``, the motorcycle stereo pair, ``text`` and the microscopy/astronomy images are
scenes, not materials). The package's ``skimage/data/README.txt`` only says that the folder
holds a subset of scikit-image's sample data; origin and licence are given in the
functions' docstrings (and scikit-image's data gallery):

- ``brick.png``: "Bricks25" from CC0Textures (now ambientCG), Creative Commons CC0. The
  flat 2048 x 2048 texture was warped by a perspective transform (a matrix found "playing
  around with GIMP 2.10", printed in ``skimage.data.brick``'s source), cropped to its top
  left 1024 x 1024, halved and rotated 90 degrees clockwise. That recipe is exactly
  invertible, so ``photo("brick")`` undoes it (``_rectify_brick``): courses horizontal,
  true proportions, 0.5 px per px of the original texture.
- ``grass.png``: "Grass-01" by linolafett on DeviantArt, CC0; the top-left 512 x 512 of
  the photograph, converted to grayscale.
- ``gravel.png``: "Gravel04" from CC0Textures, CC0; the 2048 x 2048 texture resized to
  1024 x 1024, top-left 512 x 512, grayscale.

Physical scale (metres per photo pixel)
---------------------------------------
- Brick, measured on the rectified photograph (660 x 656 px): the stretcher module
  (brick + head joint) repeats every ``BRICK_MODULE_PX`` = 145.3 px (peak of the
  row-wise autocorrelation averaged over all rows; the head joints detected course by
  course are 143-148 px apart, with some half bats at 72-75 px) and the courses every
  ``BRICK_COURSE_PX`` = 54.1 px (mean spacing of the 11 bed joints found, 50.7-57.3 px;
  the autocorrelation of the row means peaks at 54.0, 108.5, 163.5, 217.8 px). Joints are
  6-7 px wide (half maximum). The bond is irregular, about a quarter brick between
  courses. The bricks are 2.68 modules per course, not the 3.0 of a 215 x 65 mm brick
  with 10 mm joints (nor of a US modular brick, 194 x 57 mm, 203 x 68 mm with joints), so
  length and height cannot both be a standard format; the length is the common part of
  brick formats (215 mm in the UK and EU, 210 mm Dutch and Belgian, 194-203 mm in the US),
  so the stretcher is taken as 215 mm + a 10 mm joint: 0.225 m / 145.3 px = 1.55 mm/px.
  That gives 10 mm joints (6.5 px), the usual joint, as an independent check, and 84 mm
  courses (a 74 mm brick; German NF brickwork has 83.3 mm courses; a 75 mm course would
  scale everything by 0.89). The rectified photo covers 1.02 x 1.02 m: 12 courses of
  about 4.5 bricks.
- Grass: blades 2-4 px wide (autocorrelation half-maximum at 2 px radius), and lawn
  grasses (perennial ryegrass, Kentucky bluegrass, fescues) have leaf blades about 2-5 mm
  wide; at 3 mm per 3 px: 1.0 mm/px, a 0.51 m footprint. The clover and weed rosettes
  (20-30 px, leaflets 1-2 cm) agree.
- Gravel: angular crushed stones about 20 px across (the radial autocorrelation crosses
  zero at 10 px, half a stone), taken as the common 20 mm (3/4 in) grade of crushed
  stone for drives, paths and roof ballast (16-32 mm): 1.0 mm/px, a 0.51 m footprint.

Each surface gets its own random scale jitter (``SCALE_JITTER``, +-8 %: brick formats and
gravel grades vary that much), offset and flips, drawn from the texture's own seed, so
every building and ground tile shows a different piece of the photograph.

Tiling
------
A photo is about 1 m across; a facade is 10-20 m. Bricks are laid out course by course:
each bed joint of the photo is located (``brick_layout``); output courses are photo
courses in runs of 2-5 consecutive ones from a random course, joined at bed-joint centres
(mortar meets mortar); each course repeats horizontally between its first and last
head-joint centres (mortar meets mortar again), so no seam crosses a brick, and is
shifted by the best of a few random offsets so that its head joints fall between those
of the course below, as a bricklayer breaks the joints. A wall may be mirrored
left-right, never upside down (the joints are shaded by light from above). Grass and
gravel (isotropic) are quilted from random blocks of the photo (centred in its middle
half, in one of the 8 rotations/flips), overlapping by half and blended with tent
weights normalised to keep the photo's variance.

The photos are grayscale: they give the luminance structure; colour comes from the
procedural palette of the surface (the building's brick colour, the season's grass).
Without scikit-image (``HAVE_SKIMAGE`` False) ``available()`` is False and the callers in
``textures.py`` keep their procedural textures.
"""

from __future__ import annotations

import functools
import importlib.resources
import logging

import cv2
import numpy as np

try:  # the photographs ship inside scikit-image's wheel
    import skimage  # noqa: F401

    HAVE_SKIMAGE = True
except ImportError:  # pragma: no cover - exercised by monkeypatching HAVE_SKIMAGE
    HAVE_SKIMAGE = False

__all__ = [
    "BRICK_COURSE_PX",
    "BRICK_MODULE_M",
    "BRICK_MODULE_PX",
    "HAVE_SKIMAGE",
    "M_PER_PX",
    "PHOTOS",
    "SCALE_JITTER",
    "available",
    "brick_layout",
    "brick_luminance",
    "brick_tile",
    "grass_tile",
    "gravel_tile",
    "photo",
    "read_png",
]

log = logging.getLogger(__name__)

PHOTOS = ("brick", "grass", "gravel")

# Measured on photo("brick") (see the module docstring; tests/sources/synthetic/
# test_photo_textures.py measures them again).
BRICK_MODULE_PX = 145.3  # stretcher + head joint, rectified px
BRICK_COURSE_PX = 54.1  # brick + bed joint, rectified px
BRICK_MODULE_M = 0.225  # a 215 mm stretcher + a 10 mm head joint
M_PER_PX = {
    "brick": BRICK_MODULE_M / BRICK_MODULE_PX,  # 1.55 mm/px
    "grass": 0.001,  # 3 mm blades, 3 px wide
    "gravel": 0.001,  # 20 mm stones, 20 px across
}
SCALE_JITTER = 0.08  # each surface's scale is drawn in [1 - j, 1 + j]

# skimage.data.brick's recipe: warp(orig, inv(_BRICK_PERSPECTIVE)) on the 2048 x 2048
# "Bricks25" texture, [:1024, :1024], rescale 0.5, rotate(-90). _BRICK_PERSPECTIVE maps
# original (col, row) to warped (col, row), homogeneous.
_BRICK_PERSPECTIVE = np.array(
    [[0.54764, -0.00219, 0.0], [-0.12822, 0.54688, 0.0], [-0.00022, 0.0, 1.0]]
)
_RECT_SCALE = 0.5  # rectified px per px of the original texture
_RECT_MARGIN = 2.0  # original px kept clear of the warped crop's border

# Photo-rng salts: one stream per use, so the same texture seed varies each independently.
_SALT = {"brick": 1, "grass": 2, "gravel": 3}
_SAMPLES_PER_TEXEL = 4.0


def available() -> bool:
    """Whether the photographs can be used (scikit-image installed and its files readable)."""
    return HAVE_SKIMAGE and _load_all() is not None


@functools.lru_cache(maxsize=1)
def _load_all() -> dict[str, np.ndarray] | None:
    """The three photos as float32 relative luminance (mean 1), brick rectified; None on failure."""
    try:
        raw = {name: read_png(name).astype(np.float32) for name in PHOTOS}
        raw["brick"] = _rectify_brick(raw["brick"])
        return {name: img / np.float32(img.mean()) for name, img in raw.items()}
    except (ImportError, OSError, ValueError) as err:
        log.warning("photo textures unavailable (%s); using procedural textures", err)
        return None


def read_png(name: str) -> np.ndarray:
    """The file ``skimage/data/<name>.png`` as shipped (512 x 512 uint8), read locally."""
    data = importlib.resources.files("skimage").joinpath("data", f"{name}.png").read_bytes()
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    if img is None or img.shape != (512, 512):
        raise ValueError(f"skimage/data/{name}.png is not a 512x512 image")
    return img


def photo(name: str) -> np.ndarray:
    """Photo ``name`` ("brick", "grass", "gravel") as float32 luminance relative to its mean.

    ``"brick"`` is rectified (courses horizontal, 0.5 px per px of the original texture).
    """
    photos = _load_all()
    if photos is None:
        raise RuntimeError("photo textures are unavailable (scikit-image missing)")
    return photos[name]


def _rectify_brick(png: np.ndarray) -> np.ndarray:
    """Undo ``skimage.data.brick``'s perspective warp, crop, rescale and rotation.

    The output samples the original texture on a regular grid (``_RECT_SCALE`` px per
    original px) over the largest axis-aligned rectangle inside the warped crop.
    """
    M = _BRICK_PERSPECTIVE
    Hinv = np.linalg.inv(M)
    # The warped crop [0, 1024)^2 seen in the original texture: a quadrilateral.
    corners = np.array([[0, 0, 1], [1023, 0, 1], [0, 1023, 1], [1023, 1023, 1]], float) @ Hinv.T
    corners = corners[:, :2] / corners[:, 2:]
    u0 = max(corners[0, 0], corners[2, 0]) + _RECT_MARGIN
    u1 = min(corners[1, 0], corners[3, 0]) - _RECT_MARGIN
    v0 = max(corners[0, 1], corners[1, 1]) + _RECT_MARGIN
    v1 = min(corners[2, 1], corners[3, 1]) - _RECT_MARGIN
    rows, cols = int((v1 - v0) * _RECT_SCALE), int((u1 - u0) * _RECT_SCALE)
    vr, ur = np.mgrid[0:rows, 0:cols].astype(np.float64)
    u, v = u0 + ur / _RECT_SCALE, v0 + vr / _RECT_SCALE
    w = M[2, 0] * u + M[2, 1] * v + M[2, 2]
    x = (M[0, 0] * u + M[0, 1] * v + M[0, 2]) / w
    y = (M[1, 0] * u + M[1, 1] * v + M[1, 2]) / w
    # rescale(0.5): half-size pixel i samples 2 i + 0.5; rotate(-90) about (255.5, 255.5):
    # png[row, col] = half[col, 511 - row].
    i, j = (x - 0.5) / 2.0, (y - 0.5) / 2.0
    map_x, map_y = (511.0 - j).astype(np.float32), i.astype(np.float32)
    return cv2.remap(png, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _peaks(profile: np.ndarray, radius: int, threshold: float) -> np.ndarray:
    """Sub-pixel local maxima of a 1D profile above ``threshold``, at least ``radius`` apart."""
    p = np.convolve(profile, np.ones(3) / 3.0, mode="same")
    out = []
    for i in range(radius, len(p) - radius):
        if p[i] > threshold and p[i] == p[i - radius:i + radius + 1].max():
            a, b, c = p[i - 1], p[i], p[i + 1]
            den = a - 2 * b + c
            out.append(i + (0.5 * (a - c) / den if den != 0 else 0.0))
    return np.asarray(out, np.float64)


@functools.lru_cache(maxsize=1)
def brick_layout() -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """Joints of the rectified brick photo.

    Returns:
      ``(bed, heads)``: ``bed`` (C + 1,) rows of the bed-joint centres, top to bottom, so
      course ``c`` lies between ``bed[c]`` and ``bed[c + 1]``; ``heads[c]`` the columns of
      course ``c``'s head-joint centres, left to right.
    """
    img = photo("brick")
    rows = img.mean(1)
    lo, hi = np.percentile(rows, 20), np.percentile(rows, 98)
    bed = _peaks(rows, radius=int(BRICK_COURSE_PX * 0.35), threshold=(lo + hi) / 2)
    heads = []
    for c in range(len(bed) - 1):
        a, b = int(np.ceil(bed[c])) + 8, int(bed[c + 1]) - 8  # the course's bricks, no bed joint
        prof = img[a:b].mean(0)
        threshold = prof.mean() + 0.5 * (prof.max() - prof.mean())
        heads.append(_peaks(prof, radius=20, threshold=threshold))
    return bed, tuple(heads)


@functools.lru_cache(maxsize=32)
def _prefiltered(name: str, box: int) -> tuple[np.ndarray, float]:
    """Photo ``name`` box-filtered over ``box`` px (a texel's footprint), float32.

    Returns ``(image, f)``: the filtered photo resampled to ``f`` = 4 / ``box`` of its
    size (4 samples per texel), or at full size (``f`` = 1) for boxes of 4 px or less.
    Brick has two channels: luminance and mortar coverage (0 brick .. 1 mortar).
    """
    img = photo(name)
    if name == "brick":
        brick_l, mortar_l = _brick_levels()
        mortar = np.clip(
            (img - (brick_l + 0.35 * (mortar_l - brick_l))) / (0.4 * (mortar_l - brick_l)), 0.0, 1.0
        )
        img = np.dstack([img, mortar]).astype(np.float32)
    if box > 1:
        img = cv2.blur(img, (box, box), borderType=cv2.BORDER_REFLECT)
    # Keep _SAMPLES_PER_TEXEL samples per texel: enough that resampling and the bilinear
    # lookup add little to the box (a footprint ~8 % wider at 4), few enough to be fast.
    f = min(1.0, _SAMPLES_PER_TEXEL / box)
    if f < 1.0:  # (dsize from fx, fy: OpenCV maps coordinates by exactly f)
        img = cv2.resize(img, (0, 0), fx=f, fy=f, interpolation=cv2.INTER_AREA)
    return img, f


@functools.lru_cache(maxsize=1)
def _brick_levels() -> tuple[float, float]:
    """Typical relative luminance of the bricks and of the mortar in the brick photo."""
    img = photo("brick")
    return float(np.percentile(img, 40)), float(np.percentile(img, 97))


def _texel_yx(texel: float | tuple[float, float]) -> tuple[float, float]:
    return (
        (float(texel), float(texel)) if np.isscalar(texel) else (float(texel[0]), float(texel[1]))
    )


def _px_per_texel(name: str, texel, rng: np.random.Generator) -> tuple[float, float]:
    """Photo px per texel along rows and columns, with this surface's scale jitter."""
    scale = 1.0 + SCALE_JITTER * rng.uniform(-1.0, 1.0)
    ty, tx = _texel_yx(texel)
    return ty / (M_PER_PX[name] * scale), tx / (M_PER_PX[name] * scale)


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x9E3779B9, _SALT[name]])


def _sample(src: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return cv2.remap(
        src,
        u.astype(np.float32, copy=False),
        v.astype(np.float32, copy=False),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REFLECT,
    )


_BOND_CANDIDATES = 6  # random horizontal shifts tried per course


def _head_joints_x(
    heads: np.ndarray, offsets: np.ndarray, span: float, flip: float = 1.0
) -> np.ndarray:
    """Output positions (photo px from the wall's left edge) of a course's head joints.

    The course is read at ``heads[0] + (flip * x + offset) mod period``. One sorted row
    per horizontal shift in ``offsets``: (len(offsets), n).
    """
    period = heads[-1] - heads[0]
    base = np.mod(flip * (heads[None, :-1] - heads[0] - offsets[:, None]), period)
    n = int(np.ceil(span / period)) + 1
    return np.sort(
        (base[:, None, :] + period * np.arange(n)[None, :, None]).reshape(len(offsets), -1), axis=1
    )


def _joint_gap(below: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Per row of ``joints``: mean distance from its head joints to the nearest one below,
    each capped at a quarter brick."""
    i = np.clip(np.searchsorted(below, joints), 1, len(below) - 1)
    d = np.minimum(np.abs(joints - below[i - 1]), np.abs(joints - below[i]))
    return np.minimum(d, 0.25 * BRICK_MODULE_PX).mean(1)


def brick_luminance(
    seed: int, h: int, w: int, texel: float | tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """A brick wall ``h`` x ``w`` texels cut from the photo, course by course.

    Args:
      seed: the surface's seed (offsets, runs of courses, scale jitter).
      h, w: texels (rows top to bottom, columns left to right).
      texel: metres per texel, or (along rows, along columns).

    Returns:
      ``(lum, mortar)`` float32 (h, w): relative luminance (photo mean 1) and mortar
      coverage 0..1 of each texel, both area averages over the texel.
    """
    rng = _rng(seed, "brick")
    ky, kx = _px_per_texel("brick", texel, rng)
    src, f = _prefiltered("brick", max(1, round(float(0.5 * (ky + kx)))))
    bed, heads = brick_layout()
    heights = np.diff(bed)
    n_courses = len(heights)
    # The output's courses: runs of 2-5 consecutive photo courses from a random course,
    # joined at bed-joint centres; each course repeats between its first and last
    # head-joint centres, shifted so that its head joints fall between those of the
    # course below (the best of a few random shifts), as a bricklayer breaks the joints.
    first = np.array([hd[0] for hd in heads])
    period = np.array([hd[-1] - hd[0] for hd in heads])
    span = w * kx
    flip = 1.0 if rng.random() < 0.5 else -1.0  # mirrored left-right (never upside down:
    # the photo's joints are shaded by light from above)
    t = (np.arange(h) + 0.5) * ky + rng.uniform(0.0, heights.mean())
    starts, course, offset = [0.0], [], []
    below = None
    while starts[-1] <= t[-1]:
        run = int(rng.integers(2, 6))
        c0 = int(rng.integers(0, n_courses - run + 1))
        for c in range(c0, c0 + run):
            cand = rng.uniform(0.0, period[c], _BOND_CANDIDATES)
            joints = _head_joints_x(heads[c], cand, span, flip)
            best = 0 if below is None else int(np.argmax(_joint_gap(below, joints)))
            below = joints[best]
            course.append(c)
            offset.append(cand[best])
            starts.append(starts[-1] + heights[c])
    starts_a = np.asarray(starts[:-1])
    course_a, offset_a = np.asarray(course), np.asarray(offset)
    idx = np.searchsorted(starts_a, t, side="right") - 1
    c_row = course_a[idx]
    v = bed[c_row] + (t - starts_a[idx])  # photo row of each output row
    x = (np.arange(w) + 0.5) * kx
    u = first[c_row][:, None] + np.mod(
        flip * x[None, :] + offset_a[idx][:, None], period[c_row][:, None]
    )
    # Photo px -> samples of the prefiltered photo (pixel centres at (i + 0.5) / f - 0.5).
    out = _sample(
        src, (u + 0.5) * f - 0.5, np.broadcast_to(((v + 0.5) * f - 0.5)[:, None], u.shape)
    )
    return out[..., 0], np.clip(out[..., 1], 0.0, 1.0)


def brick_tile(seed: int, h: int, w: int, texel, brick_rgb, mortar_rgb) -> np.ndarray:
    """Brick wall albedo (h, w, 3) float32: the photo's structure in the given colours.

    Each texel's colour mixes ``brick_rgb`` and ``mortar_rgb`` by its mortar coverage and
    carries the photo's luminance relative to that mix, so a building keeps its brick
    colour and every brick its own tone from the photograph.
    """
    lum, mortar = brick_luminance(seed, h, w, texel)
    brick_l, mortar_l = _brick_levels()
    m = mortar[..., None]
    colour = (1.0 - m) * np.float32(brick_rgb) + m * np.float32(mortar_rgb)
    rel = lum / ((1.0 - mortar) * brick_l + mortar * mortar_l)
    return (colour * rel[..., None]).astype(np.float32)


_BLOCK = 1.0 / 3.0  # half a quilting block, in photo widths
_CENTRES = 0.25  # block centres lie in the photo's middle half: [_CENTRES, 1 - _CENTRES]
_PAD = 0.1  # mirrored margin around each atlas panel (>= _BLOCK - _CENTRES), photo widths


@functools.lru_cache(maxsize=32)
def _dihedral_atlas(name: str, box: int) -> tuple[np.ndarray, float, int]:
    """The prefiltered photo in its 8 rotations/flips side by side, and its ``f``.

    Each panel is the photo with a mirrored margin of ``pad`` samples, which the tail of
    a block centred near the photo's edge reaches into. Returns ``(atlas, f, pad)``;
    panel ``k`` spans columns ``k (size + 2 pad)`` onwards.
    """
    img, f = _prefiltered(name, box)
    pad = int(np.ceil(_PAD * img.shape[0]))
    panels = []
    for k in range(8):
        p = np.rot90(img, k % 4)
        p = np.ascontiguousarray(p[:, ::-1] if k >= 4 else p)
        panels.append(cv2.copyMakeBorder(p, pad, pad, pad, pad, cv2.BORDER_REFLECT_101))
    return np.ascontiguousarray(np.concatenate(panels, axis=1)), f, pad


@functools.lru_cache(maxsize=64)  # a ground tile is re-tinted for every season and snow
def _quilt(name: str, seed: int, h: int, w: int, texel) -> np.ndarray:
    """Relative luminance (h, w) of an isotropic photo quilted from random blocks (read-only).

    Blocks sit on a lattice of spacing S texels and span 2 S (2/3 of the photo, half
    overlap); each takes a random piece of the photo (centred in its middle half; the
    tail of a block may reach a mirrored margin) in one of its 8 rotations/flips,
    weighted by a tent around its centre; the blend is normalised by the root of the
    summed squared weights, so overlaps keep the photo's contrast instead of averaging it
    away.
    """
    rng = _rng(seed, name)
    ky, kx = _px_per_texel(name, texel, rng)
    atlas, f, pad = _dihedral_atlas(name, max(1, round(float(0.5 * (ky + kx)))))
    ky, kx = ky * f, kx * f  # atlas samples per texel
    size = atlas.shape[0] - 2 * pad  # the photos are square: every panel is size x size
    span = _BLOCK * size  # half a block, atlas samples
    sy, sx = span / ky, span / kx  # lattice spacing, texels
    ny, nx = int(h / sy) + 2, int(w / sx) + 2
    lo, hi = pad + _CENTRES * size, pad + (1.0 - _CENTRES) * size - 1
    cu = rng.uniform(lo, hi, (ny, nx)) + (size + 2 * pad) * rng.integers(0, 8, (ny, nx))
    cv = rng.uniform(lo, hi, (ny, nx))
    cu, cv = cu.astype(np.float32).ravel(), cv.astype(np.float32).ravel()
    gy = ((np.arange(h) + 0.5) / sy).astype(np.float32)
    gx = ((np.arange(w) + 0.5) / sx).astype(np.float32)
    iy0, ix0 = np.floor(gy).astype(np.int32), np.floor(gx).astype(np.int32)
    acc = np.zeros((h, w), np.float32)
    wy2 = np.zeros(h, np.float32)
    wx2 = np.zeros(w, np.float32)
    for di in (0, 1):
        iy = iy0 + di
        wy = 1.0 - np.abs(gy - iy)
        wy2 += wy * wy
        dy = ((gy - iy) * span)[:, None]
        for dj in (0, 1):
            ix = ix0 + dj
            wx = 1.0 - np.abs(gx - ix)
            if di == 0:
                wx2 += wx * wx
            dx = ((gx - ix) * span)[None, :]
            block = iy[:, None] * nx + ix[None, :]
            s = _sample(atlas, np.take(cu, block) + dx, np.take(cv, block) + dy)
            acc += (wy[:, None] * wx[None, :]) * (s - 1.0)
    out = 1.0 + acc / np.sqrt(wy2[:, None] * wx2[None, :])
    out.flags.writeable = False
    return out


def grass_tile(seed: int, h: int, w: int, texel, rgb) -> np.ndarray:
    """Lawn albedo (h, w, 3) float32: the grass photo's luminance in colour ``rgb``."""
    lum = _quilt("grass", int(seed), int(h), int(w), _texel_yx(texel))
    return (np.float32(rgb) * lum[..., None]).astype(np.float32)


def gravel_tile(seed: int, h: int, w: int, texel, rgb) -> np.ndarray:
    """Gravel albedo (h, w, 3) float32: the gravel photo's luminance in colour ``rgb``."""
    lum = _quilt("gravel", int(seed), int(h), int(w), _texel_yx(texel))
    return (np.float32(rgb) * lum[..., None]).astype(np.float32)
