"""glint_mi: GLINT (interface / transmission / reflection Gaussian sets with first-order Fresnel transport)
on Mitsuba 3 and Dr.Jit.

Importing this package points Dr.Jit at a usable LLVM (>= 17) before ``drjit`` loads; :func:`set_variant` selects a
Mitsuba variant (default ``llvm_ad_rgb``, or ``$GLINT_VARIANT``), checks LLVM and registers the plugins.
"""
from __future__ import annotations

import os
import sys

# The Ctrl-C hooks come first, before this package imports anything else: a Ctrl-C that lands in an import lock's
# weakref callback while the imports below run (0.05 s into a command on a loaded machine) would otherwise be printed
# as 'Exception ignored ... Traceback ... KeyboardInterrupt' and lost (glint_mi._interrupt).
from glint_mi._interrupt import install as _install_interrupt_hook

_install_interrupt_hook()


def _quiet_interrupt(kind, value, tb, _previous=sys.excepthook):
    """A Ctrl-C that reaches the top of a glint_mi command (in its first second, while modules still load, or in
    a library call made from a script) ends it with one line, not a traceback; the commands catch it themselves
    wherever they have something to say (what was kept, how to continue). The exit status stays that of SIGINT."""
    chain, e = [], value
    while e is not None and len(chain) < 8:  # an import in C (Dr.Jit, Mitsuba) wraps it in a SystemError
        chain.append(e)
        e = e.__cause__ or e.__context__
    if any(isinstance(e, KeyboardInterrupt) for e in chain):
        print("\ninterrupted (Ctrl-C)", file=sys.stderr)
        sys.stdout.flush(), sys.stderr.flush()
        os._exit(130)  # the shell's status for Ctrl-C; nothing is left to clean up at the top of a command
    _previous(kind, value, tb)


if sys.excepthook is sys.__excepthook__:  # leave IPython's and other hosts' hooks alone
    sys.excepthook = _quiet_interrupt

import contextlib  # noqa: E402 (after the hook, as said above)

from glint_mi._llvm import LLVMError, check_llvm, configure_environment  # noqa: E402

configure_environment()


@contextlib.contextmanager
def deferred_interrupt():
    """Hold a Ctrl-C back until the block ends: a KeyboardInterrupt raised inside a C++ extension's module
    initialisation (Dr.Jit's, Mitsuba's: Python code they run while loading) aborts the process (SIGABRT, measured at
    0.15-0.2 s into a command). In the main thread only; elsewhere the block runs as it is."""
    import signal

    pending = []
    try:
        old = signal.signal(signal.SIGINT, lambda sig, frame: pending.append(frame))
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        if pending:
            if callable(old):
                old(signal.SIGINT, pending[0])
            elif old == signal.SIG_DFL:
                signal.raise_signal(signal.SIGINT)


class _NativeImports:  # a meta path finder needs only find_spec (importlib.abc costs 70 ms of imports at start)
    """Loads Dr.Jit, Mitsuba and NumPy (the top-level packages, whose loading brings in their extensions) inside
    :func:`deferred_interrupt`, whichever module imports them first. NumPy's extension imports ``datetime`` through
    ``PyCapsule_Import``, which turns a KeyboardInterrupt landing there into a plain ImportError (measured 0.05 s into
    ``evaluate`` on a loaded machine): no trace of the Ctrl-C is left to recognise afterwards, so it is held back."""

    NAMES = ("drjit", "mitsuba", "numpy")

    def find_spec(self, name, path, target=None):
        if name not in self.NAMES:
            return None
        for finder in sys.meta_path:
            spec = None if finder is self or not hasattr(finder, "find_spec") else finder.find_spec(name, path, target)
            if spec is not None and spec.loader is not None and hasattr(spec.loader, "exec_module"):
                load = spec.loader.exec_module

                def exec_module(module, _load=load):
                    with deferred_interrupt():
                        _load(module)
                spec.loader.exec_module = exec_module
                return spec
        return None


if not any(isinstance(f, _NativeImports) for f in sys.meta_path):
    sys.meta_path.insert(0, _NativeImports())

__version__ = "0.1.0"
DEFAULT_VARIANT = "llvm_ad_rgb"


class VariantError(ValueError):
    """A Mitsuba variant this build does not have (``$GLINT_VARIANT``); the message lists the ones it has."""


def set_variant(variant: str | None = None) -> str:
    """Select the Mitsuba variant (``llvm_ad_rgb`` by default; ``cuda_ad_rgb`` on a GPU) and register the plugins."""
    import mitsuba as mi

    variant = variant or os.environ.get("GLINT_VARIANT") or DEFAULT_VARIANT
    if variant not in mi.variants():
        source = "GLINT_VARIANT" if variant == os.environ.get("GLINT_VARIANT") else "variant"
        raise VariantError(f"{source} = {variant!r}: not a variant of this Mitsuba build; use one of "
                          f"{', '.join(v for v in mi.variants() if v.endswith('_ad_rgb'))} (llvm_ad_rgb on a CPU, "
                          f"cuda_ad_rgb on a GPU).")
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


__all__ = ["LLVMError", "VariantError", "check_llvm", "set_variant", "load_file", "load_dict", "__version__"]
