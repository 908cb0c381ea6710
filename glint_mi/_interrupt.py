"""The hook for a Ctrl-C that lands where Python cannot raise it (an import lock's weakref callback, seen 0.05-0.1 s
into a command on a loaded machine): without it the KeyboardInterrupt is printed as 'Exception ignored ...
Traceback' and lost, and the command runs on. One source for both places that set it: ``glint_mi/__init__.py``
(before the package imports anything) and the start-up file that ``_llvm.install_pth`` writes, which site reads
before every other .pth file and which runs this file by its path (the package may not be importable yet then).

Only built-in modules that are loaded before site runs are imported here, so running it starts no import."""
import _thread
import sys
import time


def _deliver() -> None:
    time.sleep(0.01)
    _thread.interrupt_main()


def interrupt_again(unraisable) -> None:
    """Deliver a KeyboardInterrupt again, to be raised where code can catch it; anything else goes to Python's own
    hook. Not from inside the hook: signal.raise_signal and _thread.interrupt_main both raise it at once, here, where
    it is lost again; a thread marks it pending 10 ms later, when the hook has returned (a process that ends sooner
    needs no Ctrl-C)."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        _thread.start_new_thread(_deliver, ())
        return
    sys.__unraisablehook__(unraisable)


def install() -> None:
    """Set the hook where Python's own is set (a host's, or the start-up file's copy, is left alone)."""
    if sys.unraisablehook is sys.__unraisablehook__:
        sys.unraisablehook = interrupt_again
