"""Procedural scenes around a trajectory: `room` (Vicon-room scale), `hall` (machine-hall scale), `lowtex` (the room's
geometry with uniform surfaces and strong straight structure) and `mixed` (textured and low-texture stretches
alternating along the path). Deterministic from the seed.

A scene is a list of textured quads (see linnet/sim/scene.h) plus its ground-truth geometry: the 3D line segments of
every physical straight edge (box / frame / panel / skirting / pipe edges, wall junctions, tile grout centre lines)
and the 3D corner points (box and frame vertices, wall corners, tile crossings), all in W.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from linnet.sim import textures as tx
from linnet.sim.trajectory import InputError

SCENES = ("room", "hall", "lowtex", "mixed")
CLEARANCE_M = 0.5          # minimum distance of every object from every camera centre (issue 3)
CLEARANCE_SAFETY_M = 0.15  # extra margin used when placing objects
_LIGHT = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])


@dataclass
class SceneSpec:
    name: str
    quads: list = field(default_factory=list)      # (origin, axis_u, axis_v, texture index, shade)
    textures: list = field(default_factory=list)   # uint8 arrays
    lines: list = field(default_factory=list)      # (p0 (3,), p1 (3,), kind)
    points: list = field(default_factory=list)     # (p (3,), kind)
    bounds: tuple = ()                             # (lo (3,), hi (3,)) of the enclosure
    dropped_objects: int = 0

    def to_native(self):
        from linnet._linnet import sim as native
        scene = native.Scene()
        for t in self.textures:
            scene.add_texture(t)
        for o, u, v, ti, shade in self.quads:
            scene.add_quad(o, u, v, ti, shade)
        return scene


def _shade(normal: np.ndarray) -> float:
    n = normal / np.linalg.norm(normal)
    return float(0.45 + 0.55 * abs(n @ _LIGHT))


class _Builder:
    def __init__(self, name: str, rng: np.random.Generator, path: np.ndarray, texel_m: float):
        self.spec = SceneSpec(name)
        self.rng, self.path, self.texel = rng, path, texel_m

    # --- primitives
    def texture(self, img: np.ndarray) -> int:
        self.spec.textures.append(img)
        return len(self.spec.textures) - 1

    def surface_texture(self, size_u: float, size_v: float, low: bool, grey: float) -> int:
        texel = tx.texel_size(size_u, size_v, self.texel)
        if low:
            return self.texture(tx.plain(size_u, size_v, texel, self.rng, grey))
        return self.texture(tx.collage(size_u, size_v, texel, self.rng, base=grey))

    def quad(self, o, u, v, tex: int, shade: float | None = None):
        o, u, v = (np.asarray(x, float) for x in (o, u, v))
        self.spec.quads.append((o, u, v, tex, _shade(np.cross(u, v)) if shade is None else shade))

    def line(self, a, b, kind: str):
        self.spec.lines.append((np.asarray(a, float), np.asarray(b, float), kind))

    def point(self, p, kind: str):
        self.spec.points.append((np.asarray(p, float), kind))

    def clear_of_path(self, lo: np.ndarray, hi: np.ndarray, frame: np.ndarray | None = None,
                      origin: np.ndarray | None = None) -> bool:
        """True if the box [lo, hi] (in a local frame: p_local = frame^T (p - origin)) keeps the clearance."""
        pts = self.path if frame is None else (self.path - origin) @ frame
        d = np.linalg.norm(np.maximum(0.0, np.maximum(lo - pts, pts - hi)), axis=1)
        return bool(d.min() >= CLEARANCE_M + CLEARANCE_SAFETY_M)

    def box(self, lo, hi, yaw: float, low: bool, grey: float, kind: str, textured_faces: bool = True,
            bottom: bool = False):
        """A box with extents hi - lo, rotated by yaw about the vertical through its corner lo."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        c, s = math.cos(yaw), math.sin(yaw)
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        size = hi - lo
        ex, ey, ez = Rz[:, 0] * size[0], Rz[:, 1] * size[1], Rz[:, 2] * size[2]
        o = lo
        faces = [(o, ey, ex), (o + ez, ex, ey),          # bottom (outward -z), top
                 (o, ex, ez), (o + ey, ez, ex),          # -y, +y
                 (o, ez, ey), (o + ex, ey, ez)]          # -x, +x
        for k, (fo, fu, fv) in enumerate(faces):
            if k == 0 and not bottom:
                continue
            su, sv = np.linalg.norm(fu), np.linalg.norm(fv)
            if low or not textured_faces:
                t = self.texture(tx.plain(su, sv, self.texel, self.rng, grey, variation=3.0))
            else:
                t = self.surface_texture(su, sv, False, grey)
            self.quad(fo, fu, fv, t)
        corners = [o + i * ex + j * ey + k * ez for i in (0, 1) for j in (0, 1) for k in (0, 1)]
        for a in range(8):
            for b in range(a + 1, 8):
                if bin(a ^ b).count("1") == 1:
                    self.line(corners[a], corners[b], kind)
        for p in corners:
            self.point(p, kind)


def _wall_frames(lo, hi):
    """The four walls as (origin, along, up, inward normal, length)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    h = z1 - z0
    return [
        (np.array([x0, y0, z0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, 1.0, 0]), x1 - x0, h),
        (np.array([x1, y0, z0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]), np.array([-1.0, 0, 0]), y1 - y0, h),
        (np.array([x1, y1, z0]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, -1.0, 0]), x1 - x0, h),
        (np.array([x0, y1, z0]), np.array([0, -1.0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), y1 - y0, h),
    ]


def _panels(length: float, max_size: float) -> list[tuple[float, float]]:
    n = max(1, int(math.ceil(length / max_size)))
    return [(k * length / n, length / n) for k in range(n)]


def build_scene(name: str, path_points: np.ndarray, seed: int) -> SceneSpec:
    """Builds scene `name` enclosing `path_points` ((N, 3) camera centres and body positions along the path)."""
    if name not in SCENES:
        raise InputError(f"unknown scene '{name}' (known: {', '.join(SCENES)})")
    rng = np.random.default_rng([seed, SCENES.index(name)])
    hall = name == "hall"
    texel = 0.008 if hall else 0.004
    b = _Builder(name, rng, path_points, texel)
    plo, phi = path_points.min(axis=0), path_points.max(axis=0)
    margin = 4.0 if hall else 1.8
    min_size = np.array([20.0, 14.0]) if hall else np.array([6.0, 5.0])
    centre = 0.5 * (plo[:2] + phi[:2])
    half = np.maximum(0.5 * (phi[:2] - plo[:2]) + margin, 0.5 * min_size)
    z0 = min(0.0, plo[2] - 0.6)
    z1 = max(phi[2] + (4.0 if hall else 1.0), z0 + (9.0 if hall else 3.0))
    lo, hi = np.array([*(centre - half), z0]), np.array([*(centre + half), z1])
    b.spec.bounds = (lo, hi)
    # Which places are low-texture: everywhere (lowtex), nowhere (room, hall), or alternating bands (mixed).
    axis = int(np.argmax(phi[:2] - plo[:2]))
    band = 2.5

    def is_low(p) -> bool:
        if name == "lowtex":
            return True
        if name == "mixed":
            return int(math.floor((p[axis] - lo[axis]) / band)) % 2 == 1
        return False

    panel = 6.0 if hall else 3.0
    greys = rng.uniform(90, 170, 6)
    # --- walls (split into panels, each its own texture), wall junction lines and corners
    for wi, (o, along, up, inward, length, height) in enumerate(_wall_frames(lo, hi)):
        for s0, ds in _panels(length, panel):
            for h0, dh in _panels(height, panel):
                po = o + along * s0 + up * h0
                low = is_low(po + along * ds / 2)
                t = b.surface_texture(ds, dh, low, greys[wi])
                b.quad(po, along * ds, up * dh, t)
        b.line(o, o + up * height, "wall_corner")  # (the wall-floor junction is hidden by the skirting board)
        b.line(o + up * height, o + up * height + along * length, "wall_ceiling")
        b.point(o, "room_corner")
        b.point(o + up * height, "room_corner")
    # --- floor and ceiling panels (tiles with grout lines where low-texture)
    for zc, grey, tile, kind in ((z0, greys[4], 0.6, "floor_tile"), (z1, greys[5], 1.2, "ceiling_tile")):
        for x0, dx in _panels(hi[0] - lo[0], panel):
            for y0, dy in _panels(hi[1] - lo[1], panel):
                po = np.array([lo[0] + x0, lo[1] + y0, zc])
                low = is_low(po + np.array([dx / 2, dy / 2, 0]))
                if low:
                    img, grout = tx.tiles(dx, dy, tx.texel_size(dx, dy, texel), rng, grey, tile,
                                          offset_u=-(po[0] - lo[0]), offset_v=-(po[1] - lo[1]))
                    t = b.texture(img)
                    for ax, c in grout:
                        if ax == "u":
                            b.line(po + [c, 0, 0], po + [c, dy, 0], kind)
                        else:
                            b.line(po + [0, c, 0], po + [dx, c, 0], kind)
                    us = [c for ax, c in grout if ax == "u"]
                    vs = [c for ax, c in grout if ax == "v"]
                    for cu in us:
                        for cv in vs:
                            b.point(po + [cu, cv, 0], kind)
                else:
                    t = b.surface_texture(dx, dy, False, grey)
                b.quad(po, [dx, 0, 0], [0, dy, 0], t)
    _add_wall_structure(b, lo, hi, is_low, hall)
    _add_objects(b, lo, hi, is_low, hall)
    return b.spec


def _add_wall_structure(b: _Builder, lo, hi, is_low, hall: bool):
    """Skirting boards, doors, window frames, panels, pipes and posters on the walls."""
    rng = b.rng
    for o, along, up, inward, length, height in _wall_frames(lo, hi):
        # Skirting: a 10 cm high, 1.5 cm deep strip along the bottom of the wall.
        so = o + inward * 0.015
        t = b.texture(tx.plain(length, 0.1, 0.05, rng, 210.0, 2.0))
        b.quad(so, along * length, up * 0.1, t)
        t2 = b.texture(tx.plain(length, 0.015, 0.05, rng, 230.0, 2.0))
        b.quad(so + up * 0.1, -inward * 0.015, along * length, t2)
        b.line(so + up * 0.1, so + up * 0.1 + along * length, "skirting")
        b.line(so, so + along * length, "skirting")
        b.line(o + up * 0.1, o + up * 0.1 + along * length, "skirting")
        # Items along the wall, left to right, without overlaps.
        s = rng.uniform(0.3, 1.0)
        while s < length - 1.0:
            kind = rng.choice(["door", "window", "panel", "poster"], p=[0.2, 0.25, 0.3, 0.25])
            w = {"door": 0.9, "window": rng.uniform(1.0, 1.8), "panel": rng.uniform(0.6, 1.4),
                 "poster": rng.uniform(0.5, 1.1)}[kind]
            if s + w > length - 0.3:
                break
            bottom = {"door": 0.0, "window": 0.9, "panel": rng.uniform(0.5, 1.0),
                      "poster": rng.uniform(1.0, 1.5)}[kind]
            top = {"door": 2.05, "window": min(height - 0.3, 2.2), "panel": rng.uniform(1.6, 2.2),
                   "poster": bottom + w * rng.uniform(0.7, 1.4)}[kind]
            top = min(top, height - 0.2)
            base = o + along * s + up * bottom
            low = is_low(base)
            if kind == "poster":
                depth = 0.01
                img = tx.collage(w, top - bottom, tx.texel_size(w, top - bottom, 0.003), rng, density=60.0,
                                 min_size_m=0.015, max_size_m=0.3, base=rng.uniform(60, 200)) if not low else \
                    tx.plain(w, top - bottom, 0.05, rng, rng.uniform(30, 230), 2.0)
                b.quad(base + inward * depth, along * w, up * (top - bottom), b.texture(img))
                _rect_outline(b, base + inward * depth, along * w, up * (top - bottom), "poster")
            else:
                # A recessed or raised panel (door leaf, window pane, wall panel) framed by 5 cm x 3 cm bars.
                pane_grey = {"door": rng.uniform(40, 90), "window": rng.uniform(170, 235),
                             "panel": rng.uniform(60, 200)}[kind]
                pane = b.texture(tx.plain(w, top - bottom, 0.05, rng, pane_grey, 3.0))
                b.quad(base + inward * 0.005, along * w, up * (top - bottom), pane)
                _rect_outline(b, base + inward * 0.005, along * w, up * (top - bottom), kind)
                frame_grey = rng.uniform(150, 240) if kind != "panel" else pane_grey * 0.7
                bar = 0.05
                bars = [(-bar, 0.0, 0.0, top - bottom + bar),          # left bar
                        (w, w + bar, 0.0, top - bottom + bar),          # right bar
                        (-bar, w + bar, top - bottom, top - bottom + bar)]  # top bar
                if kind != "door":
                    bars.append((-bar, w + bar, -bar, 0.0))             # sill
                for u0, u1, v0, v1 in bars:
                    _wall_box(b, o, along, up, inward, s + u0, s + u1, bottom + v0, bottom + v1, 0.03,
                              frame_grey, kind + "_frame")
            s += w + rng.uniform(0.4, 1.5)
        # A pipe along the wall under the ceiling (hall and low-texture walls).
        if hall or is_low(o + along * length / 2):
            zp = height - rng.uniform(0.3, 0.6)
            _wall_box(b, o, along, up, inward, 0.0, length, zp, zp + 0.08, 0.1, rng.uniform(80, 200), "pipe",
                      offset=0.05)


def _rect_outline(b: _Builder, o, u, v, kind: str):
    c = [o, o + u, o + u + v, o + v]
    for k in range(4):
        b.line(c[k], c[(k + 1) % 4], kind)
        b.point(c[k], kind)


def _wall_box(b: _Builder, o, along, up, inward, s0, s1, h0, h1, depth, grey, kind, offset=0.0):
    """A bar of the wall: [s0, s1] along, [h0, h1] up, from offset to offset + depth out of the wall."""
    base = o + along * s0 + up * h0 + inward * offset
    ex, ey, ez = along * (s1 - s0), up * (h1 - h0), inward * depth
    faces = [(base + ez, ex, ey), (base, ez, ex), (base + ey, ex, ez), (base, ey, ez),
             (base + ex, ez, ey)]
    for fo, fu, fv in faces:
        su, sv = np.linalg.norm(fu), np.linalg.norm(fv)
        b.quad(fo, fu, fv, b.texture(tx.plain(su, sv, 0.05, b.rng, grey, 2.0)))
    corners = [base + i * ex + j * ey + k * ez for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    for a in range(8):
        for c in range(a + 1, 8):
            if bin(a ^ c).count("1") == 1:
                b.line(corners[a], corners[c], kind)
    for p in corners:
        b.point(p, kind)


def _add_objects(b: _Builder, lo, hi, is_low, hall: bool):
    """Boxes, shelves and (hall) pillars and machines on the floor, each kept clear of the path or dropped."""
    rng = b.rng
    area = (hi[0] - lo[0]) * (hi[1] - lo[1])
    n_boxes = int(area / (12.0 if hall else 4.0))
    for _ in range(n_boxes):
        placed = False
        for _try in range(25):
            if hall:
                size = np.array([rng.uniform(0.8, 3.0), rng.uniform(0.8, 3.0), rng.uniform(0.6, 3.5)])
            else:
                size = np.array([rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.4)])
            yaw = rng.uniform(0, math.pi / 2)
            pos = np.array([rng.uniform(lo[0] + 0.2, hi[0] - 0.2 - size[0]),
                            rng.uniform(lo[1] + 0.2, hi[1] - 0.2 - size[1]), lo[2]])
            c, s = math.cos(yaw), math.sin(yaw)
            Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            corners = pos + (np.array([[i, j, 0] for i in (0, 1) for j in (0, 1)]) * size) @ Rz.T
            if corners[:, 0].min() < lo[0] + 0.05 or corners[:, 0].max() > hi[0] - 0.05 or \
                    corners[:, 1].min() < lo[1] + 0.05 or corners[:, 1].max() > hi[1] - 0.05:
                continue
            if not b.clear_of_path(np.zeros(3), size, frame=Rz, origin=pos):
                continue
            b.box(pos, pos + size, yaw, is_low(pos), rng.uniform(50, 210), "box")
            placed = True
            break
        b.spec.dropped_objects += 0 if placed else 1
    if hall:  # pillars from floor to ceiling
        for _ in range(int(area / 60.0)):
            for _try in range(25):
                w = rng.uniform(0.4, 0.8)
                pos = np.array([rng.uniform(lo[0] + 1, hi[0] - 1 - w), rng.uniform(lo[1] + 1, hi[1] - 1 - w), lo[2]])
                size = np.array([w, w, hi[2] - lo[2]])
                if b.clear_of_path(np.zeros(3), size, frame=np.eye(3), origin=pos):
                    b.box(pos, pos + size, 0.0, is_low(pos), rng.uniform(120, 220), "pillar")
                    break
