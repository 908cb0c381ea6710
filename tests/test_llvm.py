"""LLVM discovery: a usable LLVM is found, an old one gives a Python error naming the fix (never an abort)."""
import drjit as dr
import pytest

from glint_mi import _llvm


def test_loaded_llvm_is_usable():
    assert _llvm.check_llvm() >= (17,)


def test_old_llvm_raises_clear_error(monkeypatch):
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 7))
    with pytest.raises(_llvm.LLVMError, match=r"LLVM 15\.0\.7.*>= 17.*karellen-llvm-core"):
        _llvm.check_llvm()


def test_missing_llvm_raises_clear_error(monkeypatch):
    def boom():
        raise RuntimeError("no LLVM")
    monkeypatch.setattr(dr.detail, "llvm_version", boom)
    with pytest.raises(_llvm.LLVMError, match="could not load an LLVM"):
        _llvm.check_llvm()


def test_candidate_versions_parse():
    assert _llvm._version_of("/x/libLLVM.so.19.1") == (19, 1)
    assert _llvm._version_of("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == (15,)
    assert all(_llvm._version_of(p) >= (17,) for p in _llvm.candidate_libraries())
