"""Render a generated scene with Blender Cycles for the cross-check (the optional ``cycles`` extra).

bpy 5.0.1 pins numpy < 2 and is ~1 GB, so it lives in its own environment: ``make cycles-env`` creates
``.venv-cycles``; ``$GLINT_CYCLES_PYTHON`` (a Python with bpy) or a ``blender`` binary on PATH work too.
This module (main environment) turns the scene's Mitsuba XML into a neutral description (meshes as .npz,
materials, emitters, the dataset's cameras) and runs :mod:`glint_mi.dataset.cycles_bpy` in that Python.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent.parent
BPY_SCRIPT = Path(__file__).resolve().parent / "cycles_bpy.py"


class CyclesUnavailable(RuntimeError):
    """No Python with bpy and no blender binary: the message says how to install the extra."""


def find_bpy() -> list[str]:
    """The command prefix that runs a script with bpy: [python] or [blender, -b, --python-exit-code, 1, -P]."""
    cands = [os.environ.get("GLINT_CYCLES_PYTHON"), str(ROOT / ".venv-cycles" / "bin" / "python")]
    for c in cands:
        if c and Path(c).exists():
            return [c]
    try:
        import importlib.util

        if importlib.util.find_spec("bpy") is not None:
            return [sys.executable]
    except (ImportError, ValueError):
        pass
    blender = shutil.which("blender")
    if blender:
        return [blender, "-b", "--python-exit-code", "1", "-P"]
    raise CyclesUnavailable("Blender Cycles is not installed: run `make cycles-env` (a separate .venv-cycles with "
                            "bpy==5.0.1, ~1 GB), or set GLINT_CYCLES_PYTHON to a Python that has bpy, or put a "
                            "`blender` binary on PATH.")


def _rgb(elem, name, default=(0.0, 0.0, 0.0)):
    for c in elem:
        if c.attrib.get("name") == name and c.tag in ("rgb", "float"):
            vals = [float(x) for x in c.attrib["value"].replace(",", " ").split()]
            return vals * 3 if len(vals) == 1 else vals
    return list(default)


def _bsdf(elem, xml_path: Path) -> dict:
    kind = elem.attrib["type"]
    if kind == "twosided":
        return _bsdf(elem.find("bsdf"), xml_path)
    if kind == "diffuse":
        tex = next((t for t in elem.iter("texture") if t.attrib.get("type") == "bitmap"), None)
        if tex is not None:
            fn = next(s.attrib["value"] for s in tex.iter("string") if s.attrib.get("name") == "filename")
            return {"type": "diffuse", "texture": fn}
        return {"type": "diffuse", "rgb": _rgb(elem, "reflectance", (0.5, 0.5, 0.5))}
    if kind in ("thindielectric", "dielectric"):
        ior = next((float(f.attrib["value"]) for f in elem.iter("float") if f.attrib.get("name") == "int_ior"), 1.5)
        return {"type": "thindielectric", "ior": ior, "mitsuba": kind}
    if kind == "roughplastic":
        alpha = next((float(f.attrib["value"]) for f in elem.iter("float") if f.attrib.get("name") == "alpha"), 0.1)
        return {"type": "roughplastic", "rgb": _rgb(elem, "diffuse_reflectance", (0.5, 0.5, 0.5)), "alpha": alpha}
    raise ValueError(f"{xml_path}: bsdf type '{kind}' has no Cycles mapping (supported: diffuse, twosided, "
                     f"thindielectric, dielectric, roughplastic).")


def describe_scene(scene_dir: Path, out: Path, spp: int = 256, max_depth: int = 64, seed: int = 0,
                   cameras=None) -> Path:
    """Write ``out/description.json`` + ``out/meshes.npz`` for :mod:`cycles_bpy`; returns the JSON path.
    ``cameras`` (objects with name, c2w, width, height, K): default the dataset's views."""
    from plyfile import PlyData

    from glint_mi.data import load_dataset

    scene_dir = Path(scene_dir)
    xml_path = scene_dir / "scene.xml"
    root = ET.parse(xml_path).getroot()
    shapes, arrays = [], {}
    env = [0.0, 0.0, 0.0]
    for em in root.findall("emitter"):
        if em.attrib.get("type") == "constant":
            env = _rgb(em, "radiance")
    for sh in root.findall("shape"):
        if sh.attrib.get("type") != "ply":
            raise ValueError(f"{xml_path}: shape type '{sh.attrib.get('type')}' is not supported (ply only).")
        if sh.find("transform") is not None:
            raise ValueError(f"{xml_path}: shape '{sh.attrib.get('id')}' has a to_world transform; the generated "
                             f"scenes store world-space meshes.")
        sid = sh.attrib["id"]
        fn = next(s.attrib["value"] for s in sh.findall("string") if s.attrib.get("name") == "filename")
        ply = PlyData.read(str(scene_dir / fn))
        v = ply["vertex"]
        arrays[f"{sid}/v"] = np.stack([v["x"], v["y"], v["z"]], -1).astype(np.float64)
        arrays[f"{sid}/f"] = np.stack(list(ply["face"]["vertex_indices"])).astype(np.int64)
        names = v.data.dtype.names
        if "u" in names and "v" in names:
            arrays[f"{sid}/uv"] = np.stack([v["u"], v["v"]], -1).astype(np.float64)
        emitter = sh.find("emitter")
        if emitter is not None:
            mat = {"type": "emitter", "radiance": _rgb(emitter, "radiance")}
        else:
            mat = _bsdf(sh.find("bsdf"), xml_path)
        shapes.append({"id": sid, "material": mat})
    views = cameras if cameras is not None else load_dataset(scene_dir, check_images=False).views
    cams = []
    for v in views:
        w, h, K = v.width, v.height, v.K
        s = max(w, h)
        cams.append({"name": v.name, "c2w": v.c2w.tolist(),
                     "fov_x_deg": float(np.degrees(2 * np.arctan(0.5 * w / K[0, 0]))),
                     "shift_x": float((w / 2 - K[0, 2]) / s), "shift_y": float((K[1, 2] - h / 2) / s)})
    out.mkdir(parents=True, exist_ok=True)
    np.savez(out / "meshes.npz", **arrays)
    desc = {"root": str(scene_dir.resolve()), "meshes_npz": str((out / "meshes.npz").resolve()),
            "shapes": shapes, "environment": env, "cameras": cams, "width": views[0].width,
            "height": views[0].height, "spp": spp, "max_depth": max_depth, "seed": seed}
    path = out / "description.json"
    path.write_text(json.dumps(desc, indent=1))
    return path


def render_cycles(scene_dir: Path, views: list[str] | None = None, spp: int = 256, log=print,
                  noise_view: bool = True, cameras=None) -> Path:
    """Render ``views`` (default: the test split) into ``scene_dir/cycles/<view>.exr``; with ``noise_view`` the first
    view is rendered again with another seed (``<view>.seed1.exr``) to measure Cycles' own noise. ``cameras``: see
    :func:`describe_scene` (for a scene whose images do not exist yet)."""
    cmd = find_bpy()
    scene_dir = Path(scene_dir)
    if views is None:
        views = json.loads((scene_dir / "split.json").read_text())["test"]
    out = scene_dir / "cycles"
    work = scene_dir / "cycles.partial"
    shutil.rmtree(work, ignore_errors=True)
    t0 = time.perf_counter()
    for seed, names in ((0, views), (1, views[:1] if noise_view else [])):
        if not names:
            continue
        desc = describe_scene(scene_dir, work / f"desc{seed}", spp=spp, seed=seed, cameras=cameras)
        target = work / ("seed1" if seed else "renders")
        args = ([*cmd, str(BPY_SCRIPT), "--"] if len(cmd) > 1 else [*cmd, str(BPY_SCRIPT)]) + [str(desc), str(target),
                                                                                               *names]
        r = subprocess.run(args, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"Cycles render failed ({' '.join(args[:2])} ...):\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}")
        log(f"cycles: {len(names)} view(s) at {spp} spp (seed {seed})")
    renders = work / "renders"
    if noise_view and (work / "seed1").exists():
        for f in (work / "seed1").glob("*.exr"):
            f.replace(renders / f.name.replace(".exr", ".seed1.exr"))
    meta = {"spp": spp, "views": views, "seconds": time.perf_counter() - t0, "bpy": " ".join(cmd)}
    (renders / "meta.json").write_text(json.dumps(meta, indent=1))
    shutil.rmtree(out, ignore_errors=True)
    renders.replace(out)
    shutil.rmtree(work, ignore_errors=True)
    return out


def read_cycles_exr(path: Path) -> dict[str, np.ndarray]:
    """{'rgb' [H,W,3] linear, 'depth' planar z (0 where nothing), 'normal' world [H,W,3], 'glass' [H,W]}."""
    import OpenEXR

    ch = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            for name, c in part.channels.items():
                ch[name if "." in name else f"{part.name()}.{name}"] = np.array(c.pixels)

    def get(*suffixes):
        for s in suffixes:
            hit = [k for k in ch if k.endswith(s)]
            if hit:
                return ch[sorted(hit, key=len)[0]]
        raise KeyError(f"{path}: no channel ending in {suffixes}; has {sorted(ch)}")

    rgb = np.stack([get("Combined.R"), get("Combined.G"), get("Combined.B")], -1)
    depth = get("Depth.Z")
    depth = np.where(np.isfinite(depth) & (depth < 1e9), depth, 0.0)
    normal = np.stack([get("Normal.X"), get("Normal.Y"), get("Normal.Z")], -1)
    glass = (np.abs(get("Object Index.X", "IndexOB.X", "IndexOB")) > 0.5).astype(np.float32)
    return {"rgb": rgb, "depth": depth, "normal": normal, "glass": glass}
