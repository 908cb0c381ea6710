"""The native k-buffer traversal (glint_mi.native, the integrator's ``traversal: kbuffer``).

Reference for the listing: a float64 numpy enumeration of every shell whose exit lies ahead of the origin, sorted by
entry (shells around the origin first, with entries behind it). Renders: kbuffer against Mitsuba's BVH queries
(``traversal: bvh``), to float32 shell-test noise (1e-3 on >= 99 % of pixels); any buffer size gives the same image
(same hits, same order, same arithmetic), so rounds continue exactly where the last one stopped. The brute-force
compositors of test_integrator / test_inside_origins and the FD gradient tests run on the default traversal, which
is kbuffer wherever the library builds.
"""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import drjit as dr
import mitsuba as mi

from conftest import LLVM, camera, make_integrator, random_set
from glint_mi import native

needs_native = pytest.mark.skipif(native.load() is None, reason=f"glint_mi.native not built: {native.why_not()}")
# the native traversal reads rays from host memory, so the integrator uses it on LLVM variants only
pytestmark = pytest.mark.skipif(not LLVM, reason=f"the native k-buffer traversal: LLVM variants only (running "
                                                 f"{mi.variant()})")


def _shells(rng, n):
    data = np.zeros((n, 10), np.float32)
    data[:, :3] = rng.uniform(-1, 1, (n, 3))
    data[:, 3:6] = rng.uniform(0.03, 0.15, (n, 3))
    data[:, 6:10] = Rotation.random(n, random_state=1).as_quat()  # x, y, z, w
    return data


def _entries(data, extent, o, d):
    """float64: (entry t, prim) of every shell with exit > 0 along (o, d), sorted."""
    R = Rotation.from_quat(data[:, 6:10].astype(np.float64)).as_matrix()
    s = data[:, 3:6].astype(np.float64) * extent
    ol = np.einsum("nji,nj->ni", R, o[None] - data[:, :3]) / s
    dl = np.einsum("nji,j->ni", R, d) / s
    a, b, c = (dl ** 2).sum(1), (ol * dl).sum(1), (ol ** 2).sum(1) - 1
    disc = b * b - a * c
    ok = disc > 0
    sq = np.sqrt(np.where(ok, disc, 0))
    t0, t1 = (-b - sq) / a, (-b + sq) / a
    idx = np.nonzero(ok & (t1 > 0))[0]
    return sorted(zip(t0[idx], idx))


@needs_native
def test_kbuffer_lists_shell_entries_in_order(rng):
    data, extent = _shells(rng, 400), 2.0
    shells = native.ShellSet(data, extent)
    n = 200
    o = np.concatenate([rng.uniform(-1, 1, (n // 2, 3)), np.tile([[0.0, 0.0, -3.0]], (n // 2, 1))])  # inside / far
    d = rng.normal(size=(n, 3))
    d[n // 2:] = np.array([0, 0, 3.0]) + rng.uniform(-1, 1, (n // 2, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = [[] for _ in range(n)]
    t_prev, p_prev = np.full(n, -np.inf, np.float32), np.full(n, 0xFFFFFFFF, np.uint32)
    go = np.ones(n, bool)
    k = 5
    while go.any():  # rounds of 5 entries, each continuing after the last one listed
        prims, ts, cnt = shells.query(o, d, t_prev, p_prev, go, k, 2)
        for r in np.nonzero(go)[0]:
            got[r] += list(prims[r, :cnt[r]])
            if cnt[r]:
                t_prev[r], p_prev[r] = ts[r, cnt[r] - 1], prims[r, cnt[r] - 1]
        go &= cnt == k
    same = [got[r] == [p for _, p in _entries(data, extent, o[r], d[r])] for r in range(n)]
    inside = [any(t < 0 for t, _ in _entries(data, extent, o[r], d[r])) for r in range(n // 2)]
    assert np.mean(same) >= 0.99 and sum(inside) >= 20  # shells around the origin are listed (first)


@needs_native
def test_query_on_drjits_pool_equals_one_thread(rng):
    """Blocks of rays run on Dr.Jit's worker threads (right after a kernel, while they spin): the same lists as one
    thread, inactive rays untouched, for a ray count that is not a multiple of the block."""
    data, extent = _shells(rng, 600), 2.0
    shells = native.ShellSet(data, extent)
    n = 3001
    o = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_prev, p_prev = np.full(n, -np.inf, np.float32), np.full(n, 0xFFFFFFFF, np.uint32)
    go = rng.uniform(size=n) < 0.7
    one = shells.query(o, d, t_prev, p_prev, go, 16, 1)
    x = dr.sin(dr.arange(mi.Float, 1 << 20))
    dr.eval(x)  # wakes the pool's workers
    pool = shells.query(o, d, t_prev, p_prev, go, 16, max(2, dr.thread_count()))
    assert one[2][go].sum() > 1000 and not one[2][~go].any()
    for a, b in zip(one, pool):
        np.testing.assert_array_equal(a, b)
    rows = np.nonzero(go)[0][:100]
    same = [list(pool[0][r, :pool[2][r]]) == [p for _, p in _entries(data, extent, o[r], d[r])][:16] for r in rows]
    assert np.mean(same) >= 0.98  # float32 shell-test ties aside


@needs_native
def test_a_refitted_set_lists_what_a_fresh_build_lists(rng):
    """Training moves every Gaussian a little each step: a dynamic set refits its BVH in place of a build. After
    many refits (moved, rescaled, turned shells) its lists equal those of a set built fresh on the same data, on
    rays from inside and outside; a refit of another size, or of a static set, is refused."""
    data, extent = _shells(rng, 500), 2.0
    dyn = native.ShellSet(data, extent, dynamic=True)
    n = 400
    o = np.concatenate([rng.uniform(-1, 1, (n // 2, 3)), np.tile([[0.0, 0.0, -3.0]], (n // 2, 1))]).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    args = (o, d, np.full(n, -np.inf, np.float32), np.full(n, 0xFFFFFFFF, np.uint32), np.ones(n, bool), 32, 2)
    for step in range(30):
        data = data.copy()
        data[:, :3] += rng.normal(0, 0.02, (len(data), 3))
        data[:, 3:6] *= np.exp(rng.normal(0, 0.05, (len(data), 3)))
        data[:, 6:10] += rng.normal(0, 0.05, (len(data), 4))
        dyn.refit(data)
    fresh = native.ShellSet(data, extent).query(*args)
    got = dyn.query(*args)
    assert fresh[2].sum() > 1000  # rays that list shells
    for a, b in zip(got, fresh):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="same size"):
        dyn.refit(data[:-1])
    with pytest.raises(ValueError, match="built static"):
        native.ShellSet(data, extent).refit(data)


def _scene(rng, **props):
    sets = {"interface": random_set(rng, 300, spread=(1, 1, 0.4), transparency=0.6, specular=0.1),
            "reflection": random_set(rng, 300, center=(0, 0, -0.8), spread=(1, 1, 0.4)),
            "transmission": random_set(rng, 300, center=(0, 0, 0.8), spread=(1, 1, 0.4))}
    integ = make_integrator(sets, kernels={"interface": "ellipsoid"}, components="all", **props)
    return mi.load_dict({"type": "scene", "integrator": integ, "sensor": camera(48, 36)})


def _render(seed, **props):
    return np.array(mi.render(_scene(np.random.default_rng(seed), **props), seed=0))


@needs_native
def test_kbuffer_and_bvh_render_the_same():
    a, b = _render(3, traversal="kbuffer"), _render(3, traversal="bvh")
    off = np.abs(a - b).max(axis=-1)
    assert np.mean(off > 1e-3) <= 0.01 and np.abs(a - b).mean() < 1e-3


@needs_native
def test_buffer_size_does_not_change_the_image(monkeypatch):
    import glint_mi_plugins.glint_march as gm

    rounds = []
    query = native.ShellSet.query
    monkeypatch.setattr(native.ShellSet, "query", lambda self, *a, **kw: rounds.append(a[5]) or query(self, *a, **kw))
    ref = _render(4, traversal="kbuffer", kbuffer_k=64)
    for k in (1, 3, 16, 256):
        np.testing.assert_array_equal(_render(4, traversal="kbuffer", kbuffer_k=k), ref)
    rounds.clear()
    np.testing.assert_array_equal(_render(4, traversal="kbuffer"), ref)  # the default: the hit budget in one round
    assert set(rounds) == {256} and len(rounds) == 3, rounds  # one round per pass
    monkeypatch.setattr(gm, "KBUFFER_BYTES", 12 * 48 * 36 * 5)  # the memory cap: 5 entries per round here
    rounds.clear()
    np.testing.assert_array_equal(_render(4, traversal="kbuffer"), ref)
    assert set(rounds) == {5} and len(rounds) > 3, rounds


@needs_native
def test_reused_list_buffers_change_nothing(monkeypatch):
    """The rounds write into arrays kept from earlier queries (REUSE_LISTS): the same image as fresh arrays, with
    several rounds a pass (each overwriting the last round's lists) and with the kept arrays full of garbage past
    every ray's count (what a round leaves there must never be read)."""
    import glint_mi_plugins.glint_march as gm

    seen = []
    query = native.ShellSet.query

    def poisoned(self, *a, out=None, **kw):
        if out is not None:
            seen.append(out[0].shape)
            out[0].fill(0xFFFFFFFF - 1)
            out[1].fill(np.nan)
            out[2].fill(7)
        return query(self, *a, out=out, **kw)

    monkeypatch.setattr(gm, "REUSE_LISTS", False)
    refs = {k: _render(6, traversal="kbuffer", kbuffer_k=k) for k in (3, 256)}
    monkeypatch.setattr(gm, "REUSE_LISTS", True)
    monkeypatch.setattr(native.ShellSet, "query", poisoned)
    for k, ref in refs.items():
        np.testing.assert_array_equal(_render(6, traversal="kbuffer", kbuffer_k=k), ref)
    assert (48 * 36, 3) in seen and (48 * 36, 256) in seen
    monkeypatch.setattr(gm, "KEEP_LIST_BYTES", 8 * 48 * 36 * 3)  # lists larger than the cap are not kept
    seen.clear()
    np.testing.assert_array_equal(_render(6, traversal="kbuffer", kbuffer_k=256), refs[256])
    assert not seen
    np.testing.assert_array_equal(_render(6, traversal="kbuffer", kbuffer_k=3), refs[3])
    assert seen and set(seen) == {(48 * 36, 3)}
    shells = native.ShellSet(_shells(np.random.default_rng(0), 10), 1.0)
    args = (np.zeros((4, 3), np.float32), np.ones((4, 3), np.float32), np.zeros(4, np.float32),
            np.zeros(4, np.uint32), np.ones(4, bool), 8, 1)
    with pytest.raises(ValueError, match="uint32 \\[4, 8\\]"):
        query(shells, *args, out=(np.empty((4, 8), np.int64), np.empty((4, 8), np.float32), np.empty(4, np.uint32)))


def _opacity_grads(seed, **props):
    """d(sum of the image) / d(the interface's opacities) of _scene(seed) rendered with ``props``."""
    scene = _scene(np.random.default_rng(seed), **props)
    params = mi.traverse(scene)
    key = "integrator.interface.opacities"
    dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.sum(mi.render(scene, params, seed=0), axis=None))
    return np.array(dr.grad(params[key])).ravel()


@needs_native
def test_kbuffer_gradients_equal_bvh_gradients():
    g, r = _opacity_grads(5, traversal="kbuffer"), _opacity_grads(5, traversal="bvh")
    assert np.abs(g - r).max() <= 0.02 * np.abs(r).max()


def test_unavailable_kbuffer_names_the_fix(monkeypatch, rng):
    monkeypatch.setattr(native, "_lib", None)
    monkeypatch.setattr(native, "_why", "no C++ compiler (g++, c++ or clang++; or set CXX)")
    with pytest.raises((ValueError, RuntimeError), match="python -m glint_mi.native"):
        _scene(rng, traversal="kbuffer")
    assert not _scene(rng).integrator().kbuffer  # auto: Mitsuba's BVH queries
    with pytest.raises((ValueError, RuntimeError), match="traversal"):
        _scene(rng, traversal="fast")


@needs_native
def test_a_library_that_does_not_load_is_rebuilt(monkeypatch, tmp_path):
    """A library built against wheels since moved or reinstalled fails to load: load() rebuilds it once."""
    stale = tmp_path / "libglint_kbuffer.so"
    stale.write_bytes(b"not a shared library")  # newer than the source, so only the failed load can trigger it
    monkeypatch.setattr(native, "LIBRARY", stale)
    monkeypatch.setattr(native, "_lib", None)
    monkeypatch.setattr(native, "_why", "")
    assert native.load() is not None, native.why_not()
    assert stale.read_bytes()[:4] == b"\x7fELF"
    assert not list(tmp_path.glob(".libglint_kbuffer.*"))  # no temporary left behind


@pytest.mark.parametrize("traversal", ["bvh", "kbuffer"])
def test_a_changed_set_is_traced_as_changed(rng, traversal):
    """After a push through mi.traverse (moved and rescaled Gaussians, as a training step sends them), both
    traversals see the new set: the render equals a freshly built integrator's (the Mitsuba BVH is rebuilt only
    when the bvh traversal needs it, the native shells on the next query)."""
    from glint_mi.model.render import render_buffers
    from glint_mi_plugins.glint_gaussians import make_shape, pack

    a, b = random_set(rng, 300), random_set(rng, 300, center=(0.3, 0, 0))
    scene = lambda g: mi.load_dict({"type": "scene", "sensor": camera(24, 16), "integrator": {
        "type": "glint", "traversal": traversal, "interface": make_shape(g, role="interface")}})
    sa = scene(a)
    before = render_buffers(sa)["rgb"]
    params = mi.traverse(sa.integrator())
    for k, v in pack(sa.integrator().sets["interface"].shape, b).items():
        params[f"interface.{k}"] = type(params[f"interface.{k}"])(v.ravel().astype(np.float32))
    params.update()
    after, fresh = render_buffers(sa)["rgb"], render_buffers(scene(b))["rgb"]
    assert np.abs(after - before).max() > 0.05  # the change is visible
    np.testing.assert_allclose(after, fresh, atol=1e-5)
    # a second push of the same size: the native shells are refitted, not rebuilt (same image as a fresh build)
    c = b.subset(np.arange(len(b)))  # a copy
    c.means = c.means + rng.normal(0, 0.02, c.means.shape)
    for k, v in pack(sa.integrator().sets["interface"].shape, c).items():
        params[f"interface.{k}"] = type(params[f"interface.{k}"])(v.ravel().astype(np.float32))
    params.update()
    again = render_buffers(sa)["rgb"]
    if traversal == "kbuffer":
        assert sa.integrator().sets["interface"]._refits == 1
    np.testing.assert_allclose(again, render_buffers(scene(c))["rgb"], atol=1e-5)
