"""No input silently ignored: each bad input ends in one error line naming the file or key and the fix, exit code 2
from the command line, before any work, with nothing written."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import glint_mi

glint_mi.set_variant()

from glint_mi.config import ConfigError, TrainConfig  # noqa: E402
from glint_mi.data import DatasetError, load_dataset  # noqa: E402
from glint_mi.data.priors import PriorError, check_priors  # noqa: E402
from glint_mi.dataset.generate import Preset, make_scene  # noqa: E402
from glint_mi.scene import SceneError, read_scene, scene_xml  # noqa: E402

from conftest import cli as _cli, copy_tree as _copy, files_of as _files  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("field, value, match", [
    ("fl_x", 0, r"'fl_x' = 0: the focal length must be a positive number"),
    ("fl_x", -110.0, r"'fl_x' = -110.0: the focal length"),
    ("fl_y", "abc", r"'fl_y' = 'abc'"),
    ("w", 0, r"'w' = 0: the image size in pixels must be a positive integer"),
    ("cx", "centre", r"'cx' = 'centre': the principal point must be a finite number"),
    ("camera_angle_x", 4.0, r"'camera_angle_x' = 4.0: the horizontal field of view must be in radians"),
])
def test_bad_intrinsics_are_named(tiny, tmp_path, field, value, match):
    """transforms.json intrinsics are checked for type and range when the file is read (before: fl_x = 0 passed
    `scene` with 'moved pixels by up to nan px' and failed 47 s into `optimize`; a negative one trained from random
    points)."""
    cap = _copy(tiny, tmp_path / "cap")
    tj = json.loads((cap / "transforms.json").read_text())
    if field == "camera_angle_x":
        for k in ("fl_x", "fl_y"):
            tj.pop(k, None)
            for fr in tj["frames"]:
                fr.pop(k, None)
    tj[field] = value
    (cap / "transforms.json").write_text(json.dumps(tj))
    with pytest.raises(DatasetError, match=match):
        load_dataset(cap / "transforms.json")


def test_scene_cli_refuses_a_zero_focal_length_and_writes_nothing(tiny, tmp_path):
    cap = _copy(tiny, tmp_path / "cap")
    tj = json.loads((cap / "transforms.json").read_text())
    tj["fl_x"] = 0
    (cap / "transforms.json").write_text(json.dumps(tj))
    before = _files(cap)
    r, errors = _cli("glint_mi.scene", cap / "transforms.json")
    assert r.returncode == 2 and r.stdout == "" and len(errors) == 1 and "'fl_x' = 0" in errors[0], r.stderr
    assert _files(cap) == before


def test_priors_json_keys_are_checked(tiny, tmp_path):
    """A misspelled PRIORS.json key (before: {"depht": {"type": "disparity"}} read the disparity maps as depth)."""
    cap = _copy(tiny, tmp_path / "cap")
    rec = json.loads((cap / "priors" / "PRIORS.json").read_text())
    for bad, match in (({"depht": {"type": "disparity"}}, r"unknown key 'depht'; the keys are depth, normal"),
                       ({"depth": {"typ": "disparity"}}, r"unknown key 'typ' in 'depth'; its key is 'type'")):
        (cap / "priors" / "PRIORS.json").write_text(json.dumps({**rec, **bad}))
        assert any(re_search(match, p) for p in check_priors(cap, load_dataset(cap).train_views))
        r, errors = _cli("glint_mi.scene", cap)
        assert r.returncode == 2 and len(errors) == 1 and re_search(match, errors[0]), r.stderr
    (cap / "priors" / "PRIORS.json").write_text(json.dumps({**rec, "notes": "Depth Anything v2, 518 px"}))
    assert check_priors(cap, load_dataset(cap).train_views) == []


def re_search(pattern, text):
    import re
    return re.search(pattern, text) is not None


def test_partial_and_broken_priors_are_listed_one_line_each(tiny, tmp_path):
    """A prior kind that some training views lack is named with those views (before: dropped, and the log said the
    folder held no maps); a map of the wrong size and one with NaN are named too, each on its own line; the trainer
    refuses the same before SfM and initialisation."""
    cap = _copy(tiny, tmp_path / "cap")
    ds = load_dataset(cap)
    names = [v.name for v in ds.train_views]
    for f in (cap / "priors" / "normal").glob(f"{names[1]}.*"):
        f.unlink()
    depth = next((cap / "priors" / "depth").glob(f"{names[2]}.*"))
    np.save(depth.with_suffix(".npy"), np.full((5, 7), 1.0, np.float32))
    depth.unlink() if depth.suffix != ".npy" else None
    alb = next((cap / "priors" / "albedo").glob(f"{names[0]}.*"))
    bad = np.full((ds.train_views[0].height, ds.train_views[0].width, 3), np.nan, np.float32)
    alb.unlink()
    np.save(alb.with_suffix(".npy"), bad)
    problems = check_priors(cap, ds.train_views)
    assert len(problems) == 3, problems
    assert any(f"1 of {len(names)} training views have no normal map ({names[1]})" in p for p in problems)
    assert any("NaN" in p and names[0] in p for p in problems)
    assert any(names[2] in p and "5" in p for p in problems)  # the size, named
    r, errors = _cli("glint_mi.scene", cap)
    assert r.returncode == 2 and len(errors) == 3, r.stderr
    from glint_mi.training.trainer import Trainer

    (tmp_path / "scene.xml").write_text(scene_xml(cap))
    with pytest.raises(PriorError, match="no normal map"):
        Trainer(tmp_path / "run", TrainConfig.for_preset("tiny"), scene=read_scene(tmp_path / "scene.xml"),
                log=lambda *a: None)
    assert not (tmp_path / "run").exists()


def test_scene_xml_names_are_checked(tiny, tmp_path):
    """Misspelled optimisation-scene properties (before: `componets` and `kernal` were ignored, components stayed
    auto); optimize exits 2 with the key, the nearest valid one and the list, and makes no run folder."""
    text = scene_xml(tiny, components="auto", kernel="surfel")
    for a, b, match in (('name="components"', 'name="componets"', r"no property 'componets' \(did you mean "
                                                                   r"'components'\?\)"),
                        ('name="kernel"', 'name="kernal"', r"<shape name=\"interface\"> has no property 'kernal'")):
        p = tmp_path / "scene.xml"
        p.write_text(text.replace(a, b, 1))
        with pytest.raises(SceneError, match=match):
            read_scene(p)
        r, errors = _cli("glint_mi.optimize", p, "--out", tmp_path / "run")
        assert r.returncode == 2 and len(errors) == 1 and b.split('"')[1] in errors[0], r.stderr
        assert not (tmp_path / "run").exists()


def test_integrator_and_shape_properties_are_checked():
    """Mitsuba scene files: an integrator property `max_hts` (before: ignored, max_hits stayed 256) and a
    glint_gaussians property beside 'filename' that would be ignored."""
    import mitsuba as mi

    with pytest.raises(Exception, match=r"unknown property 'max_hts' \(did you mean 'max_hits'\?\)"):
        mi.load_dict({"type": "glint", "max_hts": 64})
    assert mi.load_dict({"type": "glint", "max_hits": 64}).max_hits == 64
    with pytest.raises(Exception, match=r"propert.*'opacitie' not read"):
        mi.load_dict({"type": "glint_gaussians", "centers": mi.TensorXf(np.zeros((2, 3), np.float32)),
                      "opacitie": mi.TensorXf(np.full((2, 1), 0.5, np.float32))})


@pytest.mark.parametrize("setting, match", [("iterations=abc", r"'iterations' = 'abc': must be an integer"),
                                            ("max_hits=-1", r"'max_hits' = -1: must be >= 1"),
                                            ("components=glass", r"'components' = 'glass'"),
                                            ("warmup=5", r"'warmup' = 5.0: is a fraction of the run")])
def test_config_values_are_checked_before_any_work(tmp_path, setting, match):
    """--set values are checked for type and range when the config is built, before the dataset is read (before:
    a TypeError traceback, or a failure after a 146 s SfM leaving config.json and run.json behind)."""
    key, value = setting.split("=")
    with pytest.raises(ConfigError, match=match):
        TrainConfig.for_preset("tiny", **{key: json.loads(value) if value[0].isdigit() or value[0] == "-"
                                          else value})
    r, errors = _cli("glint_mi.optimize", ROOT / "scenes" / "glass_room" / "optimize.xml", "--out",
                     tmp_path / "run", "--set", setting)
    assert r.returncode == 2 and len(errors) == 1 and re_search(match, errors[0]), r.stderr
    assert not (tmp_path / "run").exists()


def test_colmap_model_without_images_is_named(tiny, tmp_path):
    cap = _copy(tiny, tmp_path / "cap")
    sparse = cap / "sparse" / "0"
    (sparse / "images.txt").unlink()
    (cap / "transforms.json").unlink()
    with pytest.raises(DatasetError, match=r"cameras.txt but no images.txt; a COLMAP model needs both"):
        load_dataset(cap)


def test_optimize_says_each_thing_once_and_shows_sfm_progress(tiny, tmp_path):
    """What optimize prints on a capture without priors: SfM's stages as they finish (before: nothing for 2.7
    minutes on the fox), no 'init' line for a set dropped before training (before: printed after the drop), and each
    drop's reason once (before: again at the end)."""
    import os

    pytest.importorskip("pycolmap")
    cap = tmp_path / "cap"  # images of 480 x 270 (SIFT wants >= 200 px), no SfM points: optimize triangulates
    make_scene(cap, seed=4, preset=Preset.named("gpu", views=5, spp=4), sfm="none")
    shutil.rmtree(cap / "sparse", ignore_errors=True)
    (tmp_path / "scene.xml").write_text(scene_xml(cap))
    saved = os.environ.get("GLINT_CACHE")
    os.environ["GLINT_CACHE"] = str(tmp_path / "cache")  # the subprocess triangulates afresh
    try:
        r, errors = _cli("glint_mi.optimize", tmp_path / "scene.xml", "--preset", "tiny", "--iterations", "2",
                         "--set", "priors=none", "--out", tmp_path / "run", "--no-progress", "--no-eval")
    finally:
        os.environ.pop("GLINT_CACHE")
        if saved is not None:
            os.environ["GLINT_CACHE"] = saved
    text = r.stdout + r.stderr
    assert r.returncode == 0 and not errors, text[-3000:]
    assert "SfM 1/3: SIFT features of" in text and "SfM 2/3:" in text
    assert "init transmission" not in text and "init reflection" not in text and "init interface" in text
    assert text.count("no glass cue: no albedo prior") == 1, text
    assert "components: dropped transmission, dropped reflection (why: above" in text


def test_a_missing_frame_of_unknown_size_is_reported_as_missing(tiny, tmp_path):
    """A capture with only camera_angle_x (no w, h) and a frame whose image is missing: the frame is listed with the
    missing frames (and --skip-missing drops it), not refused for a zero focal length computed from its unknown
    width."""
    cap = _copy(tiny, tmp_path / "cap")
    tj = json.loads((cap / "transforms.json").read_text())
    w = tj["w"]
    angle = 2 * np.arctan(0.5 * w / tj["fl_x"])
    for k in ("fl_x", "fl_y", "w", "h"):
        tj.pop(k, None)
    tj["camera_angle_x"] = float(angle)
    tj["frames"].append({"file_path": "images/gone.png", "transform_matrix": np.eye(4).tolist()})
    (cap / "transforms.json").write_text(json.dumps(tj))
    with pytest.raises(DatasetError, match=r"name images that are not there: images/gone\.png"):
        load_dataset(cap / "transforms.json")
    ds = load_dataset(cap / "transforms.json", missing="skip")
    assert len(ds.views) == 6 and ds.views[0].K[0, 0] == pytest.approx(tiny_fx(tiny), rel=1e-6)


def tiny_fx(root):
    return json.loads((root / "transforms.json").read_text())["fl_x"]
