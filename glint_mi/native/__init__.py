"""The native k-buffer traversal: per ray, the next K bounding-shell entries of a Gaussian set from one traversal, in
order, shells around the origin included, either through Embree (``kbuffer.cpp``, :class:`ShellSet`) or through our
own BVH (``shellbvh.h`` / ``shellbvh.cpp``, :class:`BvhShellSet`: the code a CUDA device runs too, ``shellbvh_cuda.cu``
and :mod:`glint_mi.native.cuda`); both list the same entries. And Adam on gathered rows (``adam.cpp``, the numpy
reference's arithmetic bit for bit, :func:`adam_rows`).

Built with the system C++ compiler against the Embree headers and library that ship in the mitsuba wheel
(``python -m glint_mi.native``; ``make`` runs it). :func:`load` returns the library, building it on first use when
it is missing or older than its source, or None (with :func:`why_not` saying why) when it cannot be built: the
integrator then traverses with Mitsuba's BVH queries instead (same image model, slower).
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "kbuffer.cpp"
SOURCES = (SOURCE, HERE / "shellbvh.cpp", HERE / "adam.cpp")
HEADERS = (HERE / "shellbvh.h", HERE / "raybatch.h")
LIBRARY = HERE / "libglint_kbuffer.so"
_lib = None
_why = ""


def _mitsuba_dir() -> Path:
    import mitsuba
    return Path(mitsuba.__file__).resolve().parent


def _drjit_dir() -> Path:
    import drjit
    return Path(drjit.__file__).resolve().parent


def build(verbose: bool = False) -> Path:
    """Compile SOURCES into LIBRARY (atomically: concurrent builds cannot leave a half-written file). No fused
    multiply-adds (-ffp-contract=off): adam.cpp must round as numpy does. -fno-math-errno lets sqrt be one
    instruction (the shell test's square root is never of a negative; results are the same)."""
    cxx = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++") or shutil.which("clang++")
    if not cxx:
        raise RuntimeError("no C++ compiler (g++, c++ or clang++; or set CXX)")
    mi_dir = _mitsuba_dir()
    if not (mi_dir / "include" / "embree3" / "rtcore.h").exists() or not (mi_dir / "libembree3.so").exists():
        raise RuntimeError(f"the mitsuba wheel at {mi_dir} has no Embree headers/library")
    dr_dir = _drjit_dir()  # its thread pool (nanothread) runs the queries
    if not (dr_dir / "include" / "nanothread" / "nanothread.h").exists() or not (dr_dir / "libnanothread.so").exists():
        raise RuntimeError(f"the drjit wheel at {dr_dir} has no nanothread header/library")
    fd, tmp = tempfile.mkstemp(prefix=".libglint_kbuffer.", suffix=".so", dir=LIBRARY.parent)
    os.close(fd)
    cmd = [cxx, "-O2", "-std=c++17", "-ffp-contract=off", "-fno-math-errno", "-shared", "-fPIC", "-pthread", f"-I{HERE}",
           f"-I{mi_dir / 'include'}",
           f"-I{dr_dir / 'include'}", *map(str, SOURCES), "-o", tmp, f"-L{mi_dir}", "-lembree3", f"-Wl,-rpath,{mi_dir}",
           f"-L{dr_dir}", "-lnanothread", f"-Wl,-rpath,{dr_dir}"]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{r.stderr[-2000:]}")
        os.replace(tmp, LIBRARY)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    if verbose:
        print(f"built {LIBRARY}")
    return LIBRARY


def load():
    """The ctypes library, or None when it cannot be built here (see :func:`why_not`)."""
    global _lib, _why
    if _lib is not None or _why:
        return _lib
    try:
        if not LIBRARY.exists() or LIBRARY.stat().st_mtime < max(p.stat().st_mtime for p in SOURCES + HEADERS):
            build()
        try:
            lib = ctypes.CDLL(str(LIBRARY))
        except OSError:  # built against wheels since moved or reinstalled (their paths are in the library): rebuild
            build()
            lib = ctypes.CDLL(str(LIBRARY))
    except (RuntimeError, OSError) as exc:
        _why = str(exc)
        return None
    vp, i, f = ctypes.c_void_p, ctypes.c_int, ctypes.c_float
    lib.kb_build.restype, lib.kb_build.argtypes = vp, [vp, i, f, i]  # (+ dynamic)
    lib.sb_build.restype, lib.sb_build.argtypes = vp, [vp, i, f]
    for engine in ("kb", "sb"):  # Embree's k-buffer, the shell BVH: the same refit, query and free
        fn = lambda name: getattr(lib, f"{engine}_{name}")
        fn("refit").restype, fn("refit").argtypes = i, [vp, vp, i, f]
        fn("free").restype, fn("free").argtypes = None, [vp]
        fn("query").restype, fn("query").argtypes = None, [vp, i, vp, vp, vp, vp, vp, i, vp, vp, vp, i]
    lib.sb_sizes.restype, lib.sb_sizes.argtypes = None, [vp, vp]
    lib.sb_export.restype, lib.sb_export.argtypes = None, [vp, vp, vp, vp]
    i64, d = ctypes.c_int64, ctypes.c_double
    lib.adam_rows.restype = None
    lib.adam_rows.argtypes = [vp, vp, vp, vp, vp, i64, i64, vp, vp, vp, d, d, d]
    _lib = lib
    return lib


def adam_rows(value, m, v, g, rows, c1, c2, lr, b1: float, b2: float, eps: float) -> bool:
    """Adam's update of the ``rows`` (int64 [R], each in [0, N): not checked) of one field in place, as
    ``glint_mi.training.optim.Adam.step`` computes it (bit for bit): ``value``, ``m``, ``v`` float32 [N, ...], ``g``
    float64 [N, ...] (all C-contiguous, one shape), ``c1``, ``c2`` float64 [R] (1 - b^n per row), ``lr`` float64, one
    rate per column. Returns False, touching nothing, when the library is unavailable or an array is not of that layout
    (the caller computes it)."""
    import numpy as np
    lib = load()
    if lib is None:
        return False
    shape = value.shape
    ok = (value.dtype == m.dtype == v.dtype == np.float32 and g.dtype == np.float64 and m.shape == v.shape == g.shape
          == shape and len(shape) and value.flags.c_contiguous and value.flags.writeable and m.flags.c_contiguous
          and v.flags.c_contiguous and g.flags.c_contiguous and rows.dtype == np.int64 and rows.ndim == 1
          and c1.shape == c2.shape == (len(rows),) and c1.dtype == c2.dtype == np.float64)
    if not ok:
        return False
    cols = m.size // shape[0] if shape[0] else 0
    lr = np.ascontiguousarray(np.broadcast_to(np.asarray(lr, np.float64), (1,) + shape[1:]).reshape(cols))
    lib.adam_rows(value.ctypes.data, m.ctypes.data, v.ctypes.data, g.ctypes.data, rows.ctypes.data, len(rows), cols,
                  c1.ctypes.data, c2.ctypes.data, lr.ctypes.data, float(b1), float(b2), float(eps))
    return True


def why_not() -> str:
    """Why :func:`load` returned None ('' if it did not)."""
    load()
    return _why


def why_not_here() -> str:
    """Why the integrator cannot use the k-buffer traversal in this process ('' if it can): the library is not
    built, or the Mitsuba variant's arrays are not in host memory (only LLVM variants' are)."""
    import mitsuba as mi

    return why_not() or ("" if (mi.variant() or "").startswith("llvm") else
                         f"variant {mi.variant()} (its arrays are not in host memory)")


class ShellSet:
    """One Gaussian set's shells in an Embree scene of the native library (``data`` [N, 10] as the ellipsoids shape
    holds it: centre, shell scales / extent, x y z w quaternion). :class:`BvhShellSet` is the same on our own BVH.

    ``dynamic``: a set that training moves every step. Its BVH is built in Embree's refittable mode, and
    :meth:`refit` replaces the shells of the same N Gaussians in ~0.5 ms instead of a ~6 ms build (8.5k Gaussians);
    queries return the same lists either way (the tree only decides how fast they are found)."""

    def __init__(self, data, extent: float, dynamic: bool = False):
        import numpy as np
        self._lib = load()
        if self._lib is None:
            raise RuntimeError(f"glint_mi.native is unavailable: {_why}")
        self.data = np.ascontiguousarray(data, dtype=np.float32).reshape(-1, 10)
        self.extent, self.dynamic = float(extent), bool(dynamic)
        self.handle = self._build()

    PREFIX = "kb"  # the library's functions for this engine: <PREFIX>_build, _refit, _query, _free

    def _c(self, name: str):
        return getattr(self._lib, f"{self.PREFIX}_{name}")

    def _build(self):
        return self._lib.kb_build(self.data.ctypes.data, len(self.data), self.extent, int(self.dynamic))

    def __len__(self) -> int:
        return len(self.data)

    def refit(self, data) -> None:
        """New shells for the same Gaussians (a dynamic set, same count and extent): the BVH's boxes are refitted."""
        import numpy as np
        data = np.ascontiguousarray(data, dtype=np.float32).reshape(-1, 10)
        if not self.dynamic or len(data) != len(self.data):
            raise ValueError(f"glint_mi.native: refit needs a dynamic set of the same size ({len(self.data)} "
                             f"Gaussians{'' if self.dynamic else ', built static'}; got {len(data)}): build a new "
                             f"ShellSet")
        if self._c("refit")(self.handle, data.ctypes.data, len(data), self.extent) != 0:
            raise RuntimeError("glint_mi.native: the refit refused the data")
        self.data = data

    def query(self, o, d, t_prev, p_prev, active, k: int, threads: int, out=None):
        """Per ray, the k nearest shell entries after (t_prev, p_prev): (prims [n, k] uint32, t [n, k] float32,
        count [n] uint32), sorted by (t, prim); entries behind the origin (t < 0) are shells that hold it.

        ``out``: those three arrays to write into (their shapes and dtypes as above; entries past a ray's count are
        left as they were) instead of new ones: a caller that queries the same shapes every step saves the page
        faults of fresh multi-megabyte arrays. The caller must not hand over memory still being read."""
        import numpy as np
        n = len(active)
        f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)
        o, d, t_prev = f32(o).reshape(n, 3), f32(d).reshape(n, 3), f32(t_prev)
        p_prev = np.ascontiguousarray(p_prev, dtype=np.uint32)
        act = np.ascontiguousarray(active, dtype=np.uint8)
        if out is None:
            prims, ts, count = np.zeros((n, k), np.uint32), np.zeros((n, k), np.float32), np.zeros(n, np.uint32)
        else:
            prims, ts, count = out
            if (prims.shape, ts.shape, count.shape) != ((n, k), (n, k), (n,)) or (
                    prims.dtype, ts.dtype, count.dtype) != (np.uint32, np.float32, np.uint32) or not all(
                    a.flags.c_contiguous and a.flags.writeable for a in out):
                raise ValueError(f"glint_mi.native: query's out must be writeable C-contiguous arrays uint32 [{n}, "
                                 f"{k}], float32 [{n}, {k}], uint32 [{n}]")
        self._c("query")(self.handle, n, o.ctypes.data, d.ctypes.data, t_prev.ctypes.data, p_prev.ctypes.data,
                           act.ctypes.data, k, prims.ctypes.data, ts.ctypes.data, count.ctypes.data, int(threads))
        return prims, ts, count

    def __del__(self):
        if getattr(self, "handle", None) and self._lib is not None:
            self._c("free")(self.handle)
            self.handle = None


class BvhShellSet(ShellSet):
    """:class:`ShellSet` on the shell BVH of ``shellbvh.cpp`` instead of Embree: the same lists (the same shell
    arithmetic and insertion rule), from the traversal code a CUDA device runs (:mod:`glint_mi.native.cuda`). Every
    tree can be refitted (``dynamic`` only says whether :meth:`refit` is allowed, as for Embree's sets).

    :meth:`arrays` gives the flat tree (nodes, order, shells) that a device uploads."""

    PREFIX = "sb"

    def _build(self):
        return self._lib.sb_build(self.data.ctypes.data, len(self.data), self.extent)

    def _sizes(self):
        """(nodes, slots, shells, depth) of the tree."""
        import numpy as np
        sizes = np.zeros(4, np.int64)
        self._lib.sb_sizes(self.handle, sizes.ctypes.data)
        return tuple(int(x) for x in sizes)

    def depth(self) -> int:
        """The tree's depth (its root is at 0); the traversal's stack holds one node a level."""
        return self._sizes()[3]

    def arrays(self):
        """(nodes uint8 [M, 32], order uint32 [N], shells float64 [N, 12] by slot): the tree as a device reads it
        (each node three float32 lows, an int32 index, three float32 highs, an int32 count; each shell its centre and
        its world-to-unit-sphere matrix: see ``shellbvh.h``)."""
        import numpy as np
        m, slots, n, _ = self._sizes()
        nodes, order, shells = np.zeros((m, 32), np.uint8), np.zeros(slots, np.uint32), np.zeros((n, 12), np.float64)
        self._lib.sb_export(self.handle, nodes.ctypes.data, order.ctypes.data, shells.ctypes.data)
        return nodes, order, shells
