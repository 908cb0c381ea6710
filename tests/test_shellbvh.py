"""The shell BVH (glint_mi/native/shellbvh.h, the traversal a CUDA device runs too): the same k-buffer lists as the
Embree k-buffer, entry for entry (prim, t and count), and as a float64 brute force; on random sets, a set from a
trained model, and the extremes (flat and needle shells, shells far larger than the scene, every centre in one
point, duplicates with tied entries, a broken Gaussian, an empty set, rays along axes, box faces and tangent to
shells, origins inside shells); refits; the depth cap; and the CUDA source compiling with nvcc and NVRTC.

The device itself is not run here (no GPU on the CPU machine): its kernels call the same functions tested here."""
import ctypes
import glob
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import BITWISE
from test_native import _entries  # the float64 brute force
from glint_mi import native
from glint_mi.native import cuda

needs_native = pytest.mark.skipif(native.load() is None, reason=f"glint_mi.native not built: {native.why_not()}")
pytestmark = needs_native
NO = 0xFFFFFFFF
ROOT = Path(__file__).resolve().parents[1]


def _set(rng, n, spread=1.0, scale=(0.03, 0.15)):
    data = np.zeros((n, 10), np.float32)
    data[:, :3] = rng.uniform(-spread, spread, (n, 3))
    data[:, 3:6] = rng.uniform(*scale, (n, 3))
    data[:, 6:10] = Rotation.random(n, random_state=int(rng.integers(1 << 30))).as_quat()
    return data


def _rays(rng, n, box=1.0):
    """Origins inside the set's volume and on a far sphere looking in; some directions along an axis."""
    o = np.concatenate([rng.uniform(-box, box, (n // 2, 3)), 4 * box * _unit(rng.normal(size=(n - n // 2, 3)))])
    d = rng.normal(size=(n, 3))
    d[n // 2:] = -o[n // 2:] + rng.uniform(-box, box, (n - n // 2, 3))
    d[::7] = np.eye(3)[rng.integers(0, 3, len(d[::7]))] * rng.choice([-1, 1], (len(d[::7]), 1))
    return o.astype(np.float32), _unit(d).astype(np.float32)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _walk(shells, o, d, k):
    """Every entry along each ray, in rounds of k that continue after the last one listed: ([prims], [t]) a ray."""
    n = len(o)
    got_p, got_t = [[] for _ in range(n)], [[] for _ in range(n)]
    t_prev, p_prev, go = np.full(n, -np.inf, np.float32), np.full(n, NO, np.uint32), np.ones(n, bool)
    while go.any():
        prims, ts, cnt = shells.query(o, d, t_prev, p_prev, go, k, 2)
        for r in np.nonzero(go)[0]:
            got_p[r] += prims[r, :cnt[r]].tolist()
            got_t[r] += ts[r, :cnt[r]].tolist()
            if cnt[r]:
                t_prev[r], p_prev[r] = ts[r, cnt[r] - 1], prims[r, cnt[r] - 1]
        go &= cnt == k
    return got_p, got_t


def _same_as_embree(data, extent, o, d, ks=(1, 5, 64)):
    a, b = native.ShellSet(data, extent), native.BvhShellSet(data, extent)
    n = len(o)
    for k in ks:  # one round: the same k entries, t and count
        args = (o, d, np.full(n, -np.inf, np.float32), np.full(n, NO, np.uint32), np.ones(n, bool), k, 2)
        (pa, ta, ca), (pb, tb, cb) = a.query(*args), b.query(*args)
        np.testing.assert_array_equal(ca, cb)
        mask = np.arange(k)[None] < ca[:, None]
        np.testing.assert_array_equal(pa[mask], pb[mask])
        np.testing.assert_array_equal(ta[mask], tb[mask])
    walk = _walk(b, o, d, ks[1])
    assert walk == _walk(a, o, d, ks[1])  # whole lists, in rounds
    return walk


def test_lists_equal_embree_and_float64_on_random_sets(rng):
    for n, extent in ((1, 2.0), (7, 2.0), (3000, 1.5)):
        data = _set(rng, n)
        o, d = _rays(rng, 400)
        prims, _ = _same_as_embree(data, extent, o, d)
        o64, d64 = o.astype(np.float64), d.astype(np.float64)
        same = [prims[r] == [p for _, p in _entries(data, extent, o64[r], d64[r])] for r in range(len(o))]
        assert np.mean(same) >= 0.99, (n, np.mean(same))
        assert sum(map(len, prims)) > (0 if n < 10 else 5 * len(o))


def test_lists_equal_embree_on_a_trained_model(rng):
    """The bundled display case's sets (clustered on planes, anisotropic, many scales), as the integrator's shells."""
    from glint_mi.model.gaussians import SHELL_EXTENT, GaussianSet
    total = 0
    for name in ("interface", "reflection", "transmission"):
        gs = GaussianSet.load_ply(ROOT / "scenes" / "display_case" / f"{name}.ply")
        data = gs.to_mitsuba()["data"]
        lo, hi = data[:, :3].min(0), data[:, :3].max(0)
        o = np.concatenate([rng.uniform(lo, hi, (150, 3)), np.tile([[0.3, -1.8, 1.0]], (150, 1))]).astype(np.float32)
        d = _unit(np.concatenate([rng.normal(size=(150, 3)), rng.uniform(lo, hi, (150, 3)) - o[150:]]))
        prims, _ = _same_as_embree(data, SHELL_EXTENT, o, d.astype(np.float32), ks=(3, 16))
        total += sum(map(len, prims))
    assert total > 3 * 300


def test_extremes(rng):
    n = 600
    flat = _set(rng, n)
    flat[:, 5] = 1e-7  # disks
    needle = _set(rng, n)
    needle[:, 3:5] = 1e-6
    huge = _set(rng, 50, scale=(5.0, 20.0))  # shells far larger than the room: every origin inside
    point = _set(rng, n)
    point[:, :3] = 0.25  # every centre in one point (no split by centroid)
    dup = np.repeat(_set(rng, 40), 5, axis=0)  # tied entries: ordered by prim
    broken = _set(rng, 200)
    broken[3, :3] = np.nan  # a broken Gaussian no ray hits
    broken[4, 6:10] = 0  # a zero quaternion: the identity
    broken[5, 3:6] = 0  # zero scales: the floor
    o, d = _rays(rng, 300)
    for name, data in (("flat", flat), ("needle", needle), ("huge", huge), ("point", point), ("dup", dup),
                       ("broken", broken)):
        prims, _ = _same_as_embree(data, 1.0, o, d)
        if name == "dup":
            ties = [p for p in prims if len(p) >= 2]
            assert ties and all(all(a < b for a, b in zip(p[0::5], p[1::5])) for p in ties)
        if name == "huge":
            assert min(len(p) for p in prims[: len(o) // 2]) >= 1  # origins inside get their shells
        if name == "broken":
            assert not any(3 in p for p in prims)


def test_rays_along_faces_and_tangent_to_shells():
    """Axis-aligned unit boxes of spheres on a grid: rays in the planes of box faces, along them, and grazing a
    sphere at exactly its radius (a float64 tangent: the quadratic's discriminant is ~0)."""
    g = np.stack(np.meshgrid(*[np.arange(4.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    data = np.zeros((len(g), 10), np.float32)
    data[:, :3], data[:, 3:6], data[:, 9] = g, 0.5, 1.0
    o, d = [], []
    for y in np.arange(-0.5, 4.0, 0.25):
        for z in np.arange(-0.5, 4.0, 0.25):
            o.append([-3.0, y, z])
            d.append([1.0, 0.0, 0.0])
    o, d = np.array(o, np.float32), np.array(d, np.float32)
    prims, _ = _same_as_embree(data, 1.0, o, d)
    hit = [len(p) for p in prims]
    assert max(hit) == 4 and 0 in hit


def test_empty_set():
    data = np.zeros((0, 10), np.float32)
    o, d = np.zeros((5, 3), np.float32), np.tile(np.float32([0, 0, 1]), (5, 1))
    for kind in (native.ShellSet, native.BvhShellSet):
        prims, ts, cnt = kind(data, 1.0).query(o, d, np.full(5, -np.inf, np.float32), np.full(5, NO, np.uint32),
                                               np.ones(5, bool), 4, 1)
        assert (cnt == 0).all()


def test_refit_lists_equal_a_fresh_build(rng):
    data = _set(rng, 1500)
    tree = native.BvhShellSet(data, 1.0, dynamic=True)
    moved = data.copy()
    moved[:, :3] += rng.normal(0, 0.05, (1500, 3)).astype(np.float32)
    moved[:, 3:6] *= rng.uniform(0.5, 2.0, (1500, 3)).astype(np.float32)
    tree.refit(moved)
    o, d = _rays(rng, 300)
    assert _walk(tree, o, d, 8) == _walk(native.ShellSet(moved, 1.0), o, d, 8)
    with pytest.raises(ValueError, match="same size"):
        tree.refit(moved[:10])


def test_depth_is_capped_and_lists_stay_exact():
    """Centres spaced geometrically along a line defeat a binned SAH (each split peels a few off): the build caps the
    depth below the traversal's stack and leaves larger leaves; the lists are still exact."""
    n = 400
    data = np.zeros((n, 10), np.float32)
    data[:, 0] = 2.0 ** -np.arange(n, dtype=np.float64).clip(0, 120)
    data[:, 3:6], data[:, 9] = 1e-3, 1.0
    tree = native.BvhShellSet(data, 1.0)
    assert tree.depth() <= 62
    rng = np.random.default_rng(3)
    o = np.float32([[-1, 0, 0]] * 50) + rng.normal(0, 1e-4, (50, 3)).astype(np.float32)
    d = np.tile(np.float32([1, 0, 0]), (50, 1))
    _same_as_embree(data, 1.0, o, d, ks=(4, 7))


def test_device_levels_cover_the_tree(rng):
    """The refit's levels (what a device walks backwards): every node once, each child one level below its parent."""
    nodes, order, shells = native.BvhShellSet(_set(rng, 2000), 1.0).arrays()
    assert sorted(order.tolist()) == list(range(2000)) and shells.shape == (2000, 12)
    levels = cuda.levels(nodes)
    ids = np.concatenate(levels)
    assert sorted(ids.tolist()) == list(range(len(nodes)))
    raw = np.frombuffer(nodes.tobytes(), np.int32).reshape(-1, 8)
    depth = {int(i): li for li, lv in enumerate(levels) for i in lv}
    for i in ids:
        if raw[i, 7] == 0:
            assert depth[int(raw[i, 3])] == depth[int(i)] + 1 == depth[int(raw[i, 3]) + 1]


@pytest.mark.skipif(not shutil.which("nvcc"), reason="no nvcc here: the CUDA build is checked where one is")
def test_cuda_source_compiles_with_nvcc(tmp_path):
    r = subprocess.run(["nvcc", "-std=c++17", "-arch=sm_90", f"-I{native.HERE}", "-c",
                        str(native.HERE / "shellbvh_cuda.cu"), "-o", str(tmp_path / "sb.o")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]


def _nvrtc():
    for pat in (os.environ.get("GLINT_NVRTC", "/nonexistent"), "/usr/local/cuda*/lib64/libnvrtc.so*", "/usr/lib/x86_64-linux-gnu/libnvrtc.so*",
                os.path.join(os.path.dirname(np.__file__), "..", "nvidia", "cu*", "lib", "libnvrtc.so*")):
        for path in sorted(glob.glob(pat)):
            try:
                return ctypes.CDLL(path)
            except OSError:
                continue
    return None


@pytest.mark.skipif(_nvrtc() is None, reason="no NVRTC library here (CuPy's wheels bring it on a GPU machine)")
def test_cuda_source_compiles_with_nvrtc():
    """What CuPy compiles on a device: the .cu with the header pasted in, no system headers."""
    lib = _nvrtc()
    prog = ctypes.c_void_p()
    assert lib.nvrtcCreateProgram(ctypes.byref(prog), cuda.source().encode(), b"shellbvh_cuda.cu", 0, None, None) == 0
    opts = [b"-std=c++17", b"-arch=compute_90"]
    rc = lib.nvrtcCompileProgram(prog, len(opts), (ctypes.c_char_p * 2)(*opts))
    size = ctypes.c_size_t()
    lib.nvrtcGetProgramLogSize(prog, ctypes.byref(size))
    log = ctypes.create_string_buffer(size.value)
    lib.nvrtcGetProgramLog(prog, log)
    assert rc == 0, log.value.decode()[-3000:]
    for k in cuda.KERNELS:
        assert f"void {k}(" in cuda.source()


@BITWISE
def test_shellbvh_traversal_renders_as_kbuffer():
    """The integrator's traversal=shellbvh: the same lists and arithmetic as kbuffer, so the same image bit for bit,
    with any buffer size; and its gradients."""
    import drjit as dr
    from test_native import _opacity_grads, _render
    ref = _render(3, traversal="kbuffer")
    np.testing.assert_array_equal(_render(3, traversal="shellbvh"), ref)
    np.testing.assert_array_equal(_render(3, traversal="shellbvh", kbuffer_k=3), ref)
    threads = dr.thread_count()
    dr.set_thread_count(1)  # the gradient's atomics sum in a fixed order on one thread
    try:
        g, ref_g = _opacity_grads(5, traversal="shellbvh"), _opacity_grads(5, traversal="kbuffer")
    finally:
        dr.set_thread_count(threads)
    assert np.abs(ref_g).max() > 0
    np.testing.assert_array_equal(g, ref_g)


@BITWISE
def test_the_device_march_with_numpy_standing_in_for_cupy(monkeypatch):
    """The k-buffer march's device branch (CuPy arrays by DLPack, the set's query on them, the streams waited for)
    run here with numpy in CuPy's place and the host shell BVH as the device set: the same image as the host march,
    bit for bit. What only a GPU can check is left: CuPy's own DLPack hand-over and the kernel itself."""
    import sys
    import types

    import glint_mi_plugins.glint_composite as gc
    from test_native import _render

    ref = _render(3, traversal="shellbvh", kbuffer_k=5)
    fake = types.ModuleType("cupy")
    for name in ("stack", "full", "arange", "maximum", "where", "float32", "uint32", "int64"):
        setattr(fake, name, getattr(np, name))
    calls = {"dlpack": 0, "sync": 0}

    def from_dlpack(x):
        calls["dlpack"] += 1
        return np.from_dlpack(x)

    class Stream:
        def synchronize(self):
            calls["sync"] += 1

    fake.from_dlpack = from_dlpack
    fake.cuda = types.SimpleNamespace(get_current_stream=lambda: Stream())
    monkeypatch.setitem(sys.modules, "cupy", fake)

    class DeviceStandIn(native.BvhShellSet):
        xp_name = "cupy"

    real = gc.GaussianSetRef.native
    monkeypatch.setattr(gc.GaussianSetRef, "native", lambda self, engine="embree": _as_device(real(self, engine)))

    def _as_device(s):
        s.__class__ = DeviceStandIn
        return s

    np.testing.assert_array_equal(_render(3, traversal="shellbvh", kbuffer_k=5), ref)
    assert calls["dlpack"] > 0 and calls["sync"] > 0
