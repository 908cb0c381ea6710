"""What a figure was measured on: the Mitsuba variant in force, the device that ran its kernels (the GPU's name, or
the CPU model for LLVM variants) and the host's cores. Written into ``metrics.json``, ``report.json`` and the
benchmark tables, so a number always says where it came from."""
from __future__ import annotations

import ctypes
import functools
import os
import platform
import subprocess
from pathlib import Path


@functools.lru_cache(maxsize=1)
def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


@functools.lru_cache(maxsize=1)
def gpu_name() -> str | None:
    """The name of CUDA device 0 (the one Dr.Jit's cuda backend uses), from the driver library, else nvidia-smi;
    None when neither answers."""
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
        dev, buf = ctypes.c_int(0), ctypes.create_string_buffer(256)
        if (cuda.cuInit(0) == 0 and cuda.cuDeviceGet(ctypes.byref(dev), 0) == 0
                and cuda.cuDeviceGetName(buf, 256, dev) == 0):
            return buf.value.decode(errors="replace")
    except (OSError, AttributeError):
        pass
    try:
        r = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader", "-i", "0"],
                           capture_output=True, text=True, timeout=10)
        if r.returncode == 0 and r.stdout.strip():
            return r.stdout.strip().splitlines()[0]
    except (OSError, subprocess.SubprocessError):
        pass
    return None


def variant() -> str:
    """The Mitsuba variant in force (set by :func:`glint_mi.set_variant`); 'none' before one is set."""
    import mitsuba as mi

    return mi.variant() or "none"


def describe() -> dict:
    """{"variant", "backend" (llvm / cuda / scalar), "device" (GPU name or CPU model), "cpu", "cores", "system"}."""
    v = variant()
    backend = "cuda" if v.startswith("cuda") else ("llvm" if v.startswith("llvm") else v.split("_")[0])
    device = (gpu_name() or "CUDA device 0 (name unknown)") if backend == "cuda" else cpu_model()
    return {"variant": v, "backend": backend, "device": device, "cpu": cpu_model(), "cores": os.cpu_count(),
            "system": platform.system()}


def summary(d: dict | None = None) -> str:
    """One line of :func:`describe` (``d``, default now): 'NVIDIA H200 (cuda_ad_rgb), host: <cpu>, 16 cores, Linux' or
    '<cpu>, 2 cores, Linux, Dr.Jit llvm_ad_rgb'."""
    d = describe() if d is None else d
    if d["backend"] == "cuda":
        return f"{d['device']} ({d['variant']}), host: {d['cpu']}, {d['cores']} cores, {d['system']}"
    return f"{d['cpu']}, {d['cores']} cores, {d['system']}, Dr.Jit {d['variant']}"
