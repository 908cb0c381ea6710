"""Small synthetic Gaussian scenes (a display case in a room) for the demo scene, tests and benchmarks.

They are hand-built Gaussian sets, not reconstructions: an interface set holding glass panes (high transparency)
and opaque room surfaces, a transmission set (the room without the glass) and a reflection set (a surrounding shell).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from glint_mi.model.gaussians import GaussianSet


def _plane(rng, n, origin, u, v, normal_axis_quat, color, opacity=0.9, size=0.05, jitter=0.15, **extra):
    a, b = rng.uniform(-1, 1, (2, n, 1))
    means = np.asarray(origin) + a * np.asarray(u) + b * np.asarray(v)
    col = np.clip(np.asarray(color) + jitter * rng.normal(size=(n, 3)), 0.02, 0.98)
    scales = np.column_stack([np.full(n, size), np.full(n, size), np.full(n, size * 0.2)])
    return GaussianSet.from_activated(means, scales, np.tile(normal_axis_quat, (n, 1)), opacities=np.full(n, opacity),
                                      colors=col, **extra)


Q_Z = (0.0, 0.0, 0.0, 1.0)           # thin axis along z (xy plane)
Q_X = (0.0, 0.70710678, 0.0, 0.70710678)   # thin axis along x (yz plane)
Q_Y = (0.70710678, 0.0, 0.0, 0.70710678)   # thin axis along y (xz plane)


def display_case_sets(n: int = 4000, seed: int = 0, glass: bool = True) -> dict[str, GaussianSet]:
    """Three Gaussian sets of a 4 x 4 x 2.5 m room (z up) with, if ``glass``, a 0.8 m glass case on the floor."""
    rng = np.random.default_rng(seed)
    k = max(n // 8, 8)
    room = [
        _plane(rng, 2 * k, (0, 0, 0), (2, 0, 0), (0, 2, 0), Q_Z, (0.55, 0.45, 0.35), specular=0.05),  # floor
        _plane(rng, k, (0, 2, 1.25), (2, 0, 0), (0, 0, 1.25), Q_Y, (0.3, 0.45, 0.6)),                  # back wall
        _plane(rng, k, (-2, 0, 1.25), (0, 2, 0), (0, 0, 1.25), Q_X, (0.6, 0.55, 0.45)),                # left wall
        _plane(rng, k, (2, 0, 1.25), (0, 2, 0), (0, 0, 1.25), Q_X, (0.45, 0.6, 0.4)),                  # right wall
        _plane(rng, k // 2, (0.0, 0.3, 0.25), (0.15, 0, 0), (0, 0, 0.25), Q_Y, (0.8, 0.15, 0.1), size=0.03),  # object
    ]
    trans = GaussianSet.concatenate(room)
    interface = [GaussianSet.concatenate(room)]
    if glass:
        pane = dict(opacity=0.6, size=0.04, jitter=0.02, specular=0.02, transparency=0.95)
        interface += [
            _plane(rng, k, (0, -0.1, 0.4), (0.4, 0, 0), (0, 0, 0.4), Q_Y, (0.9, 0.9, 0.9), **pane),   # front pane
            _plane(rng, k // 2, (-0.4, 0.3, 0.4), (0, 0.4, 0), (0, 0, 0.4), Q_X, (0.9, 0.9, 0.9), **pane),
            _plane(rng, k // 2, (0.4, 0.3, 0.4), (0, 0.4, 0), (0, 0, 0.4), Q_X, (0.9, 0.9, 0.9), **pane),
        ]
    # reflection set: a shell of coloured blobs around the room (what glass mirrors)
    m = 2 * k
    dirs = rng.normal(size=(m, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    refl = GaussianSet.from_activated(dirs * 3.5 + [0, 0, 1.2], rng.uniform(0.2, 0.4, (m, 3)), rng.normal(size=(m, 4)),
                                      opacities=0.8, colors=0.5 + 0.5 * dirs[:, [2, 0, 1]] * [1, 0.6, 0.6])
    out = {"interface": GaussianSet.concatenate(interface), "transmission": trans, "reflection": refl}
    for s in out.values():
        s.logit_transparency[:] = np.where(s.logit_transparency > 0, s.logit_transparency, -20.0)  # opaque ~ 0
    if not glass:
        del out["transmission"]
    return out


def camera_dict(width=96, height=54, spp=1, origin=(0.3, -1.8, 1.0), target=(0.0, 0.3, 0.4), fov=60):
    import mitsuba as mi

    return {"type": "perspective", "fov": fov,
            "to_world": mi.ScalarTransform4f().look_at(origin=list(origin), target=list(target), up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp}}


def gaussian_scene_dict(sets: dict[str, GaussianSet], kernel="surfel", opacity_shells: bool = True,
                        normal_source: str = "axis", **integrator_props) -> dict:
    """A Mitsuba scene dict: the glint integrator with one glint_gaussians shape per set (no sensor)."""
    from glint_mi.model.shapes import make_shape

    integ = {"type": "glint", **integrator_props}
    for role, s in sets.items():
        integ[role] = make_shape(s, kernel=kernel, role=role, shape_id=role, opacity_shells=opacity_shells,
                                 normal_source=normal_source)
    return {"type": "scene", "integrator": integ}


def scene_dict(sets: dict[str, GaussianSet], kernel="surfel", width=96, height=54, **integrator_props) -> dict:
    """:func:`gaussian_scene_dict` plus a camera."""
    return {**gaussian_scene_dict(sets, kernel, **integrator_props), "sensor": camera_dict(width, height)}


def write_scene(folder: str | Path, sets: dict[str, GaussianSet], width=96, height=54, kernel="surfel") -> Path:
    """Write the sets as 3DGS .ply files and a Mitsuba scene XML that loads them; returns the XML path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    shapes = []
    for role, s in sets.items():
        s.save_ply(folder / f"{role}.ply")
        shapes.append(f'        <shape type="glint_gaussians" name="{role}" id="{role}">\n'
                      f'            <string name="filename" value="{role}.ply"/>\n'
                      f'            <string name="kernel" value="{kernel}"/>\n        </shape>')
    xml = f"""<scene version="3.0.0">
    <!-- GLINT scene: one glint_gaussians shape per set, nested in the glint integrator -->
    <integrator type="glint" id="integrator">
        <string name="components" value="auto"/>
{chr(10).join(shapes)}
    </integrator>
    <sensor type="perspective" id="sensor">
        <float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0.3, -1.8, 1.0" target="0, 0.3, 0.4" up="0, 0, 1"/></transform>
        <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/>
            <rfilter type="box"/></film>
        <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
    </sensor>
</scene>
"""
    path = folder / "scene.xml"
    path.write_text(xml)
    return path
