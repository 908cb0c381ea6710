"""Shared fixtures: the Mitsuba variant (with plugins) and small Gaussian scenes."""
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import glint_mi

glint_mi.set_variant()

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi import native  # noqa: E402
from glint_mi.model.gaussians import GaussianSet  # noqa: E402
from glint_mi_plugins.glint_gaussians import make_shape  # noqa: E402


LLVM = mi.variant().startswith("llvm")
KBUFFER = not native.why_not_here()  # the integrator's traversal "auto" takes the native k-buffer


def llvm_only(why: str):
    """Skip a test on other variants (``GLINT_VARIANT=cuda_ad_rgb``), saying why it needs the LLVM backend."""
    return pytest.mark.skipif(not LLVM, reason=f"{why}: needs an LLVM variant (running {mi.variant()})")


try:  # pycolmap (SfM, undistortion): on PyPI for this machine and CI, absent on the GPU machine (no package index)
    import pycolmap  # noqa: F401
    PYCOLMAP = True
except ImportError:
    PYCOLMAP = False
needs_pycolmap = pytest.mark.skipif(not PYCOLMAP, reason="needs pycolmap (SfM, undistortion), not installed here")

# bit-for-bit runs: on one LLVM thread the gradient atomics sum in a fixed order; a GPU's atomics do not
BITWISE = llvm_only("bit-for-bit equality of two runs on one Dr.Jit thread")


def random_set(rng, n, center=(0, 0, 0), spread=(1, 1, 0.2), scale=(0.1, 0.3), **kw):
    kw.setdefault("opacities", rng.uniform(0.3, 0.9, n))
    kw.setdefault("colors", rng.uniform(0, 1, (n, 3)))
    return GaussianSet.from_activated(np.asarray(center) + rng.uniform(-1, 1, (n, 3)) * spread,
                                      rng.uniform(*scale, (n, 3)), rng.normal(size=(n, 4)), **kw)


def camera(w=32, h=24):
    """A small pinhole camera 4 m in front of the origin, looking at it (box filter, 1 spp)."""
    return {"type": "perspective", "fov": 45,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0.2, 0.1, -4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 1}}


def make_integrator(sets: dict, kernels=None, shape_kw=None, **props):
    kernels = kernels or {}
    desc = {"type": "glint", **props}
    for role, s in sets.items():
        desc[role] = make_shape(s, kernel=kernels.get(role, "surfel"), role=role, **(shape_kw or {}))
    return mi.load_dict(desc)


def rays(origins, directions):
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    return mi.Ray3f(mi.Point3f(*[mi.Float(o[:, i]) for i in range(3)]), mi.Vector3f(*[mi.Float(d[:, i]) for i in range(3)]))


def central_difference(params, key: str, i: int, value, rel_step: float = 1e-3) -> float:
    """Central finite difference of ``value()`` (a float) with respect to entry ``i`` of ``params[key]``, step
    ``rel_step * max(1, |x|)``; the parameter is restored afterwards."""
    T = type(params[key])
    base = np.array(params[key]).ravel().astype(np.float64)
    h = rel_step * max(1.0, abs(base[i]))
    vals = []
    for s in (1, -1):
        b = base.copy()
        b[i] += s * h
        params[key] = T(b.astype(np.float32))
        params.update()
        vals.append(value())
    params[key] = T(base.astype(np.float32))
    params.update()
    return (vals[0] - vals[1]) / (2 * h)


def to_np(x):
    return np.array(x)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    """A tiny room (48 x 27, 8 views) with its optimisation scene beside it; its priors see the glass surface
    (GLINT's video-prior assumption). One per test module (tests write runs beside it)."""
    from glint_mi.dataset.generate import Preset, make_scene
    from glint_mi.dataset.priors import Corruption, derive_priors
    from glint_mi.scene import scene_xml

    out = tmp_path_factory.mktemp("train") / "room"
    make_scene(out, seed=0, preset=Preset.named("tiny"), sfm="none")
    derive_priors(out, 0, Corruption(see_through_glass=0.0))
    (out.parent / "scene.xml").write_text(scene_xml(out))
    return out


def tiny_cfg(**kw):
    """The tiny preset, logging rarely (tests read the history they need), reading the albedo prior as the paper does
    (trans_albedo: masks): the test room has no SfM tracks, so without it components: auto would find no glass cue
    and train the interface alone, where these tests exercise all three sets."""
    from glint_mi.config import TrainConfig

    return TrainConfig.for_preset("tiny", **{"log_every": 1000, "trans_albedo": "masks", **kw})


ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A tiny generated room with derived priors (transforms.json, a COLMAP model, priors/), 6 views of 48 x 27."""
    from glint_mi.dataset.generate import Preset, make_scene
    from glint_mi.dataset.priors import derive_priors

    out = tmp_path_factory.mktemp("inputs") / "room"
    make_scene(out, seed=3, preset=Preset.named("tiny", views=6, spp=4), sfm="none")
    derive_priors(out, 0)
    return out


def copy_tree(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def files_of(folder: Path) -> set:
    return {p.relative_to(folder) for p in folder.rglob("*")}


def cli(*args, cwd=ROOT, env=None):
    """(CompletedProcess, the lines of stderr that start with 'error:') of ``python -m ARGS``."""
    r = subprocess.run([sys.executable, "-m", *map(str, args)], capture_output=True, text=True, cwd=cwd,
                       timeout=600, env=env)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    return r, errors
