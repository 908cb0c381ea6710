"""The objective's remaining pieces against independent references: D-SSIM (scikit-image's SSIM), the transparency
regulariser and the plausibility term (hand-computed values and finite differences), and the stage schedule of both
schedule variants (glint_mi, supplement, release)."""
import dataclasses

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from glint_mi.training import losses as L
from glint_mi.training import objective as O
from glint_mi.training.batch import patch_neighbours
from glint_mi.config import ConfigError, TrainConfig


def _f(a):
    return mi.Float(np.asarray(a, np.float32).ravel())


def test_dssim_equals_scikit_image_ssim_per_patch(rng):
    """Each p x p patch is one SSIM window with uniform weights: 1 - mean over patches and channels of
    scikit-image's SSIM of that patch (win_size p, uniform, population covariance, data range 1)."""
    from skimage.metrics import structural_similarity

    P, p = 5, 7
    a = rng.uniform(0, 1, (P, p, p, 3))
    b = np.clip(a + rng.normal(0, 0.15, a.shape), 0, 1)
    a[3:], b[3:] = 0.03 * a[3:], 0.03 * b[3:]  # dark patches: there the constants C1, C2 decide the value
    ours = float(np.array(L.dssim(mi.Color3f(*[_f(a[..., c]) for c in range(3)]),
                                  mi.Color3f(*[_f(b[..., c]) for c in range(3)]), p))[0])
    ref = np.mean([structural_similarity(a[i, ..., c], b[i, ..., c], win_size=p, gaussian_weights=False,
                                         use_sample_covariance=False, data_range=1.0)
                   for i in range(P) for c in range(3)])
    assert abs(ours - (1 - ref)) < 1e-5, (ours, 1 - ref)
    same = float(np.array(L.dssim(mi.Color3f(*[_f(a[..., c]) for c in range(3)]),
                                  mi.Color3f(*[_f(a[..., c]) for c in range(3)]), p))[0])
    assert abs(same) < 1e-6


def test_transparency_regulariser_values_and_gradient():
    """entropy + mean t + edge-aware TV: t = 0.5 everywhere gives ln 2 + 0.5 (no TV); a step in t across an image
    edge costs exp(-grad) of what it costs on a flat image; the gradient matches central differences."""
    p, P = 4, 1
    nb = patch_neighbours(P, p)
    flat = _f(np.full(p * p, 0.5))
    val = float(np.array(L.transparency_regulariser(flat, _f(np.zeros(len(nb[0]))), nb))[0])
    assert abs(val - (np.log(2) + 0.5)) < 1e-5
    step = np.full((p, p), 0.2)
    step[:, 2:] = 0.8  # a vertical step between columns 1 and 2
    t = _f(step)
    tv = lambda g: float(np.array(L.transparency_regulariser(t, _f(np.full(len(nb[0]), g)), nb))[0])
    base = tv(0.0) - tv(50.0)  # the TV part alone (exp(-50) ~ 0)
    # TV = mean over the (p-1)^2 neighbour triples of |t_right - t| + |t_down - t|: 3 of 9 triples cross the step
    assert abs(base - 3 * 0.6 / 9) < 1e-5
    assert abs((tv(1.0) - tv(50.0)) - np.exp(-1.0) * base) < 1e-5
    x = step.ravel().astype(np.float64)
    ti = mi.Float(x.astype(np.float32))
    dr.enable_grad(ti)
    g_img = _f(np.full(len(nb[0]), 0.3))
    dr.backward(L.transparency_regulariser(ti, g_img, nb))
    g = np.array(dr.grad(ti))
    for k in (0, 5, 10):
        e = np.zeros_like(x)
        e[k] = 1e-3
        fd = (float(np.array(L.transparency_regulariser(_f(x + e), g_img, nb))[0])
              - float(np.array(L.transparency_regulariser(_f(x - e), g_img, nb))[0])) / 2e-3
        assert abs(fd - g[k]) < 2e-3 * max(1.0, abs(fd)), (k, fd, g[k])


def test_plausibility_pulls_only_the_transmission_set():
    """|D_T - D_I| / extent + (1 - <n_T, n_I>), weighted mean: hand-computed value; the gradient reaches D_T and
    n_T only (the interface is detached)."""
    d_i, d_t = _f([2.0, 2.0, 3.0]), _f([2.5, 2.0, 3.0])
    n_i = mi.Vector3f(0, 0, -1)
    n_t = mi.Vector3f(_f([0, 0.6, 0]), _f([0, 0, 0]), _f([-1, -0.8, -1]))
    w = _f([1.0, 1.0, 0.0])
    for x in (d_i, d_t, n_t):
        dr.enable_grad(x)
    loss = L.plausibility(d_t, d_i, n_t, n_i, w, extent=5.0)
    assert abs(float(np.array(loss)[0]) - (0.5 / 5.0 + 0.2) / 2) < 1e-6  # ray 3 has weight 0
    dr.backward(loss)
    assert np.allclose(np.array(dr.grad(d_i)), 0)
    assert np.allclose(np.array(dr.grad(d_t)), [0.5 / 5.0, 0.0, 0.0], atol=1e-6)  # sign(D_T - D_I) / extent / sum(w)
    assert np.abs(np.array(dr.grad(n_t))).sum() > 0


def _traced_batch(tr, st, need=frozenset()):
    """One ray batch of a trainer's bank traced with the sets the stage ``st`` traces (and the buffer groups in
    ``need``): (batch, rays, camera forward axes, the integrator's buffers), the inputs of
    ``objective.batch_objective``."""
    c = tr.cfg
    tr.integ.select(st["traced"])
    b = tr.bank.sample(np.random.default_rng(0), c.patches, c.patch)
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(b.origin[:, k]) for k in range(3)]),
                   mi.Vector3f(*[mi.Float(b.direction[:, k]) for k in range(3)]))
    fwd = mi.Vector3f(*[mi.Float(b.axes[:, k, 2]) for k in range(3)])
    return b, ray, fwd, tr.integ.trace(ray, mi.Bool(True), need=need, forward=fwd)


def _room_batch_at(tmp_path, c, frac: float):
    """A trainer of the bundled room with config ``c`` at ``frac`` of its run, its stage there and one traced batch:
    (trainer, stage, batch, rays, forward axes, buffers)."""
    from pathlib import Path

    from glint_mi.scene import read_scene
    from glint_mi.training.trainer import Trainer

    spec = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "glass_room" / "optimize.xml"))
    tr = Trainer(tmp_path / "run", c, scene=spec, log=lambda *a, **k: None)
    tr.it = c.at(frac)
    st = tr.stage()
    return (tr, st) + _traced_batch(tr, st)


@pytest.mark.parametrize("variant", ["glint_mi", "supplement", "release"])
def test_stage_schedule(variant):
    """Which sets are traced and trained and which terms are on, iteration by iteration, for 600 iterations."""
    from types import SimpleNamespace

    from glint_mi.training.trainer import Trainer

    c = TrainConfig.for_preset("tiny", variant, iterations=600, sh_degree=2)
    fake = SimpleNamespace(cfg=c, it=0, prior_floor=0.0, prior_weight={},
                           sets={"interface": 0, "transmission": 0, "reflection": 0},
                           dropped={},
                           bank=SimpleNamespace(has={"depth", "normal"}, sfm_depth=None))
    stage = lambda it: Trainer.stage(fake, it)
    at = c.at
    s = stage(at(c.warmup) - 1)
    if variant != "release":
        assert s["traced"] == {"interface"} and s["name"] == "warm-up" and not s["trans"] and not s["plausibility"]
    s = stage(max(at(c.transmission_from), at(c.reflection_from), at(c.warmup)))
    assert s["traced"] == {"interface", "transmission", "reflection"} and s["trained"] == s["traced"]
    assert s["name"] == "joint" and s["direct"]
    assert not stage(at(c.trans_from) - 1)["trans"] and stage(at(c.trans_from))["trans"]
    assert stage(at(c.plausibility_from))["plausibility"]
    # the paper's (the default since 2026-11-26): the normal term from the start, unmasked until normal_from
    assert stage(0)["normal"] and not stage(at(c.normal_from) - 1)["normal_masked"]
    assert stage(at(c.normal_from))["normal"] and stage(at(c.normal_from))["normal_masked"]
    assert not stage(at(c.treg_from) - 1)["treg"] and stage(at(c.treg_from))["treg"]
    assert not stage(at(c.densify_until) - 1)["t_gate"] and stage(at(c.densify_until))["t_gate"]
    late = SimpleNamespace(**{**vars(fake), "cfg": c.replace(grow_until=0.9)})  # grow_until moves growth alone
    assert [Trainer.stage(late, at(c.densify_until) + d)["t_gate"] for d in (-1, 0)] == [False, True]
    last = stage(599)
    if variant == "supplement":  # the refine stage freezes the interface
        assert last["name"] == "refine" and "interface" not in last["trained"]
        assert "interface" in stage(at(c.refine_from) - 1)["trained"]
    else:
        assert last["name"] == "joint" and "interface" in last["trained"]
    if variant == "glint_mi":  # glint_mi's default: the supplement's schedule without its refine stage
        sup = TrainConfig.for_preset("tiny", "supplement", iterations=600, sh_degree=2)
        differ = {k for k, v in c.flat().items() if getattr(sup, k) != v}
        assert differ == {"variant", "refine_from"} and c.refine_from == 1.0
        from glint_mi.methods import config_for

        assert config_for("glint-paper", "tiny").refine_from == sup.refine_from  # the paper's choices keep it
        assert config_for("glint", "tiny").refine_from == config_for("tsgs", "tiny").refine_from == 1.0
    assert [stage(at(c.sh_every) * k)["sh_degree"] for k in range(4)] == [0, 1, 2, 2]
    if variant != "supplement":  # secondary_until: the transmission and reflection sets frozen, the interface not
        fr = SimpleNamespace(**{**vars(fake), "cfg": c.replace(secondary_until=0.5)})
        assert Trainer.stage(fr, at(0.5) - 1)["trained"] == {"interface", "transmission", "reflection"}
        late = Trainer.stage(fr, at(0.5))
        assert late["trained"] == {"interface"} and late["traced"] == {"interface", "transmission", "reflection"}
        with pytest.raises(ConfigError, match="'secondary_until'.*trains nothing"):  # with the refine stage: nothing
            c.replace(secondary_until=0.9, refine_from=0.8)
        with pytest.raises(ConfigError, match="'secondary_until' = 1.5: is a fraction"):
            c.replace(secondary_until=1.5)
    assert stage(0)["depth"] and stage(0)["consistency"]
    fake.dropped = {"transmission": "x", "reflection": "y"}  # dropped sets are never traced again
    assert stage(599)["traced"] == {"interface"} and not stage(599)["trans"]
    off = TrainConfig.for_preset("tiny", variant, iterations=600, normal_early="off")  # glint_mi's until then
    fake.cfg = off
    assert not stage(at(c.normal_from) - 1)["normal"] and stage(at(c.normal_from))["normal"]


def test_position_rate_falls_log_linearly_to_lr_position_until_and_holds():
    """The position learning rate (a multiple of lr_position): 1 at the start, lr_position_final / lr_position at
    ``lr_position_until`` of the run, held after; halfway in log space at half that fraction. 1.0 is 3DGS's
    schedule over the whole run."""
    from glint_mi.training.trainer import position_rate

    c = TrainConfig.for_preset("tiny", iterations=101, lr_position=1e-4, lr_position_final=1e-6)
    assert c.lr_position_until == 1.0
    assert [position_rate(c, i) for i in (0, 50, 100)] == pytest.approx([1.0, 0.1, 0.01], rel=1e-12)
    h = c.replace(lr_position_until=0.5)
    assert [position_rate(h, i) for i in (0, 25, 50, 75, 100)] == pytest.approx([1.0, 0.1, 0.01, 0.01, 0.01],
                                                                                rel=1e-12)
    assert position_rate(h, 49) > position_rate(h, 50) == position_rate(h, 51)
    for bad in (0.0, 1.5, -0.2):
        with pytest.raises(ConfigError, match="'lr_position_until'"):
            c.replace(lr_position_until=bad)


def test_2dgs_runs_its_release_schedule_and_terms(tmp_path):
    """2DGS as its release trains it: depth distortion (lambda 10) from 3k of 30k iterations, normal consistency
    (0.05) on the median depth from 7k; GLINT has neither the distortion nor the delay. One training step of the
    bundled room past both starts: the distortion term is on and positive, and the consistency term reads the
    median depth (a changed median changes it, a changed expected depth does not)."""
    from types import SimpleNamespace

    import drjit as dr
    import mitsuba as mi

    from glint_mi.methods import config_for
    from glint_mi.training.trainer import Trainer

    c = config_for("2dgs", "tiny", iterations=300)
    assert (c.w_dist, c.dist_from, c.w_consistency, c.consistency_from, c.consistency_depth) == \
        (10.0, 0.1, 0.05, 7 / 30, "median")
    g = config_for("glint", "tiny", iterations=300)
    assert g.w_dist == 0 and g.consistency_from == 0 and g.consistency_depth == "expected"
    fake = SimpleNamespace(cfg=c, it=0, prior_floor=0.0, prior_weight={}, sets={"interface": 0}, dropped={},
                           bank=SimpleNamespace(has=set(), sfm_depth=None))
    stage = lambda it: Trainer.stage(fake, it)
    assert not stage(c.at(0.1) - 1)["distortion"] and stage(c.at(0.1))["distortion"]
    assert not stage(c.at(7 / 30) - 1)["consistency"] and stage(c.at(7 / 30))["consistency"]

    from glint_mi.scene import read_scene
    from pathlib import Path
    spec = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "glass_room" / "optimize.xml"))
    tr = Trainer(tmp_path / "run", c, scene=spec, log=lambda *a, **k: None)
    tr.it = c.at(0.5)
    terms = tr.step()
    assert terms["distortion"] > 0 and terms["consistency"] > 0
    # the consistency term's depth: shift the median, then the expected depth, of the same traced batch
    st = tr.stage()
    b, ray, fwd, out = _traced_batch(tr, st)
    rng = np.random.default_rng(1)
    value = lambda o: O.batch_objective(c, b, o, st, ray, fwd, len(tr.bank.views), tr.extent)[0]["consistency"]
    base = value(out)
    bumped = lambda k: {**out, k: out[k] * mi.Float(1 + 0.05 * rng.standard_normal(dr.width(out[k])))}
    assert abs(value(bumped("median")) - base) > 1e-4 * max(base, 1e-3)
    assert value(bumped("depth")) == pytest.approx(base, rel=1e-6)


@pytest.mark.parametrize("disparity", [False, True])
def test_whole_image_depth_fit(tmp_path, disparity):
    """depth_align: image — each view's (w, q) fitted over a grid of the whole view from rendered depths: a prior
    that is exactly w D + q (or w / D + q for a disparity prior) gives back w and q."""
    from PIL import Image

    from glint_mi.training.batch import RayBank
    from glint_mi.data import load_dataset
    from glint_mi.data.cameras import Camera, write_transforms_json

    folder = tmp_path / "cap"
    (folder / "images").mkdir(parents=True)
    (folder / "priors" / "depth").mkdir(parents=True)
    cams = [Camera(f"v{i}", np.eye(4), 40, 30, 30.0, 30.0, 20.0, 15.0) for i in range(2)]
    write_transforms_json(folder / "transforms.json", cams)
    depth = {c.name: np.linspace(1.0, 3.0, 40 * 30).reshape(30, 40) * (1 + i) for i, c in enumerate(cams)}
    wq = {"v0": (2.0, 0.5), "v1": (0.7, -0.1)}
    for c in cams:
        Image.fromarray(np.zeros((30, 40, 3), np.uint8)).save(folder / "images" / f"{c.name}.png")
        x = 1.0 / depth[c.name] if disparity else depth[c.name]
        np.save(folder / "priors" / "depth" / f"{c.name}.npy", (wq[c.name][0] * x + wq[c.name][1]).astype(np.float32))
    if disparity:
        (folder / "priors" / "PRIORS.json").write_text('{"depth": {"type": "disparity"}}')
    ds = load_dataset(folder)
    bank = RayBank(ds.views, folder)
    flat_depth = np.concatenate([depth[v.name].ravel() for v in ds.views])
    seen = []

    def render(flat, vid):
        seen.append(len(flat))
        return flat_depth[flat], np.ones(len(flat))

    bank.fit_depth_to_renders(render, max_rays=300)
    assert seen[0] <= 2 * 300 + 40
    np.testing.assert_allclose(bank.depth_affine, [wq["v0"], wq["v1"]], rtol=1e-3, atol=1e-3)


def test_prior_decay_scales_the_prior_terms_without_recompiling(tmp_path):
    """prior_decay: the depth and normal prior weights are 1 until that fraction of the run, then fall linearly to 0
    at its end; the objective's prior terms scale by exactly that factor, and a new factor launches the same
    kernels (an opaque scalar: no compilation per iteration)."""
    from types import SimpleNamespace

    from glint_mi.training.trainer import Trainer

    c = TrainConfig.for_preset("tiny", iterations=200, prior_decay=0.5, prior_decay_terms="depth,normal",
                               prior_decay_ref=0.0, components="interface")
    fake = SimpleNamespace(cfg=c, it=0, prior_floor=0.0, prior_weight={}, sets={"interface": 0}, dropped={},
                           bank=SimpleNamespace(has={"depth", "normal"}, sfm_depth=None))
    scale = lambda it: Trainer.stage(fake, it)["prior_scale"]
    assert scale(0) == scale(100) == 1.0 and scale(150) == pytest.approx(0.5) and scale(200) == 0.0
    fake.cfg = TrainConfig.for_preset("tiny", iterations=200, prior_decay=1.0)
    assert scale(199) == 1.0  # constant weights (the paper, every baseline)
    fake.cfg = TrainConfig.for_preset("tiny", iterations=200)  # the default: the normal prior falls from half the run
    assert fake.cfg.prior_decay_terms == "normal" and scale(100) == 1.0 and scale(150) == pytest.approx(0.5)
    fake.prior_floor = 0.4  # prior_decay_ref: the normal prior falls to its floor from SfM agreement, not to 0
    fake.prior_weight = {"normal": 0.3}  # prior_weight_ref: the run's shares go to the objective with each stage
    assert Trainer.stage(fake, 150)["prior_weight"] == {"normal": 0.3}
    # prior_weight_from: the shares apply from that fraction of the run; before it every term keeps its weight
    fake.cfg = TrainConfig.for_preset("tiny", iterations=200, prior_weight_ref=10.0, prior_weight_from=0.5)
    assert [Trainer.stage(fake, it)["prior_weight"] for it in (0, 99, 100, 199)] == [{}, {}] + [{"normal": 0.3}] * 2
    fake.cfg = TrainConfig.for_preset("tiny", iterations=200)
    assert scale(100) == 1.0 and scale(150) == pytest.approx(0.7) and scale(200) == pytest.approx(0.4)

    tr, st, b, ray, fwd, out = _room_batch_at(tmp_path, c, 0.6)
    assert st["depth"] and st["normal"]
    terms = lambda s: O.batch_objective(c, b, out, {**st, "prior_scale": s}, ray, fwd, len(tr.bank.views),
                                        tr.extent)[0]
    full = terms(1.0)
    assert full["depth"] > 0 and full["normal"] > 0
    terms(0.7)  # compiles what a first factor other than 1 needs
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        part = terms(0.25)
        compiled = [k for k in dr.kernel_history() if not k.get("cache_hit", 1)]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert part["depth"] == pytest.approx(0.25 * full["depth"], rel=1e-5)
    assert part["normal"] == pytest.approx(0.25 * full["normal"], rel=1e-5)
    assert part["l1"] == pytest.approx(full["l1"], rel=1e-6)
    assert not compiled, compiled
    # depth_prior_ref: each ray's depth term times its view's weight (RayBank.depth_prior_weights)
    n_rays = dr.width(b.rgb)
    weighted = O.batch_objective(c, dataclasses.replace(b, depth_weight=dr.full(mi.Float, 0.3, n_rays)), out,
                                 {**st, "prior_scale": 1.0}, ray, fwd, len(tr.bank.views), tr.extent)[0]
    assert b.depth_affine is not None and weighted["depth"] == pytest.approx(0.3 * full["depth"], rel=1e-5)
    assert weighted["normal"] == pytest.approx(full["normal"], rel=1e-6)
    # prior_decay_terms: normal - the normal prior falls, the depth prior keeps its weight (exact priors: the normal
    # prior is what costs 3DGS PSNR, the depth prior gains)
    c_n = TrainConfig.for_preset("tiny", iterations=200, prior_decay=0.5, prior_decay_terms="normal",
                                 components="interface")
    only_n = O.batch_objective(c_n, b, out, {**st, "prior_scale": 0.25}, ray, fwd, len(tr.bank.views), tr.extent)[0]
    assert only_n["normal"] == pytest.approx(0.25 * full["normal"], rel=1e-5)
    assert only_n["depth"] == pytest.approx(full["depth"], rel=1e-5)
    with pytest.raises(ConfigError, match="prior_decay_terms"):
        TrainConfig.for_preset("tiny", prior_decay_terms="albedo")
    # prior_weight_ref: a term's share from the priors' agreement with SfM multiplies its schedule, on that term only
    shared = O.batch_objective(c_n, b, out, {**st, "prior_scale": 0.25, "prior_weight": {"normal": 0.4}}, ray, fwd,
                               len(tr.bank.views), tr.extent)[0]
    assert shared["normal"] == pytest.approx(0.1 * full["normal"], rel=1e-5)
    assert shared["depth"] == pytest.approx(full["depth"], rel=1e-5)
    both = O.batch_objective(c, b, out, {**st, "prior_scale": 1.0, "prior_weight": {"normal": 0.5, "depth": 0.5}},
                             ray, fwd, len(tr.bank.views), tr.extent)[0]
    assert both["normal"] == pytest.approx(0.5 * full["normal"], rel=1e-5)
    assert both["depth"] == pytest.approx(0.5 * full["depth"], rel=1e-5)
    assert both["l1"] == pytest.approx(full["l1"], rel=1e-6)
    with pytest.raises(ConfigError, match="prior_weight_terms"):
        TrainConfig.for_preset("tiny", prior_weight_terms="albedo").validate()
    # the run's shares reach the objective through its stage: none at prior_weight_ref 0 (this run); on the bundled
    # room's own SfM points and priors, ref 10 gives the normal prior min(1, (10 / mean)^2), reported as used
    from glint_mi.training.inputs import normal_prior_schedule

    assert tr.prior_weight == {} and st["prior_weight"] is tr.prior_weight and "prior_weight" not in tr.report
    report = {}
    c10 = TrainConfig.for_preset("tiny", iterations=200, prior_weight_ref=10.0, components="interface")
    _, scale10 = normal_prior_schedule(tr.bank, tr.ds, c10, report, log=lambda *a: None)
    mean = report["normal_prior_sfm"]["mean_deg"]
    assert mean is not None and scale10 == {"normal": pytest.approx(min(1.0, (10.0 / mean) ** 2))}
    assert report["prior_weight"]["scale"] == scale10


@pytest.mark.parametrize("cover, share, kept", [(0.0041, 0.0063, True),    # tuning room 7301 with its glass case
                                                (0.0003, 0.0033, False),   # the same room without the glass
                                                (0.0214, 0.0020, True)])   # room 7101 at 5 epochs: glass, a young set
def test_components_auto_decision_on_the_measured_pair(cover, share, kept):
    """components: auto decides the transmission set at the end of densification from L_trans's mask coverage
    (mean since it started) alone: the pair measured on room 7301 with and without its glass (docs/decisions.md)
    falls on either side of the default threshold, and a short run whose set still carries little of the image
    energy keeps its glass (the energy share, which grows with the budget, used to drop it)."""
    from glint_mi.training.components import ComponentsPolicy

    c = TrainConfig.for_preset("bench", iterations=1000)
    policy = ComponentsPolicy(c)
    at = policy.decide_at()["transmission"]
    roles = ["interface", "transmission", "reflection"]
    assert at == c.at(max(c.densify_until, c.trans_from + 0.1)) and policy.due(at - 1, roles) == []
    assert ComponentsPolicy(c.replace(grow_until=0.9)).decide_at() == policy.decide_at()  # growth alone moves
    hist = [{"mask_t": cover, "share_transmission": share, "share_reflection": 0.05}] * 60
    for role in policy.due(at, roles):
        keep, why = policy.decide(role, hist, roles)
        policy.record(role, keep, at, why)
    assert policy.decisions["transmission"]["kept"] is kept
    assert ("transmission" not in policy.dropped) is kept
    assert policy.due(at, roles) == [r for r in roles[2:] if r not in policy.decisions]  # each set decided once


def test_prior_layer_nearer_in_the_objective(tmp_path):
    """The batch objective with ``prior_layer: nearer``: where the interface is opaque (t = 0) it is exactly the
    paper's; where it is transparent (t = 1) each prior term takes, per ray, the better of the two layers - never
    more than the paper's, less where the transmission set agrees better."""
    from pathlib import Path

    from glint_mi.scene import read_scene
    from glint_mi.training.trainer import Trainer

    c = TrainConfig.for_preset("tiny", iterations=200, components="all", prior_layer="interface")
    spec = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "glass_room" / "optimize.xml"))
    tr = Trainer(tmp_path / "run", c, scene=spec, log=lambda *a, **k: None)
    tr.it = c.at(0.6)
    st = tr.stage()
    assert st["depth"] and st["normal"] and "transmission" in st["traced"]
    b, ray, fwd, out = _traced_batch(tr, st, need={"trans_direct"})
    n = dr.width(out["depth"])

    def terms(layer, t):
        cfg = TrainConfig.for_preset("tiny", iterations=200, components="all", prior_layer=layer)
        o = {**out, "transparency": mi.Float(np.full(n, t, np.float32))}
        return O.batch_objective(cfg, b, o, st, ray, fwd, len(tr.bank.views), tr.extent)[0]

    for key in ("depth", "normal"):
        assert terms("nearer", 0.0)[key] == pytest.approx(terms("interface", 0.0)[key], rel=1e-6)
    paper, nearer = terms("interface", 1.0), terms("nearer", 1.0)
    assert nearer["depth"] < paper["depth"] and nearer["normal"] <= paper["normal"] + 1e-7
    assert nearer["l1"] == pytest.approx(paper["l1"], rel=1e-6)


# float64 numpy definitions of the statistics the objective reduces on the device (losses.component_stats,
# losses.depth_gap_stats): the references they are checked against
def _rows(x):
    a = np.array(x)
    return a.T if a.ndim == 2 and a.shape[0] == 3 else a


def _component_stats_reference(b, out) -> dict:
    lum = lambda x: np.asarray(x).mean(0) if np.asarray(x).ndim == 2 else np.asarray(x)
    w = out["weights"]
    img_e = max(float(lum(np.array(out["rgb"])).mean()), 1e-6)
    ref = {"share_reflection": float(np.mean(np.array(w[1]) * lum(np.array(out["reflection"])))) / img_e,
           "share_transmission": float(np.mean(np.array(w[2]) * lum(np.array(out["transmission"])))) / img_e}
    surface = np.array(out["alpha"]) >= 0.5
    C, cI, gt = _rows(out["rgb"])[surface], _rows(out["interface"])[surface], b.rgb[surface]
    e = max(float(np.abs(C - gt).mean()), 1e-6)
    for k, name in ((1, "reflection"), (2, "transmission")):
        wk = np.array(w[k])
        if wk.ndim == 0 or wk.size == 1:
            continue
        without = C - wk[surface][:, None] * (_rows(out[name])[surface] - cI)
        ref[f"gain_{name}"] = (float(np.abs(without - gt).mean()) - e) / e
    return ref


def _depth_gap_reference(c, out, extent) -> dict:
    _, Dd, _, DA = out["trans_direct"]
    dI, dT = np.array(out["depth"]), np.array(Dd)
    valid = (dI > 0) & (dT > 0) & (np.array(out["alpha"]) >= c.trans_min_alpha) & (np.array(DA) >= c.trans_min_alpha)
    dz, tau = dT - dI, c.tau_delta * extent
    return {"gap_behind": float(np.mean(valid & (dz > tau))), "gap_front": float(np.mean(valid & (dz < -tau)))}


def test_device_statistics_equal_numpy_and_are_read_only_when_asked(tmp_path):
    """The objective's statistics (each set's share of the image energy and gain, the depth gaps, the hit budget)
    are reduced on the device: equal to their float64 numpy definitions within float32 rounding (rel 1e-4), and with
    read=False nothing is a float until read_values; a training run reads them back when it logs, as floats."""
    from glint_mi.scene import read_scene
    from glint_mi.training.trainer import Trainer, budget_full
    from pathlib import Path

    spec = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "glass_room" / "optimize.xml"))
    c = TrainConfig.for_preset("tiny", iterations=40, log_every=8)
    tr = Trainer(tmp_path / "run", c, scene=spec, log=lambda *a, **k: None)
    tr.it = c.at(0.6)
    st = tr.stage()
    assert {"transmission", "reflection"} <= st["traced"] and st["trans"]
    b, ray, fwd, out = _traced_batch(tr, st, need={"trans_direct"})
    got = L.component_stats(out, mi.Color3f(*[mi.Float(b.rgb[:, k].astype(np.float32)) for k in range(3)]))
    got.update(L.depth_gap_stats(c, out, tr.extent))
    got = L.read_values(got)
    ref = {**_component_stats_reference(b, out), **_depth_gap_reference(c, out, tr.extent)}
    assert set(got) == set(ref) and ref["share_reflection"] > 0 and ref["gap_behind"] + ref["gap_front"] > 0
    for k in ref:
        assert got[k] == pytest.approx(ref[k], rel=1e-4, abs=1e-7), k
    terms, _, stats = O.batch_objective(c, b, out, st, ray, fwd, len(tr.bank.views), tr.extent, read=False)
    assert all(isinstance(terms[k], dr.ArrayBase) for k in ("total", "l1", "dssim", "trans"))
    assert isinstance(stats["share_reflection"], dr.ArrayBase) and isinstance(stats["mask_t"], dr.ArrayBase)
    read = L.read_values(terms)
    assert read["total"] == pytest.approx(sum(v for k, v in read.items() if k != "total"), rel=1e-5)
    rec = tr.integ.trace(ray, mi.Bool(True), forward=fwd, record=True)
    assert isinstance(budget_full(rec, 4, read=False), dr.ArrayBase)
    full = float(np.mean(np.asarray(rec["hit_lists"][0][1]) >= 4))
    assert budget_full(rec, 4) == pytest.approx(full) and 0 < full
    # a run: every logged row holds floats
    tr.it = 0
    tr.train(progress=False)
    assert all(isinstance(v, (float, int, str)) for h in tr.history for v in h.values())


def _release_normalize_depth(depth: np.ndarray, p: float = 0.01) -> np.ndarray:
    """The release's ``normalize_depth`` (easyvolcap/utils/depth_utils.py), transcribed in numpy: near = the largest
    of the int(p N) smallest values, far = the smallest of the int(p N) largest, 1 - (D - near) / (far - near)."""
    k = int(depth.size * p)
    s = np.sort(depth.ravel())
    near, far = s[k - 1], s[s.size - k]
    return np.clip(1 - (depth - near) / (far - near), 0, 1)


def test_near_weight_is_the_release_depth_scale_and_gates_the_normal_terms(tmp_path):
    """normal_weight: near (the release's use_dpt_scale_norm_loss / use_dpt_scale_gs_norm_loss): the weight equals
    the release's normalize_depth over the valid rays (0 elsewhere); in the objective it scales the normal prior and
    the depth-normal consistency per pixel, so a ray at or beyond the far quantile sends no gradient to its normal
    while it does under the default; and the weighted normal prior's gradient matches central differences."""
    rng = np.random.default_rng(3)
    d = rng.uniform(0.5, 9.0, 4096).astype(np.float32)
    w = L.near_weight(mi.Float(d), mi.Bool(True)).numpy()
    assert np.allclose(w, _release_normalize_depth(d), atol=1e-6)
    valid = rng.random(d.size) > 0.3
    w = L.near_weight(mi.Float(d), mi.Bool(valid)).numpy()
    assert np.all(w[~valid] == 0) and np.allclose(w[valid], _release_normalize_depth(d[valid]), atol=1e-6)
    assert L.near_weight(mi.Float(d), mi.Bool(False)).numpy().max() == 0  # no valid ray: nothing, no NaN

    # the weighted normal prior against central differences (float64 arithmetic on float32 values: 2 % on 6 rays)
    n = rng.normal(size=(64, 3)); n /= np.linalg.norm(n, axis=1, keepdims=True)
    pr = n + 0.4 * rng.normal(size=(64, 3)); pr /= np.linalg.norm(pr, axis=1, keepdims=True)
    wt = rng.uniform(0, 1, 64)
    vec = lambda a: mi.Vector3f(*[mi.Float(a[:, k]) for k in range(3)])
    value = lambda a: float(L.normal_loss(vec(a), vec(pr), 0.3, True, "cos", False, None, mi.Float(wt))[0][0])
    N = vec(n)
    dr.enable_grad(N)
    dr.backward(L.normal_loss(N, vec(pr), 0.3, True, "cos", False, None, mi.Float(wt))[0])
    g = _rows(dr.grad(N))
    for i in rng.choice(64, 6, replace=False):
        e = np.zeros_like(n); e[i, 0] = 1e-3
        fd = (value(n + e) - value(n - e)) / 2e-3
        assert g[i, 0] == pytest.approx(fd, rel=2e-2, abs=1e-5)

    # in the objective, one traced batch of the bundled room past the normal prior's start
    c = TrainConfig.for_preset("tiny", iterations=200, components="interface", normal_weight="uniform")
    tr, st, b, ray, fwd, out = _room_batch_at(tmp_path, c, 0.6)
    assert st["normal"] and st["consistency"]
    run = lambda cfg: O.batch_objective(cfg, b, out, st, ray, fwd, len(tr.bank.views), tr.extent)
    (tu, au, _), (tn, an, _) = run(c), run(dataclasses.replace(c, normal_weight="near"))
    for k in ("normal", "consistency"):
        assert 0 < tn[k] < tu[k]
    assert tn["l1"] == tu["l1"] and tn["depth"] == tu["depth"]
    A = np.array(out["alpha"]).ravel()
    w = L.near_weight(out["depth"], mi.Float(A) > 0.5).numpy()
    far = (A > 0.5) & (w == 0)
    gu, gn = (np.abs(_rows(a["normal"])).sum(-1) for a in (au, an))
    assert far.sum() >= int(0.01 * (A > 0.5).sum()) >= 1 and gu[far].max() > 0 and gn[far].max() == 0
    # near_consistency: the weight on the consistency only, the normal prior as under the default
    tc, ac, _ = run(dataclasses.replace(c, normal_weight="near_consistency"))
    assert tc["normal"] == tu["normal"] and tc["consistency"] == pytest.approx(tn["consistency"], rel=1e-6)
    from glint_mi.config import ConfigError
    from glint_mi.methods import config_for
    assert config_for("glint-paper", "tiny").normal_weight == "near"  # the release's
    assert config_for("glint", "tiny").normal_weight == TrainConfig().normal_weight == "near_consistency"
    from glint_mi.methods import METHODS
    for name in METHODS:  # GLINT's ablations keep its weight; every baseline weighs uniformly, as its paper does
        want = "near" if name == "glint-paper" else "near_consistency" if name.startswith("glint") else "uniform"
        assert config_for(name, "tiny").normal_weight == want, name
    with pytest.raises(ConfigError, match="'normal_weight' = 'far'"):
        TrainConfig.for_preset("tiny", normal_weight="far")


def test_the_objective_is_its_table_of_terms(tmp_path, monkeypatch):
    """Issue 64: the loss terms are rows of objective.TERMS (name, weight field, schedule field, buffers read,
    function); every LOSS_NAMES entry has a row, every weight is a field of the losses layer, every start one of the
    schedule layer, and the total is the sum of the rows that run (a table of two terms gives their sum). The table
    replaced a chain of ifs; the terms, adjoints and statistics were compared bit for bit with it on glint,
    glint-paper, 2dgs, tsgs (given masks) and 3dgs-priors at three stages (2026-11-28, in the closing note)."""
    from glint_mi.config import FIELD_LAYER, LOSS_NAMES
    from glint_mi.model.render import AOV_GROUPS
    from glint_mi.training import objective

    assert {t.name for t in objective.TERMS} == set(LOSS_NAMES) - {"total"}
    for t in objective.TERMS:
        assert FIELD_LAYER[t.weight] == "losses", t
        assert t.starts is None or FIELD_LAYER[t.starts] == "schedule", t
        assert set(t.needs) <= set(AOV_GROUPS) | {"median", "distortion"}, t
    c = TrainConfig.for_preset("tiny", components="all", trans_albedo="masks")
    tr, st, b, ray, fwd, out = _room_batch_at(tmp_path, c, 0.5)
    assert st["l1"] and st["dssim"]  # the stage switches on a term it has no rule for while it is weighted
    full = objective.batch_objective(c, b, out, st, ray, fwd, len(tr.bank.views), tr.extent)[0]
    assert full["total"] == pytest.approx(sum(v for k, v in full.items() if k != "total"), rel=1e-5)
    two = [t for t in objective.TERMS if t.name in ("l1", "dssim")]
    monkeypatch.setattr(objective, "TERMS", tuple(two))
    part = objective.batch_objective(c, b, out, st, ray, fwd, len(tr.bank.views), tr.extent)[0]
    assert part["total"] == pytest.approx(full["l1"] + full["dssim"], rel=1e-6) and part["depth"] == 0.0


def test_off_glass_pull_reaches_the_objective_per_ray(tmp_path):
    """prior_weight_where: off_glass in the objective: where the interface's rendered transparency is 1 every ray
    keeps the whole pull (the depth's adjoint equals the uncut one's), where it is 0 and no cue labels a ray every
    ray gets the share (it equals prior_weight_where: all's); a cue's seen-through rays take the whole pull back."""
    import dataclasses

    import drjit as dr

    kw = dict(iterations=200, prior_weight_ref=10.0, prior_weight_terms="consistency")
    c_all = TrainConfig.for_preset("tiny", **kw)
    c_off = TrainConfig.for_preset("tiny", **kw, prior_weight_where="off_glass")
    tr, st, b, ray, fwd, out = _room_batch_at(tmp_path, c_all, 0.6)
    assert st["consistency"]
    b = dataclasses.replace(b, cue=None)
    n = dr.width(out["depth"])
    adj = lambda c, o, bb, share: np.array(O.batch_objective(
        c, bb, o, {**st, "prior_weight": {"consistency": share}}, ray, fwd, len(tr.bank.views), tr.extent)[1]["depth"])
    with_t = lambda v: {**out, "transparency": mi.Float(np.full(n, v, np.float32))}
    whole, cut = adj(c_all, with_t(1.0), b, 1.0), adj(c_all, with_t(0.0), b, 0.25)
    np.testing.assert_array_equal(whole, adj(c_all, with_t(0.0), b, 1.0))  # under all, t does not move it ...
    assert np.abs(whole - cut).max() > 1e-6  # ... the share does
    np.testing.assert_allclose(adj(c_off, with_t(1.0), b, 0.25), whole, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(adj(c_off, with_t(0.0), b, 0.25), cut, rtol=1e-4, atol=1e-9)
    cue = np.zeros(n, np.int8)
    cue[: n // 2] = 1  # the cue says seen through on the first half of the batch's rays
    got = adj(c_off, with_t(0.0), dataclasses.replace(b, cue=cue), 0.25)
    ref_whole = adj(c_all, with_t(0.0), dataclasses.replace(b, cue=cue), 1.0)
    ref_cut = adj(c_all, with_t(0.0), dataclasses.replace(b, cue=cue), 0.25)
    assert np.abs(got - ref_cut).max() > 1e-6 and np.abs(got - ref_whole).max() > 1e-6  # neither all whole nor all cut
    # prior_weight_glass_t 0.5: half-found glass (t 0.5) keeps the whole pull; under gpull's g = t it gets less
    c_step = dataclasses.replace(c_off, prior_weight_glass_t=0.5)
    np.testing.assert_allclose(adj(c_step, with_t(0.5), b, 0.25), whole, rtol=1e-4, atol=1e-9)
    assert np.abs(adj(c_off, with_t(0.5), b, 0.25) - whole).max() > 1e-6
    np.testing.assert_allclose(adj(c_step, with_t(0.0), b, 0.25), cut, rtol=1e-4, atol=1e-9)
