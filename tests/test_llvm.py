"""LLVM discovery: a usable LLVM is found, an old one gives a Python error naming the fix (never an abort)."""
import drjit as dr
import pytest

from glint_mi import _llvm

from conftest import LLVM, ROOT

pytestmark = pytest.mark.skipif(not LLVM, reason="checks the LLVM library the llvm variants load (a cuda run may have "
                                "none)")


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


def test_import_order_does_not_matter():
    """`import mitsuba` before `import glint_mi` still runs on LLVM >= 17 (the start-up hook make installs)."""
    import os
    import subprocess
    import sys
    import sysconfig
    if not os.path.exists(os.path.join(sysconfig.get_paths()["purelib"], _llvm.PTH_NAME)):
        pytest.skip("start-up hook not installed (run `python -m glint_mi.setup_llvm`, as make does)")
    env = {k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    code = "import mitsuba, drjit; import glint_mi; print(glint_mi.set_variant(), drjit.detail.llvm_version())"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "llvm_ad_rgb" in r.stdout


def test_old_llvm_message_points_at_the_installed_one(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 6))
    with pytest.raises(_llvm.LLVMError, match="imported before glint_mi") if _llvm.candidate_libraries() else \
            pytest.raises(_llvm.LLVMError, match="karellen"):
        _llvm.check_llvm()


def test_the_startup_hook_turns_ctrl_c_into_one_line_and_status_130():
    """The .pth hook runs inside Python's start-up, where a KeyboardInterrupt is a fatal error with a traceback
    (seen when Ctrl-C came 0.05 s into a process on a loaded machine): it exits 130 with one line instead."""
    import subprocess
    import sys

    stub = ("import sys, types; m = types.ModuleType('glint_mi._llvm'); "
            "m.configure_environment = lambda: (_ for _ in ()).throw(KeyboardInterrupt()); "
            "sys.modules['glint_mi._llvm'] = m; import glint_mi; glint_mi._llvm = m; ")
    r = subprocess.run([sys.executable, "-c", stub + f"exec({_llvm.PTH_LINE!r})"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 130 and r.stderr == "interrupted\n", (r.returncode, r.stderr)


LOST_IN_A_CALLBACK = """
import _signal  # a shell's background job (CI run with &) starts with SIGINT ignored: Python's handler, as a terminal
_signal.signal(_signal.SIGINT, _signal.default_int_handler)
import time, weakref
class Lock: pass
def cb(ref): raise KeyboardInterrupt  # as a Ctrl-C landing in an import lock's weakref callback (importlib's cb)
lock = Lock(); ref = weakref.ref(lock, cb)
try:
    del lock
    until = time.monotonic() + WAIT  # the hook's thread delivers it 10 ms later (later on a loaded machine)
    while time.monotonic() < until:
        time.sleep(0.05)
    print("lost")
except KeyboardInterrupt:
    print("raised")
"""


@pytest.mark.parametrize("hook", ["start-up", "package"])
def test_a_ctrl_c_landing_in_a_callback_is_raised_again(hook):
    """A KeyboardInterrupt in a weakref callback is one Python cannot raise: without a hook it is printed as
    'Exception ignored ... Traceback' and lost, and the command runs on (CI: a Ctrl-C 0.05 s into `evaluate`). The
    start-up hook (read before any other .pth file) and the package's own deliver it again, to be raised where code
    can catch it; and signal.raise_signal would not do (it raises inside the hook, where it is lost again)."""
    import subprocess
    import sys

    first = (f"exec({_llvm.early_pth_line()!r})\n" if hook == "start-up" else
             f"import sys; sys.path.insert(0, {str(ROOT)!r}); import glint_mi\n")
    r = subprocess.run([sys.executable, "-S", "-c", first + "WAIT = 60\n" + LOST_IN_A_CALLBACK], capture_output=True,
                       text=True, timeout=120)
    assert r.stdout == "raised\n" and "Traceback" not in r.stderr, (r.stdout, r.stderr)
    r = subprocess.run([sys.executable, "-S", "-c", "WAIT = 2\n" + LOST_IN_A_CALLBACK], capture_output=True, text=True,
                       timeout=120)
    assert r.stdout == "lost\n" and "KeyboardInterrupt" in r.stderr, (r.stdout, r.stderr)  # the test can fail


def test_the_interrupt_hook_is_read_before_every_other_startup_file():
    import os
    import sysconfig

    site = sysconfig.get_paths()["purelib"]
    if not os.path.exists(os.path.join(site, _llvm.EARLY_PTH_NAME)):
        pytest.skip("start-up hooks not installed (run `python -m glint_mi.setup_llvm`, as make does)")
    pths = sorted(f for f in os.listdir(site) if f.endswith(".pth"))
    assert pths[0] == _llvm.EARLY_PTH_NAME, pths
    assert open(os.path.join(site, _llvm.EARLY_PTH_NAME)).read() == _llvm.early_pth_line()
