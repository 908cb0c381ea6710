"""A small mesh room with real glass (thin pane + solid sphere) for comparing the first-order reference with `path`."""
from __future__ import annotations


def glass_room_dict(integrator: dict, glass: bool = True, width: int = 48, height: int = 36, spp: int = 64) -> dict:
    import mitsuba as mi

    T = mi.ScalarTransform4f
    diffuse = lambda rgb: {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}
    d = {"type": "scene", "integrator": integrator,
         "sensor": {"type": "perspective", "fov": 40,
                    "to_world": T().look_at(origin=[0, 1, 4.5], target=[0, 0.8, 0], up=[0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
                    "sampler": {"type": "independent", "sample_count": spp}},
         "light": {"type": "rectangle", "to_world": T().translate([0, 2.5, 0]).rotate([1, 0, 0], 90).scale(0.6),
                   "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 8.0}}},
         "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(3), "bsdf": diffuse([0.6, 0.5, 0.4])},
         "back": {"type": "rectangle", "to_world": T().translate([0, 1.5, -1.5]).scale(3), "bsdf": diffuse([0.2, 0.4, 0.7])},
         "box": {"type": "cube", "to_world": T().translate([0, 0.3, -0.4]).scale(0.3), "bsdf": diffuse([0.8, 0.1, 0.1])}}
    if glass:
        d["pane"] = {"type": "rectangle", "to_world": T().translate([0, 0.8, 0.6]).scale(0.8),
                     "bsdf": {"type": "thindielectric", "int_ior": 1.5}}
        d["ball"] = {"type": "sphere", "center": [0.8, 0.4, 0.3], "radius": 0.3,
                     "bsdf": {"type": "dielectric", "int_ior": 1.5}}
    return d
