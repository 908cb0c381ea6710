"""The shell BVH's k-buffer traversal on a CUDA device (the integrator's ``traversal: shellbvh`` under a ``cuda_*``
variant): the tree is built on the host by the native library (:class:`glint_mi.native.BvhShellSet`), uploaded, and
refitted on the device while the set keeps its size; a query runs ``shellbvh_cuda.cu``, the same traversal code as
the CPU's, compiled at run time by NVRTC through CuPy (``pip install cupy-cuda12x`` or ``cupy-cuda13x``, which bring
NVRTC: no CUDA toolkit needed). Arrays go to and from Dr.Jit by DLPack.

:func:`source` is the kernel text NVRTC compiles (the header inlined), :func:`why_not` says why the device path is
unavailable ('' when it is available).
"""
from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
KERNELS = ("glint_shell_query", "glint_shell_fill", "glint_shell_refit_level")
MAX_K = 32       # GLINT_CUDA_K: entries a query lists per round on the device (more rounds continue the list)
THREADS = 128    # threads a block

_module = None
_why = None


def source() -> str:
    """``shellbvh_cuda.cu`` with ``shellbvh.h`` pasted in place of its include (NVRTC reads no files)."""
    header = (HERE / "shellbvh.h").read_text()
    cu = (HERE / "shellbvh_cuda.cu").read_text()
    return cu.replace('#include "shellbvh.h"', header, 1)


def _load():
    """The compiled CuPy module, or None with the reason in _why."""
    global _module, _why
    if _module is not None or _why is not None:
        return _module
    try:
        import cupy
        cupy.cuda.runtime.getDeviceCount()
        mod = cupy.RawModule(code=source(), options=("-std=c++17",), name_expressions=None)
        for k in KERNELS:
            mod.get_function(k)
        _module = mod
        _why = ""
    except Exception as exc:  # no CuPy, no device, or NVRTC refused the source
        _why = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
    return _module


def why_not() -> str:
    """Why the device traversal is unavailable here ('' when it is)."""
    _load()
    return _why or ""


def levels(nodes_raw):
    """The node ids of each level of a flat tree (``nodes`` as :meth:`BvhShellSet.arrays` gives it), deepest last:
    a refit walks them backwards, one launch a level."""
    import numpy as np
    nodes = np.frombuffer(np.ascontiguousarray(nodes_raw).tobytes(), dtype=np.int32).reshape(-1, 8)
    index, count = nodes[:, 3], nodes[:, 7]
    out, cur = [], np.array([0], np.int64)
    while len(cur):
        out.append(cur.astype(np.int32))
        inner = cur[count[cur] == 0]
        inner = inner[index[inner] > 0] if len(nodes) > 1 else inner[:0]
        cur = np.concatenate([index[inner], index[inner] + 1]).astype(np.int64) if len(inner) else cur[:0]
    return out


class CudaShellSet:
    """A Gaussian set's shells on the device: :class:`glint_mi.native.ShellSet`'s interface with CuPy arrays.

    ``data`` [N, 10] (numpy or anything DLPack hands over) as the ellipsoids shape holds it. Built on the host, then
    the nodes, order and shells live on the device; :meth:`refit` recomputes the shells and boxes there."""

    xp_name = "cupy"

    def __init__(self, data, extent: float, dynamic: bool = False):
        import numpy as np
        from glint_mi.native import BvhShellSet
        mod = _load()
        if mod is None:
            raise RuntimeError(f"glint_mi.native.cuda is unavailable: {_why}")
        import cupy as cp
        self.cp, self.mod = cp, mod
        host = np.ascontiguousarray(cp.asnumpy(cp.asarray(data)) if not isinstance(data, np.ndarray) else data,
                                    np.float32).reshape(-1, 10)
        self.extent, self.dynamic, self.n = float(extent), bool(dynamic), len(host)
        tree = BvhShellSet(host, extent)
        nodes, order, shells = tree.arrays()
        self.depth = tree.depth()
        del tree
        self.nodes, self.order, self.shells = cp.asarray(nodes), cp.asarray(order), cp.asarray(shells)
        self.levels = [cp.asarray(ids) for ids in levels(nodes)]
        self.lo = cp.empty((self.n, 3), cp.float32)
        self.hi = cp.empty((self.n, 3), cp.float32)

    def __len__(self) -> int:
        return self.n

    def _launch(self, name, n, *args):
        if n:
            self.mod.get_function(name)(((n + THREADS - 1) // THREADS,), (THREADS,), args)

    def refit(self, data) -> None:
        """New shells for the same Gaussians (device or host data [N, 10]); the tree's boxes are refitted level by
        level from the deepest."""
        cp, np = self.cp, __import__("numpy")
        data = cp.ascontiguousarray(cp.asarray(data, dtype=cp.float32).reshape(-1, 10))
        if not self.dynamic or len(data) != self.n:
            raise ValueError(f"glint_mi.native.cuda: refit needs a dynamic set of the same size ({self.n} Gaussians"
                             f"{'' if self.dynamic else ', built static'}; got {len(data)}): build a new set")
        self._launch("glint_shell_fill", self.n, data, self.order, np.int32(self.n), np.float32(self.extent),
                     self.shells, self.lo, self.hi)
        for ids in reversed(self.levels):
            self._launch("glint_shell_refit_level", len(ids), self.nodes, self.lo, self.hi, ids, np.int32(len(ids)))

    def query(self, o, d, t_prev, p_prev, active, k: int, threads: int = 0, out=None):
        """As :meth:`glint_mi.native.ShellSet.query`, on CuPy arrays (k <= MAX_K)."""
        cp, np = self.cp, __import__("numpy")
        if not 1 <= k <= MAX_K:
            raise ValueError(f"glint_mi.native.cuda: k must be in 1..{MAX_K} (got {k})")
        n = len(active)
        o = cp.ascontiguousarray(cp.asarray(o, dtype=cp.float32).reshape(n, 3))
        d = cp.ascontiguousarray(cp.asarray(d, dtype=cp.float32).reshape(n, 3))
        t_prev = cp.ascontiguousarray(cp.asarray(t_prev, dtype=cp.float32))
        p_prev = cp.ascontiguousarray(cp.asarray(p_prev, dtype=cp.uint32))
        act = cp.ascontiguousarray(cp.asarray(active).astype(cp.uint8))
        prims, ts, count = out if out is not None else (cp.zeros((n, k), cp.uint32), cp.zeros((n, k), cp.float32),
                                                         cp.zeros(n, cp.uint32))
        if self.n == 0:
            count[...] = 0
            return prims, ts, count
        self._launch("glint_shell_query", n, self.nodes, self.order, self.shells, np.int32(n), o, d, t_prev, p_prev,
                     act, np.int32(k), prims, ts, count)
        return prims, ts, count
