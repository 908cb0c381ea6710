"""Real captures as they come: distorted JPEGs in a transforms.json, missing and broken frames, images_<k> folders,
priors written by monocular estimators, SfM from the known poses, evaluation that can be interrupted; and the
instant-ngp fox (a real phone capture, ../shared/data/real_fox) end to end at tiny scale."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from glint_mi.data import DatasetError, load_dataset

from conftest import needs_pycolmap

ROOT = Path(__file__).resolve().parent.parent
FOX = Path(os.environ.get("GLINT_FOX", ROOT.parent / "shared" / "data" / "real_fox"))
K1, K2, P1, P2 = 0.12, -0.05, 0.002, -0.001


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("GLINT_CACHE", str(tmp_path / "cache"))


def texture(h=96, w=128):
    """A smooth natural image (bilinear resampling twice stays within a few %)."""
    from scipy.ndimage import gaussian_filter, zoom
    from skimage import data

    img = data.astronaut()[::2, ::2].astype(np.float64) / 255.0
    img = zoom(img, (h / img.shape[0], w / img.shape[1], 1), order=1)
    return np.clip(gaussian_filter(img, (1.5, 1.5, 0)), 0, 1)


def sample(img, x, y):
    """Bilinear sample of [H,W,3] at continuous pixel coordinates (pixel centres at +0.5)."""
    from scipy.ndimage import map_coordinates

    return np.stack([map_coordinates(img[..., c], [y - 0.5, x - 0.5], order=1, mode="nearest") for c in range(3)], -1)


def distorted_capture(folder: Path, n=3, ext=".png", frame_intrinsics=False):
    """A transforms.json capture whose images are ``texture()`` seen through an OPENCV camera (k1 k2 p1 p2)."""
    import pycolmap
    from PIL import Image

    h, w = 96, 128
    fx, cx, cy = 110.0, 63.0, 49.0
    cam = pycolmap.Camera(model="OPENCV", width=w, height=h, params=[fx, fx, cx, cy, K1, K2, P1, P2])
    pin = texture(h, w)
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    norm = np.asarray(cam.cam_from_img(np.stack([xs.ravel(), ys.ravel()], -1)))
    dist = sample(pin, norm[:, 0] * fx + cx, norm[:, 1] * fx + cy).reshape(h, w, 3)
    (folder / "images").mkdir(parents=True)
    frames = []
    for i in range(n):
        Image.fromarray((dist * 255 + 0.5).astype(np.uint8)).save(folder / "images" / f"f{i}{ext}", quality=95)
        m = np.eye(4)
        m[0, 3] = 0.1 * i
        fr = {"file_path": f"images/f{i}{ext}", "transform_matrix": m.tolist()}
        if frame_intrinsics:
            fr.update(fl_x=fx, fl_y=fx, cx=cx, cy=cy, w=w, h=h)
        frames.append(fr)
    meta = {"k1": K1, "k2": K2, "p1": P1, "p2": P2, "frames": frames}
    if not frame_intrinsics:
        meta.update(fl_x=fx, fl_y=fx, cx=cx, cy=cy, w=w, h=h)
    (folder / "transforms.json").write_text(json.dumps(meta))
    return pin, np.array([[fx, 0, cx], [0, fx, cy], [0, 0, 1.0]])


@needs_pycolmap
@pytest.mark.parametrize("frame_intrinsics", [False, True])
def test_undistorted_views_see_the_pinhole_image(tmp_path, frame_intrinsics):
    """An OPENCV capture is undistorted once (pycolmap) into the cache: each undistorted pixel's ray, through the
    view's K, lands where the pinhole image has the same colour (mean error < 2 %), with shared or per-frame
    intrinsics; a second load reads the cache."""
    pin, K0 = distorted_capture(tmp_path / "cap", frame_intrinsics=frame_intrinsics)
    logs = []
    ds = load_dataset(tmp_path / "cap", log=logs.append)
    assert any("undistorting 3 images" in m for m in logs)
    assert any("OPENCV camera undistorted" in n for n in ds.notes)
    v = ds.views[1]
    assert v.image_path.parent.parent == tmp_path / "cache" / "undistorted"
    img = v.load_image()
    ys, xs = np.mgrid[0:v.height, 0:v.width] + 0.5
    rays = np.linalg.solve(v.K, np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)]))
    px = K0 @ rays
    want = sample(pin, px[0], px[1]).reshape(img.shape)
    inner = (slice(4, -4), slice(4, -4))
    err = np.abs(img[inner] - want[inner]).mean()
    assert err < 0.02, err
    # the same image without undistortion is clearly off (the test can fail)
    raw = np.asarray(__import__("PIL.Image", fromlist=["Image"]).open(tmp_path / "cap" / "images" / "f1.png"),
                     np.float64) / 255
    assert np.abs(raw[:v.height, :v.width][inner] - want[inner]).mean() > 2 * err
    logs.clear()
    again = load_dataset(tmp_path / "cap", log=logs.append)
    assert not logs and np.allclose(again.views[1].K, v.K)
    if frame_intrinsics:
        return
    # the cache is keyed by the images' contents: a copy elsewhere with new file times reads it; changed bytes miss it
    import shutil
    import time

    time.sleep(0.01)
    shutil.copytree(tmp_path / "cap", tmp_path / "copy")  # copytree keeps times; touch them all
    for f in (tmp_path / "copy" / "images").iterdir():
        os.utime(f)
    copied = load_dataset(tmp_path / "copy", log=logs.append)
    assert not logs and copied.views[1].image_path == v.image_path
    f1 = tmp_path / "copy" / "images" / "f1.png"
    raw_copy = np.asarray(__import__("PIL.Image", fromlist=["Image"]).open(f1)).copy()
    raw_copy[0, 0] ^= 1
    __import__("PIL.Image", fromlist=["Image"]).fromarray(raw_copy).save(f1)
    load_dataset(tmp_path / "copy", log=logs.append)
    assert any("undistorting 3 images" in m for m in logs)


@needs_pycolmap
def test_missing_and_broken_frames_are_named(tmp_path):
    """Missing images are listed all at once (skip drops them and says so); a truncated JPEG is named before any
    work; downscale reads images_<k> when the capture ships one."""
    distorted_capture(tmp_path / "cap", n=4, ext=".jpg")
    tj = json.loads((tmp_path / "cap" / "transforms.json").read_text())
    tj["frames"] += [{"file_path": "images/gone_a.jpg", "transform_matrix": np.eye(4).tolist()},
                     {"file_path": "images/gone_b.jpg", "transform_matrix": np.eye(4).tolist()}]
    (tmp_path / "cap" / "transforms.json").write_text(json.dumps(tj))
    with pytest.raises(DatasetError, match=r"2 of 6 frames name images that are not there: images/gone_a\.jpg, "
                                           r"images/gone_b\.jpg\. .*--skip-missing"):
        load_dataset(tmp_path / "cap")
    ds = load_dataset(tmp_path / "cap", missing="skip")
    assert [v.name for v in ds.views] == ["f0", "f1", "f2", "f3"]
    assert any("2 of 6 frames skipped" in n for n in ds.notes) and any("every 8th view" in n for n in ds.notes)
    jpg = tmp_path / "cap" / "images" / "f2.jpg"
    jpg.write_bytes(jpg.read_bytes()[: len(jpg.read_bytes()) // 2])
    with pytest.raises(DatasetError, match=r"1 image\(s\) cannot be decoded:\n  .*f2\.jpg: cannot decode the image"):
        load_dataset(tmp_path / "cap", missing="skip")


def test_images_k_folder_and_downscale(tmp_path):
    from PIL import Image

    from glint_mi.data.cameras import write_transforms_json, Camera

    folder = tmp_path / "pin"
    (folder / "images").mkdir(parents=True)
    (folder / "images_2").mkdir()
    img = (texture(40, 64) * 255).astype(np.uint8)
    cams = []
    for i in range(2):
        Image.fromarray(img).save(folder / "images" / f"v{i}.png")
        Image.fromarray(img[::2, ::2] // 2).save(folder / "images_2" / f"v{i}.png")  # recognisably different
        cams.append(Camera(f"v{i}", np.eye(4), 64, 40, 50.0, 50.0, 32.0, 20.0))
    write_transforms_json(folder / "transforms.json", cams)
    full, half, quarter = (load_dataset(folder, downscale=k) for k in (1, 2, 4))
    assert half.views[0].image_path.parent.name == "images_2"  # the capture's own copy
    assert np.allclose(half.views[0].load_image(), img[::2, ::2] // 2 / 255.0, atol=1e-6)
    assert np.allclose(half.views[0].K[:2], full.views[0].K[:2] / 2)
    q = quarter.views[0]  # no images_4: the full image, block-averaged
    assert (q.width, q.height) == (16, 10) and q.image_path.parent.name == "images"
    assert np.allclose(q.load_image(), (img / 255.0).reshape(10, 4, 16, 4, 3).mean((1, 3)), atol=1e-6)
    with pytest.raises(DatasetError, match="downscale 32 leaves 2x1 pixels"):
        load_dataset(folder, downscale=32)


def test_estimator_priors_conventions(tmp_path):
    """PRIORS.json names the conventions of estimator output: disparity depth (the loss then fits 1 / depth),
    OpenGL normals in [0,1]-encoded 16-bit PNG, sRGB albedo PNG; a map of another size is refused naming it."""
    from PIL import Image

    from glint_mi.training.batch import RayBank
    from glint_mi.data.priors import PriorError, load_prior
    from glint_mi.data.cameras import Camera, write_transforms_json

    folder = tmp_path / "cap"
    (folder / "images").mkdir(parents=True)
    Image.fromarray((texture(20, 32) * 255).astype(np.uint8)).save(folder / "images" / "v0.png")
    write_transforms_json(folder / "transforms.json", [Camera("v0", np.eye(4), 32, 20, 30.0, 30.0, 16.0, 10.0)])
    v = load_dataset(folder).views[0]
    for kind in ("depth", "normal", "albedo"):
        (folder / "priors" / kind).mkdir(parents=True)
    n_gl = np.zeros((20, 32, 3))
    n_gl[..., 1], n_gl[..., 2] = 0.6, 0.8  # OpenGL axes: up and towards the camera
    Image.fromarray(np.round((n_gl * 0.5 + 0.5) * 255).astype(np.uint8)).save(folder / "priors" / "normal" / "v0.png")
    disp = np.full((20, 32), 30000, np.uint16)  # a 16-bit disparity PNG
    Image.fromarray(disp).save(folder / "priors" / "depth" / "v0.png")
    Image.fromarray(np.full((20, 32, 3), 188, np.uint8)).save(folder / "priors" / "albedo" / "v0.png")
    (folder / "priors" / "PRIORS.json").write_text(json.dumps({"depth": {"type": "disparity"},
                                                               "normal": {"frame": "opengl"}}))
    n = load_prior(folder, v, "normal")
    assert np.allclose(n[5, 5], [0.0, -0.6, -0.8], atol=0.01)  # OpenCV: y down, z forward; facing the camera
    assert np.allclose(load_prior(folder, v, "depth")[3, 3], 30000 / 65535, atol=1e-6)
    a = load_prior(folder, v, "albedo")
    assert np.allclose(a[0, 0], ((188 / 255 + 0.055) / 1.055) ** 2.4, atol=1e-4)  # 8-bit PNG: sRGB -> linear
    np.save(folder / "priors" / "albedo" / "v0.npy", np.full((20, 32, 3), 0.3, np.float32))
    (folder / "priors" / "albedo" / "v0.png").unlink()
    assert np.allclose(load_prior(folder, v, "albedo"), 0.3)  # float files are linear
    bank = RayBank([v], folder)
    assert bank.depth_inverse and bank.has == {"depth", "normal", "albedo"}
    (folder / "priors" / "depth" / "v0.png").unlink()
    np.save(folder / "priors" / "depth" / "v0.npy", np.ones((21, 32), np.float32))
    with pytest.raises(PriorError, match=r"v0\.npy: 21x32 \(HxW\) but its view is 20x32"):
        load_prior(folder, v, "depth")
    (folder / "priors" / "PRIORS.json").write_text(json.dumps({"depth": {"type": "inverse"}}))
    with pytest.raises(PriorError, match=r"PRIORS\.json: depth\.type = 'inverse'"):
        load_prior(folder, v, "depth")


def test_disparity_prior_depth_loss_fits_inverse_depth():
    """With a disparity prior the depth loss is affine in 1 / D: a prior that is exactly a / D + b costs nothing,
    the same prior read as depth does not."""
    import drjit as dr
    import mitsuba as mi

    from glint_mi.training import losses as L

    D = np.linspace(1.0, 4.0, 64)
    P = 0.7 / D + 0.2
    view = mi.UInt32(np.zeros(64, np.uint32))
    mask = mi.Bool(np.ones(64, bool))
    inv = L.depth_loss(1.0 / mi.Float(D), mi.Float(P), mask, view, 1)
    lin = L.depth_loss(mi.Float(D), mi.Float(P), mask, view, 1)
    assert float(dr.sum(inv)[0]) < 1e-10 < float(dr.sum(lin)[0])


def test_out_is_checked_before_any_work(tmp_path):
    from glint_mi import optimize

    f = tmp_path / "afile"
    f.write_text("x")
    r = subprocess.run([sys.executable, "-m", "glint_mi.optimize", str(tmp_path / "no_such_scene.xml"), "--out",
                        str(f)], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2 and "is a file, not a folder" in r.stderr and "Traceback" not in r.stderr
    assert optimize.main([str(tmp_path / "no_such_scene.xml"), "--out", str(tmp_path / "new")]) == 2


def test_sfm_failure_is_one_line_in_the_report(tmp_path):
    """Known-pose SfM on images without features fails; the reason is one line in the log and in report.json, and
    training starts from random points."""
    from PIL import Image

    from glint_mi.config import TrainConfig
    from glint_mi.data.cameras import Camera, write_transforms_json
    from glint_mi.dataset.trajectory import look_at
    from glint_mi.scene import read_scene, scene_xml
    from glint_mi.training.trainer import Trainer

    folder = tmp_path / "flat"
    (folder / "images").mkdir(parents=True)
    cams = []
    for i in range(4):
        Image.fromarray(np.full((200, 240, 3), 90 + i, np.uint8)).save(folder / "images" / f"v{i}.jpg")
        cams.append(Camera(f"v{i}", look_at([i * 0.2, -3, 0], [0, 0, 0]), 240, 200, 200.0, 200.0, 120.0, 100.0))
    write_transforms_json(folder / "transforms.json", cams)
    tj = json.loads((folder / "transforms.json").read_text())
    for fr in tj["frames"]:
        fr["file_path"] = fr["file_path"].replace(".png", ".jpg")
    (folder / "transforms.json").write_text(json.dumps(tj))
    (tmp_path / "s.xml").write_text(scene_xml(folder))
    logs = []
    tr = Trainer(tmp_path / "run", TrainConfig.for_preset("tiny", iterations=1, init_min_points=50,
                                                          components="interface"),
                 scene=read_scene(tmp_path / "s.xml"), log=logs.append)
    sfm = tr.report["init"]["sfm"]
    assert sfm["source"] == "none" and "\n" not in sfm["why"] and sfm["why"].startswith("SfM (pycolmap")
    assert any(sfm["why"] in m for m in logs) and "random points on training rays" in tr.report["init"]["interface"]
    tr.train(progress=False)
    assert json.loads((tmp_path / "run" / "report.json").read_text())["init"]["sfm"]["why"] == sfm["why"]


def test_evaluation_keeps_finished_views_on_ctrl_c(tmp_path, monkeypatch):
    from glint_mi.evaluation import renders as E
    from glint_mi.data.cameras import Camera, write_transforms_json
    from PIL import Image

    folder = tmp_path / "cap"
    (folder / "images").mkdir(parents=True)
    cams = []
    for i in range(3):
        Image.fromarray((texture(20, 32) * 255).astype(np.uint8)).save(folder / "images" / f"v{i}.png")
        cams.append(Camera(f"v{i}", np.eye(4), 32, 20, 30.0, 30.0, 16.0, 10.0))
    write_transforms_json(folder / "transforms.json", cams)
    views = load_dataset(folder).views
    calls = []

    def fake_render(integ, view, need_direct=False, depth_rule="expected", glass=None):
        calls.append(view.name)
        if len(calls) == 2:
            raise KeyboardInterrupt
        z = np.zeros((view.height, view.width))
        return {"rgb": view.load_image(), "depth": z + 1, "normal": np.zeros((*z.shape, 3)), "transparency": z,
                "interface": np.zeros((*z.shape, 3)), "reflection": np.zeros((*z.shape, 3)),
                "transmission": np.zeros((*z.shape, 3)), "alpha": z + 1}

    monkeypatch.setattr(E, "render_view", fake_render)
    with pytest.raises(KeyboardInterrupt):
        E.evaluate(None, views, tmp_path / "run", write=True)
    # what was finished stays in evaluation_partial/ (nothing was complete before: no metrics.json)
    from glint_mi.runs import finished_metrics

    part = tmp_path / "run" / "evaluation_partial"
    m = json.loads((part / "metrics.json").read_text())
    assert m["views_done"] == 1 and m["views_total"] == 3 and m["interrupted"] and m["views"] == ["v0"]
    assert (part / "per_view" / "v0.json").exists() and (part / "renders" / "v0.exr").exists()
    assert not (part / "per_view" / "v1.json").exists() and not (tmp_path / "run" / "metrics.json").exists()
    assert finished_metrics(tmp_path / "run") is None


@needs_pycolmap
@pytest.mark.skipif(not (FOX / "transforms.json").exists(), reason=f"the real fox capture is not at {FOX}")
def test_fox_real_capture_tiny(tmp_path):
    """The instant-ngp fox (phone JPEGs, OPENCV distortion, 17 missing frames, no points, no priors, no glass) at
    tiny scale: 12 frames at 1/8 size read, undistort, triangulate from the JPEGs, train and evaluate; components:
    auto keeps neither the transmission nor the reflection set."""

    meta = json.loads((FOX / "transforms.json").read_text())
    frames = [f for f in meta["frames"] if (FOX / f["file_path"]).exists()][::4][:12]
    meta["frames"] = [{**f, "file_path": str(FOX / f["file_path"])} for f in frames]
    meta["frames"].append({**frames[0], "file_path": str(FOX / "images" / "0005.jpg")})  # missing, as published
    cap = tmp_path / "fox"
    cap.mkdir()
    (cap / "transforms.json").write_text(json.dumps(meta))
    r = subprocess.run([sys.executable, "-m", "glint_mi.scene", str(cap), "--skip-missing"], capture_output=True,
                       text=True, cwd=ROOT, timeout=300, env={**os.environ})
    assert r.returncode == 0, r.stderr
    assert "1 of 13 frames skipped" in r.stderr and "OPENCV camera undistorted" in r.stderr
    (tmp_path / "fox.xml").write_text(r.stdout)
    run = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "glint_mi.optimize", str(tmp_path / "fox.xml"), "--preset", "tiny",
                        "--set", "downscale=8", "--out", str(run), "--no-progress"], capture_output=True, text=True,
                       cwd=ROOT, timeout=900, env={**os.environ})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    rep = json.loads((run / "report.json").read_text())
    assert rep["init"]["sfm"]["source"] == "triangulated" and rep["init"]["sfm"]["points"] > 500, rep["init"]
    assert rep["components"]["transmission"]["kept"] is False, rep["components"]
    assert rep["components"]["reflection"]["kept"] is False, rep["components"]
    assert sorted(p.name for p in (run / "model").glob("*.ply")) == ["interface.ply"]  # dropped before training
    ckpt = np.load(run / "checkpoint.npz")
    assert not any(k.startswith(("set/transmission/", "set/reflection/")) for k in ckpt.files)
    from glint_mi.config import TrainConfig

    cfg = TrainConfig.load(run / "config.json").flat()  # no glass: the interface alone trains as 3DGS does
    assert (cfg["kernel"], cfg["w_l1"], cfg["w_dssim"], cfg["w_consistency"], cfg["w_sfm_depth"]) == \
        ("ellipsoid", 0.8, 0.2, 0.0, 0.0)
    m = json.loads((run / "metrics.json").read_text())
    assert m["resolution"] == [133, 237] and m["views_done"] == 2 and np.isfinite(m["metrics"]["psnr"])
