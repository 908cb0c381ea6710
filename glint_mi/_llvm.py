"""Locate an LLVM >= 17 shared library for Dr.Jit's LLVM backend and refuse older ones with a clear error.

drjit 1.5 aborts the whole process (``LLVM ERROR: Cannot select ... fminimum``) on LLVM 15/16 and refuses LLVM 14,
so the choice must be made *before* ``drjit`` is first imported, through ``DRJIT_LIBLLVM_PATH``.
"""
from __future__ import annotations

import glob
import os
import re
import sys

MIN_LLVM = (17,)
FIX = ("Install a usable LLVM: `pip install karellen-llvm-core==19.1.7` (puts libLLVM.so.19.1 in <venv>/lib) "
       "or `apt-get install libllvm19`, or point DRJIT_LIBLLVM_PATH at a libLLVM of version >= 17.")


class LLVMError(RuntimeError):
    """Raised when Dr.Jit's LLVM backend would run on an LLVM that drjit 1.5 cannot use."""


def _version_of(path: str) -> tuple[int, ...] | None:
    m = re.search(r"LLVM[-.]?(?:so\.)?(\d+)(?:\.(\d+))?", os.path.basename(path))
    if not m:
        return None
    return tuple(int(g) for g in m.groups() if g is not None)


def candidate_libraries() -> list[str]:
    """Every libLLVM this process could use, best first (venv wheel, then system packages)."""
    prefixes = {sys.prefix, os.path.dirname(os.path.dirname(sys.executable))}
    found: list[str] = []
    for prefix in prefixes:
        found += glob.glob(os.path.join(prefix, "lib", "libLLVM.so.*")) + glob.glob(os.path.join(prefix, "lib", "libLLVM-*.so*"))
    for major in range(25, 16, -1):
        found += glob.glob(f"/usr/lib/llvm-{major}/lib/libLLVM*.so*")
        found += glob.glob(f"/usr/lib/*-linux-gnu/libLLVM-{major}*.so*") + glob.glob(f"/usr/lib/*-linux-gnu/libLLVM.so.{major}*")
        found += glob.glob(f"/opt/homebrew/opt/llvm@{major}/lib/libLLVM.dylib")
    usable = [p for p in dict.fromkeys(found) if (_version_of(p) or (0,)) >= MIN_LLVM and os.path.exists(p)]
    return sorted(usable, key=lambda p: (not p.startswith(sys.prefix), tuple(-v for v in _version_of(p) or (0,))))


def configure_environment() -> str | None:
    """Set DRJIT_LIBLLVM_PATH to a usable LLVM unless the user chose one; returns the path in force."""
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    if chosen:
        return chosen
    if "drjit" in sys.modules:  # too late to steer the search; check_llvm() will judge what was loaded
        return None
    libs = candidate_libraries()
    if libs:
        os.environ["DRJIT_LIBLLVM_PATH"] = libs[0]
        return libs[0]
    return None


def check_llvm() -> tuple[int, ...]:
    """Return the LLVM version Dr.Jit loaded; raise LLVMError (never abort) when it is missing or older than 17."""
    import drjit as dr

    try:
        version = tuple(dr.detail.llvm_version())
    except Exception as exc:  # no LLVM could be loaded at all
        raise LLVMError(f"Dr.Jit could not load an LLVM library ({exc}). {FIX}") from None
    if version < MIN_LLVM:
        where = os.environ.get("DRJIT_LIBLLVM_PATH", "the system search path")
        usable = candidate_libraries()
        fix = (f"A usable LLVM is installed ({usable[0]}) but drjit was imported before glint_mi chose it: import "
               f"glint_mi before mitsuba/drjit, export DRJIT_LIBLLVM_PATH={usable[0]}, or run "
               f"`python -m glint_mi.setup_llvm` once (make does) so every start of this Python picks it."
               if usable and "DRJIT_LIBLLVM_PATH" not in os.environ else FIX)
        raise LLVMError(f"Dr.Jit loaded LLVM {'.'.join(map(str, version))} from {where}; drjit 1.5 needs LLVM >= 17 "
                        f"(LLVM 15/16 abort the process, 14 is refused). {fix}")
    return version


PTH_NAME = "glint_mi_llvm.pth"
EARLY_PTH_NAME = "00_glint_mi_interrupt.pth"  # site reads .pth files in sorted order: this one before any other


def install_pth() -> str:
    """Write start-up hooks into this environment's site-packages: one that sets DRJIT_LIBLLVM_PATH before any
    import (so ``import mitsuba`` before ``import glint_mi`` also gets a usable LLVM), and one read before every
    other .pth file that keeps a Ctrl-C landing in an import lock's weakref callback during start-up (0.05 s into a
    command on a loaded machine) from being printed as 'Exception ignored' with a traceback and lost."""
    import sysconfig

    site = sysconfig.get_paths()["purelib"]
    for name, line in ((EARLY_PTH_NAME, early_pth_line()), (PTH_NAME, PTH_LINE)):
        with open(os.path.join(site, name), "w") as f:
            f.write(line)
    return os.path.join(site, PTH_NAME)


def early_pth_line() -> str:
    """The start-up file read before every other .pth: it runs glint_mi/_interrupt.py by its path (the editable
    install's finder, read after it, is what makes the package importable) and sets its hook; a file no longer there
    (the checkout moved) is skipped, as `make` writes the line again."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_interrupt.py")
    code = (f"try:\n f = open({path!r})\nexcept OSError:\n pass\nelse:\n"
            f" with f:\n  g = {{'__name__': 'glint_mi_startup_interrupt'}}; exec(compile(f.read(), {path!r}, 'exec'), g)"
            f"\n g['install']()")
    return f"import sys; exec({code!r})\n"


# the hook runs inside Python's start-up (site), where a KeyboardInterrupt is a "Fatal Python error" with a traceback:
# a Ctrl-C that lands in it ends the process with one line and status 130, as it would a moment later
PTH_LINE = ("import os, sys; exec('try:\\n import glint_mi._llvm as _glint_llvm; _glint_llvm.configure_environment()"
            "\\nexcept KeyboardInterrupt:\\n sys.stderr.write(\"interrupted\\\\n\"); os._exit(130)')\n")

