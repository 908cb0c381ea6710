"""Losses: the depth loss's closed form against a least-squares solve and finite differences, the normal mask,
the L_trans masks on hand-made depth maps, BCE."""
import numpy as np
import pytest

import drjit as dr
import mitsuba as mi

from glint_mi.training.losses import (bce, depth_fit, depth_loss, depth_loss_aligned, normal_loss, plausibility_weight,
                                      transparency_masks)


def _batch(rng, n_views=3, per=200):
    view = np.repeat(np.arange(n_views), per)
    D = rng.uniform(1, 5, n_views * per)
    scale, shift = rng.uniform(0.5, 2, n_views), rng.uniform(-1, 1, n_views)
    P = scale[view] * D + shift[view] + rng.normal(0, 0.05, D.size)
    mask = rng.random(D.size) > 0.2
    return D, P, mask, view


def test_depth_fit_matches_least_squares(rng):
    D, P, mask, view = _batch(rng)
    w, q = depth_fit(mi.Float(D), mi.Float(P), mi.Bool(mask), mi.UInt32(view), 3)
    w, q = np.array(w), np.array(q)
    for v in range(3):
        sel = (view == v) & mask
        A = np.column_stack([D[sel], np.ones(sel.sum())])
        (w_ref, q_ref), *_ = np.linalg.lstsq(A, P[sel], rcond=None)
        np.testing.assert_allclose(w[view == v], w_ref, rtol=1e-4)
        np.testing.assert_allclose(q[view == v], q_ref, atol=1e-4)


def test_depth_loss_gradient_matches_finite_differences(rng):
    """Detached (w, q) give the exact gradient of the minimised loss (envelope theorem)."""
    D, P, mask, view = _batch(rng, 2, 50)
    f = lambda d: float(np.array(depth_loss(mi.Float(d), mi.Float(P), mi.Bool(mask), mi.UInt32(view), 2))[0])
    Dd = mi.Float(D)
    dr.enable_grad(Dd)
    dr.backward(depth_loss(Dd, mi.Float(P), mi.Bool(mask), mi.UInt32(view), 2))
    g = np.array(dr.grad(Dd))
    for i in (0, 7, 60, 99):
        h = 1e-3
        e = np.zeros_like(D)
        e[i] = h
        fd = (f(D + e) - f(D - e)) / (2 * h)
        assert abs(g[i] - fd) < max(2e-3 * abs(fd), 1e-6), (i, g[i], fd)
    assert np.all(g[~mask] == 0)


def test_depth_loss_is_scale_shift_invariant(rng):
    D, P, mask, view = _batch(rng)
    P_exact = 1.7 * D - 0.3
    loss = depth_loss(mi.Float(D), mi.Float(P_exact), mi.Bool(mask), mi.UInt32(view), 3)
    assert float(np.array(loss)[0]) < 1e-8


def test_prior_layer_nearer_sends_each_ray_to_the_layer_the_prior_describes():
    """prior_layer: nearer - where the interface is transparent, a see-through prior supervises the transmitted
    surface, not the pane; elsewhere (or where the pane agrees better) the interface, exactly as without it."""
    D_I = np.array([2.0, 2.0, 2.0, 2.0])      # a pane at 2
    D_T = np.array([3.0, 3.0, 3.0, 3.0])      # the room behind it at 3
    P = np.array([3.1, 2.1, 3.1, 3.1])        # views that see through (0, 2, 3) and one that sees the pane (1)
    ok = np.array([True, True, False, True])  # ray 2: the interface is opaque there
    mask = np.array([True, True, True, False])
    one, zero = mi.Float(np.ones(4)), mi.Float(np.zeros(4))
    di, dt = mi.Float(D_I), mi.Float(D_T)
    dr.enable_grad(di, dt)
    loss = depth_loss_aligned(di, mi.Float(P), mi.Bool(mask), one, zero, (dt, mi.Bool(ok)))
    dr.backward(loss)
    # residuals: ray 0 -> D_T (0.1), ray 1 -> D_I (0.1), ray 2 -> D_I (1.1, opaque), ray 3 masked out
    np.testing.assert_allclose(float(np.array(loss)[0]), (0.01 + 0.01 + 1.21) / 3, rtol=1e-5)
    np.testing.assert_allclose(np.array(dr.grad(di)), [0, -0.2 / 3, -2.2 / 3, 0], atol=1e-6)
    np.testing.assert_allclose(np.array(dr.grad(dt)), [-0.2 / 3, 0, 0, 0], atol=1e-6)
    # without a second layer: the interface takes every residual
    base = depth_loss_aligned(mi.Float(D_I), mi.Float(P), mi.Bool(mask), one, zero)
    np.testing.assert_allclose(float(np.array(base)[0]), (1.21 + 0.01 + 1.21) / 3, rtol=1e-5)
    # normals: the pane faces the camera, the wall behind it is tilted 40 deg; the prior sees the wall
    ang = np.radians(40)
    p = mi.Vector3f(mi.Float([np.sin(ang)] * 2), mi.Float([0, 0]), mi.Float([-np.cos(ang)] * 2))
    loss, _ = normal_loss(mi.Vector3f(mi.Float([0, 0]), 0, mi.Float([-1, -1])), p, 0.3, True, "cos",
                          behind=(mi.Vector3f(mi.Float([np.sin(ang)] * 2), 0, mi.Float([-np.cos(ang)] * 2)),
                                  mi.Bool([True, False])))
    # ray 0 takes the wall (term 0), ray 1 the pane (1 - cos 40 deg)
    np.testing.assert_allclose(float(np.array(loss)[0]), (1 - np.cos(ang)) / 2, rtol=1e-5)


def test_normal_loss_cosine_mask():
    n = mi.Vector3f([0, 0, 0], [0, 0, 0], [-1, -1, -1])
    c = np.cos(np.radians([10, 70, 100]))
    s = np.sin(np.radians([10, 70, 100]))
    p = mi.Vector3f(mi.Float(s), mi.Float(np.zeros(3)), mi.Float(-c))
    loss, mask = normal_loss(n, p, tau_n=0.3)
    assert list(np.array(mask)) == [True, True, False]  # cos 10 deg, cos 70 deg = 0.34 >= 0.3, cos 100 deg < 0
    _, mask5 = normal_loss(n, p, tau_n=0.5)
    assert list(np.array(mask5)) == [True, False, False]
    # hand-computed: at 10 deg |n - p|_1 = 0.17365 + 0.01519, 1 - cos = 0.01519; at 70 deg 0.93969 + 0.65798, 0.65798
    np.testing.assert_allclose(float(np.array(loss)[0]), 1.22984, rtol=1e-4)
    paper, _ = normal_loss(n, p, tau_n=0.3, form="cos")  # the supplement's 1 - cos over the mask
    np.testing.assert_allclose(float(np.array(paper)[0]), 0.336586, rtol=1e-4)
    early, mask_all = normal_loss(n, p, tau_n=0.3, form="cos", masked=False)  # before 10k/60k: no mask
    assert list(np.array(mask_all)) == [True, True, True]
    np.testing.assert_allclose(float(np.array(early)[0]), 0.615607, rtol=1e-4)


def test_transparency_masks_on_hand_made_depths():
    H, W = 12, 16
    D_I = np.full((H, W), 2.0)
    D_T = np.full((H, W), 2.0)
    D_T[:, 8:] = 3.0                      # right half: the transmission set sees something behind the interface
    D_I[0, :] = 0                         # an invalid row
    m_t, m_o = transparency_masks(D_T, D_I, tau_delta=0.005)
    assert m_t[2:-1, 9:-1].min() == 1 and m_t[:, :8].max() == 0   # behind -> transparent (eroded at the border)
    assert m_o[2:-1, 1:7].min() == 1 and m_o[:, 8:].max() == 0    # same -> opaque
    assert m_t[0].max() == 0 and m_o[0].max() == 0                 # invalid depth -> neither
    # albedo prior: glass = near-black albedo with a bright base colour; dark opaque objects stay opaque
    albedo = np.full((H, W), 0.02)
    base = np.full((H, W), 0.6)
    base[:, 12:] = 0.1                    # dark base colour: LowA & ~HighB -> opaque even though "behind"
    m_t, m_o = transparency_masks(D_T, D_I, 0.005, albedo=albedo, base=base)
    assert m_t[2:-1, 9:11].min() == 1 and m_t[:, 12:].max() == 0 and m_o[2:-1, 13:-1].min() == 1
    # without the dark-surface vote: the dark "behind" quarter votes for nothing, "same" still votes (HighA: the
    # batch gate's test below)
    _, m_o2 = transparency_masks(D_T, D_I, 0.005, albedo=albedo, base=base, dark_votes=False)
    _, m_o1 = transparency_masks(D_T, D_I, 0.005, albedo=albedo, base=base)
    assert m_o2[:, 12:].max() == 0 and m_o1[2:-1, 13:-1].min() == 1
    np.testing.assert_array_equal(m_o2[:, :8], m_o1[:, :8])
    # view-angle weight: 1 up to 70 deg, 0 beyond 80
    cos = np.cos(np.radians(np.full((H, W), 75.0)))
    m_t, _ = transparency_masks(D_T, D_I, 0.005, cos_view=cos)
    np.testing.assert_allclose(m_t[m_t > 0], 0.5, rtol=1e-6)  # float32 on a GPU: 0.5 + 1 ulp


def test_bce_pulls_towards_its_target():
    t = mi.Float([0.2, 0.5, 0.9])
    dr.enable_grad(t)
    dr.backward(bce(t, 0.98, mi.Float([1.0, 1.0, 0.0])))
    g = np.array(dr.grad(t))
    assert g[0] < 0 and g[1] < 0 and g[2] == 0  # descending raises t towards 0.98 where weighted


def test_transparency_masks_ignore_faint_layers():
    """A depth is valid only where its set is a surface (accumulated alpha >= 0.5): a translucent veil in front of
    the room (alpha 0.3) must not be read as glass with the room behind it, nor as an opaque 'same' surface."""
    H, W = 12, 16
    D_I, D_T = np.full((H, W), 1.0), np.full((H, W), 3.0)     # interface in front of what the transmission set sees
    A_I, A_T = np.full((H, W), 0.3), np.ones((H, W))
    A_I[:, 8:] = 0.95                                          # right half: a real surface (glass) in front
    m_t, m_o = transparency_masks(D_T, D_I, tau_delta=0.005, alpha_t=A_T, alpha_i=A_I)
    assert m_t[:, :8].max() == 0 and m_o[:, :8].max() == 0      # the veil votes for nothing
    assert m_t[2:-1, 9:-1].min() == 1
    # without alphas the veil would have been marked transparent (the old rule)
    assert transparency_masks(D_T, D_I, tau_delta=0.005)[0][2:-1, 1:7].min() == 1


def test_transparency_off_and_on_glass_metrics():
    from glint_mi.evaluation.metrics import view_metrics
    H, W = 6, 8
    glass = np.zeros((H, W))
    glass[:, :2] = 1
    depth = np.ones((H, W))
    depth[0] = 0                                  # no surface: counted in neither
    t = np.where(glass > 0, 0.9, 0.2)
    t[0] = 1.0
    img = np.zeros((H, W, 3))
    n = np.zeros((H, W, 3))
    n[..., 2] = 1
    m = view_metrics({"rgb": img, "depth": depth, "normal": n, "transparency": t},
                     {"depth": depth, "normal": n, "glass": glass}, img)
    assert np.isclose(m["t_off_glass"], 0.2) and np.isclose(m["t_on_glass"], 0.9)


def test_psnr_split_on_and_off_glass():
    """psnr_glass / psnr_off_glass: the PSNR over the glass pixels and over the rest, each from its own pixels'
    error alone (an error on the glass leaves the other untouched); NaN where a view has no glass."""
    from glint_mi.evaluation.metrics import view_metrics
    H, W = 6, 8
    glass = np.zeros((H, W))
    glass[:, :2] = 1
    depth = np.ones((H, W))
    n = np.zeros((H, W, 3))
    n[..., 2] = 1
    photo = np.full((H, W, 3), 0.5)
    pred = photo.copy()
    pred[:, :2] += 0.1                             # error 0.1 on the glass: 20 dB there
    pred[:, 2:] -= 0.01                            # error 0.01 elsewhere: 40 dB
    t = np.zeros((H, W))
    m = view_metrics({"rgb": pred, "depth": depth, "normal": n, "transparency": t},
                     {"depth": depth, "normal": n, "glass": glass}, photo)
    assert np.isclose(m["psnr_glass"], 20.0) and np.isclose(m["psnr_off_glass"], 40.0), m
    mse = (2 * 0.1 ** 2 + 6 * 0.01 ** 2) / 8
    assert np.isclose(m["psnr"], -10 * np.log10(mse))
    m0 = view_metrics({"rgb": pred, "depth": depth, "normal": n, "transparency": t},
                      {"depth": depth, "normal": n, "glass": np.zeros((H, W))}, photo)
    assert np.isnan(m0["psnr_glass"]) and np.isclose(m0["psnr"], m0["psnr_off_glass"])


def test_plausibility_weight_reads_the_interface_only():
    """plausibility_mask: interface pulls G_trans where the interface is a surface, by 1 - t, without gradient."""
    t, a = mi.Float([0.0, 0.25, 1.0, 0.1]), mi.Float([1.0, 0.8, 0.9, 0.2])
    dr.enable_grad(t)
    w = plausibility_weight(t, a, 0.5)
    np.testing.assert_allclose(np.array(w), [1.0, 0.75, 0.0, 0.0])
    assert not dr.grad_enabled(w)


def test_transparency_masks_with_cue_and_albedo():
    """With an albedo prior, the cue still decides "behind" / "same": an opaque cue is opaque even where the depths
    are not valid, a seen-through cue is transparent only for near-black albedo and a bright base colour."""
    H, W = 12, 16
    D_I, D_T = np.full((H, W), 2.0), np.full((H, W), 2.0)
    D_T[:, 12:] = 0                                   # right quarter: no transmission depth
    cue = np.zeros((H, W), np.int8)
    cue[:, :6], cue[:, 10:] = 1, -1
    albedo, base = np.full((H, W), 0.02), np.full((H, W), 0.6)
    base[:, 3:6] = 0.1                                # dark base: not glass although seen through
    m_t, m_o = transparency_masks(D_T, D_I, 0.005, albedo=albedo, base=base, cue=cue)
    assert m_t[1:-1, 1:2].min() == 1 and m_t[:, 3:].max() == 0
    assert m_o[1:-1, 11:-1].min() == 1                # including where D_T is invalid
    assert m_o[:, 6:9].max() == 0                     # no evidence: no vote


def _colours(rows):
    """[M, 3] numpy rows -> mi.Color3f."""
    rows = np.asarray(rows, np.float32)
    return mi.Color3f(*[mi.Float(rows[:, k]) for k in range(3)])


def test_see_through_gain_compares_the_two_explanations():
    """gain = clip((e_0 - e_1) / e_0, 0, 1): 1 where the transmitted colour alone fits and the interface's does not,
    0 where the interface fits; a blend of two fits does not count as evidence."""
    from types import SimpleNamespace
    from glint_mi.training.losses import see_through_gain
    b = SimpleNamespace(rgb=_colours([[0.5, 0.5, 0.5], [0.2, 0.2, 0.2], [0.4, 0.4, 0.4]]))
    out = {"weights": (None, mi.Float(np.zeros(3)), None), "reflection": _colours(np.zeros((3, 3))),
           "interface": _colours([[0.9, 0.9, 0.9], [0.2, 0.2, 0.2], [0.5, 0.5, 0.5]]),
           "transmission": _colours([[0.5, 0.5, 0.5], [0.6, 0.6, 0.6], [0.3, 0.3, 0.3]])}
    g = np.array(see_through_gain(b, out))
    np.testing.assert_allclose(g, [1.0, 0.0, 0.0], atol=1e-6)  # the third: both off by 0.1, a blend would fit


@pytest.mark.parametrize("votes", ["all", "geometric"])
def test_t_gate_reads_the_opaque_votes_it_is_told(votes):
    """batch_transparency_masks(gate=True): t may rise where the opaque mask does not vote; with t_gate_votes
    geometric the dark-surface vote (near-black albedo, dark interface colour: also a glass pane in front of a dark
    background) no longer closes the gate, HighA still does; L_trans's own opaque mask keeps every vote."""
    from types import SimpleNamespace
    from glint_mi.config import TrainConfig
    from glint_mi.training.losses import batch_transparency_masks
    p = 8
    n = p * p
    albedo = np.full((n, 3), 0.02)
    albedo.reshape(p, p, 3)[:, 4:] = 0.5                       # right half: HighA
    b = SimpleNamespace(patches=1, patch=p, albedo_prior=_colours(albedo), cue=None, rgb=_colours(np.full((n, 3), 0.3)),
                        direction=mi.Vector3f(0.0, 0.0, 1.0))
    full = lambda v: mi.Float(np.full(n, v, np.float32))
    out = {"trans_direct": (None, full(3.0), None, full(1.0)), "depth": full(2.0), "alpha": full(1.0),
           "interface": _colours(np.full((n, 3), 0.1)), "normal": mi.Vector3f(full(0.0), full(0.0), full(-1.0)),
           "weights": (None, full(0.0), None), "reflection": _colours(np.zeros((n, 3))),
           "transmission": _colours(np.zeros((n, 3)))}
    cfg = TrainConfig(t_gate_votes=votes)
    w_t, w_o, cover, allowed = batch_transparency_masks(cfg, b, out, 1.0, gate=True)
    w_o, allowed = np.array(w_o).reshape(p, p), np.array(allowed).reshape(p, p)
    assert float(cover[0]) == 0 and w_o[1:-1, 1:-1].min() == 1  # L_trans: opaque everywhere (dark, or HighA)
    assert not allowed[1:-1, 5:-1].any()                        # HighA (eroded) closes the gate in both modes
    dark = allowed[1:-1, 1:3]                                   # the dark vote closes it only with all
    assert dark.all() if votes == "geometric" else not dark.any()
    assert batch_transparency_masks(cfg, b, out, 1.0)[3] is None


def _masks_reference(depth_t, depth_i, tau_delta, albedo=None, base=None, cos_view=None, alpha_t=None,
                     alpha_i=None, cue=None, min_alpha=0.5, low_a=0.05, high_a=0.10, high_b=0.25):
    """transparency_masks' rules written again in numpy / scipy (float32 in, per [B, p, p] stack): the reference."""
    from scipy.ndimage import binary_erosion

    valid = (depth_t > 0) & (depth_i > 0)
    if alpha_t is not None:
        valid &= (alpha_t >= min_alpha) & (alpha_i >= min_alpha)
    dz = depth_t - depth_i
    behind, same = valid & (dz > tau_delta), valid & (dz <= tau_delta)
    if cue is not None:
        valid_i = (depth_i > 0) if alpha_i is None else (depth_i > 0) & (alpha_i >= min_alpha)
        behind, same = valid_i & (cue > 0), cue < 0
    if albedo is not None:
        low, high, bright = albedo < low_a, albedo > high_a, base > high_b
        m_t, m_o = low & bright & behind, (valid & (high | (low & ~bright))) | same
    else:
        m_t, m_o = behind, same
    w = np.clip((80.0 - np.degrees(np.arccos(np.clip(cos_view, -1, 1)))) / 10.0, 0.0, 1.0)
    erode = lambda m: binary_erosion(m, structure=np.ones((1, 3, 3), bool), border_value=0)
    return erode(m_t) * w, erode(m_o & ~m_t) * w


@pytest.mark.parametrize("albedo, cue, alphas", [(True, False, True), (False, False, False), (True, True, True)])
def test_device_patch_masks_equal_the_numpy_definition(albedo, cue, alphas):
    """block_transparency_masks (Dr.Jit, per ray, 8 x 8 patches one after the other: what training runs) against the
    rules in numpy / scipy on the [P, p, p] stack: the same masks pixel for pixel, weights within float32 rounding;
    random depths, alphas, albedo, base colours, view angles across the 70-80 degree ramp and SfM cues on 64
    patches; and transparency_masks (the image API) gives the same on the stack."""
    from glint_mi.training.losses import block_transparency_masks
    rng = np.random.default_rng(4)
    P, p = 64, 8
    shape = (P, 2, 2)  # drawn per 4 x 4 block, so that something survives the erosion
    f32 = lambda x: np.asarray(np.repeat(np.repeat(x, 4, axis=1), 4, axis=2), np.float32)
    D_I = f32(rng.uniform(1, 3, shape) * (rng.random(shape) > 0.1))
    D_T = f32(rng.uniform(1, 3, shape) * (rng.random(shape) > 0.1))
    A_I, A_T = f32(rng.uniform(0.3, 1, shape)), f32(rng.uniform(0.3, 1, shape))
    alb = f32(rng.choice([0.02, 0.07, 0.5], shape)) if albedo else None
    base = f32(rng.uniform(0, 0.5, shape)) if albedo else None
    cos = f32(np.cos(np.radians(rng.uniform(40, 85, shape))))
    cues = f32(rng.choice([-1.0, 0.0, 1.0], shape)) if cue else None
    kw = dict(alpha_t=A_T if alphas else None, alpha_i=A_I if alphas else None, cue=cues)
    ref_t, ref_o = _masks_reference(D_T, D_I, 0.01, alb, base, cos, **kw)
    dev = lambda x: None if x is None else mi.Float(x.ravel())
    got_t, got_o = block_transparency_masks(dev(D_T), dev(D_I), (p, p), 0.01, dev(alb), dev(base), dev(cos),
                                            **{k: dev(v) for k, v in kw.items()})
    image_t, image_o = transparency_masks(D_T, D_I, 0.01, alb, base, cos, **kw)
    for got, ref, image in ((got_t, ref_t, image_t), (got_o, ref_o, image_o)):
        got, ref = np.array(got), ref.ravel()
        np.testing.assert_array_equal(got > 0, ref > 0)
        np.testing.assert_allclose(got, ref, atol=2e-5)
        np.testing.assert_array_equal(image.ravel(), got)
        assert (ref > 0).sum() >= 16
    both = np.concatenate([ref_t.ravel(), ref_o.ravel()])
    assert ((both > 0) & (both < 1)).sum() >= 16  # pixels on the view-angle ramp
