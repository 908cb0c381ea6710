"""Every kernel that traces queries one Gaussian set's scene.

Each set is its own ``mi.Scene``; OptiX (the cuda variants) takes one shader binding table per kernel and turns the
queries of any other scene in that kernel into misses ("more than one OptiX shader binding table was used within a
single kernel"), so a kernel that traced two sets would render their passes black on a GPU. The check runs on LLVM,
where the same kernels are built: the kernel IR calls Embree once per query with the scene's pointer as a kernel
parameter (one parameter per scene, shared by every query of that scene), so the number of distinct scene
parameters among a kernel's trace calls is the number of scenes it queries.
"""
import re

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from glint_mi.model import examples

from conftest import llvm_only, make_integrator, rays

pytestmark = llvm_only("reads LLVM kernel IR (the same kernels a cuda variant builds and OptiX would reject)")

# a ray query in LLVM IR: call void %fn(ptr %args, ptr %scene, ptr %ctx, ptr %hit)
_TRACE = re.compile(r"call void %\w+\(ptr [^,]+, ptr (%\w+), ptr [^,]+, ptr [^)]+\)")


class Kernels:
    """Collects the kernels launched inside ``with`` (Dr.Jit's kernel history) and the scenes each queries."""

    def __enter__(self):
        dr.eval()
        dr.kernel_history()  # drop older entries
        self._flag = dr.flag(dr.JitFlag.KernelHistory)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        return self

    def __exit__(self, *exc):
        dr.eval()
        self.scenes = [len(set(_TRACE.findall(k["ir"].getvalue()))) for k in dr.kernel_history()
                       if k.get("ir") is not None]
        dr.set_flag(dr.JitFlag.KernelHistory, self._flag)

    @property
    def tracing(self) -> int:
        return sum(n > 0 for n in self.scenes)

    def check(self, what: str):
        bad = [n for n in self.scenes if n > 1]
        assert not bad, (f"{what}: {len(bad)} kernel(s) query {max(bad)} sets' scenes (OptiX would drop all but the "
                         f"first scene's queries)")
        assert self.tracing > 0, f"{what}: no kernel traced a scene (the check saw nothing)"


def test_the_check_sees_two_scenes_in_one_kernel():
    """The detector itself: one expression that queries two scenes is one kernel with two scene parameters."""
    a = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    b = mi.load_dict({"type": "scene", "s": {"type": "sphere", "center": [0, 0, 3]}})
    ray = mi.Ray3f(mi.Point3f(0, 0, -5), mi.Vector3f(0, 0, 1))
    with Kernels() as k:
        t = a.ray_intersect_preliminary(ray).t + b.ray_intersect_preliminary(ray).t
        dr.eval(t)
    assert max(k.scenes) == 2
    with Kernels() as k:
        ta = a.ray_intersect_preliminary(ray).t
        dr.eval(ta)
        dr.eval(ta + b.ray_intersect_preliminary(ray).t)
    assert max(k.scenes) == 1 and k.tracing == 2


def _case(rng, **props):
    sets = examples.display_case_sets(600, seed=3)
    integ = make_integrator(sets, traversal="bvh", components="all", max_order=2, **props)
    n = 256
    o = np.tile([0.3, -2.5, 0.9], (n, 1)) + rng.normal(0, 0.05, (n, 3))
    d = np.column_stack([rng.uniform(-0.35, 0.35, n), np.ones(n), rng.uniform(-0.35, 0.2, n)])
    return integ, rays(o, d)


ADJ = {"rgb": mi.Color3f(1.0, 0.5, 0.25), "depth": mi.Float(0.1), "transparency": mi.Float(-0.3),
       "trans_direct": (mi.Color3f(0.2), mi.Float(0.1), mi.Vector3f(0.1, 0.0, 0.0), mi.Float(0.1))}


@pytest.mark.parametrize("record", [False, True])
def test_trace_and_replay_query_one_scene_per_kernel(rng, record):
    """trace() (every pass: interface, reflection, transmission, second order, direct) and the path-replay backward,
    re-tracing (no stored lists) or walking the lists, with the Mitsuba BVH traversal that cuda variants use."""
    integ, ray = _case(rng)
    params = mi.traverse(integ)
    for key in ("interface.data", "reflection.sh_coeffs", "transmission.opacities"):
        dr.enable_grad(params[key])
    params.update()
    fwd = mi.Vector3f(0, 0, 1)
    with Kernels() as k:
        out = integ.trace(ray, mi.Bool(True), need={"trans_direct"}, forward=fwd, record=record)
        dr.eval(out["rgb"])
    k.check("trace")
    with Kernels() as k:
        integ.backward(ray, mi.Bool(True), out, ADJ, forward=fwd)
    if record:  # the replay walks the stored lists: no query at all
        assert k.tracing == 0
    else:
        k.check("backward (re-tracing replay)")
    g = np.array(dr.grad(params["reflection.sh_coeffs"]))
    assert np.abs(g).sum() > 0, "the reflection pass took part"


@pytest.mark.parametrize("stored_mb", [1024.0, 0.0])
def test_mi_render_and_its_backward_query_one_scene_per_kernel(stored_mb):
    """mi.render (primal) and its path-replay backward, with stored hit lists and with lists over budget."""
    sets = examples.display_case_sets(600, seed=3)
    scene = mi.load_dict(examples.scene_dict(sets, width=24, height=16, components="all", traversal="bvh",
                                             stored_hits_mb=stored_mb, aovs="depth,transparency,trans_direct"))
    params = mi.traverse(scene)
    key = "integrator.interface.data"
    with Kernels() as k:
        img = mi.render(scene, params)
        dr.eval(img)
    k.check("mi.render")
    dr.enable_grad(params[key])
    params.update()
    with Kernels() as k:
        img = mi.render(scene, params)
        dr.backward(dr.sum(img, axis=None))
    k.check("mi.render backward")
    assert np.abs(np.array(dr.grad(params[key]))).sum() > 0


def test_plain_ad_queries_one_scene_per_kernel(rng):
    """gradient = ad: trace(ad=True) through evaluated loops and Dr.Jit's own backward."""
    integ, ray = _case(rng, gradient="ad")
    params = mi.traverse(integ)
    dr.enable_grad(params["interface.opacities"])
    params.update()
    with Kernels() as k:
        out = integ.trace(ray, mi.Bool(True), ad=True, need={"trans_direct"}, forward=mi.Vector3f(0, 0, 1))
        dr.backward(dr.sum(out["rgb"].x + out["trans_direct"][0].y))
    k.check("trace(ad=True) + backward")
