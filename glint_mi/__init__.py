"""glint_mi: GLINT (interface / transmission / reflection Gaussian sets with first-order Fresnel transport)
on Mitsuba 3 and Dr.Jit.

Importing this package points Dr.Jit at a usable LLVM (>= 17) before ``drjit`` loads; :func:`set_variant` selects a
Mitsuba variant (default ``llvm_ad_rgb``, or ``$GLINT_VARIANT``), checks LLVM and registers the plugins.
"""
from __future__ import annotations

import os

from glint_mi._llvm import LLVMError, check_llvm, configure_environment

configure_environment()

__version__ = "0.1.0"
DEFAULT_VARIANT = "llvm_ad_rgb"


def set_variant(variant: str | None = None) -> str:
    """Select the Mitsuba variant (``llvm_ad_rgb`` by default; ``cuda_ad_rgb`` on a GPU) and register the plugins."""
    import mitsuba as mi

    variant = variant or os.environ.get("GLINT_VARIANT") or DEFAULT_VARIANT
    if variant.startswith("llvm"):
        check_llvm()  # raise a Python error instead of letting an old LLVM abort the process
    if mi.variant() != variant:
        mi.set_variant(variant)

    from glint_mi_plugins import register

    register()
    return variant


def load_file(path, **kwargs):
    """``mi.load_file`` with the variant set and the glint plugins registered."""
    import mitsuba as mi

    set_variant(None if mi.variant() is None else mi.variant())
    return mi.load_file(str(path), **kwargs)


def load_dict(desc: dict):
    import mitsuba as mi

    set_variant(None if mi.variant() is None else mi.variant())
    return mi.load_dict(desc)


__all__ = ["LLVMError", "check_llvm", "set_variant", "load_file", "load_dict", "__version__"]
