"""Procedural grey-level textures, deterministic from a numpy Generator.

* `collage`: multi-octave value noise plus a collage of random rectangles, ellipses, triangles and lines of random grey
  levels at sizes from ~2 cm to ~60 cm: corners at every scale for FAST / KLT, and no repeating tile (each texture is
  drawn afresh), so matching is never ambiguous by construction.
* `plain`: a uniform grey with a faint large-scale shading gradient: the low-texture surfaces of `lowtex`.
* `tiles`: plain plus dark grout lines on a square grid (floor / ceiling tiles of `lowtex`).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

MAX_TEXELS = 2048  # per side


def texel_size(size_u: float, size_v: float, base_texel_m: float) -> float:
    return max(base_texel_m, max(size_u, size_v) / MAX_TEXELS)


def _dims(size_u: float, size_v: float, texel_m: float) -> tuple[int, int]:
    return max(2, int(round(size_u / texel_m))), max(2, int(round(size_v / texel_m)))


def value_noise(w: int, h: int, rng: np.random.Generator, cell_texels: float, octaves: int) -> np.ndarray:
    """Sum of smooth random fields, each octave twice as fine and half as strong; zero mean, roughly unit range."""
    out = np.zeros((h, w), np.float32)
    amp, cell, total = 1.0, cell_texels, 0.0
    for _ in range(octaves):
        gw, gh = max(2, int(math.ceil(w / cell)) + 1), max(2, int(math.ceil(h / cell)) + 1)
        grid = rng.random((gh, gw), dtype=np.float32) - 0.5
        out += amp * cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)
        total += amp
        amp *= 0.5
        cell = max(2.0, cell / 2.0)
    return out / total


def collage(size_u: float, size_v: float, texel_m: float, rng: np.random.Generator, density: float = 30.0,
            min_size_m: float = 0.02, max_size_m: float = 0.6, base: float = 128.0) -> np.ndarray:
    """Textured surface of size_u x size_v metres. `density`: shapes per square metre."""
    w, h = _dims(size_u, size_v, texel_m)
    img = base + 60.0 * value_noise(w, h, rng, cell_texels=0.5 / texel_m, octaves=4)
    canvas = np.clip(img, 0, 255).astype(np.uint8)
    n = int(round(density * size_u * size_v))
    lo, hi = math.log(min_size_m / texel_m), math.log(max_size_m / texel_m)
    kinds = rng.integers(0, 4, n)
    sizes = np.exp(rng.uniform(lo, hi, (n, 2)))
    centres = rng.uniform(0, 1, (n, 2)) * [w, h]
    greys = rng.integers(15, 241, n)
    angles = rng.uniform(0, 180, n)
    for k in range(n):
        cx, cy = centres[k]
        sx, sy = sizes[k]
        g = int(greys[k])
        if kinds[k] == 0:  # rotated rectangle
            box = cv2.boxPoints(((float(cx), float(cy)), (float(sx), float(sy)), float(angles[k])))
            cv2.fillPoly(canvas, [np.round(box * 16).astype(np.int32)], g, cv2.LINE_AA, shift=4)
        elif kinds[k] == 1:  # ellipse
            cv2.ellipse(canvas, (int(cx * 16), int(cy * 16)), (int(sx * 8), int(sy * 8)), float(angles[k]), 0, 360,
                        g, -1, cv2.LINE_AA, shift=4)
        elif kinds[k] == 2:  # triangle
            pts = np.array([[cx, cy], [cx + sx, cy + 0.3 * sy], [cx + 0.2 * sx, cy + sy]])
            cv2.fillPoly(canvas, [np.round(pts * 16).astype(np.int32)], g, cv2.LINE_AA, shift=4)
        else:  # line of random thickness
            a = math.radians(angles[k])
            d = np.array([math.cos(a), math.sin(a)]) * sx
            p0, p1 = np.array([cx, cy]) - d / 2, np.array([cx, cy]) + d / 2
            thick = max(1, int(min(sy * 0.1, 0.03 / texel_m)))
            cv2.line(canvas, tuple(int(v) for v in np.round(p0 * 16)), tuple(int(v) for v in np.round(p1 * 16)), g,
                     thick, cv2.LINE_AA, shift=4)
    fine = 12.0 * value_noise(w, h, rng, cell_texels=4.0, octaves=2)
    return np.clip(canvas.astype(np.float32) + fine, 0, 255).astype(np.uint8)


def plain(size_u: float, size_v: float, texel_m: float, rng: np.random.Generator, grey: float,
          variation: float = 6.0) -> np.ndarray:
    """Uniform grey with a faint smooth variation (no corners)."""
    texel = max(texel_m, 0.05)  # plain surfaces need no fine texels
    w, h = _dims(size_u, size_v, texel)
    img = grey + variation * value_noise(w, h, rng, cell_texels=1.5 / texel, octaves=2)
    return np.clip(img, 0, 255).astype(np.uint8)


def tiles(size_u: float, size_v: float, texel_m: float, rng: np.random.Generator, grey: float, tile_m: float,
          offset_u: float, offset_v: float, grout_m: float = 0.01, grout_grey: float = 60.0
          ) -> tuple[np.ndarray, list[tuple[str, float]]]:
    """Tiles with grout lines every tile_m metres, at positions offset_u + k tile_m along u (and likewise v) measured
    from the texture origin. Returns the texture and the grout centre lines as ("u" | "v", coordinate in m)."""
    w, h = _dims(size_u, size_v, texel_m)
    img = grey + 4.0 * value_noise(w, h, rng, cell_texels=1.0 / texel_m, octaves=2)
    canvas = np.clip(img, 0, 255).astype(np.uint8)
    lines = []
    half = grout_m / 2.0
    # Texel k covers [k, k+1) / scale metres; OpenCV puts texel centres at integer coordinates, hence the -0.5.
    for axis, size, off, scale in (("u", size_u, offset_u, w / size_u), ("v", size_v, offset_v, h / size_v)):
        c = off % tile_m
        while c < size:
            if half < c < size - half:
                lines.append((axis, c))
                a, b = (c - half) * scale - 0.5, (c + half) * scale - 0.5
                if axis == "u":
                    pts = np.array([[a, -1], [b, -1], [b, h], [a, h]])
                else:
                    pts = np.array([[-1, a], [w, a], [w, b], [-1, b]])
                cv2.fillPoly(canvas, [np.round(pts * 16).astype(np.int32)], int(grout_grey), cv2.LINE_AA, shift=4)
            c += tile_m
    return canvas, lines
