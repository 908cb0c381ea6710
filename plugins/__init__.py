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

    from . import glint_gaussians, glint_integrator

    if _registered:  # the integrator class derives from the variant's ADIntegrator: rebuild it for this variant
        importlib.reload(glint_integrator)
    glint_gaussians.register()
    glint_integrator.register()
    _registered.add(variant)
