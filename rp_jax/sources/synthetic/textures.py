"""Procedural, band-limited textures of the synthetic world (stand-in for Sec. IV-A data).

The paper's datasets are photographs of real streets (Webcam Clip Art, Extended CMU
Seasons); SIFT (Sec. IV) finds interest points on facade details, windows, signs, foliage,
cars and road markings. This module paints those details procedurally so that the rendered
pixels carry the same kind of structure: every brick, window and sign is drawn with its own
random variation (no two windows alike: curtains, blinds, objects), and every texture is
pre-blurred (band-limited) before it is sampled, so that renders at sub-pixel offsets do
not alias. Where scikit-image is installed, brick walls, lawns, lawn paths and flat roofs
take their material from real photographs of brick, grass and gravel
(``photo_textures``), in the colours drawn here and around the same windows, doors, signs
and snow; the procedural materials are the fallback.

Every function returns an RGBA ``uint8`` array ``(H, W, 4)``: RGB albedo in sRGB and a
fourth *aux* channel whose meaning depends on the material (see ``quads.Material``):
window ids on facades, snow susceptibility on ground and roofs, alpha on cut-out objects
(trees, people), emission on lamps and car lights. Sizes are multiples of 16 so that the
mip pyramid (``mip_pyramid``) keeps texel centres exactly aligned.

Why this module is over 600 lines: the facade is one recipe whose draws, in their order,
are every window, door and sign of a building; the walls, windows, signs and shop fronts
it paints, and the later tenants and repaints of ``slow_changes``, read its generator in
step and stay beside it.
"""

from __future__ import annotations

import string

import cv2
import numpy as np

from rp_jax.sources.synthetic import photo_textures as pt

__all__ = [
    "apply_snow",
    "LETTERS",
    "TEXEL_M",
    "finish",
    "put_text",
    "rand_colour",
    "repaint_colours",
    "value_noise",
    "facade_texture",
    "side_wall_texture",
    "roof_texture",
    "sign_texture",
    "mip_pyramid",
    "pad16",
]

TEXEL_M = 0.025  # metres per texel of near-camera surfaces (facades, road, sidewalks)
LETTERS = string.ascii_uppercase + string.digits


def pad16(n: float) -> int:
    """Round a texel count to a positive multiple of 16."""
    return max(16, int(round(n / 16.0)) * 16)


def value_noise(
    shape: tuple[int, int], rng: np.random.Generator, cell: float, octaves: int = 4
) -> np.ndarray:
    """Fractal value noise in [0, 1], smooth at scale ``cell`` texels.

    Args:
      shape: (H, W).
      rng: random generator.
      cell: size of the coarsest noise cell in texels.
      octaves: number of octaves, each half the size and amplitude of the previous.

    Returns:
      float32 array of shape ``shape``.
    """
    h, w = shape
    out = np.zeros((h, w), np.float32)
    amp, total = 1.0, 0.0
    for _ in range(octaves):
        gh, gw = max(2, int(np.ceil(h / cell)) + 1), max(2, int(np.ceil(w / cell)) + 1)
        grid = rng.random((gh, gw), dtype=np.float32)
        out += amp * cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)
        total += amp
        amp *= 0.5
        cell = max(1.0, cell / 2.0)
    return np.clip(out / total, 0.0, 1.0)


def finish(rgb: np.ndarray, aux: np.ndarray, blur: float = 0.6) -> np.ndarray:
    """float RGB in [0,1] + uint8 aux -> band-limited RGBA uint8."""
    rgb = np.clip(rgb, 0.0, 1.0)
    if blur > 0:
        rgb = cv2.GaussianBlur(rgb, (0, 0), blur)
    out = np.empty(rgb.shape[:2] + (4,), np.uint8)
    out[..., :3] = (rgb * 255.0 + 0.5).astype(np.uint8)
    out[..., 3] = aux
    return out


def mip_pyramid(tex: np.ndarray, levels: int = 5) -> list[np.ndarray]:
    """Gaussian pyramid (``cv2.pyrDown``) of a texture: each level band-limited, half size."""
    pyr = [tex]
    for _ in range(levels):
        h, w = pyr[-1].shape[:2]
        if h < 32 or w < 32 or h % 2 or w % 2:
            break
        pyr.append(cv2.pyrDown(pyr[-1]))
    return pyr


# ---------------------------------------------------------------- wall materials


_BRICK_COLOURS = np.array(
    [
        [0.55, 0.25, 0.18],
        [0.62, 0.33, 0.22],
        [0.45, 0.22, 0.17],
        [0.70, 0.50, 0.38],
        [0.50, 0.35, 0.30],
    ],
    np.float32,
)
_PLASTER_COLOURS = np.array(
    [
        [0.85, 0.80, 0.68],
        [0.78, 0.72, 0.62],
        [0.70, 0.74, 0.76],
        [0.88, 0.78, 0.60],
        [0.75, 0.62, 0.55],
        [0.66, 0.66, 0.62],
        [0.82, 0.84, 0.80],
    ],
    np.float32,
)
_SIDING_COLOURS = np.array(
    [
        [0.90, 0.90, 0.86],
        [0.62, 0.70, 0.78],
        [0.86, 0.80, 0.55],
        [0.60, 0.68, 0.58],
        [0.78, 0.72, 0.66],
    ],
    np.float32,
)


_MORTAR = np.float32([0.72, 0.70, 0.66])


def _wall(
    style: str,
    h: int,
    w: int,
    rng: np.random.Generator,
    texel: float | tuple[float, float],
    photo_seed: int | None = None,
    paint: np.ndarray | None = None,
) -> np.ndarray:
    """Wall albedo (H, W, 3) float32 for a style: brick, plaster, siding or concrete.

    ``texel`` is metres per texel, or (along rows, along columns). Brick is the brick
    photograph (``photo_textures.brick_tile``, cut by ``photo_seed``) in the building's
    brick colour when the photos are available and ``photo_seed`` is given, else drawn
    brick by brick. Either way ``rng`` is drawn from exactly as before, so everything a
    caller draws after the wall (windows, doors, signs, snow) stays where it was.
    ``paint``, when given, is the colour a repaint put on a plaster, siding or concrete
    wall in place of the drawn one (bare brick is not painted; ``rng`` is drawn from as
    without it).
    """
    texel_yx = (
        (float(texel), float(texel)) if np.isscalar(texel) else (float(texel[0]), float(texel[1]))
    )
    ppm = 1.0 / texel_yx[1]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    grain = value_noise((h, w), rng, cell=6, octaves=3)[..., None]
    stain = value_noise((h, w), rng, cell=ppm * 3, octaves=3)[..., None]
    if style == "brick":
        base = _BRICK_COLOURS[rng.integers(len(_BRICK_COLOURS))]
        phase = rng.random() * 100
        if photo_seed is not None and pt.available():
            # The photograph's bricks and mortar (its own tone per brick, its own joints)
            # replace the drawn ones, in this building's brick colour.
            rgb = pt.brick_tile(photo_seed, h, w, texel_yx, base, _MORTAR)
        else:
            course, brick_len = 0.075 * ppm, 0.215 * ppm
            row = np.floor(yy / course)
            xs = xx + (row % 2) * brick_len * 0.5
            col = np.floor(xs / brick_len)
            hsh = np.sin(row * 12.9898 + col * 78.233 + phase) * 43758.5453
            hsh = (hsh - np.floor(hsh))[..., None].astype(np.float32)
            rgb = base * (0.78 + 0.4 * hsh) * (0.92 + 0.16 * grain)
            mortar = ((yy % course) < 0.012 * ppm + 0.6) | ((xs % brick_len) < 0.012 * ppm + 0.6)
            rgb = np.where(mortar[..., None], _MORTAR * (0.9 + 0.2 * grain), rgb)
    elif style == "siding":
        base = _SIDING_COLOURS[rng.integers(len(_SIDING_COLOURS))]
        base = base if paint is None else paint
        board = 0.18 * ppm
        frac = (yy % board) / board
        shade = 0.8 + 0.2 * np.clip(frac * 3, 0, 1)
        rgb = base * shade[..., None] * (0.95 + 0.08 * grain)
    elif style == "concrete":
        base = np.float32([0.62, 0.61, 0.58]) * (0.85 + 0.3 * rng.random())
        base = base if paint is None else paint
        panel_w, panel_h = rng.uniform(1.2, 3.0) * ppm, rng.uniform(1.0, 3.0) * ppm
        joints = ((xx % panel_w) < 1.5) | ((yy % panel_h) < 1.5)
        rgb = base * (0.85 + 0.25 * grain) * np.where(joints, 0.6, 1.0)[..., None]
    else:  # plaster
        base = _PLASTER_COLOURS[rng.integers(len(_PLASTER_COLOURS))]
        base = base if paint is None else paint
        rgb = base * (0.88 + 0.24 * grain)
    # Weathering: large blotches and vertical rain streaks.
    streak = cv2.resize(
        rng.random((1, max(2, w // 6)), dtype=np.float32), (w, h), interpolation=cv2.INTER_LINEAR
    )
    rgb = rgb * (0.85 + 0.25 * stain) * (0.93 + 0.1 * streak[..., None])
    return rgb.astype(np.float32)


def rand_colour(rng: np.random.Generator, sat: float = 0.6) -> np.ndarray:
    hue = rng.random()
    c = np.array([abs(hue * 6 - 3) - 1, 2 - abs(hue * 6 - 2), 2 - abs(hue * 6 - 4)], np.float32)
    c = np.clip(c, 0, 1)
    v = rng.uniform(0.25, 0.9)
    return (v * (1 - sat + sat * c)).astype(np.float32)


def _window(
    rgb: np.ndarray,
    aux: np.ndarray,
    x0: int,
    y0: int,
    ww: int,
    wh: int,
    wid: int,
    rng: np.random.Generator,
    frame_col: np.ndarray,
) -> None:
    """Paints one window with its own clutter in place; marks its glass in ``aux`` with ``wid``."""
    h, w = rgb.shape[:2]
    x1, y1 = min(w, x0 + ww), min(h, y0 + wh)
    if x1 - x0 < 6 or y1 - y0 < 6:
        return
    fw = max(2, int(0.05 * ww))
    rgb[y0:y1, x0:x1] = frame_col
    gx0, gy0, gx1, gy1 = x0 + fw, y0 + fw, x1 - fw, y1 - fw
    gh, gw_ = gy1 - gy0, gx1 - gx0
    # Glass: dark interior with a reflected-sky gradient, different for each window.
    tint = np.float32([0.10, 0.12, 0.15]) + rng.uniform(0, 0.08, 3).astype(np.float32)
    grad = np.linspace(rng.uniform(0.3, 1.4), rng.uniform(0.3, 1.0), gh, dtype=np.float32)[
        :, None, None
    ]
    glass = tint * grad * np.ones((gh, gw_, 1), np.float32)
    kind = rng.choice(["curtains", "blinds", "objects", "dark", "curtains", "plants"])
    if kind == "curtains":
        col = rand_colour(rng, 0.5)
        freq = rng.uniform(0.6, 1.4)
        cw = max(1, int(gw_ * rng.uniform(0.15, 0.45)))
        glass[:, :cw] = col * (0.8 + 0.2 * np.sin(np.arange(cw) * freq))[None, :, None]
        if rng.random() < 0.7:
            cw2 = max(1, int(gw_ * rng.uniform(0.15, 0.45)))
            glass[:, gw_ - cw2 :] = (
                col * 0.95 * (0.8 + 0.2 * np.sin(np.arange(cw2) * freq))[None, :, None]
            )
    elif kind == "blinds":
        down = int(gh * rng.uniform(0.2, 1.0))
        col = np.float32([0.85, 0.83, 0.78]) * rng.uniform(0.6, 1.0)
        slat = np.where((np.arange(down) % 4) < 3, 1.0, 0.75).astype(np.float32)[:, None, None]
        glass[:down] = col * slat
    elif kind in ("objects", "plants"):
        for _ in range(rng.integers(1, 5)):
            ox, oy = (
                rng.integers(0, max(1, gw_ - 4)),
                rng.integers(gh // 3, max(gh // 3 + 1, gh - 4)),
            )
            ow, oh = rng.integers(3, max(4, gw_ // 3)), rng.integers(3, max(4, gh // 3))
            col = (
                rand_colour(rng, 0.7)
                if kind == "objects"
                else np.float32([0.1, 0.35, 0.1]) * rng.uniform(0.6, 1.3)
            )
            if kind == "plants":
                cv2.ellipse(
                    glass,
                    (int(ox + ow // 2), int(oy)),
                    (int(ow // 2 + 1), int(oh // 2 + 1)),
                    0,
                    0,
                    360,
                    col.tolist(),
                    -1,
                )
            else:
                glass[oy : oy + oh, ox : ox + ow] = col
    rgb[gy0:gy1, gx0:gx1] = glass
    # aux = 128 + a lighting rank: a window is lit at night when its rank beats the hour's
    # threshold. Interpolated texels between glass (>= 128) and wall (0) never exceed the
    # window's own value, so unlit windows cannot grow lit outlines.
    aux[gy0:gy1, gx0:gx1] = 128 + (wid * 37 + int(rng.integers(0, 127))) % 127
    # Mullions: a cross or a vertical bar, chosen per window.
    m = rng.integers(0, 3)
    bw = max(1, fw // 2)
    if m >= 1:
        cx = (gx0 + gx1) // 2
        rgb[gy0:gy1, cx - bw : cx + bw] = frame_col
    if m == 2:
        cy = gy0 + int(gh * rng.uniform(0.3, 0.6))
        rgb[cy - bw : cy + bw, gx0:gx1] = frame_col
    # Sill and lintel.
    rgb[y1 : min(h, y1 + max(2, fw)), max(0, x0 - fw) : min(w, x1 + fw)] = frame_col * 0.85
    rgb[max(0, y0 - fw) : y0, max(0, x0 - fw) : min(w, x1 + fw)] = frame_col * 0.7


def put_text(
    img: np.ndarray, text: str, org, font: int, scale: float, colour: np.ndarray, thick: int
) -> None:
    """``cv2.putText`` on a float [0, 1] image (OpenCV 5 draws text on 8-bit images only)."""
    canvas = np.zeros(img.shape[:2], np.uint8)
    cv2.putText(canvas, text, org, font, scale, 255, thick, cv2.LINE_AA)
    a = (canvas.astype(np.float32) / 255.0)[..., None]
    img[:] = img * (1 - a) + np.asarray(colour, np.float32) * a


def sign_texture(rng: np.random.Generator, w: int, h: int) -> np.ndarray:
    """A shop sign: a coloured panel with random letters (float RGB)."""
    bg = rand_colour(rng, 0.8)
    fg = np.float32([1, 1, 1]) - bg * rng.uniform(0.6, 1.0)
    img = np.ones((h, w, 3), np.float32) * bg
    n = int(rng.integers(3, 10))
    text = "".join(rng.choice(list(LETTERS), n))
    font = int(
        rng.choice(
            [
                cv2.FONT_HERSHEY_SIMPLEX,
                cv2.FONT_HERSHEY_DUPLEX,
                cv2.FONT_HERSHEY_TRIPLEX,
                cv2.FONT_HERSHEY_COMPLEX,
            ]
        )
    )
    (tw, th), _ = cv2.getTextSize(text, font, 1.0, 2)
    scale = min(0.9 * w / max(tw, 1), 0.7 * h / max(th, 1))
    thick = max(1, int(scale * 2))
    (tw, th), _ = cv2.getTextSize(text, font, scale, thick)
    put_text(img, text, ((w - tw) // 2, (h + th) // 2), font, scale, fg, thick)
    return img


# Streams of the slow changes (``slow_changes``) in a facade's own seed: a later tenant's
# shop front and a repaint's colours; the facade's first draws never read them.
_TENANT_STREAM = 101
_REPAINT_STREAM = 102


def repaint_colours(seed: int, repaint: int) -> tuple[np.ndarray, np.ndarray]:
    """(wall, trim) float32 RGB of a facade's ``repaint``-th repaint: an exterior paint
    (any hue, muted, light to mid) and a white or muted trim, drawn from (seed, repaint)."""
    rng = np.random.default_rng([int(seed), _REPAINT_STREAM, int(repaint)])
    hue = rng.random()
    c = np.array([abs(hue * 6 - 3) - 1, 2 - abs(hue * 6 - 2), 2 - abs(hue * 6 - 4)], np.float32)
    sat, value = rng.uniform(0.05, 0.4), rng.uniform(0.55, 0.92)
    wall = (value * (1 - sat + sat * np.clip(c, 0, 1))).astype(np.float32)
    trim = np.float32([0.92, 0.91, 0.88]) if rng.random() < 0.5 else rand_colour(rng, 0.3) * 0.7
    return wall, trim.astype(np.float32)


def _shopfront(
    rgb: np.ndarray,
    aux: np.ndarray,
    rng: np.random.Generator,
    y_top: int,
    ppm: float,
    width_m: float,
    wid: int,
) -> tuple[int, tuple[int, int, int]]:
    """Paints a ground-floor shop from ``rng`` in place: a shop window with a display each
    side of a door, and a sign above. Returns the next window id and the sign's top ledge
    (x0, x1, y)."""
    H, W = rgb.shape[:2]
    sx0, sx1 = int(0.3 * ppm), W - int(0.3 * ppm)
    door_w = int(1.0 * ppm)
    door_x = int(rng.uniform(0.3, max(0.31, width_m - 1.4)) * ppm)
    sh_top = y_top + int(0.9 * ppm)
    for a, b in ((sx0, door_x), (door_x + door_w, sx1)):
        if b - a > 20:
            _window(
                rgb,
                aux,
                a,
                sh_top,
                b - a,
                H - int(0.4 * ppm) - sh_top,
                wid % 255 + 1,
                rng,
                np.float32([0.15, 0.15, 0.16]),
            )
            wid += 1
    door_col = rand_colour(rng, 0.4) * 0.6
    rgb[sh_top:H, door_x : door_x + door_w] = door_col
    rgb[sh_top + 8 : H - 40, door_x + 8 : door_x + door_w - 8] *= 0.6
    sign_h = int(0.6 * ppm)
    sign_w = int(rng.uniform(0.5, 0.9) * (sx1 - sx0))
    sx = sx0 + int(rng.uniform(0, 1) * (sx1 - sx0 - sign_w))
    rgb[y_top + int(0.15 * ppm) : y_top + int(0.15 * ppm) + sign_h, sx : sx + sign_w] = (
        sign_texture(rng, sign_w, sign_h)
    )
    return wid, (sx, sx + sign_w, y_top + int(0.15 * ppm))


def facade_texture(
    seed: int,
    width_m: float,
    height_m: float,
    floor_h: float,
    style: str,
    shopfront: bool,
    texel: float = TEXEL_M,
    snow: int = 0,
    snow_pattern: int = 0,
    *,
    tenant: int | None = None,
    repaint: int | None = None,
) -> np.ndarray:
    """Street-facing facade of one building.

    Args:
      seed: per-building seed.
      width_m, height_m: facade size in metres.
      floor_h: storey height in metres.
      style: ``"brick"``, ``"plaster"``, ``"siding"`` or ``"concrete"``.
      shopfront: a shop window with a sign on the ground floor (urban) instead of a door
        and windows (residential).
      texel: metres per texel.
      snow: snow level 0..4: snow lies on the horizontal ledges (window sills and lintels,
        string courses, the cornice, sign and air-conditioner tops), ``_ledge_snow``.
      snow_pattern: id of the snow pack (``conditions.snow_state``): which stretches of the
        ledges hold snow.
      tenant: with a shop front, the n-th tenant after the one the world was built with
        (``slow_changes``): their shop windows, door and sign, drawn from (seed, n); None
        (the default) draws the first tenant's alone, exactly as before.
      repaint: the n-th repaint since the world was built: walls (but bare brick) and
        trims in the colours ``repaint_colours(seed, n)``; None keeps the first paint.

    Returns:
      RGBA uint8 whose aux channel holds 128 + a lighting rank (0..126) on glass, 0 on walls.
    """
    rng = np.random.default_rng(seed)
    paint = None if repaint is None else repaint_colours(seed, repaint)
    ledges: list[tuple[int, int, int]] = []  # (x0, x1, y): horizontal ledges, top at row y
    W, H = pad16(width_m / texel), pad16(height_m / texel)
    ppm = W / width_m
    rgb = _wall(
        style,
        H,
        W,
        rng,
        (height_m / H, 1.0 / ppm),
        photo_seed=seed,
        paint=None if paint is None else paint[0],
    )
    aux = np.zeros((H, W), np.uint8)
    frame_col = (
        np.float32([0.92, 0.91, 0.88]) if rng.random() < 0.5 else rand_colour(rng, 0.3) * 0.7
    )
    if paint is not None:  # a repaint does the trim too (drawn above all the same)
        frame_col = paint[1]
    n_floors = max(1, int(height_m / floor_h))
    win_w = rng.uniform(0.8, 1.4)
    win_h = rng.uniform(1.2, 1.7) if style != "siding" else rng.uniform(1.0, 1.4)
    bay = win_w + rng.uniform(0.8, 2.0)
    n_cols = max(1, int((width_m - 0.6) / bay))
    margin = (width_m - n_cols * bay) / 2
    wid = 1
    start_floor = 0
    if shopfront:
        start_floor = 1
        y_top = H - int(min(floor_h, height_m) * ppm)
        wall = rgb[y_top:].copy() if tenant is not None else None
        first_wid = wid
        wid, sign_ledge = _shopfront(rgb, aux, rng, y_top, ppm, width_m, wid)
        if tenant is not None:
            # A later tenant: the ground floor's bare wall, then their own shop front, from
            # a stream of their own (the first tenant's draws above keep ``rng`` in step).
            rgb[y_top:], aux[y_top:] = wall, 0
            tenant_rng = np.random.default_rng([int(seed), _TENANT_STREAM, int(tenant)])
            _, sign_ledge = _shopfront(rgb, aux, tenant_rng, y_top, ppm, width_m, first_wid)
        ledges.append(sign_ledge)
    else:
        door_w, door_h = int(1.0 * ppm), int(2.2 * ppm)
        dx = int(rng.uniform(0.4, max(0.41, width_m - 1.5)) * ppm)
        rgb[H - door_h : H, dx : dx + door_w] = rand_colour(rng, 0.5) * 0.7
        rgb[H - door_h + 10 : H - 10, dx + 8 : dx + door_w - 8] *= 0.75
        rgb[H - door_h - 6 : H - door_h, dx - 6 : dx + door_w + 6] = frame_col * 0.8
        cv2.circle(rgb, (dx + door_w - 12, H - door_h // 2), 3, (0.8, 0.7, 0.3), -1)
    for f in range(start_floor, n_floors):
        y_floor_bottom = H - int(f * floor_h * ppm)
        y0 = y_floor_bottom - int((0.9 + win_h) * ppm)
        if y0 < int(0.3 * ppm):
            break
        for c in range(n_cols):
            if (
                f == 0
                and not shopfront
                and abs((margin + c * bay + bay / 2) * ppm - (dx + door_w / 2)) < bay * ppm * 0.6
            ):
                continue
            x0 = int((margin + c * bay + (bay - win_w) / 2) * ppm)
            _window(
                rgb,
                aux,
                x0,
                y0,
                int(win_w * ppm),
                int(win_h * ppm),
                (wid - 1) % 255 + 1,
                rng,
                frame_col,
            )
            fw = max(2, int(0.05 * int(win_w * ppm)))
            x1 = x0 + int(win_w * ppm)
            ledges += [(x0 - fw, x1 + fw, y0 + int(win_h * ppm)), (x0 - fw, x1 + fw, y0 - fw)]
            wid += 1
            if rng.random() < 0.06:  # an air conditioner under some windows
                ax0, ay0 = x0 + int(0.1 * ppm), y0 + int(win_h * ppm) + 6
                ledges.append((ax0, ax0 + int(0.6 * ppm), ay0))
                rgb[ay0 : ay0 + int(0.4 * ppm), ax0 : ax0 + int(0.6 * ppm)] = np.float32(
                    [0.75, 0.75, 0.72]
                )
                rgb[ay0 + 4 : ay0 + int(0.4 * ppm) - 4 : 3, ax0 + 4 : ax0 + int(0.6 * ppm) - 4] *= (
                    0.6
                )
        if f > start_floor and rng.random() < 0.5:  # string course between floors
            yb = y_floor_bottom - 4
            rgb[yb : yb + 6] = rgb[yb : yb + 6] * 0.7 + frame_col * 0.3
            ledges.append((0, W, yb))
    # Cornice at the top and a drain pipe.
    ch = int(rng.uniform(0.2, 0.6) * ppm)
    rgb[:ch] = rgb[:ch] * 0.5 + frame_col * 0.4
    rgb[ch : ch + 3] *= 0.55
    ledges.append((0, W, ch))
    if rng.random() < 0.6:
        px = int(rng.choice([0.15, width_m - 0.25]) * ppm)
        rgb[:, px : px + 4] = np.float32([0.35, 0.36, 0.36])
    if rng.random() < 0.35:  # graffiti-ish tag or posters near the ground
        for _ in range(rng.integers(1, 4)):
            pw, ph = int(rng.uniform(0.4, 0.8) * ppm), int(rng.uniform(0.5, 1.0) * ppm)
            px, py = int(rng.uniform(0, width_m - 0.8) * ppm), H - int(rng.uniform(1.0, 2.2) * ppm)
            if py + ph < H and px + pw < W and aux[py : py + ph, px : px + pw].max() == 0:
                rgb[py : py + ph, px : px + pw] = sign_texture(rng, pw, ph)
    rgb = _ledge_snow(rgb, ledges, snow, seed, snow_pattern, texel)
    return finish(rgb, aux, blur=0.7)


# Snow on a ledge: depth (m) and the share of the ledge's length covered, per level 1..4.
LEDGE_SNOW = {1: (0.03, 0.35), 2: (0.05, 0.6), 3: (0.08, 0.85), 4: (0.12, 1.0)}


def _ledge_snow(
    rgb: np.ndarray, ledges, snow: int, seed: int, pattern: int, texel: float
) -> np.ndarray:
    """Snow lying on a facade's horizontal ledges (Sec. IV-A-1: winter changes buildings too).

    Vertical walls hold no snow, but sills, lintels, string courses, cornices and sign tops
    do: a white band on top of each ledge, ``LEDGE_SNOW[level]`` deep, covering stretches
    drawn from ``(seed, pattern)`` (the same pack keeps its pattern; each new snowfall lays
    another), so window corners, where many interest points sit, change in winter.
    """
    if snow <= 0 or not ledges:
        return rgb
    depth_m, share = LEDGE_SNOW[int(min(snow, 4))]
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 78, int(pattern) & 0xFFFFFFFF])
    h, w = rgb.shape[:2]
    along = value_noise((1, w), rng, cell=max(2.0, 0.6 / texel), octaves=2)[0]
    covered = along < np.quantile(along, share) if share < 1.0 else np.ones(w, bool)
    depth = max(1, int(round(depth_m / texel)))
    white = np.float32([0.93, 0.94, 0.97])
    out = rgb.copy()
    for x0, x1, y in ledges:
        x0, x1 = max(0, int(x0)), min(w, int(x1))
        y0, y1 = max(0, int(y) - depth), min(h, int(y) + 1)
        if x1 <= x0 or y1 <= y0:
            continue
        cols = np.flatnonzero(covered[x0:x1]) + x0
        if cols.size:
            # A rounded drift: deepest mid-ledge, thinning towards the ends.
            t = (cols - x0) / max(1, x1 - x0 - 1)
            top = (
                y1
                - 1
                - np.round((y1 - y0 - 1) * np.sqrt(np.clip(4 * t * (1 - t), 0, 1))).astype(int)
            )
            rows = np.arange(y0, y1)[:, None]
            mask = rows >= top[None, :]
            region = out[y0:y1, cols]
            region[mask] = white * rng.uniform(0.9, 1.0)
            out[y0:y1, cols] = region
    return out


def side_wall_texture(
    seed: int, width_m: float, height_m: float, style: str, texel: float = 0.04, snow: int = 0
) -> np.ndarray:
    """A side (party) wall: the building's material with few, sparse windows."""
    del snow
    rng = np.random.default_rng(seed)
    W, H = pad16(width_m / texel), pad16(height_m / texel)
    rgb = _wall(style, H, W, rng, (height_m / H, width_m / W), photo_seed=seed)
    aux = np.zeros((H, W), np.uint8)
    ppm = W / width_m
    for k in range(int(rng.integers(0, 4))):
        x0 = int(rng.uniform(0.5, max(0.6, width_m - 1.5)) * ppm)
        y0 = int(rng.uniform(0.5, max(0.6, height_m - 2.5)) * ppm)
        _window(
            rgb,
            aux,
            x0,
            y0,
            int(0.8 * ppm),
            int(1.2 * ppm),
            200 + k,
            rng,
            np.float32([0.8, 0.8, 0.78]),
        )
    return finish(rgb, aux, blur=0.7)


def roof_texture(
    seed: int,
    width_m: float,
    depth_m: float,
    snow: int = 0,
    texel: float = 0.08,
    snow_pattern: int = 0,
) -> np.ndarray:
    """Flat roof (tar/gravel); aux = snow susceptibility (high everywhere).

    With the photos, the roof is gravel-ballasted (the gravel photograph: 20 mm stones,
    as the 16-32 mm ballast of flat roofs), under the same metre-scale weathering.
    """
    rng = np.random.default_rng(seed)
    W, H = pad16(width_m / texel), pad16(depth_m / texel)
    g = value_noise((H, W), rng, cell=8, octaves=3)[..., None]
    if pt.available():
        rgb = pt.gravel_tile(seed, H, W, (depth_m / H, width_m / W), [0.33, 0.32, 0.31]) * (
            0.8 + 0.4 * g
        )
    else:
        rgb = np.float32([0.33, 0.32, 0.31]) * (0.8 + 0.4 * g)
    aux = (200 + 55 * value_noise((H, W), rng, cell=10, octaves=2)).astype(np.uint8)
    rgb = apply_snow(rgb, aux, snow, seed, snow_pattern)
    return finish(rgb, aux, blur=0.6)


def apply_snow(rgb: np.ndarray, aux: np.ndarray, snow: int, seed: int, pattern: int) -> np.ndarray:
    """Covers texels whose susceptibility (aux) beats the snow level (0..4) with snow.

    The drift/melt pattern comes from ``(seed, pattern)``: one snow pack (``pattern``, the
    last snowfall) melts back through nested patterns as its level drops, and every new
    snowfall lays a different one.
    """
    if snow <= 0:
        return rgb
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 77, int(pattern) & 0xFFFFFFFF])
    h, w = aux.shape
    thr = {1: 215, 2: 170, 3: 110, 4: 45}[int(min(snow, 4))]
    patch = value_noise((h, w), rng, cell=24, octaves=3)
    cover = np.clip((aux.astype(np.float32) + 90 * (patch - 0.5) - thr) / 25.0, 0.0, 1.0)[..., None]
    snow_col = (
        np.float32([0.93, 0.94, 0.97])
        * (0.92 + 0.08 * value_noise((h, w), rng, cell=5, octaves=2))[..., None]
    )
    return rgb * (1 - cover) + snow_col * cover
