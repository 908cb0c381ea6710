"""Generated transparent rooms: geometry rules, ground truth, camera exports and the dataset loader."""
import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mitsuba as mi

import glint_mi
from glint_mi.data import DatasetError, View, load_dataset
from glint_mi.conventions import MI_TO_COLMAP, qvec_to_rotmat, rotmat_to_qvec
from glint_mi.dataset.generate import Preset, make_scene
from glint_mi.data.exr import read_gt_exr
from glint_mi.dataset.room import _overlap, build_room

from conftest import needs_pycolmap

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "scene"
    make_scene(out, seed=6, preset=Preset.named("tiny", views=9, spp=16), sfm="none")
    return out


@pytest.mark.parametrize("seed", range(6))
def test_case_rests_on_a_support_and_intersects_nothing(seed):
    room = build_room(seed)
    lo, hi = room.case_lo, room.case_hi
    assert np.all(lo >= 0) and np.all(hi <= room.size)
    tops = {name: h[2] for l, h, name in room.boxes()}
    assert np.isclose(lo[2], 0.0 if room.support == "floor" else tops[room.support], atol=1e-9)
    for l2, h2, name in room.boxes():
        assert not _overlap(lo + [0, 0, 1e-6], hi, l2, h2), f"case intersects {name}"
    glass = [p for p in room.parts if p.glass]
    assert len(glass) == 6 and any(p.name == "case_frame" for p in room.parts)
    assert 1 <= sum(p.name.startswith("case_object") for p in room.parts) <= 3
    furniture = {p.name.split("_")[0] for p in room.parts if p.aabb is not None and not p.name.startswith("case")}
    assert 2 <= len(furniture) <= 5


def test_scene_folder_layout_and_ground_truth(scene_dir):
    for rel in ("scene.xml", "meta.json", "split.json", "transforms.json", "sparse/0/cameras.txt",
                "sparse/0/images.txt", "sparse/0/points3D.txt"):
        assert (scene_dir / rel).exists(), rel
    meta = json.loads((scene_dir / "meta.json").read_text())
    assert meta["views"] == 9 and 0.01 < meta["glass_pixel_fraction"] < 0.9
    split = json.loads((scene_dir / "split.json").read_text())
    assert split["test"] == ["view_000", "view_008"] and len(split["train"]) == 7
    gt = read_gt_exr(scene_dir / "gt" / "view_003.exr")
    assert set(gt) == {"R", "G", "B", "Z", "N.X", "N.Y", "N.Z", "T"}
    assert gt["Z"].shape == (27, 48)
    n = np.stack([gt["N.X"], gt["N.Y"], gt["N.Z"]], -1)
    hit = gt["Z"] > 0
    assert hit.mean() > 0.99, "a closed room: every pixel sees a surface"
    np.testing.assert_allclose(np.linalg.norm(n[hit], axis=-1), 1.0, atol=1e-4)
    assert set(np.unique(gt["T"])) <= {0.0, 1.0} and gt["T"].mean() > 0.01
    rgb = np.stack([gt["R"], gt["G"], gt["B"]], -1)
    assert np.isfinite(rgb).all() and 0.03 < rgb.mean() < 2.0


def test_scene_xml_rerenders_and_cameras_round_trip(scene_dir):
    """COLMAP and transforms.json cameras reproduce the scene.xml sensors; GT depth matches a fresh ray cast."""
    scene = glint_mi.load_file(scene_dir / "scene.xml")
    ds_colmap = load_dataset(scene_dir)
    ds_gl = load_dataset(scene_dir / "transforms.json")
    assert ds_colmap.source == "colmap" and ds_gl.source == "transforms"
    for i, sensor in enumerate(scene.sensors()):
        m = np.array(sensor.world_transform().matrix)[..., 0] if np.array(sensor.world_transform().matrix).ndim == 3 \
            else np.array(sensor.world_transform().matrix)
        for ds in (ds_colmap, ds_gl):
            v = ds.views[i]
            np.testing.assert_allclose(v.c2w, m, atol=1e-5)
            fov = mi.traverse(sensor)["x_fov"][0]
            np.testing.assert_allclose(v.K[0, 0], 0.5 * v.width / np.tan(np.radians(fov) / 2), rtol=1e-5)
    # planar depth in the EXR equals z of the back-projected surface point in COLMAP camera coordinates
    v = ds_colmap.views[2]
    gt = v.load_gt()
    from glint_mi.model.render import camera_rays
    pix = np.array([[10, 5], [24, 13], [40, 20]])
    ray, _ = camera_rays(scene.sensors()[2], pix)
    si = scene.ray_intersect(ray)
    p_world = np.array(si.p).T
    R_c2w = v.c2w[:3, :3] @ MI_TO_COLMAP
    p_cam = (p_world - v.c2w[:3, 3]) @ R_c2w  # world -> OpenCV camera
    np.testing.assert_allclose(p_cam[:, 2], gt["depth"][pix[:, 1], pix[:, 0]], rtol=1e-4)
    uv = (p_cam / p_cam[:, 2:]) @ v.K.T  # pinhole projection lands on the pixel centre
    np.testing.assert_allclose(uv[:, :2], pix + 0.5, atol=1e-3)


def test_principal_point_offset_matches_K():
    """View.sensor_dict() rays go through K^-1 (u, v, 1) also for an off-centre principal point."""
    K = np.array([[40.0, 0, 30.0], [0, 40.0, 14.0], [0, 0, 1]])
    v = View("x", Path("x.png"), 48, 27, K, np.eye(4))
    sensor = mi.load_dict(v.sensor_dict())
    from glint_mi.model.render import camera_rays
    pix = np.array([[3, 2], [30, 14], [45, 25]])
    ray, _ = camera_rays(sensor, pix)
    d_mi = np.array(ray.d).T
    d_cv = np.column_stack([(pix + 0.5 - K[:2, 2]) / 40.0, np.ones(3)]) * [-1, -1, 1]  # OpenCV -> Mitsuba camera axes
    d_cv /= np.linalg.norm(d_cv, axis=1, keepdims=True)
    np.testing.assert_allclose(d_mi, d_cv, atol=1e-5)


def test_quaternion_round_trip(rng):
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[0] >= 0 else -q
        np.testing.assert_allclose(rotmat_to_qvec(qvec_to_rotmat(q)), q, atol=1e-9)


def _write_colmap_bin(src: Path, dst: Path):
    """Convert the text model to COLMAP's binary format (cameras.bin, images.bin, points3D.bin)."""
    dst.mkdir(parents=True)
    cams = [l.split() for l in open(src / "cameras.txt") if l.strip() and not l.startswith("#")]
    with open(dst / "cameras.bin", "wb") as f:
        f.write(struct.pack("<Q", len(cams)))
        for c in cams:
            f.write(struct.pack("<iiQQ", int(c[0]), 1, int(c[2]), int(c[3])) + struct.pack("<4d", *map(float, c[4:8])))
    ims = [l.split() for l in open(src / "images.txt") if l.strip() and not l.startswith("#")]
    with open(dst / "images.bin", "wb") as f:
        f.write(struct.pack("<Q", len(ims)))
        for im in ims:
            f.write(struct.pack("<i7di", int(im[0]), *map(float, im[1:8]), int(im[8])) + im[9].encode() + b"\x00")
            f.write(struct.pack("<Q", 0))
    with open(dst / "points3D.bin", "wb") as f:
        f.write(struct.pack("<Q", 1) + struct.pack("<Q3d3BdQ", 1, 1.0, 2.0, 3.0, 10, 20, 30, 0.5, 0))


def test_colmap_binary_equals_text(scene_dir, tmp_path):
    copy = tmp_path / "bin"
    shutil.copytree(scene_dir / "images", copy / "images")
    _write_colmap_bin(scene_dir / "sparse" / "0", copy / "sparse" / "0")
    a, b = load_dataset(scene_dir), load_dataset(copy)
    for va, vb in zip(a.views, b.views):
        np.testing.assert_allclose(va.c2w, vb.c2w, atol=1e-9)
        np.testing.assert_allclose(va.K, vb.K)
    np.testing.assert_allclose(b.points, [[1.0, 2.0, 3.0]])


@needs_pycolmap
def test_loader_errors_name_file_and_fix(scene_dir, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(scene_dir, bad, ignore=shutil.ignore_patterns("meshes", "textures", "gt"))
    (bad / "images" / "view_004.png").unlink()
    with pytest.raises(DatasetError, match=r"1 of 9 frames name images that are not there: .*view_004\.png.*"
                                           r"--skip-missing"):
        load_dataset(bad)
    skipped = load_dataset(bad, missing="skip")
    assert "view_004" not in [v.name for v in skipped.views] and len(skipped.views) == 8
    assert "view_004" not in skipped.split["train"] + skipped.split["test"]
    shutil.copy(bad / "images" / "view_003.png", bad / "images" / "view_004.png")
    from PIL import Image
    Image.new("RGB", (10, 7)).save(bad / "images" / "view_005.png")
    with pytest.raises(DatasetError, match=r"view_005\.png: 7x10 \(HxW\) but its camera says 27x48"):
        load_dataset(bad)
    shutil.copy(bad / "images" / "view_003.png", bad / "images" / "view_005.png")
    cams = (bad / "sparse" / "0" / "cameras.txt").read_text().replace("PINHOLE", "OPENCV", 1)
    (bad / "sparse" / "0" / "cameras.txt").write_text(cams)
    with pytest.raises(DatasetError, match=r"camera model OPENCV takes the parameters .*got 4 values"):
        load_dataset(bad)
    shutil.rmtree(bad / "sparse")
    (bad / "split.json").write_text(json.dumps({"train": ["view_001", "nope"], "test": ["view_000"]}))
    with pytest.raises(DatasetError, match=r"split\.json: names view\(s\) the camera file does not list: \['nope'\]"):
        load_dataset(bad)
    (bad / "split.json").unlink()
    ds = load_dataset(bad)  # transforms.json, default split: every 8th view from 0
    assert ds.split["test"] == ["view_000", "view_008"]
    tj = json.loads((bad / "transforms.json").read_text())
    del tj["frames"][0]["transform_matrix"]
    (bad / "transforms.json").write_text(json.dumps(tj))
    with pytest.raises(DatasetError, match=r"frames\[0\] needs 'file_path' and 'transform_matrix'"):
        load_dataset(bad)
    with pytest.raises(DatasetError, match="no such dataset folder"):
        load_dataset(tmp_path / "missing")


def test_nan_in_gt_exr_is_reported(scene_dir, tmp_path):
    from glint_mi.data.exr import write_gt_exr
    ds = load_dataset(scene_dir)
    v = ds.views[1]
    gt = v.load_gt()
    z = gt["depth"].copy()
    z[3, 4] = np.nan
    bad = tmp_path / "nan.exr"
    write_gt_exr(bad, gt["rgb"], {"Z": z[..., None], "N": gt["normal"], "T": gt["glass"][..., None]})
    v.gt_path = bad
    with pytest.raises(DatasetError, match=r"nan\.exr: NaN/Inf in 'depth'"):
        v.load_gt()


def test_cli_make_tiny(tmp_path):
    r = subprocess.run([sys.executable, "-m", "glint_mi.dataset", "make", str(tmp_path), "--scenes", "1", "--seed", "3",
                        "--preset", "tiny", "--views", "3", "--spp", "4"], capture_output=True, text=True, cwd=ROOT,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert "scene_003: 3 views" in r.stdout
    assert json.loads((tmp_path / "summary.json").read_text())["scenes"][0]["scene"] == "scene_003"
    assert not any(p.name.endswith(".partial") for p in tmp_path.iterdir())
    # a rerun resumes: the finished scene is skipped, not regenerated
    stamp = (tmp_path / "scene_003" / "meta.json").stat().st_mtime_ns
    r = subprocess.run([sys.executable, "-m", "glint_mi.dataset", "make", str(tmp_path), "--scenes", "1", "--seed", "3",
                        "--preset", "tiny", "--views", "3", "--spp", "4"], capture_output=True, text=True, cwd=ROOT,
                       timeout=600)
    assert r.returncode == 0 and "already complete" in r.stdout, r.stdout + r.stderr
    assert (tmp_path / "scene_003" / "meta.json").stat().st_mtime_ns == stamp


def test_interrupted_scene_resumes_with_identical_views(tmp_path):
    """A run stopped after two views keeps them; the rerun renders only the rest and matches an uninterrupted run."""
    preset = Preset.named("tiny", views=4, spp=4)

    def stop_after_two(done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        make_scene(tmp_path / "a", seed=5, preset=preset, progress=stop_after_two, sfm="none", priors=False)
    assert not (tmp_path / "a").exists() and len(list((tmp_path / "a.partial" / "images").glob("*.png"))) == 2
    meta = make_scene(tmp_path / "a", seed=5, preset=preset, sfm="none", priors=False)
    assert meta["views_resumed"] == 2 and not (tmp_path / "a" / "partial.json").exists()
    make_scene(tmp_path / "b", seed=5, preset=preset, sfm="none", priors=False)
    for f in sorted((tmp_path / "b" / "gt").glob("*.exr")):
        a, b = read_gt_exr(tmp_path / "a" / "gt" / f.name), read_gt_exr(f)
        assert all(np.array_equal(a[k], b[k]) for k in b), f.name
    # another seed does not reuse the partial views of this one
    with pytest.raises(KeyboardInterrupt):
        make_scene(tmp_path / "c", seed=5, preset=preset, progress=stop_after_two, sfm="none", priors=False)
    assert make_scene(tmp_path / "c", seed=6, preset=preset, sfm="none", priors=False)["views_resumed"] == 0


def test_room_without_glass_is_the_same_room():
    """--no-glass drops exactly the six glass panels; every other part is identical (a controlled comparison)."""
    a, b = build_room(4), build_room(4, glass=False)
    glass = [p.name for p in a.parts if p.glass]
    assert len(glass) == 6 and not any(p.glass for p in b.parts)
    rest = [p for p in a.parts if not p.glass]
    assert [p.name for p in rest] == [p.name for p in b.parts]
    for p, q in zip(rest, b.parts):
        np.testing.assert_array_equal(p.mesh.vertices, q.mesh.vertices)
    np.testing.assert_array_equal(a.case_lo, b.case_lo)


@needs_pycolmap
def test_sfm_points_lie_on_surfaces(tmp_path):
    """Known-pose triangulation (pycolmap SIFT + matching) gives points on the scene's surfaces."""
    from glint_mi.dataset.trajectory import trajectory
    from glint_mi.dataset.generate import sfm_points, write_scene_files
    room = build_room(2)
    cams = trajectory(room, 10, 96, 54, 2)
    scene = glint_mi.load_file(write_scene_files(tmp_path, room, cams, 16))
    xyz, rgb, stats, tracks = sfm_points(scene, tmp_path, cams, "known", width=384, spp=128)
    assert stats["points3D"] >= 20 and stats["mean_reprojection_error_px"] < 2.0
    # the tracks: each observation is where its point projects in that view (dataset pixels), and they reach
    # the COLMAP files and read back as the same observations
    from glint_mi.data import read_observations
    from glint_mi.data.cameras import write_colmap_text
    n_obs = 0
    for c in cams:
        xy, rows = tracks[c.name]
        pc = (xyz[rows] - c.c2w[:3, 3]) @ (c.c2w[:3, :3] @ MI_TO_COLMAP)  # OpenCV camera coordinates
        proj = np.column_stack([c.fx * pc[:, 0] / pc[:, 2] + c.cx, c.fy * pc[:, 1] / pc[:, 2] + c.cy])
        if len(rows):
            assert np.median(np.linalg.norm(proj - xy, axis=1)) < 1.0
        n_obs += len(rows)
    assert n_obs >= 2 * stats["points3D"]
    write_colmap_text(tmp_path / "sparse" / "0", cams, (xyz, rgb), tracks)
    obs = read_observations(tmp_path)
    for c in cams:
        np.testing.assert_allclose(obs[c.name][0], tracks[c.name][0], atol=1e-5)
        np.testing.assert_allclose(obs[c.name][1], xyz[tracks[c.name][1]], rtol=1e-6, atol=1e-6)
    # `python -m glint_mi.dataset tracks`: the same triangulation again from the kept sfm/images, written to sparse/0
    from PIL import Image

    from glint_mi.dataset.__main__ import main as dataset_main
    (tmp_path / "images").mkdir()
    for c in cams:
        Image.open(tmp_path / "sfm" / "images" / f"{c.name}.png").resize((c.width, c.height)).save(
            tmp_path / "images" / f"{c.name}.png")
    (tmp_path / "sparse" / "0" / "points3D.txt").write_text("")  # as an old room: no points, no tracks
    assert dataset_main(["tracks", str(tmp_path)]) == 0
    again = read_observations(tmp_path)
    assert abs(sum(len(v[0]) for v in again.values()) - n_obs) <= 0.1 * n_obs
    # distance from each point to the first surface seen from the nearest camera along the line of sight
    errs = []
    for p in xyz:
        c = min(cams, key=lambda c: np.linalg.norm(c.c2w[:3, 3] - p)).c2w[:3, 3]
        d = p - c
        dist = np.linalg.norm(d)
        ray = mi.Ray3f(mi.Point3f(*c.tolist()), mi.Vector3f(*(d / dist).tolist()))
        errs.append(abs(float(np.array(scene.ray_intersect(ray).t)[0]) - dist))
    assert np.median(errs) < 0.03, f"median distance to the surface {np.median(errs):.3f} m"


def test_derived_priors_have_the_documented_corruptions(scene_dir):
    """The default (realistic) priors of a generated room: depth affine in the truth off glass up to smooth warps,
    farther than the glass where the estimator sees through it; albedo there is the far surface's (darkened, the photo
    baked in), never the glass BSDF's; normals in OpenCV camera space, facing the camera, ~15 deg off."""
    import glint_mi
    import mitsuba as mi
    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.dataset.priors import _behind_glass, _first_albedo, load_prior, priors_are_derived
    ds = load_dataset(scene_dir)
    assert priors_are_derived(scene_dir)
    scene = glint_mi.load_file(scene_dir / "scene.xml")
    record = json.loads((scene_dir / "priors" / "PRIORS.json").read_text())
    assert record["model"] == "realistic"
    checked, angles = 0, []
    for v in ds.views:
        gt = v.load_gt()
        d, n, a = (load_prior(scene_dir, v, k) for k in ("depth", "normal", "albedo"))
        glass = gt["glass"] > 0.5
        opaque = ~glass & (gt["depth"] > 0)
        rec = record["views"][v.name]
        # depth: affine in the truth off glass (unknown scale/shift) up to the smooth warps
        A = np.column_stack([gt["depth"][opaque], np.ones(opaque.sum())])
        (s, b), *_ = np.linalg.lstsq(A, d[opaque], rcond=None)
        assert np.isclose(s, rec["depth_scale"], rtol=0.35)
        assert np.median(np.abs(A @ [s, b] - d[opaque]) / np.abs(d[opaque])) < 0.08
        n_gt = world_to_opencv_normals(gt["normal"], v.c2w)
        angles.append(np.degrees(np.arccos(np.clip((n * n_gt).sum(-1), -1, 1)))[opaque].mean())
        assert n_gt[opaque][:, 2].mean() < 0, "normals face the camera: negative z in OpenCV camera space"
        if glass.sum() > 5 and rec["see_through_share_of_glass"] > 0.5:
            sensor = mi.load_dict(v.sensor_dict())
            z_behind, _, alb_behind = _behind_glass(scene, sensor)
            excess = (d - b) / s - gt["depth"]
            assert np.median(excess[glass]) > 0.05
            ratio = a[glass].mean() / max(alb_behind[glass].mean(), 1e-6)
            assert 0.4 < ratio < 1.8, ratio  # darkening 0.7-1, gain 0.8-1.2, the photo's leak, edge blur
            bsdf = _first_albedo(scene, sensor)  # the glass's own (~0): never what the prior reports
            assert (np.abs(a - bsdf).max(-1) < 0.01)[glass].mean() < 0.05
            checked += 1
    assert checked >= 1
    assert 8 < np.mean(angles) < 25, angles


def test_prior_readers_take_exr_channels_by_name(scene_dir, tmp_path):
    """An R,G,B EXR albedo keeps its channel order (not alphabetical); a normal EXR may use N.X/N.Y/N.Z."""
    import OpenEXR
    from glint_mi.dataset.priors import PriorError, load_prior
    v = load_dataset(scene_dir).views[0]
    rgb = np.stack([np.full((27, 48), 0.1), np.full((27, 48), 0.5), np.full((27, 48), 0.9)], -1).astype(np.float32)
    root = tmp_path / "ds"
    for kind, chans in (("albedo", {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]}),
                        ("normal", {"N.X": rgb[..., 0], "N.Y": rgb[..., 1], "N.Z": rgb[..., 2]})):
        (root / "priors" / kind).mkdir(parents=True)
        with OpenEXR.File({"type": OpenEXR.scanlineimage}, {k: np.ascontiguousarray(c) for k, c in chans.items()}) as f:
            f.write(str(root / "priors" / kind / f"{v.name}.exr"))
        want = np.array([0.1, 0.5, 0.9])
        want = want / np.linalg.norm(want) if kind == "normal" else want  # normals come back unit length
        np.testing.assert_allclose(load_prior(root, v, kind)[3, 4], want, atol=1e-6)
    (root / "priors" / "depth").mkdir(parents=True)
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Q": np.zeros((27, 48), np.float32)}) as f:
        f.write(str(root / "priors" / "depth" / f"{v.name}.exr"))
    with pytest.raises(PriorError, match="a depth prior needs one of"):
        load_prior(root, v, "depth")


def test_priors_without_albedo_that_see_the_glass(scene_dir, tmp_path):
    """--no-albedo-prior writes depth and normal only (the same maps as with albedo: one random stream);
    see-through 0 gives the glass surface's depth."""
    import shutil

    from glint_mi.dataset.priors import Corruption, derive_priors, load_prior
    work = tmp_path / "s"
    shutil.copytree(scene_dir, work)
    derive_priors(work, seed=2, corruption=Corruption(see_through_glass=0.0), albedo=True)
    ds = load_dataset(work)
    with_albedo = [load_prior(work, v, "depth") for v in ds.views]
    derive_priors(work, seed=2, corruption=Corruption(see_through_glass=0.0), albedo=False)
    record = json.loads((work / "priors" / "PRIORS.json").read_text())
    assert record["kinds"] == ["depth", "normal"] and not (work / "priors" / "albedo").exists()
    checked = 0
    for v, before in zip(ds.views, with_albedo):
        assert load_prior(work, v, "albedo") is None
        d, gt = load_prior(work, v, "depth"), v.load_gt()
        np.testing.assert_array_equal(d, before)
        valid = gt["depth"] > 0
        A = np.column_stack([gt["depth"][valid], np.ones(valid.sum())])
        (s, b), *_ = np.linalg.lstsq(A, d[valid], rcond=None)
        glass = (gt["glass"] > 0.5) & valid
        if glass.sum() > 5:  # on the glass the prior follows the glass surface, not what is behind it
            assert np.median(np.abs((d[glass] - b) / s - gt["depth"][glass]) / gt["depth"][glass]) < 0.05
            checked += 1
    assert checked >= 1


def test_realistic_priors_measure_like_an_estimator(scene_dir, tmp_path):
    """The realistic model (the default), measured here from the written maps against ground truth: normals ~15 deg
    off glass, depth AbsRel ~0.05 after a per-image affine fit, smooth errors (neighbouring pixels err alike); on glass
    the estimator sees through over part of the glass; the masks are a segmenter's; PRIORS.json records what the
    test measures, and the amplitudes it drew."""
    import shutil

    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.dataset.priors import derive_priors, load_prior

    work = tmp_path / "s"
    shutil.copytree(scene_dir, work)
    derive_priors(work, seed=3)
    record = json.loads((work / "priors" / "PRIORS.json").read_text())
    assert record["model"] == "realistic" and record["derived_from_ground_truth"]
    assert set(record["drawn"]) >= {"normal_world_deg", "depth_world", "tint", "pane_difficulty"}
    ds = load_dataset(work)
    n_err, d_err, smooth, through, ious = [], [], [], [], []
    for v in ds.views:
        gt = v.load_gt()
        valid, glass = gt["depth"] > 0, (gt["glass"] > 0.5) & (gt["depth"] > 0)
        off = valid & ~glass
        n = load_prior(work, v, "normal")
        g = world_to_opencv_normals(gt["normal"], v.c2w)
        ang = np.degrees(np.arccos(np.clip(np.sum(n * g, -1), -1, 1)))
        n_err.append(ang[off].mean())
        d = load_prior(work, v, "depth")
        A = np.column_stack([gt["depth"][valid], np.ones(valid.sum())])
        (w, q), *_ = np.linalg.lstsq(A, d[valid], rcond=None)  # as PRIORS.json measures (the fit sees the glass)
        rec = record["views"][v.name]
        assert abs(rec["measured"]["normal_mae_deg_off_glass"] - n_err[-1]) < 1e-3
        assert abs(rec["measured"]["depth_absrel_off_glass"]
                   - np.mean(np.abs((d[off] - q) / w - gt["depth"][off]) / gt["depth"][off])) < 1e-4
        A = np.column_stack([gt["depth"][off], np.ones(off.sum())])  # the estimator's error off glass alone
        (w, q), *_ = np.linalg.lstsq(A, d[off], rcond=None)
        d_err.append(np.mean(np.abs((d[off] - q) / w - gt["depth"][off]) / gt["depth"][off]))
        both = off[:, 1:] & off[:, :-1]
        smooth.append(np.abs(ang[:, 1:] - ang[:, :-1])[both].mean() / max(ang[off].mean(), 1e-6))
        if glass.sum() > 10:
            through.append(rec["see_through_share_of_glass"])
            m = load_prior(work, v, "glass") > 0.5
            ious.append((m & glass).sum() / max((m | glass).sum(), 1))
            assert abs(rec["mask_iou"] - ious[-1]) < 1e-6
    assert 9 < np.mean(n_err) < 22 and 0.02 < np.mean(d_err) < 0.1, (np.mean(n_err), np.mean(d_err))
    assert np.mean(smooth) < 0.4, np.mean(smooth)
    assert len(through) >= 3 and 0.1 <= np.mean(through) < 1.0, through
    assert abs(record["measured"]["normal_mae_deg_off_glass"] - np.mean(n_err)) < 1e-3
    assert 0.2 < np.mean(ious) < 0.95 and abs(record["measured"]["glass_mask_iou"] - np.mean(ious)) < 1e-6, ious


def test_cycles_rendered_scene_is_a_complete_dataset(tmp_path):
    """dataset make --renderer cycles: every view and every gt pass from Cycles, in the protocol layout; the passes
    agree with Mitsuba's first-surface buffers of the same room (depth 1 %, normals facing the camera, glass)."""
    from glint_mi.dataset.cycles_render import CyclesUnavailable, find_bpy
    from glint_mi.dataset.generate import first_surface_buffers
    try:
        find_bpy()
    except CyclesUnavailable as e:
        pytest.skip(f"optional cycles extra not installed: {e}")
    import glint_mi
    meta = make_scene(tmp_path / "c", seed=4, preset=Preset.named("tiny", views=3, spp=16), sfm="none",
                      renderer="cycles", albedo_prior=False, see_through=0.0)
    assert meta["renderer"] == "cycles" and meta["gt_noise_psnr_db"] > 10
    ds = load_dataset(tmp_path / "c")
    assert len(ds.views) == 3 and not (tmp_path / "c" / "priors" / "albedo").exists()
    scene = glint_mi.load_file(tmp_path / "c" / "scene.xml")
    for i, v in enumerate(ds.views):
        gt, ref = v.load_gt(), first_surface_buffers(scene, scene.sensors()[i])
        ok = (gt["depth"] > 0) & (ref["Z"][..., 0] > 0)
        assert ok.mean() > 0.9
        rel = np.abs(gt["depth"] - ref["Z"][..., 0])[ok] / ref["Z"][..., 0][ok]
        cos = np.sum(gt["normal"] * ref["N"], -1)[ok]
        # Cycles filters normals over the pixel: at 48 x 27 about 10 % are edge pixels
        assert np.mean(rel < 0.01) > 0.95 and np.median(cos) > 0.999 and np.mean(cos > 0.9) > 0.85
        assert np.mean((gt["glass"] > 0.5) == (ref["T"][..., 0] > 0.5)) > 0.97
        assert v.load_image().shape == (v.height, v.width, 3)


def test_sfm_observations_text_and_binary(tmp_path):
    """read_observations: per image, the tracked features that triangulated (POINT3D_ID -1 dropped) and their
    points, the same from COLMAP's text and binary models; None without points3D."""
    from glint_mi.data import read_observations

    pts = {7: (1.0, 2.0, 3.0), 9: (-1.0, 0.5, 4.0)}
    ims = [(1, "a.png", [(10.5, 4.0, 7), (3.0, 3.0, -1), (20.0, 8.0, 9)]), (2, "sub/b.jpg", [])]
    txt = tmp_path / "txt" / "sparse" / "0"
    txt.mkdir(parents=True)
    (txt / "cameras.txt").write_text("1 PINHOLE 32 24 30 30 16 12\n")
    with open(txt / "images.txt", "w") as f:
        f.write("# header\n")
        for iid, name, obs in ims:
            f.write(f"{iid} 1 0 0 0 0 0 0 1 {name}\n" + " ".join(f"{x} {y} {p}" for x, y, p in obs) + "\n")
    with open(txt / "points3D.txt", "w") as f:
        for pid, xyz in pts.items():
            f.write(f"{pid} {xyz[0]} {xyz[1]} {xyz[2]} 1 2 3 0.5 1 0\n")
    bin_ = tmp_path / "bin" / "sparse" / "0"
    bin_.mkdir(parents=True)
    (bin_ / "cameras.bin").write_bytes(struct.pack("<Q", 1) + struct.pack("<iiQQ", 1, 1, 32, 24)
                                       + struct.pack("<4d", 30, 30, 16, 12))
    with open(bin_ / "images.bin", "wb") as f:
        f.write(struct.pack("<Q", len(ims)))
        for iid, name, obs in ims:
            f.write(struct.pack("<i7di", iid, 1, 0, 0, 0, 0, 0, 0, 1) + name.encode() + b"\x00")
            f.write(struct.pack("<Q", len(obs)) + b"".join(struct.pack("<ddq", x, y, p) for x, y, p in obs))
    with open(bin_ / "points3D.bin", "wb") as f:
        f.write(struct.pack("<Q", len(pts)))
        for pid, xyz in pts.items():
            f.write(struct.pack("<Q3d3BdQ", pid, *xyz, 1, 2, 3, 0.5, 1) + struct.pack("<ii", 1, 0))
    for root in (tmp_path / "txt", tmp_path / "bin"):
        obs = read_observations(root)
        assert sorted(obs) == ["a", "b"]
        np.testing.assert_allclose(obs["a"][0], [[10.5, 4.0], [20.0, 8.0]])
        np.testing.assert_allclose(obs["a"][1], [pts[7], pts[9]])
        assert obs["b"][0].shape == (0, 2) and obs["b"][1].shape == (0, 3)
    (txt / "points3D.txt").unlink()
    assert read_observations(tmp_path / "txt") is None


def test_sfm_points_come_from_the_same_scene_generated_elsewhere(tmp_path):
    """``make --sfm-from DIR`` (a GPU without pycolmap): sparse/0 is copied from the same scene generated with
    --sfm known, at the size given by --size; a scene with other cameras (seed, size) is refused before anything is
    written, with one line naming the folder and the fix."""
    run = lambda out, *extra: subprocess.run(
        [sys.executable, "-m", "glint_mi.dataset", "make", str(out), "--seed", "4", "--preset", "tiny", "--views", "3",
         "--spp", "4", "--priors", "none", *extra], capture_output=True, text=True, cwd=ROOT, timeout=600)
    src = tmp_path / "src"
    assert run(src, "--size", "40x24").returncode == 0
    scene = src / "scene_004"
    meta = json.loads((scene / "meta.json").read_text())
    assert meta["preset"]["width"] == 40 and meta["preset"]["height"] == 24
    # stand-in for a --sfm known scene (pycolmap's triangulation takes a minute): points and the mode it records
    (scene / "sparse" / "0" / "points3D.txt").write_text("# 1 point\n1 0.1 0.2 0.3 200 100 50 0.5\n")
    (scene / "meta.json").write_text(json.dumps({**meta, "sfm": {"mode": "known", "points3D": 1}}))
    r = run(tmp_path / "gpu", "--size", "40x24", "--sfm-from", str(src))
    assert r.returncode == 0, r.stderr
    out = tmp_path / "gpu" / "scene_004"
    assert (out / "sparse" / "0" / "points3D.txt").read_text() == (scene / "sparse" / "0" / "points3D.txt").read_text()
    assert json.loads((out / "meta.json").read_text())["sfm"]["copied_from"] == str(scene)
    r = run(tmp_path / "other", "--size", "48x27", "--sfm-from", str(src))
    assert r.returncode == 2 and r.stderr.strip().splitlines()[-1].startswith("error: --sfm-from:"), r.stderr
    assert "is not this scene" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "other").exists() or not any((tmp_path / "other").iterdir())
    r = run(tmp_path / "bad", "--size", "40x", "--sfm-from", str(src))
    assert r.returncode == 2 and "--size 40x" in r.stderr
