"""The depth each method reports (glint_mi.evaluation.depth_rules): 2DGS's median depth and TSGS's first-surface depth.

Hand-made hit lists check TSGS's rule case by case (glass in front of a wall, two candidate windows, an opaque-mask
pixel, background); on a rendered stack of surfels the numpy median equals the integrator's own median composite, and
an evaluation with each rule writes those depths.
"""
import numpy as np
import pytest

import drjit as dr
import mitsuba as mi

from conftest import make_integrator, rays
from glint_mi.evaluation import depth_rules as R
from glint_mi.model.gaussians import GaussianSet


def _pad(rows, k=8):
    a, z = np.zeros((len(rows), k)), np.zeros((len(rows), k))
    for i, hits in enumerate(rows):
        for j, (alpha, depth) in enumerate(hits):
            a[i, j], z[i, j] = alpha, depth
    return a, z


def test_first_surface_follows_tsgs():
    rows = [
        # glass (three layers 1.00-1.02 m) in front of a wall at 3 m: the glass takes the first 20 % of weight (its
        # third layer crosses it), so its window is the one
        [(0.08, 1.00), (0.08, 1.01), (0.08, 1.02), (0.9, 3.0), (0.9, 3.01)],
        # two windows inside the first 20 %: a sparse one at 2.0 and a denser one at 2.5 (listed out of depth order)
        [(0.06, 2.5), (0.03, 2.0), (0.07, 2.51), (0.07, 2.52), (0.9, 4.0)],
        # the same hits as row 0 where the mask says opaque: the median rule (last hit while T > 0.5: the wall)
        [(0.05, 1.00), (0.06, 1.01), (0.05, 1.02), (0.9, 3.0), (0.9, 3.01)],
        # background: T stays above 0.98
        [(0.005, 2.0), (0.005, 2.2)],
        # fainter glass (15 % of weight): the hit that carries the sum past 20 % is in the range (TSGS's loop), and
        # the wall's single hit outweighs the glass window
        [(0.05, 1.00), (0.06, 1.01), (0.05, 1.02), (0.9, 3.0), (0.9, 3.01)],
    ]
    a, z = _pad(rows)
    mask = np.array([1.0, 0.9, 0.0, 1.0, 1.0])
    got = R.first_surface_depth(a, z, mask, **R.TSGS)
    assert got[4] == pytest.approx(3.0)
    w0 = np.array([0.08, 0.08 * 0.92, 0.08 * 0.92 ** 2])
    assert got[0] == pytest.approx(np.sum(w0 * [1.00, 1.01, 1.02]) / w0.sum(), rel=1e-9)
    T = np.cumprod([1, 0.94, 0.97, 0.93])
    w1 = np.array([0.06, 0.03, 0.07, 0.07]) * T  # in list order: 2.5, 2.0, 2.51, 2.52
    assert got[1] == pytest.approx((w1[0] * 2.5 + w1[2] * 2.51 + w1[3] * 2.52) / (w1[0] + w1[2] + w1[3]), rel=1e-9)
    assert got[2] == pytest.approx(3.0)
    assert got[3] == 0.0
    # the window width decides: with 5 mm windows each glass layer stands alone and the heaviest (the first) wins
    narrow = R.first_surface_depth(a[:1], z[:1], mask[:1], **{**R.TSGS, "window": 0.005})
    assert narrow[0] == pytest.approx(1.00)


def test_median_of_hit_lists_equals_the_integrators_median(rng):
    n = 30
    surfels = GaussianSet.from_activated(np.c_[rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0.5, 4.0, n)],
                                         np.c_[rng.uniform(0.3, 0.6, (n, 2)), np.full(n, 0.01)],
                                         opacities=rng.uniform(0.05, 0.4, n), colors=rng.uniform(0, 1, (n, 3)))
    integ = make_integrator({"interface": surfels}, components="all", max_hits=64)
    m = 64
    r = rays(np.c_[rng.uniform(-1.0, 1.0, (m, 2)), np.full(m, -1.0)], np.c_[rng.normal(0, 0.05, (m, 2)), np.ones(m)])
    fwd = mi.Vector3f(0, 0, 1)
    with dr.suspend_grad():
        out = integ.trace(r, mi.Bool(True), forward=fwd, record=True)
    alpha, z, count = R.interface_hits(integ, r, fwd, out["hit_lists"][0])
    expected = np.array(out["depth"], np.float64)
    numpy_med, crossed = R._median(alpha, z, 0.5)  # from the hit lists, as TSGS's rule reads them
    med = R.median_depth(np.array(out["median"], np.float64), np.array(r.d)[2], expected)  # the composite
    assert crossed.sum() >= 10 and (~crossed).sum() >= 5 and count.max() > 5
    assert np.array_equal(crossed, np.array(out["alpha"]) >= 0.5)
    np.testing.assert_allclose(med[crossed], numpy_med[crossed], rtol=1e-5)
    np.testing.assert_allclose(med[~crossed], expected[~crossed], rtol=1e-6)  # 2DGS's median needs T <= 0.5


def _interface_transmittance(integ, view, pixels):
    """For the selected pixels of ``view``: the interface pass's running transmittance [n, K + 1] in float64, from
    the pass's hit list (1 before the first hit), and the rendered alpha."""
    from glint_mi.data.rays import pixel_rays
    from glint_mi.model.render import floats

    dd = pixel_rays(view).astype(np.float32)[pixels.reshape(-1)]
    o, f = view.c2w[:3, 3].astype(np.float32), view.c2w[:3, 2]
    ray = mi.Ray3f(mi.Point3f(*floats(np.broadcast_to(o, dd.shape))), mi.Vector3f(*floats(dd)))
    fwd = mi.Vector3f(*[float(x) for x in f])
    with dr.suspend_grad():
        out = integ.trace(ray, mi.Bool(True), forward=fwd, record=True)
    alpha, _, _ = R.interface_hits(integ, ray, fwd, out["hit_lists"][0])
    return np.cumprod(np.c_[np.ones(len(alpha)), 1.0 - alpha], axis=1), np.array(out["alpha"], np.float64)


def test_evaluation_reports_each_methods_depth(tmp_path):
    """The same trained room evaluated with each rule: median and first_surface change the depth where their rules
    say and nowhere else; first_surface reads the test views' masks, and a missing mask is refused by name."""
    from pathlib import Path

    from glint_mi.config import TrainConfig
    from glint_mi.data import DatasetError
    from glint_mi.evaluate import evaluate
    from glint_mi.scene import read_scene
    from glint_mi.evaluate import eval_options
    from glint_mi.training.trainer import Trainer

    spec = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "glass_room" / "optimize.xml"))
    tr = Trainer(tmp_path / "run", TrainConfig.for_preset("tiny", iterations=60), scene=spec, log=lambda *a, **k: None)
    tr.train()
    views = tr.eval_views()[:1]
    gt_glass = (views[0].load_gt() or {}).get("glass")
    res = {rule: evaluate(tr.integ_for_eval(), views, write=False, depth_rule=rule,
                          glass_of=(lambda v: gt_glass) if rule == "first_surface" else None)
           for rule in R.RULES}
    d = {k: v["renders"][views[0].name]["depth"] for k, v in res.items()}
    for rule in ("median", "first_surface"):
        assert np.mean(np.abs(d[rule] - d["expected"]) > 1e-3) > 0.05, rule  # the rule changes the depth
    alpha = res["expected"]["renders"][views[0].name]["alpha"]
    opaque = (gt_glass < 0.5) & (alpha >= 0.5)  # TSGS's opaque pixels where T falls to 0.5: 2DGS's median
    assert opaque.mean() > 0.2
    # The integrator's median is a float32 running product T *= 1 - alpha (and alpha a float32 sum of weights); the
    # numpy rule reads the same hits in float64. Where T passes 0.5 within float32 rounding (256 factors x 6e-8, a
    # few 1e-6) the two may pick neighbouring hits: such ties are allowed (rare: one pixel in ~3,000 seen once, none
    # in 470,000 on this machine), any other difference fails.
    T, a = _interface_transmittance(tr.integ_for_eval(), views[0], opaque)
    np.testing.assert_allclose(T[:, -1], 1.0 - a, atol=2e-5)  # the hit lists hold what the render composited
    margin = np.minimum(np.abs(T - 0.5).min(axis=1), np.abs(a - 0.5))
    differ = ~np.isclose(d["first_surface"][opaque], d["median"][opaque], rtol=1e-5, atol=1e-6)
    assert differ.mean() < 1e-3 and np.all(margin[differ] < 2e-5), (np.nonzero(differ), margin[differ])
    cfg = TrainConfig.for_preset("tiny", eval_depth="first_surface")
    with pytest.raises(DatasetError, match="priors/glass"):
        eval_options(cfg, tmp_path)["glass_of"](views[0])
