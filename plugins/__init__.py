"""Mitsuba plugins of glint_mi: the ``glint_gaussians`` shape and the ``glint`` integrator.

Mitsuba registers Python plugins per variant; :func:`register` does it for the variant in force (idempotent).
"""
from __future__ import annotations

_registered: set[str] = set()


def register() -> None:
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("Set a Mitsuba variant first (glint_mi.set_variant('llvm_ad_rgb')).")
    if variant in _registered:
        return
    import importlib

    from . import glint_composite, glint_gaussians, glint_integrator, glint_march, glint_mesh

    if _registered:  # the integrator derives from the variant's ADIntegrator and Composite holds its array types:
        for module in (glint_composite, glint_march, glint_mesh, glint_integrator):  # rebuild them for this variant
            importlib.reload(module)
    glint_gaussians.register()
    glint_integrator.register()
    _registered.add(variant)
