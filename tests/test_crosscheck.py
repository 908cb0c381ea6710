"""Cycles cross-check: the scene description handed to Blender, the comparison, and (when the optional cycles
extra is installed) a real Cycles render against Mitsuba's ground truth."""
import json

import numpy as np
import pytest

from glint_mi.crosscheck import compare_view, crosscheck
from glint_mi.data import load_dataset
from glint_mi.dataset.cycles_render import CyclesUnavailable, describe_scene, find_bpy, render_cycles
from glint_mi.dataset.generate import Preset, make_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("cc") / "scene"
    make_scene(out, seed=3, preset=Preset.named("tiny", views=3, spp=32), sfm="none", priors=False)
    return out


def test_description_maps_every_shape(scene, tmp_path):
    desc = json.loads(describe_scene(scene, tmp_path).read_text())
    arrays = np.load(desc["meshes_npz"])
    kinds = {s["material"]["type"] for s in desc["shapes"]}
    assert {"diffuse", "thindielectric", "emitter"} <= kinds
    glass = [s for s in desc["shapes"] if s["material"]["type"] == "thindielectric"]
    assert len(glass) == 6 and all(s["material"]["ior"] == 1.5 for s in glass)
    for s in desc["shapes"]:
        assert arrays[f"{s['id']}/v"].shape[1] == 3 and arrays[f"{s['id']}/f"].shape[1] == 3
        if s["material"].get("texture"):
            assert (scene / s["material"]["texture"]).exists()
    ds = load_dataset(scene, check_images=False)
    assert [c["name"] for c in desc["cameras"]] == [v.name for v in ds.views]
    np.testing.assert_allclose(desc["cameras"][1]["c2w"], ds.views[1].c2w)
    assert desc["environment"][0] > 0


def test_compare_view_measures_what_it_says():
    rng = np.random.default_rng(0)
    h, w = 10, 12
    n = np.zeros((h, w, 3))
    n[..., 2] = -1
    gt = {"rgb": rng.uniform(0.1, 1, (h, w, 3)), "depth": np.full((h, w), 2.0), "normal": n,
          "glass": (np.arange(w)[None].repeat(h, 0) < 4).astype(float)}
    same = compare_view(gt, {**gt, "normal": -n}, None, np.eye(4))  # a flipped normal is the same surface
    assert same["rgb_rel_diff"] == 0 and same["glass_iou"] == 1 and same["depth_within_1pct"] == 1
    assert same["normal_mean_angle_deg"] < 1e-3
    darker = compare_view(gt, {**gt, "rgb": gt["rgb"] * 0.9, "depth": gt["depth"] * 1.05}, None, np.eye(4))
    assert darker["rgb_mean_ratio"] == pytest.approx(0.9) and darker["depth_median_rel_diff"] == pytest.approx(0.05)


def test_cycles_render_agrees_with_mitsuba(scene):
    try:
        find_bpy()
    except CyclesUnavailable as e:
        pytest.skip(f"optional cycles extra not installed: {e}")
    render_cycles(scene, views=["view_000"], spp=64)
    rep = crosscheck(scene)
    m = rep["per_view"]["view_000"]
    assert m["depth_within_1pct"] > 0.98 and m["glass_iou"] > 0.95 and m["normal_mean_angle_deg"] < 6  # edge pixels: Cycles filters normals over the pixel
    assert 0.85 < m["rgb_mean_ratio"] < 1.15 and m["rgb_rel_diff"] < 0.2
    assert (scene / "crosscheck" / "view_000.png").exists()
