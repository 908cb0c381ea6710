"""The derived priors' models (glint_mi.dataset.priors) on synthetic views: what an estimator would report, with
nothing copied from the ground truth's glass (issue 44)."""
import json

import numpy as np
import pytest

H, W = 40, 64


def _view(rng_tex=0):
    """A synthetic view: a wall at 2 m, two glass panes (different normals) in front of a bright textured surface
    at 4 m, a glossy stripe and a dark corner off glass; the glass BSDF's own albedo is 0."""
    r = np.random.default_rng(rng_tex)
    ys, xs = np.mgrid[0:H, 0:W]
    glass = np.zeros((H, W))
    glass[8:32, 8:30] = 1.0
    glass[8:32, 34:56] = 1.0
    normal = np.zeros((H, W, 3))
    normal[..., 2] = -1.0
    normal[8:32, 34:56] = _unit3([0.8, 0.0, -0.6])  # another pane key (x axis)
    depth = np.full((H, W), 2.0)
    first_p = np.stack([(xs - W / 2) / W * 2, (ys - H / 2) / W * 2, depth], -1)
    behind_p = first_p * 2.0
    wall = 0.3 + 0.1 * r.random((H, W, 3))
    far = 0.5 + 0.2 * r.random((H, W, 3))
    first_albedo = np.where(glass[..., None] > 0.5, 0.0, wall)
    glossy = np.zeros((H, W), bool)
    glossy[34:38, :] = True
    rgb = np.where(glass[..., None] > 0.5, 0.85 * far * 0.4 + 0.05, wall * 0.4)
    rgb[:6, :6] = 0.005  # a dark corner
    gt = {"depth": depth, "normal": normal, "glass": glass, "rgb": rgb}
    tr = {"first_p": first_p, "first_albedo": first_albedo, "first_glossy": glossy,
          "behind_depth": np.where(glass > 0.5, 4.0, depth), "behind_normal": normal.copy(),
          "behind_albedo": np.where(glass[..., None] > 0.5, far, wall), "behind_p": behind_p}
    return gt, tr


def _unit3(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _maps(model, views=6, seed=0, same_view=True, **kw):
    from glint_mi.dataset.priors import (PerViewRealistic, Realistic, _room_draws, estimator_view,
                                         realistic_view)

    rng = np.random.default_rng(seed)
    out = []
    if model == "realistic":
        c = Realistic(**kw)
        room = _room_draws(rng, c)
        for i in range(views):
            gt, tr = _view(0 if same_view else i)
            out.append((*estimator_view(rng, c, room, gt, tr, np.eye(4)), gt, tr))
    else:
        c = PerViewRealistic(**kw)
        for i in range(views):
            gt, tr = _view(0 if same_view else i)
            behind = {"depth": tr["behind_depth"], "normal": tr["behind_normal"], "albedo": tr["behind_albedo"]}
            out.append((*realistic_view(rng, c, gt, behind, tr["first_albedo"], np.eye(4)), gt, tr))
    return out


def _copies_the_glass_bsdf(maps, gt, tr, tol=0.02) -> float:
    """The share of glass pixels whose albedo prior is the glass BSDF's own (within tol)."""
    glass = gt["glass"] > 0.5
    return float((np.abs(maps["albedo"] - tr["first_albedo"]).max(-1) < tol)[glass].mean())


def test_glass_albedo_is_never_the_glass_bsdfs():
    """On glass the albedo prior is what an estimator reports (the far surface, darkened, the photo partly baked in),
    never the glass BSDF's ~0; the former model (realistic-v1) copies it where it does not see through, which this
    check catches."""
    for maps, rec, gt, tr in _maps("realistic", views=8):
        glass = gt["glass"] > 0.5
        assert _copies_the_glass_bsdf(maps, gt, tr) == 0.0
        ratio = maps["albedo"][glass].mean() / tr["behind_albedo"][glass].mean()
        assert 0.45 < ratio < 1.6, ratio  # darkening 0.7-1, gain 0.8-1.2, the photo's leak
    old = [_copies_the_glass_bsdf(m, gt, tr) for m, _, gt, tr in _maps("realistic-v1", views=8,
                                                                       see_through_glass=0.0)]
    assert max(old) > 0.5, old


def test_the_albedo_does_not_outline_the_glass():
    """Dark albedo is no glass detector: off glass a dark surface is as dark, and the share of glass among the prior's
    darkest pixels stays near the share of glass (the issue's realistic-v1 room: 76 % of pixels under 0.05 glass)."""
    for maps, _, gt, tr in _maps("realistic", views=4):
        glass = gt["glass"] > 0.5
        lum = maps["albedo"].mean(-1)
        darkest = lum <= np.quantile(lum, 0.1)
        assert glass[darkest].mean() < glass.mean() + 0.1, glass[darkest].mean()


def _panned(k: int):
    """The synthetic view with its content moved k pixels to the right: the same surfaces (their world points, normals
    and albedo) seen at other pixels, as a camera pan shows them."""
    gt, tr = _view(0)
    roll = lambda a: np.roll(a, k, axis=1)
    return {key: roll(v) for key, v in gt.items()}, {key: roll(v) for key, v in tr.items()}


def _normal_errors(model, views, seed=3, **kw):
    """Per view, the [H, W, 3] error of the normal prior (NaN on glass), for ``views`` = [(gt, tr), ...]."""
    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.dataset.priors import PerViewRealistic, Realistic, _room_draws, estimator_view, realistic_view

    rng = np.random.default_rng(seed)
    c = Realistic(**kw) if model == "realistic" else PerViewRealistic(**kw)
    room = _room_draws(rng, c) if model == "realistic" else None
    out = []
    for gt, tr in views:
        if room is not None:
            maps, _ = estimator_view(rng, c, room, gt, tr, np.eye(4))
        else:
            behind = {"depth": tr["behind_depth"], "normal": tr["behind_normal"], "albedo": tr["behind_albedo"]}
            maps, _ = realistic_view(rng, c, gt, behind, tr["first_albedo"], np.eye(4))
        e = maps["normal"] - world_to_opencv_normals(gt["normal"], np.eye(4))
        out.append(np.where((gt["glass"] < 0.5)[..., None], e, np.nan))
    return out


def _same_surface_vs_same_pixel(e0, e1, k):
    """Correlations of two views' errors (the second panned by k px): at the same surface points, at the same
    pixels."""
    def corr(a, b):
        ok = np.isfinite(a) & np.isfinite(b)
        return float(np.corrcoef(a[ok], b[ok])[0, 1])
    return corr(e0[:, :-k], e1[:, k:]), corr(e0[:, k:], e1[:, k:])


def test_errors_repeat_for_a_surface_in_every_view():
    """The same surface seen again gets the same mistake (a world-space field): in a second view that shows the room
    panned by 28 px (more than the field varies over), the normal errors correlate with the first view's at the same
    surface points (>= 0.5), and more than at the same pixels. An error fixed in image space (the control below, which
    the former test, one pose for every view, let through) and the former model's per-view errors are not anchored
    to the surfaces."""
    k = 28
    views = [_panned(0), _panned(k)]

    def anchored(e0, e1):
        surface, pixel = _same_surface_vs_same_pixel(e0, e1, k)
        return surface > 0.5 and surface > pixel + 0.2, (round(surface, 2), round(pixel, 2))

    new = anchored(*_normal_errors("realistic", views, normal_world_deg=(12.0, 12.0), normal_view_deg=(5.0, 5.0)))
    assert new[0], new
    old = anchored(*_normal_errors("realistic-v1", views))
    assert not old[0], old
    fixed = np.random.default_rng(0).normal(size=(H, W, 3))
    control = anchored(*(np.where((v[0]["glass"] < 0.5)[..., None], fixed, np.nan) for v in views))
    assert not control[0], control


def test_glass_masks_fail_as_a_segmenter_does():
    """Over many views: whole panes missed in some (more often the same panes), holes inside detected panes, false
    positives only on glossy or dark pixels, masks that change between views of the same glass; IoU well below 1."""
    runs = _maps("realistic", views=40, seed=5)
    ious, missed, holes, false_ok, masks = [], 0, [], True, []
    for maps, rec, gt, tr in runs:
        glass = gt["glass"] > 0.5
        m = maps["glass"] > 0.5
        ious.append(rec["mask_iou"])
        missed += len(rec["panes_missed"])
        masks.append(m)
        inner = np.zeros_like(glass)
        inner[11:29, 11:27] = True  # the left pane's interior, away from the ragged edge
        if 4 in rec["panes_detected"]:  # the left pane (normal -z)
            holes.append(1 - m[inner].mean())
        fp = m & ~glass
        lum = gt["rgb"].mean(-1)
        allowed = tr["first_glossy"] | (lum <= np.quantile(lum, 0.1))
        grown = fp & ~_dilate(allowed, 2) & ~_dilate(glass, 3)
        false_ok &= not grown.any()
    assert 0.4 < np.mean(ious) < 0.85, np.mean(ious)
    assert missed >= 4
    assert np.mean(holes) > 0.03
    assert false_ok, "false positives away from glossy and dark pixels"
    flicker = [np.mean(a ^ b) for a, b in zip(masks, masks[1:])]
    assert np.mean(flicker) > 0.01  # the same view, another draw: the mask changes


def _dilate(m, r):
    from scipy.ndimage import binary_dilation

    return binary_dilation(m, iterations=r)


def _other_geometry():
    """The synthetic view with other wall normals (a wavy wall): the same draws meet other surfaces."""
    gt, tr = _view(0)
    ys, xs = np.mgrid[0:H, 0:W]
    off = gt["glass"] < 0.5
    wavy = np.stack([0.5 * np.sin(xs / 9.0), 0.3 * np.cos(ys / 7.0), -np.ones((H, W))], -1)
    wavy /= np.linalg.norm(wavy, axis=-1, keepdims=True)
    gt["normal"] = np.where(off[..., None], wavy, gt["normal"])
    tr["behind_normal"] = np.where(off[..., None], wavy, tr["behind_normal"])
    return gt, tr


def test_amplitudes_are_drawn_not_fitted():
    """The errors come from drawn amplitudes, not from bisection against the ground truth: the same draws (one seed)
    on two rooms of other geometry give the same recorded amplitudes and different measured errors; a model fitted to
    a target error (the former realistic-v1) measures its target in both rooms, which this test catches. Over seeds
    the measured errors spread."""
    from glint_mi.dataset.priors import PerViewRealistic, Realistic, _room_draws, estimator_view, measure_priors
    from glint_mi.dataset.priors import realistic_view

    def first_view(model, seed, scene):
        rng = np.random.default_rng(seed)
        gt, tr = scene()
        if model == "realistic":
            c = Realistic()
            room = _room_draws(rng, c)
            maps, rec = estimator_view(rng, c, room, gt, tr, np.eye(4))
            draws = (room["normal_world_deg"], room["depth_world"], rec["normal_view_deg"])
        else:
            c = PerViewRealistic()
            behind = {"depth": tr["behind_depth"], "normal": tr["behind_normal"], "albedo": tr["behind_albedo"]}
            maps, rec = realistic_view(rng, c, gt, behind, tr["first_albedo"], np.eye(4))
            draws = tuple(v for k, v in sorted(rec.items()) if k.startswith("target"))
        return measure_priors(maps, gt, np.eye(4))["normal_mae_deg_off_glass"], draws

    def moves(model):
        shifts, measured = [], []
        for seed in range(4):
            (a, da), (b, db) = first_view(model, seed, lambda: _view(0)), first_view(model, seed, _other_geometry)
            assert da == db, (model, da, db)  # the draws do not look at the room
            shifts.append(abs(a - b))
            measured.append(a)
        return float(np.mean(shifts)), float(np.ptp(measured)), float(np.mean(measured))

    shift, spread, mean = moves("realistic")
    assert shift > 0.15 and spread > 0.3 and 5 < mean < 30, (shift, spread, mean)
    assert moves("realistic-v1")[0] < 0.05  # fitted: its first view measures its target whatever the room


def test_prior_models_listed_once():
    from glint_mi.dataset.__main__ import PRIOR_MODELS
    from glint_mi.dataset.priors import MODELS, model_name

    assert sorted(PRIOR_MODELS) == sorted(MODELS)
    for name, cls in MODELS.items():
        assert model_name(cls()) == name
    with pytest.raises(TypeError, match="not a prior model"):
        model_name(object())


def test_priors_cli_writes_measured_errors_and_mask_iou(tmp_path, capsys):
    """`python -m glint_mi.dataset priors ROOM --model realistic`: PRIORS.json with the measured errors, the masks'
    IoU and the albedo's glass cue; `--model realistic-v1` keeps the former model for comparison."""
    from glint_mi.dataset.__main__ import main
    from glint_mi.dataset.generate import Preset, make_scene

    room = tmp_path / "r"
    make_scene(room, seed=11, preset=Preset.named("tiny", views=4, spp=8), sfm="none", priors=False)
    assert main(["priors", str(room), "--model", "realistic"]) == 0
    rec = json.loads((room / "priors" / "PRIORS.json").read_text())
    assert rec["model"] == "realistic" and rec["derived_from_ground_truth"]
    m = rec["measured"]
    for k in ("normal_mae_deg_off_glass", "depth_absrel_off_glass", "glass_mask_iou", "albedo_dark_pixels_on_glass"):
        assert k in m, k
    assert "normal_world_deg" in rec["drawn"] and "IoU" in capsys.readouterr().out
    assert main(["priors", str(room), "--model", "realistic-v1"]) == 0
    assert json.loads((room / "priors" / "PRIORS.json").read_text())["model"] == "realistic-v1"


def test_error_scale_sweeps_prior_quality():
    """``--error-scale F`` (issue 66's sweep of prior quality): the normal and depth error amplitudes times F and
    nothing else; scale 1 is the model itself, and the measured normal error grows with F for both models."""
    import dataclasses

    from glint_mi.dataset.priors import ERROR_FIELDS, MODELS, scale_errors

    for name, cls in MODELS.items():
        c = cls()
        assert scale_errors(c, 1.0) == c
        s = scale_errors(c, 2.0)
        changed = {f.name for f in dataclasses.fields(c) if getattr(s, f.name) != getattr(c, f.name)}
        assert changed == set(ERROR_FIELDS[name]), name
    with pytest.raises(ValueError, match="positive"):
        scale_errors(MODELS["realistic"](), 0.0)
    with pytest.raises(ValueError, match="89 deg"):  # a normal error past what can be drawn: refused, not clipped
        scale_errors(MODELS["realistic-v1"](), 6.0)
    views = [_view(i) for i in range(3)]
    for model in ("realistic", "realistic-v1"):
        base = MODELS[model]()
        mae = []
        for f in (0.5, 1.0, 2.0):
            kw = {k: getattr(scale_errors(base, f), k) for k in ERROR_FIELDS[model]}
            e = _normal_errors(model, views, **kw)
            mae.append(float(np.nanmean([np.degrees(np.linalg.norm(x, axis=-1)) for x in e])))
        assert mae[0] < mae[1] < mae[2] and mae[2] > 1.6 * mae[0], (model, mae)
