"""A random room (z up, metres) with furniture, area lights, a door and a window, and a glass display case resting
on the floor or on furniture. Produces a :class:`RoomScene`: named meshes with materials, lights, the case.

Recipe of the paper's 3D-FRONT-T (supplement A), re-made procedurally: 2-5 furniture pieces built from boxes; a case
of six thin glass panels (IOR 1.5) with a black metal frame along its 12 edges, enclosing 1-3 opaque objects,
dropped from a random position until it rests on a support, never intersecting anything.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from glint_mi.dataset.geometry import Mesh, box, cylinder, quad, sphere, wall_with_openings


@dataclasses.dataclass
class Material:
    kind: str                 # textured | color | glass | frame | emitter
    rgb: tuple = (0.5, 0.5, 0.5)
    texture: str | None = None  # key of RoomScene.textures
    radiance: float = 0.0


@dataclasses.dataclass
class Part:
    name: str
    mesh: Mesh
    material: Material
    aabb: tuple | None = None  # (lo, hi) for boxes: used by placement and support tests
    glass: bool = False


@dataclasses.dataclass
class RoomScene:
    size: np.ndarray                              # [3] room extent (x, y, z); the room spans [0, size]
    parts: list[Part]
    textures: dict[str, np.ndarray]               # name -> [H, W, 3] uint8
    case_lo: np.ndarray
    case_hi: np.ndarray
    support: str                                  # what the case rests on
    door: tuple                                   # wall, (a0, a1, b0, b1)
    window: tuple
    sky: float = 1.0                              # constant environment radiance seen through the openings

    @property
    def case_center(self) -> np.ndarray:
        return 0.5 * (self.case_lo + self.case_hi)

    def boxes(self, include_case=False):
        return [(p.aabb[0], p.aabb[1], p.name) for p in self.parts if p.aabb is not None
                and (include_case or not p.name.startswith("case"))]


# ---------------------------------------------------------------- textures
def natural_images() -> list[np.ndarray]:
    """Natural RGB images bundled with scikit-image (no download): non-repeating texture sources."""
    from skimage import data

    out = []
    for name in ("astronaut", "coffee", "chelsea", "rocket", "immunohistochemistry", "hubble_deep_field", "camera",
                 "moon", "brick", "grass", "gravel", "page", "text", "coins", "clock"):
        try:
            img = getattr(data, name)()
        except Exception:  # an image that would need a download on this version
            continue
        img = np.asarray(img)
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=2)
        out.append(np.ascontiguousarray(img[..., :3]).astype(np.uint8))
    if len(out) < 4:
        raise RuntimeError("scikit-image's bundled sample images are missing; reinstall scikit-image.")
    return out


def make_texture(rng, sources, size=256, tint=None) -> np.ndarray:
    """A random crop (random size, flip, rotation, colour tint) of a natural image: unique per surface."""
    from skimage.transform import resize

    img = sources[rng.integers(len(sources))]
    h, w = img.shape[:2]
    s = int(rng.uniform(0.35, 0.9) * min(h, w))
    y, x = rng.integers(0, h - s + 1), rng.integers(0, w - s + 1)
    crop = img[y:y + s, x:x + s]
    crop = np.rot90(crop, rng.integers(4))
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    out = resize(crop, (size, size, 3), anti_aliasing=True)
    tint = rng.uniform(0.5, 1.0, 3) if tint is None else np.asarray(tint)
    out = 0.15 + 0.7 * out * tint  # keep albedos in [0.15, 0.85]
    return np.clip(out * 255, 0, 255).astype(np.uint8)


# ---------------------------------------------------------------- furniture
def _table(lo, size, rng):
    (x, y, z), (w, d, h) = lo, size
    t = 0.04
    parts = [("top", (x, y, z + h - t), (x + w, y + d, z + h))]
    for i, (a, b) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
        lx, ly = x + a * (w - 0.05), y + b * (d - 0.05)
        parts.append((f"leg{i}", (lx, ly, z), (lx + 0.05, ly + 0.05, z + h - t)))
    return parts


def _cabinet(lo, size, rng):
    (x, y, z), (w, d, h) = lo, size
    return [("body", (x, y, z), (x + w, y + d, z + h))]


def _shelf(lo, size, rng):
    (x, y, z), (w, d, h) = lo, size
    t = 0.03
    parts = [("side0", (x, y, z), (x + t, y + d, z + h)), ("side1", (x + w - t, y, z), (x + w, y + d, z + h))]
    n = int(rng.integers(3, 5))
    for i in range(n + 1):
        bz = z + i * (h - t) / n
        parts.append((f"board{i}", (x + t, y, bz), (x + w - t, y + d, bz + t)))
    return parts


def _sofa(lo, size, rng):
    (x, y, z), (w, d, h) = lo, size
    return [("base", (x, y, z), (x + w, y + d, z + 0.42)), ("back", (x, y + d - 0.2, z + 0.42), (x + w, y + d, z + h)),
            ("arm0", (x, y, z + 0.42), (x + 0.15, y + d - 0.2, z + 0.62)),
            ("arm1", (x + w - 0.15, y, z + 0.42), (x + w, y + d - 0.2, z + 0.62))]


FURNITURE = {  # name: (builder, (w range), (d range), (h range))
    "table": (_table, (0.8, 1.4), (0.6, 0.9), (0.7, 0.8)),
    "cabinet": (_cabinet, (0.6, 1.2), (0.45, 0.6), (0.75, 1.0)),
    "shelf": (_shelf, (0.8, 1.2), (0.3, 0.4), (1.4, 1.9)),
    "sofa": (_sofa, (1.6, 2.2), (0.8, 0.95), (0.8, 0.9)),
}


def _overlap(lo1, hi1, lo2, hi2, margin=0.0, dims=3):
    """Open-interval AABB overlap on the first ``dims`` axes; ``margin`` scalar or per axis."""
    m = np.broadcast_to(np.asarray(margin, float), (3,))
    return all(lo1[i] < hi2[i] + m[i] and lo2[i] < hi1[i] + m[i] for i in range(dims))


# ------------------------------------------------------------------ builder
def build_room(seed: int, glass: bool = True) -> RoomScene:
    """A random room with furniture, lights, openings and a glass case resting on a support.

    ``glass=False`` builds the same room (same random draws) with the case's six glass panels left out: its frame
    and objects stay, so a room with and one without glass differ only by the glass (the components comparison)."""
    rng = np.random.default_rng(seed)
    sources = natural_images()
    textures: dict[str, np.ndarray] = {}

    def tex(name, tint=None):
        textures[name] = make_texture(rng, sources, 512 if name.startswith(("wall", "floor", "ceiling")) else 256, tint)
        return Material("textured", texture=name)

    W, D, H = rng.uniform(4.0, 6.0), rng.uniform(4.0, 6.0), rng.uniform(2.6, 3.0)
    size = np.array([W, D, H])
    parts: list[Part] = []
    # walls: 0 = y=0 (front), 1 = x=W (right), 2 = y=D (back), 3 = x=0 (left); openings on two different walls
    door_wall, window_wall = rng.choice(4, 2, replace=False)
    walls = {0: ((0, 0, 0), (W, 0, 0), (0, 0, H)), 1: ((W, 0, 0), (0, D, 0), (0, 0, H)),
             2: ((W, D, 0), (-W, 0, 0), (0, 0, H)), 3: ((0, D, 0), (0, -D, 0), (0, 0, H))}
    length = {0: W, 1: D, 2: W, 3: D}
    da = rng.uniform(0.15, 0.85 - 0.9 / length[door_wall])
    door = (int(door_wall), (da, da + 0.9 / length[door_wall], 0.0, 2.05 / H))
    wa = rng.uniform(0.15, 0.85 - 1.2 / length[window_wall])
    window = (int(window_wall), (wa, wa + 1.2 / length[window_wall], 0.9 / H, 2.1 / H))
    for k, (o, u, v) in walls.items():
        holes = [h for wall, h in (door, window) if wall == k]
        parts.append(Part(f"wall{k}", wall_with_openings(o, u, v, holes), tex(f"wall{k}", rng.uniform(0.7, 1.0, 3))))
    parts.append(Part("floor", quad((0, 0, 0), (W, 0, 0), (0, D, 0)), tex("floor")))
    parts.append(Part("ceiling", quad((0, 0, H), (0, D, 0), (W, 0, 0)), Material("color", rgb=(0.8, 0.8, 0.78))))
    # lights: one large diffuse panel just below the ceiling, facing down (large sources keep the path-traced
    # ground truth's variance low); the exposure is normalised later (generate.auto_exposure)
    lw, ld = rng.uniform(0.45, 0.7) * W, rng.uniform(0.45, 0.7) * D
    cx, cy = rng.uniform(lw / 2 + 0.2, W - lw / 2 - 0.2), rng.uniform(ld / 2 + 0.2, D - ld / 2 - 0.2)
    parts.append(Part("light0", quad((cx - lw / 2, cy - ld / 2, H - 0.01), (0, ld, 0), (lw, 0, 0)),
                      Material("emitter", radiance=float(rng.uniform(2.0, 4.0)))))

    # furniture along the walls, not overlapping each other nor the door's swing area
    occupied = []
    dw, (a0, a1, _, _) = door
    door_pts = [np.array(walls[dw][0]) + t * np.array(walls[dw][1]) for t in (a0, a1)]
    door_lo = np.minimum(*door_pts) - [0.9, 0.9, 0]
    door_hi = np.maximum(*door_pts) + [0.9, 0.9, 2.1]
    n_furn = int(rng.integers(2, 6))
    kinds = list(FURNITURE)
    for i in range(n_furn):
        for _ in range(100):
            kind = kinds[rng.integers(len(kinds))]
            build, wr, dr_, hr = FURNITURE[kind]
            w, d, h = rng.uniform(*wr), rng.uniform(*dr_), rng.uniform(*hr)
            side = rng.integers(4)
            if side in (1, 3):
                w, d = d, w
            x = {0: rng.uniform(0.05, W - w - 0.05), 1: W - w - 0.02, 2: rng.uniform(0.05, W - w - 0.05), 3: 0.02}[side]
            y = {0: 0.02, 1: rng.uniform(0.05, D - d - 0.05), 2: D - d - 0.02, 3: rng.uniform(0.05, D - d - 0.05)}[side]
            lo, hi = np.array([x, y, 0.0]), np.array([x + w, y + d, h])
            if any(_overlap(lo, hi, l2, h2, 0.15, 2) for l2, h2 in occupied) or _overlap(lo, hi, door_lo, door_hi, 0, 2):
                continue
            occupied.append((lo, hi))
            mat = tex(f"{kind}{i}")
            for pname, plo, phi in build(lo, (w, d, h), rng):
                parts.append(Part(f"{kind}{i}_{pname}", box(plo, phi), mat, aabb=(np.array(plo), np.array(phi))))
            break

    # the glass case: dropped at random until it rests fully on one support, intersecting nothing
    cw, cd, ch = rng.uniform(0.4, 0.9), rng.uniform(0.35, 0.7), rng.uniform(0.35, 0.7)
    boxes = [(p.aabb[0], p.aabb[1], p.name) for p in parts if p.aabb is not None]
    on_furniture = rng.random() < 0.5
    for attempt in range(2000):
        tops = [(lo, hi) for lo, hi, _ in boxes if hi[2] < 1.3 and hi[0] - lo[0] > cw + 0.04 and hi[1] - lo[1] > cd + 0.04]
        if on_furniture and tops and attempt < 1000:  # aim above a furniture top; the drop decides where it rests
            tlo, thi = tops[rng.integers(len(tops))]
            x, y = rng.uniform(tlo[0] + 0.02, thi[0] - cw - 0.02), rng.uniform(tlo[1] + 0.02, thi[1] - cd - 0.02)
        else:
            x, y = rng.uniform(0.3, W - cw - 0.3), rng.uniform(0.3, D - cd - 0.3)
        grid = np.stack(np.meshgrid(np.linspace(x + 0.01, x + cw - 0.01, 5), np.linspace(y + 0.01, y + cd - 0.01, 5)),
                        -1).reshape(-1, 2)
        heights, names = [], []
        for px, py in grid:  # vertical ray cast from the drop height onto box tops (and the floor)
            best, nm = 0.0, "floor"
            for lo, hi, name in boxes:
                if lo[0] <= px <= hi[0] and lo[1] <= py <= hi[1] and hi[2] <= 2.0 and hi[2] > best:
                    best, nm = hi[2], name
            heights.append(best)
            names.append(nm)
        z = max(heights)
        if max(heights) - min(heights) > 1e-3:
            continue  # partly over an edge: it would tip over
        lo, hi = np.array([x, y, z]), np.array([x + cw, y + cd, z + ch])
        if hi[2] > H - 0.3 or any(_overlap(lo + [0, 0, 1e-4], hi, l2, h2, (0.02, 0.02, 0.0)) for l2, h2, _ in boxes):
            continue
        if _overlap(lo, hi, door_lo, door_hi, 0, 2):
            continue
        support = names[0]
        break
    else:
        raise RuntimeError(f"seed {seed}: could not place the glass case (room too cluttered); try another seed.")
    parts += [p for p in _case_parts(lo, hi, rng, tex) if glass or not p.glass]
    return RoomScene(size, parts, textures, lo, hi, support, door, window, sky=float(rng.uniform(0.6, 1.2)))


def _case_parts(lo, hi, rng, tex) -> list[Part]:
    """Six thin-glass panels, a black frame of 12 bars along the edges, and 1-3 objects resting on the bottom."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    glass = Material("glass")
    L = hi - lo
    parts = [
        Part("case_glass_bottom", quad((x0, y0, z0 + 0.002), (L[0], 0, 0), (0, L[1], 0)), glass, glass=True),
        Part("case_glass_top", quad((x0, y0, z1), (L[0], 0, 0), (0, L[1], 0)), glass, glass=True),
        Part("case_glass_front", quad((x0, y0, z0), (L[0], 0, 0), (0, 0, L[2])), glass, glass=True),
        Part("case_glass_back", quad((x0, y1, z0), (L[0], 0, 0), (0, 0, L[2])), glass, glass=True),
        Part("case_glass_left", quad((x0, y0, z0), (0, L[1], 0), (0, 0, L[2])), glass, glass=True),
        Part("case_glass_right", quad((x1, y0, z0), (0, L[1], 0), (0, 0, L[2])), glass, glass=True),
    ]
    t = 0.012  # frame bar thickness
    frame = Material("frame", rgb=(0.02, 0.02, 0.02))
    bars = []
    for ax in range(3):
        others = [i for i in range(3) if i != ax]
        for a in (0, 1):
            for b in (0, 1):
                blo, bhi = lo.copy() - t / 2, hi.copy() + t / 2
                for o, s in zip(others, (a, b)):
                    c = lo[o] if s == 0 else hi[o]
                    blo[o], bhi[o] = c - t / 2, c + t / 2
                bars.append(box(blo, bhi))
    parts.append(Part("case_frame", Mesh.concatenate(bars), frame, aabb=(lo - t / 2, hi + t / 2)))
    # objects on the bottom panel, non-overlapping footprints
    placed = []
    for i in range(int(rng.integers(1, 4))):
        for _ in range(50):
            kind = ("sphere", "box", "cylinder")[rng.integers(3)]
            r = rng.uniform(0.05, min(0.14, 0.3 * min(L[0], L[1])))
            h = rng.uniform(0.08, 0.7 * L[2])
            cx, cy = rng.uniform(x0 + r + 0.03, x1 - r - 0.03), rng.uniform(y0 + r + 0.03, y1 - r - 0.03)
            if any(np.hypot(cx - px, cy - py) < r + pr + 0.02 for px, py, pr in placed):
                continue
            placed.append((cx, cy, r))
            base = z0 + 0.003
            mesh = {"sphere": lambda: sphere((cx, cy, base + r), r),
                    "box": lambda: box((cx - r, cy - r, base), (cx + r, cy + r, base + h)),
                    "cylinder": lambda: cylinder((cx, cy, base), r, h)}[kind]()
            parts.append(Part(f"case_object{i}_{kind}", mesh, tex(f"object{i}")))
            break
    return parts
