"""Optimisation scenes: ``python -m glint_mi.scene DATASET > scene.xml`` and the initial Gaussian sets.

An optimisation scene is a Mitsuba XML whose ``glint`` integrator names the dataset (``<string name="dataset">``,
absolute or relative to the XML) and holds one ``glint_gaussians`` shape per set, each either a trained ``.ply``
(``filename``) or an initialisation rule (``init``: ``sfm`` = the dataset's SfM points, ``grid`` = the reflection
grid of N^3 cells with K random points each, ``none`` = leave the set out). Initialisation follows the paper
(method section 1): opacity 0.1, scale = sqrt(mean squared distance to the 3 nearest neighbours), SfM colours.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from glint_mi import conventions as cv
from glint_mi.data import Dataset, DatasetError, load_dataset
from glint_mi.model.gaussians import GaussianSet


class SceneError(ValueError):
    """Bad optimisation scene XML; the message names the file, the element and the fix."""


@dataclasses.dataclass
class SetSpec:
    role: str
    init: str = "sfm"            # sfm | grid | file | none
    filename: Path | None = None


@dataclasses.dataclass
class OptimScene:
    path: Path
    dataset: Path
    sets: dict[str, SetSpec]
    settings: dict                # the training settings the XML states (TrainConfig fields: components and
    #                               max_order on the integrator, kernel on every shape alike, grid_n and grid_k on the
    #                               grid shape). The config owns them: optimize.build_config refuses another source
    #                               giving a different value, and the trainer a config that disagrees with them
    missing: str = "error"        # frames whose image is missing: error | skip (``missing_images``)


# ------------------------------------------------------------------ writer
def scene_xml(dataset: str | Path, components: str | None = None, kernel: str | None = None,
              grid_n: int | None = None, grid_k: int | None = None, relative_to: Path | None = None,
              missing: str = "error", max_order: int | None = None) -> str:
    """The XML text. A setting left None is not written: the training config's value applies (the preset's, a
    method's, --set); one given here is stated in the XML, and the config must then agree with it."""
    from xml.sax.saxutils import quoteattr

    ds = Path(dataset).resolve()
    if relative_to is not None:
        try:
            ds = ds.relative_to(Path(relative_to).resolve())
        except ValueError:
            pass
    prop = lambda tag, name, value, ind: f'\n{ind}<{tag} name="{name}" value={quoteattr(str(value))}/>'
    kern = prop("string", "kernel", kernel, " " * 12) if kernel is not None else ""
    shape = lambda role, init, extra="": (
        f'        <shape type="glint_gaussians" name="{role}">'
        f'{prop("string", "init", init, " " * 12)}{kern}{extra}\n        </shape>')
    grid = "".join(prop("integer", k, v, " " * 12) for k, v in (("grid_n", grid_n), ("grid_k", grid_k))
                   if v is not None)
    skip = ('\n        <!-- frames whose image is missing are left out -->'
            + prop("string", "missing_images", "skip", " " * 8)) if missing == "skip" else ""
    stated = "".join(prop(tag, k, v, " " * 8) for k, v, tag in (("components", components, "string"),
                                                                 ("max_order", max_order, "integer"))
                     if v is not None)
    return f"""<scene version="3.0.0">
    <!-- GLINT optimisation input: python -m glint_mi.optimize <this file>
         init: sfm = the dataset's SfM points (SfM runs if it has none), grid = N^3 cells x K points over the scene
         bounds, none = leave the set out. Training settings (components, max_order, kernel, grid_n, grid_k) are
         the training config's (its preset, a method, optimize's set option); one written here must agree
         with it. -->
    <integrator type="glint" id="integrator">{prop("string", "dataset", ds, " " * 8)}{skip}{stated}
{shape("interface", "sfm")}
{shape("transmission", "sfm")}
{shape("reflection", "grid", grid)}
    </integrator>
</scene>
"""


# ------------------------------------------------------------------ parser
PROPERTY_TAGS = ("string", "integer", "float", "boolean")
# the properties an optimisation scene's integrator and shapes take (what scene_xml writes, and what it documents),
# with their element type
INTEGRATOR_KEYS = {"dataset": "string", "missing_images": "string", "components": "string", "max_order": "integer"}
SHAPE_KEYS = {"role": "string", "init": "string", "kernel": "string", "filename": "string", "grid_n": "integer",
              "grid_k": "integer"}


def _props(path: Path, where: str, elem, keys: dict, children: tuple = ()) -> dict:
    """The properties of ``elem``, each checked: a known name (a misspelled one would be ignored without a word),
    the element type that name takes (``<int>`` or ``<integer name="components">`` would be, too) and a value of
    that type; ``children`` are the other elements ``elem`` may hold."""
    import difflib

    out = {}
    for child in elem:
        if not isinstance(child.tag, str):  # a comment
            continue
        if child.tag in children:
            continue
        name = child.attrib.get("name")
        if child.tag not in PROPERTY_TAGS:
            near = difflib.get_close_matches(child.tag, PROPERTY_TAGS + children, n=1)
            raise SceneError(f"{path}: {where} holds <{child.tag}"
                             + (f' name="{name}"' if name else "") + ">, which is not read"
                             + (f" (did you mean <{near[0]}>?)" if near else "")
                             + f"; its elements are {', '.join(f'<{t}>' for t in PROPERTY_TAGS + children)}.")
        if name is None or "value" not in child.attrib:
            raise SceneError(f"{path}: {where}: <{child.tag}> needs name=\"...\" and value=\"...\" attributes.")
        if name not in keys:
            near = difflib.get_close_matches(name, list(keys), n=1)
            raise SceneError(f"{path}: {where} has no property '{name}'"
                             + (f" (did you mean '{near[0]}'?)" if near else "")
                             + f"; its properties are {', '.join(keys)}.")
        if name in out:
            raise SceneError(f"{path}: {where} gives '{name}' twice; keep one.")
        want, v = keys[name], child.attrib["value"]
        if child.tag != want:
            raise SceneError(f"{path}: {where}: '{name}' is given as <{child.tag}>; write it as "
                             f"<{want} name=\"{name}\" value=\"{v}\"/>.")
        if want == "integer":
            try:
                v = int(v)
            except ValueError:
                raise SceneError(f"{path}: {where}: '{name}' = {v!r} is not an integer.") from None
        out[name] = v
    return out


def read_scene(path: str | Path) -> OptimScene:
    path = Path(path)
    if not path.exists():
        raise SceneError(f"{path}: no such scene file; write one with `python -m glint_mi.scene DATASET > {path}`.")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise SceneError(f"{path}: not valid XML ({e}); a path holding & or < must be written &amp; or &lt;.")
    integ = next((e for e in root.iter("integrator") if e.attrib.get("type") == "glint"), None)
    if integ is None:
        raise SceneError(f"{path}: no <integrator type=\"glint\">; write the file with "
                         f"`python -m glint_mi.scene DATASET > {path.name}`.")
    props = _props(path, "the glint integrator", integ, INTEGRATOR_KEYS, children=("shape",))
    if not props.get("dataset"):
        raise SceneError(f"{path}: the glint integrator has no <string name=\"dataset\" value=\"...\"/>; add the "
                         f"dataset folder (COLMAP, transforms.json or generated layout) to it.")
    dataset = Path(props.pop("dataset"))
    missing = str(props.pop("missing_images", "error"))
    if missing not in ("error", "skip"):
        raise SceneError(f"{path}: missing_images = {missing!r}; use error or skip.")
    if not dataset.is_absolute():
        dataset = (path.parent / dataset).resolve()
    settings = dict(props)  # components, max_order
    if "max_order" in settings and settings["max_order"] not in (1, 2):
        raise SceneError(f"{path}: max_order = {settings['max_order']}; use 1 (first order) or 2 (the release's "
                         f"second-surface reflection).")
    sets, kernels = {}, {}
    for shape in integ.iter("shape"):
        role = shape.attrib.get("name", "")
        p = _props(path, f"<shape name=\"{role}\">", shape, SHAPE_KEYS)
        role = p.get("role", role)
        if role not in cv.ROLES:
            raise SceneError(f"{path}: <shape name=\"{role}\">: the name must be one of {cv.ROLES}.")
        if role in sets or role in kernels:
            raise SceneError(f"{path}: two shapes for the {role} set; keep one.")
        if "kernel" in p:
            if p["kernel"] not in cv.KERNELS:
                raise SceneError(f"{path}: shape '{role}': kernel '{p['kernel']}' unknown; use one of {cv.KERNELS}.")
            kernels[role] = p["kernel"]
        if "filename" in p:
            f = Path(p["filename"])
            f = f if f.is_absolute() else path.parent / f
            if not f.exists():
                raise SceneError(f"{path}: shape '{role}': file {f} does not exist.")
            sets[role] = SetSpec(role, "file", f)
            continue
        init = p.get("init")
        if init not in ("sfm", "grid", "none"):
            raise SceneError(f"{path}: shape '{role}': give <string name=\"init\" value=\"sfm|grid|none\"/> or a "
                             f"<string name=\"filename\"/> (a trained .ply); got init={init!r}.")
        for key in ("grid_n", "grid_k"):
            if key in p and init != "grid":
                raise SceneError(f"{path}: shape '{role}': {key} applies to init=grid only; remove it.")
            if key in p and p[key] < 1:
                raise SceneError(f"{path}: shape '{role}': {key} = {p[key]}; give at least 1 (the paper: "
                                 f"grid_n 32, grid_k 5), or leave it out for the training preset's.")
            if key in p:
                if settings.get(key, p[key]) != p[key]:
                    raise SceneError(f"{path}: two grid shapes give {key} = {settings[key]} and {p[key]}; the "
                                     f"reflection grid has one size.")
                settings[key] = p[key]
        if init != "none":
            sets[role] = SetSpec(role, init, None)
    if len(set(kernels.values())) > 1:
        given = ", ".join(f"{r}: {k}" for r, k in kernels.items())
        raise SceneError(f"{path}: the shapes give different kernels ({given}); every set of a run has one kernel "
                         f"(the config's 'kernel'): give it once, the same on each shape, or leave it out.")
    if kernels:
        settings["kernel"] = next(iter(kernels.values()))
    if "interface" not in sets:
        raise SceneError(f"{path}: no interface set; the glint integrator needs <shape name=\"interface\">.")
    return OptimScene(path, dataset, sets, settings, missing)


def check_settings(spec: OptimScene, cfg) -> None:
    """Refuse a config that disagrees with a training setting the scene XML states (one setting, one value)."""
    from glint_mi.config import ConfigError

    for key, value in spec.settings.items():
        if getattr(cfg, key) != value:
            raise ConfigError(f"{spec.path}: states {key} = {value!r} but the training config has {key} = "
                              f"{getattr(cfg, key)!r}; a setting is given in one place: remove it from the XML, or "
                              f"set the config to {value!r}.")


# ---------------------------------------------------------- initialisation
def knn_scales(points: np.ndarray, k: int = 3) -> np.ndarray:
    """sqrt(mean squared distance to the k nearest neighbours) per point (3DGS's initial scale)."""
    from scipy.spatial import cKDTree

    if len(points) < 2:
        return np.full(len(points), 0.01)
    kk = min(k, len(points) - 1)
    d, _ = cKDTree(points).query(points, k=kk + 1)
    s = np.sqrt(np.mean(np.square(d[:, 1:]), axis=1))
    return np.maximum(s, 1e-7)


def scene_bounds(ds: Dataset, points: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float]:
    """(lo, hi, extent): a box holding the cameras and the robust bulk of the points, and the scene scale.

    extent = 1.1 x the radius of the camera centres' bounding sphere (3DGS's scene scale), but at least the median
    camera-to-point distance: cameras on an arc looking inwards (our trajectories) have a small radius while the
    room is several metres deep."""
    centres = np.array([v.c2w[:3, 3] for v in ds.views])
    parts = [centres]
    radius = float(np.linalg.norm(centres - centres.mean(0), axis=1).max()) * 1.1
    extent = radius
    if points is not None and len(points) >= 8:
        parts.append(np.percentile(points, [1, 99], axis=0))
        dist = np.linalg.norm(points[:, None] - centres[None], axis=-1).min(1)
        extent = max(extent, float(np.median(dist)))
    allp = np.concatenate(parts)
    lo, hi = allp.min(0), allp.max(0)
    diag = float(np.linalg.norm(hi - lo))
    extent = max(extent, 0.1 * diag, 1e-6)
    pad = 0.1 * max(diag, extent)
    return lo - pad, hi + pad, extent


SFM_VERSION = 1


def sfm_points(ds: Dataset, log=print) -> tuple[np.ndarray, np.ndarray, dict]:
    """The dataset's SfM points, or points triangulated with pycolmap from its images and known poses (cached under
    ``$GLINT_CACHE``/sfm, with their tracks, which then become the dataset's ``sparse`` model). Returns (xyz, rgb,
    report); the report says where the points came from, or in one line why there are none."""
    from glint_mi.data.images import image_size
    from glint_mi.data.undistort import cache_root, digest, file_key
    from glint_mi.data.cameras import Camera, write_colmap_text
    from glint_mi.data.sfm import triangulate_known_poses

    none = (np.zeros((0, 3)), np.zeros((0, 3), np.uint8))
    if ds.points is not None and len(ds.points):
        return ds.points, (ds.colors if ds.colors is not None else np.full((len(ds.points), 3), 128, np.uint8)), {
            "source": "dataset", "points": int(len(ds.points))}
    files = [v.image_path for v in ds.views]
    cams = []
    for v in ds.views:  # SIFT on the image files as they are (full size unless a capture's images_<k> is used)
        w, h = image_size(v.image_path)
        s = v.downscale if (w // v.downscale, h // v.downscale) == (v.width, v.height) else 1
        c = Camera.from_view(v)
        cams.append(dataclasses.replace(c, width=w, height=h, fx=c.fx * s, fy=c.fy * s, cx=c.cx * s, cy=c.cy * s))
    if max(max(c.width, c.height) for c in cams) < 200:
        why = "the images are too small for SIFT (< 200 px)"
        log(f"no SfM points: {why}; starting from random points")
        return (*none, {"source": "none", "points": 0, "why": why})
    key = digest(SFM_VERSION, [(c.name, file_key(f), c.K.tolist(), c.c2w.tolist()) for f, c in zip(files, cams)])
    folder = cache_root() / "sfm" / key / "sparse" / "0"
    if (folder / "points3D.txt").exists():
        from glint_mi.data.colmap import read_text

        _, _, xyz, rgb, _, _ = read_text(folder)
        rep = {"source": "triangulated (cached)", "points": int(len(xyz)), "cache": str(folder)}
    else:
        log(f"no SfM points in {ds.root}: triangulating with pycolmap from the {len(files)} images and their known "
            f"poses (SIFT, exhaustive matching; once, cached in {folder.parent.parent})")
        import time

        t0 = time.perf_counter()
        try:
            xyz, rgb, stats, tracks = triangulate_known_poses(files, cams, log=log)
        except Exception as e:  # pycolmap fails in many ways (no features, no matches): one line, then fall back
            why = f"SfM (pycolmap, known poses) failed: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
            log(f"{why}; starting from random points")
            return (*none, {"source": "none", "points": 0, "why": why})
        scale = {c.name: c.fx / v.K[0, 0] / v.downscale for c, v in zip(cams, ds.views)}  # -> full-size pixels
        tmp = folder.with_name(f"0.partial-{__import__('os').getpid()}")
        write_colmap_text(tmp, [c.scaled(1 / scale[c.name]) for c in cams], (xyz, rgb),
                          {n: (xy / scale[n], rows) for n, (xy, rows) in tracks.items()})
        source = "triangulated"
        try:
            tmp.rename(folder)
        except OSError:
            # another run cached its points first: use them, so that every run starts from one cloud (SIFT
            # matching is multi-threaded, and two triangulations of the same images differ by a few points)
            import shutil

            from glint_mi.data.colmap import read_text

            shutil.rmtree(tmp, ignore_errors=True)
            _, _, xyz, rgb, _, _ = read_text(folder)
            source = "triangulated (another run cached its own first; those points are used)"
        rep = {"source": source, "points": int(len(xyz)), "cache": str(folder),
               "seconds": round(time.perf_counter() - t0, 1), **stats}
        log(f"SfM (pycolmap, known poses): {stats['points3D']} points, {stats['mean_reprojection_error_px']:.2f} px "
            f"in {rep['seconds']:.0f} s" + ("" if source == "triangulated" else
                                             f"; another run cached {len(xyz)} points first, those are used"))
    ds.sparse, ds.tracks_distorted = folder, False  # its tracks feed the L_trans see-through cue
    return xyz, rgb, rep


def points_set(points: np.ndarray, colors: np.ndarray, opacity: float, sh_degree: int,
               rng: np.random.Generator) -> GaussianSet:
    """Gaussians on points: k-NN scale, the points' colours, uniformly random orientations (surfels facing every
    way, so that walls seen from any side are covered from the start)."""
    s = knn_scales(points)
    q = rng.normal(size=(len(points), 4))
    q /= np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12)
    return GaussianSet.from_activated(points, np.repeat(s[:, None], 3, axis=1), quats_xyzw=q, opacities=opacity,
                                      colors=np.asarray(colors, np.float64) / 255.0, sh_degree=sh_degree)


def grid_points(lo, hi, n: int, k: int, rng: np.random.Generator) -> np.ndarray:
    """K uniform random points in each of the N^3 cells of the box [lo, hi]."""
    cells = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    u = (np.repeat(cells, k, axis=0) + rng.random((len(cells) * k, 3))) / n
    return lo + u * (hi - lo)


def ray_points(ds: Dataset, n: int, extent: float, rng: np.random.Generator, depth_range=None):
    """``n`` points on random training-pixel rays at random depths (``depth_range``, default [0.2, 4] x extent),
    with the pixel's colour: a random initialisation restricted to what the cameras see (no SfM points)."""
    from glint_mi.data.rays import pixel_rays

    views = ds.train_views or ds.views
    vi = rng.integers(0, len(views), n)
    pts, cols = np.zeros((n, 3)), np.zeros((n, 3), np.uint8)
    for k, v in enumerate(views):
        sel = np.flatnonzero(vi == k)
        if not len(sel):
            continue
        px = np.stack([rng.integers(0, v.width, len(sel)), rng.integers(0, v.height, len(sel))], -1)
        d = pixel_rays(v, px)
        lo_d, hi_d = depth_range if depth_range is not None else (0.2 * extent, 4.0 * extent)
        depth = rng.uniform(lo_d, hi_d, len(sel))
        pts[sel] = v.c2w[:3, 3] + d * depth[:, None]
        cols[sel] = (v.load_image()[px[:, 1], px[:, 0]] * 255 + 0.5).astype(np.uint8)
    return pts, cols


def initial_sets(scene: OptimScene, ds: Dataset, cfg, rng: np.random.Generator, log=print):
    """The three sets at the start of training, the scene box and extent, and a report of where they came from."""
    report = {}
    specs = scene.sets
    need_sfm = any(s.init == "sfm" for s in specs.values())
    pts, cols, report["sfm"] = (sfm_points(ds, log) if need_sfm else
                                (np.zeros((0, 3)), np.zeros((0, 3), np.uint8), {"source": "not needed"}))
    lo, hi, extent = scene_bounds(ds, pts if len(pts) else None)
    report["sfm_points"] = int(len(pts))
    if need_sfm and len(pts) < cfg.init_min_points:
        # too few SfM points to start from: top up. Around the SfM points when there are some (jittered copies
        # stay on the surfaces; uniform points along rays would sit in front of them as floaters that a narrow
        # camera arc never removes), else along training rays (the images are too small for SIFT).
        extra = cfg.init_min_points - len(pts)
        if len(pts) >= 8:
            pick = rng.integers(0, len(pts), extra)
            rp = pts[pick] + rng.normal(size=(extra, 3)) * knn_scales(pts)[pick, None]
            rc = cols[pick]
            report["random_points"] = f"{extra} jittered copies of SfM points"
        else:
            rp, rc = ray_points(ds, extra, extent, rng)
            report["random_points"] = f"{extra} random points on training rays"
        pts, cols = np.concatenate([pts, rp]), np.concatenate([cols, rc])
    sets = {}
    for role, spec in specs.items():
        if spec.init == "file":
            gs = GaussianSet.load_ply(spec.filename)
            if gs.sh_degree < cfg.sh_degree:  # pad the SH bands the config trains
                sh = np.zeros((len(gs), (cfg.sh_degree + 1) ** 2, 3))
                sh[:, :gs.sh.shape[1]] = gs.sh
                gs.sh = sh
            report[role] = f"{len(gs)} Gaussians from {spec.filename}"
        elif spec.init == "sfm":
            if not len(pts):
                raise DatasetError(f"{ds.root}: the point cloud is empty (no SfM points and SfM found none) and "
                                   f"init_min_points = 0; raise init_min_points or add sparse/0/points3D.")
            gs = points_set(pts, cols, cfg.init_opacity, cfg.sh_degree, rng)
            report[role] = f"{len(gs)} Gaussians from {report['sfm_points']} SfM points" + (
                f" + {report['random_points']}" if "random_points" in report else "")
        else:
            n, k = cfg.grid_n, cfg.grid_k
            gp = grid_points(lo, hi, n, k, rng)
            gs = points_set(gp, np.full((len(gp), 3), 128, np.uint8), cfg.init_opacity, cfg.sh_degree, rng)
            report[role] = f"{len(gs)} Gaussians on the {n}^3 x {k} grid"
        sets[role] = gs
    return sets, (lo, hi, extent), report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.scene",
                                 description="Print an optimisation scene XML for a dataset (redirect it to a file); "
                                             "what reading the dataset found goes to stderr.")
    ap.add_argument("dataset", type=Path, help="COLMAP folder, transforms.json or a generated scene folder")
    ap.add_argument("--components", help="auto | all | a comma list of sets; written into the XML (default: not "
                                          "written, the training config's applies)")
    ap.add_argument("--kernel", choices=cv.KERNELS, help="every set's kernel, written into the XML (default: not "
                                                         "written; the config's, surfel for glint)")
    ap.add_argument("--max-order", type=int, choices=(1, 2), help="written into the XML (default: the config's, 1)")
    ap.add_argument("--grid-n", type=int, help="reflection grid cells per axis (default: the preset's; paper 32)")
    ap.add_argument("--grid-k", type=int, help="random points per cell (default: the preset's; paper 5)")
    ap.add_argument("--skip-missing", action="store_true",
                    help="leave out the frames whose image is missing (default: refuse, listing them)")
    args = ap.parse_args(argv)
    missing = "skip" if args.skip_missing else "error"
    for flag, value in (("--grid-n", args.grid_n), ("--grid-k", args.grid_k)):
        if value is not None and value < 1:
            print(f"error: {flag} {value}: give at least 1 (the paper: --grid-n 32 --grid-k 5), or leave it out for "
                  f"the training preset's.", file=sys.stderr)
            return 2
    if args.components is not None:
        from glint_mi.config import ConfigError, TrainConfig

        try:
            TrainConfig.for_preset("quick", components=args.components)
        except ConfigError as e:
            print(f"error: --components {args.components}: {str(e).split(': ', 2)[-1]}", file=sys.stderr)
            return 2
    try:
        ds = load_dataset(args.dataset, missing=missing, log=lambda m: print(m, file=sys.stderr))
    except DatasetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(ds.summary(), file=sys.stderr)
    from glint_mi.data.priors import check_priors

    problems = check_priors(ds.root, ds.train_views)
    if problems:
        for line in problems:
            print(f"error: {line}", file=sys.stderr)
        return 2
    sys.stdout.write(scene_xml(args.dataset, args.components, args.kernel, args.grid_n, args.grid_k, missing=missing,
                               max_order=args.max_order))
    return 0


if __name__ == "__main__":
    sys.exit(main())
