"""The generated rooms' camera arcs around the glass case (the paper's design): every view looks at the case."""
from __future__ import annotations

import numpy as np

from glint_mi.data.cameras import Camera


def look_at(origin, target, up=(0, 0, 1)) -> np.ndarray:
    """Mitsuba's look_at: columns (left, up', forward, origin)."""
    origin, target, up = (np.asarray(v, float) for v in (origin, target, up))
    f = target - origin
    f /= np.linalg.norm(f)
    left = np.cross(up, f)
    left /= np.linalg.norm(left)
    new_up = np.cross(f, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, f, origin
    return m


def _free(p, room, margin=0.25) -> bool:
    if np.any(p < margin) or np.any(p > room.size - margin):
        return False
    return not any(np.all(p > lo - margin) and np.all(p < hi + margin) for lo, hi, _ in room.boxes(include_case=True))


def _sees_case(p, room, steps=48) -> bool:
    """No furniture box between the camera and the case centre (sampled along the segment)."""
    c = room.case_center
    for s in np.linspace(0.05, 0.95, steps):
        q = p + s * (c - p)
        if np.all(q >= room.case_lo - 0.01) and np.all(q <= room.case_hi + 0.01):
            return True
        if any(np.all(q > lo) and np.all(q < hi) for lo, hi, _ in room.boxes()):
            return False
    return True


def trajectory(room, n_views: int, width: int, height: int, seed: int, fov_deg: float = 60.0) -> list[Camera]:
    """A continuous arc of viewpoints around the case, every view looking at it (the paper's design)."""
    rng = np.random.default_rng(seed + 7919)
    c = room.case_center
    fx = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    for attempt in range(400):
        radius = rng.uniform(1.0, 2.2) * (1 - attempt / 500)
        start, span = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(80, 150))
        h0, h1 = rng.uniform(1.1, 1.7, 2)
        ts = np.linspace(0, 1, n_views)
        pos = np.stack([c[0] + radius * np.cos(start + span * ts), c[1] + radius * np.sin(start + span * ts),
                        h0 + (h1 - h0) * ts], -1)
        if all(_free(p, room) and _sees_case(p, room) for p in pos):
            break
    else:
        raise RuntimeError("no camera arc around the case fits this room; try another seed.")
    cams = []
    for i, p in enumerate(pos):
        target = c + rng.normal(0, 0.03, 3)
        cams.append(Camera(f"view_{i:03d}", look_at(p, target), width, height, fx, fx, width / 2, height / 2))
    return cams
