"""Blender Cycles side of the cross-check. Runs INSIDE a Python that has ``bpy`` (the optional ``cycles`` extra, kept
in its own venv because bpy 5.0.1 pins numpy < 2) or inside ``blender -b -P``; imports nothing from glint_mi.

    <bpy-python> cycles_bpy.py DESCRIPTION.json OUT_DIR [VIEW ...]

DESCRIPTION.json is written by :func:`glint_mi.dataset.cycles_render.describe_scene` from the scene's Mitsuba XML (meshes as
.npz arrays, materials, emitters, cameras). For every view, OUT_DIR/<view>.exr is Blender's multi-layer EXR with
the Combined (linear RGB), Depth (planar camera z), Normal (world) and IndexOB (1 = glass) passes.

Material mapping (Mitsuba -> Cycles):
- diffuse (bitmap or rgb reflectance, two-sided) -> Diffuse BSDF (image texture, sRGB colour space);
- thindielectric, IOR 1.5 -> Cycles has no thin-sheet BSDF: a mix of a sharp Glossy BSDF and a Transparent BSDF
  weighted by the thin-sheet reflectance R' = 2R / (1 + R) (R: air -> glass Fresnel from the Fresnel node, on back
  faces too), which is what Mitsuba's thindielectric does (summed inter-reflections, no refraction offset);
- roughplastic -> Principled BSDF (base colour = diffuse reflectance, roughness = sqrt(alpha), IOR 1.5);
- pixel filter: Cycles' Gaussian 1 px wide (Cycles has no box filter; Mitsuba's ground truth uses a 1 px box);
- area emitter (one-sided) -> Emission on front faces only (Geometry.Backfacing), strength = radiance (Cycles'
  emission strength is radiance for mesh emitters); constant emitter -> World background colour, strength 1.
"""
import json
import math
import sys
import time
from pathlib import Path

sys.path[:] = [p for p in sys.path if Path(p).resolve() != Path(__file__).resolve().parent]  # no shadowing of add-ons
import bpy  # noqa: E402
import mathutils  # noqa: E402
import numpy as np  # noqa: E402


def _clear():
    """Empty the start-up scene (a factory reset would also unload the Cycles add-on)."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.cameras, bpy.data.lights,
                 bpy.data.images):
        for item in list(coll):
            coll.remove(item)


def _node(nt, kind, **inputs):
    n = nt.nodes.new(kind)
    for k, v in inputs.items():
        n.inputs[k].default_value = v
    return n


def material(desc, root: Path, name: str):
    m = bpy.data.materials.new(name)
    if not m.node_tree:  # Blender 5 materials always have nodes (use_nodes is deprecated)
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    kind = desc["type"]
    if kind == "diffuse":
        bsdf = _node(nt, "ShaderNodeBsdfDiffuse")
        if desc.get("texture"):
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = bpy.data.images.load(str(root / desc["texture"]))
            tex.image.colorspace_settings.name = "sRGB"
            tex.interpolation = "Linear"
            nt.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
        else:
            bsdf.inputs["Color"].default_value = (*desc["rgb"], 1.0)
        shader = bsdf.outputs[0]
    elif kind == "thindielectric":
        # The Fresnel node uses 1/IOR on back faces (a glass -> air interface, with total internal reflection); a
        # thin sheet is air -> glass from both sides, so back faces get 1/IOR as input: the node then uses IOR.
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        ior = _node(nt, "ShaderNodeMath")
        ior.operation = "MULTIPLY_ADD"  # backfacing * (1/n - n) + n
        nt.links.new(geo.outputs["Backfacing"], ior.inputs[0])
        ior.inputs[1].default_value = 1.0 / desc["ior"] - desc["ior"]
        ior.inputs[2].default_value = desc["ior"]
        fres = _node(nt, "ShaderNodeFresnel")
        nt.links.new(ior.outputs[0], fres.inputs["IOR"])
        two = _node(nt, "ShaderNodeMath")
        two.operation = "MULTIPLY"
        two.inputs[1].default_value = 2.0
        nt.links.new(fres.outputs[0], two.inputs[0])
        one_plus = _node(nt, "ShaderNodeMath")
        one_plus.operation = "ADD"
        one_plus.inputs[1].default_value = 1.0
        nt.links.new(fres.outputs[0], one_plus.inputs[0])
        div = _node(nt, "ShaderNodeMath")
        div.operation = "DIVIDE"
        nt.links.new(two.outputs[0], div.inputs[0])
        nt.links.new(one_plus.outputs[0], div.inputs[1])
        gloss = _node(nt, "ShaderNodeBsdfGlossy", Roughness=0.0)
        transp = _node(nt, "ShaderNodeBsdfTransparent")
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(div.outputs[0], mix.inputs[0])
        nt.links.new(transp.outputs[0], mix.inputs[1])
        nt.links.new(gloss.outputs[0], mix.inputs[2])
        shader = mix.outputs[0]
    elif kind == "roughplastic":
        bsdf = _node(nt, "ShaderNodeBsdfPrincipled")
        bsdf.inputs["Base Color"].default_value = (*desc["rgb"], 1.0)
        bsdf.inputs["Roughness"].default_value = math.sqrt(desc.get("alpha", 0.1))
        bsdf.inputs["IOR"].default_value = 1.5
        shader = bsdf.outputs[0]
    elif kind == "emitter":
        em = _node(nt, "ShaderNodeEmission", Strength=1.0)
        em.inputs["Color"].default_value = (*desc["radiance"], 1.0)
        black = _node(nt, "ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")  # Mitsuba area lights emit from their front side only
        nt.links.new(geo.outputs["Backfacing"], mix.inputs[0])
        nt.links.new(em.outputs[0], mix.inputs[1])
        nt.links.new(black.outputs[0], mix.inputs[2])
        shader = mix.outputs[0]
    else:
        raise ValueError(f"unsupported material {kind}")
    nt.links.new(shader, out.inputs["Surface"])
    return m


def build(desc: dict, root: Path):
    _clear()
    scene = bpy.context.scene
    arrays = np.load(root / desc["meshes_npz"])
    mats = {}
    for i, s in enumerate(desc["shapes"]):
        v, f = arrays[f"{s['id']}/v"], arrays[f"{s['id']}/f"]
        mesh = bpy.data.meshes.new(s["id"])
        mesh.from_pydata(v.tolist(), [], f.tolist())
        if f"{s['id']}/uv" in arrays:
            uv = arrays[f"{s['id']}/uv"]
            layer = mesh.uv_layers.new(name="UVMap")
            loops = np.array([li for poly in mesh.polygons for li in poly.loop_indices])
            vidx = np.array([mesh.loops[li].vertex_index for li in loops])
            # Mitsuba's uv origin is the top-left of the image, Blender's the bottom-left
            layer.data.foreach_set("uv", np.stack([uv[vidx, 0], 1.0 - uv[vidx, 1]], -1).ravel())
        mesh.update()
        obj = bpy.data.objects.new(s["id"], mesh)
        scene.collection.objects.link(obj)
        key = json.dumps(s["material"], sort_keys=True)
        if key not in mats:
            mats[key] = material(s["material"], root, f"m{len(mats)}")
        obj.data.materials.append(mats[key])
        obj.pass_index = 1 if s["material"]["type"] == "thindielectric" else 0
    world = bpy.data.worlds.new("world")
    scene.world = world
    if not world.node_tree:
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*desc["environment"], 1.0)
    bg.inputs["Strength"].default_value = 1.0
    r = scene.render
    r.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(desc["spp"])
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    for k in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_max_bounces",
              "volume_bounces"):
        setattr(scene.cycles, k, int(desc["max_depth"]))
    scene.cycles.caustics_reflective = True
    scene.cycles.caustics_refractive = True
    scene.cycles.blur_glossy = 0.0
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.filter_width = 1.0  # Gaussian, 1 px wide: Cycles has no box filter (Mitsuba's GT uses one)
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.display_settings.display_device = "sRGB"
    r.resolution_x, r.resolution_y = desc["width"], desc["height"]
    r.resolution_percentage = 100
    if hasattr(r.image_settings, "media_type"):  # Blender 5: multi-layer is a media type of OPEN_EXR
        r.image_settings.media_type = "MULTI_LAYER_IMAGE"  # (its only format is OPEN_EXR_MULTILAYER)
    else:
        r.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    r.image_settings.color_depth = "32"
    vl = scene.view_layers[0]
    vl.use_pass_z = True
    vl.use_pass_normal = True
    vl.use_pass_object_index = True
    vl.pass_alpha_threshold = 0.0  # data passes from the first surface, glass included (protocol.md)
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene, cam


def main(argv):
    desc_path, out_dir = Path(argv[0]), Path(argv[1])
    desc = json.loads(desc_path.read_text())
    scene, cam = build(desc, Path(desc["root"]))
    out_dir.mkdir(parents=True, exist_ok=True)
    want = set(argv[2:])
    timings = {}
    for view in desc["cameras"]:
        if want and view["name"] not in want:
            continue
        c2w = np.array(view["c2w"])  # Mitsuba camera: +z forward, +y up, +x left
        m = c2w.copy()
        m[:3, :3] = c2w[:3, :3] @ np.diag([-1.0, 1.0, -1.0])  # Blender camera: -z forward, +y up, +x right
        cam.matrix_world = mathutils.Matrix([list(map(float, row)) for row in m])
        cam.data.sensor_fit = "HORIZONTAL"
        cam.data.angle = math.radians(view["fov_x_deg"])
        cam.data.shift_x = view.get("shift_x", 0.0)
        cam.data.shift_y = view.get("shift_y", 0.0)
        cam.data.clip_start = 1e-3
        cam.data.clip_end = 1e4
        scene.render.filepath = str(out_dir / f"{view['name']}.exr")
        scene.cycles.seed = int(desc.get("seed", 0))
        t0 = time.time()
        bpy.ops.render.render(write_still=True)
        timings[view["name"]] = time.time() - t0
        print(f"cycles: {view['name']} {timings[view['name']]:.1f} s", flush=True)
    (out_dir / "timings.json").write_text(json.dumps(timings, indent=1))


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    main(args)
