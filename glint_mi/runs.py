"""Run folders: atomic file writes, the run error, and reading a run's dataset as the run read it."""
from __future__ import annotations

import contextlib
import json
import os
import socket
from pathlib import Path

LOCK_NAME = ".lock"


class RunError(ValueError):
    """Bad run folder / resume request; the message names the file and the fix."""


def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".partial")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def check_run_folder(run: Path) -> None:
    """Refuse, before any work, a run folder that cannot be one: an existing file, or a folder that already holds
    a run (continue it with --resume), or one that cannot be created."""
    run = Path(run)
    if run.exists() and not run.is_dir():
        raise RunError(f"--out {run}: is a file, not a folder; choose another --out.")
    if (run / "checkpoint.npz").exists():
        raise RunError(f"{run}: already holds a run; continue it with --resume {run} or choose --out.")
    if run.is_dir() and not (run / "config.json").exists():
        other = sorted(p.name for p in run.iterdir() if p.name != LOCK_NAME)
        if other:
            listed = ", ".join(other[:4]) + (", ..." if len(other) > 4 else "")
            raise RunError(f"--out {run}: holds other files ({listed}), not a run; a run writes config.json, "
                           f"model/, renders/ ... into its folder: choose a new or empty folder.")
    parent = run if run.exists() else next((p for p in run.parents if p.exists()), Path("."))
    if not os.access(parent, os.W_OK):
        raise RunError(f"--out {run}: {parent} is not writable; choose another --out.")


@contextlib.contextmanager
def undo_new_run(run: Path):
    """Around a new run's set-up: if it raises (a bad input found late, Ctrl-C), remove what the set-up wrote into
    ``run`` (the folder itself when it did not exist before), so that no folder is left that looks like a run but
    holds no checkpoint."""
    import shutil

    run = Path(run)
    existed = run.exists()
    before = set(run.iterdir()) if existed else set()
    try:
        yield
    except BaseException:
        if not existed:
            shutil.rmtree(run, ignore_errors=True)
        elif run.exists():
            for p in set(run.iterdir()) - before:
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        raise


def check_writable(folder: Path) -> None:
    """Refuse a run folder this process cannot write into (a read-only copy, a read-only mount, an immutable folder):
    probed by creating a file, since permission bits say nothing to root."""
    import tempfile

    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".write-probe-"):
            pass
        lock = Path(folder) / LOCK_NAME
        if lock.exists():
            open(lock, "a").close()
    except OSError as e:
        raise RunError(f"{folder}: not writable ({e.strerror}); training and evaluation write into the run "
                       f"folder: make it writable (chmod -R u+w {folder}) or copy the run elsewhere and use the "
                       f"copy.") from None


def hold_run(run: Path):
    """Take the run folder's lock (``.lock``, a POSIX record lock: the kernel drops it when the process ends, so a
    killed run leaves no stale lock) and return the open lock file, which must stay referenced for as long as the
    process works on the run. Raises RunError when another process holds it: two processes training one folder
    overwrite each other's checkpoints. Within one process the lock is re-entrant (a test may resume a run whose
    first Trainer is still alive; closing either lock file then frees the folder, as POSIX record locks are per
    process). On a filesystem without POSIX locks the lock is not taken and a note says so."""
    import fcntl

    run = Path(run)
    run.mkdir(parents=True, exist_ok=True)
    check_writable(run)
    f = open(run / LOCK_NAME, "a+")
    try:
        fcntl.lockf(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        import errno

        f.seek(0)
        holder = f.read().strip() or "unknown"
        f.close()
        if e.errno in (errno.EACCES, errno.EAGAIN):
            raise RunError(f"{run}: another process ({holder}) is training or evaluating this run (lock "
                           f"{run / LOCK_NAME}); wait for it to finish, stop it, or choose another --out. Two "
                           f"processes on one run folder overwrite each other's checkpoints.") from None
        print(f"note: {run / LOCK_NAME}: cannot lock ({e}); nothing stops a second process on this run")
        return None
    f.seek(0)
    f.truncate()
    f.write(f"pid {os.getpid()} on {socket.gethostname()}\n")
    f.flush()
    return f


def read_checkpoint(path: Path, keys: tuple | None = None) -> dict:
    """The arrays ``keys`` of a checkpoint (default: every one), or a RunError naming the file when it is damaged
    (truncated by a full disk or a copy that stopped): a checkpoint is written atomically, so a damaged one was not
    written by this run."""
    import zipfile

    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as f:
            for key in ("iteration", "elapsed", "extent", "bounds", "rng", "report"):
                if key not in f.files:
                    raise ValueError(f"no '{key}' array")
            return {k: f[k] for k in (f.files if keys is None else keys)}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as e:
        raise RunError(f"{path}: damaged, cannot be resumed ({e}); restore the file from a copy, or start the run "
                       f"again in a new folder (--out).") from None


def load_run_dataset(run_dir: Path, cfg, full: bool = False, log=None):
    """The dataset of a run folder, read as the run read it (``run.json``), at the training resolution or, with
    ``full``, at its full resolution."""
    from glint_mi.data import load_dataset

    info = json.loads((Path(run_dir) / "run.json").read_text())
    opts = {**{"missing": "error"}, **info.get("dataset_options", {}), "downscale": 1 if full else cfg.downscale}
    ds = load_dataset(info["dataset"], log=log, **opts)
    if info.get("sparse"):  # the SfM model the run triangulated (its tracks feed the see-through cue)
        ds.sparse, ds.tracks_distorted = Path(info["sparse"]), bool(info.get("tracks_distorted"))
    return ds


def finished_metrics(run: Path) -> dict | None:
    """A run's ``metrics.json`` when its latest evaluation finished; None when there is none or one was interrupted
    (its ``evaluation_partial/`` folder is left, and metrics.json is an older evaluation's, or an interrupted one's
    marked ``"interrupted": true`` as evaluations wrote them before): it must be evaluated again, not read as done."""
    path = Path(run) / "metrics.json"
    if not path.exists() or (Path(run) / "evaluation_partial").exists():
        return None
    res = json.loads(path.read_text())
    return None if res.get("interrupted") else res


def train_unless_done(trainer) -> dict:
    """``trainer.train()`` unless the run already finished its schedule and saved its model (``model/scene.xml``,
    written last; its evaluation was what was interrupted): then the training seconds are the checkpoint's and
    nothing is trained or logged again. A run killed after its last checkpoint but before its model was saved goes
    through ``train()``, which trains nothing more and finishes the end of the run (last convergence point, model)."""
    if trainer.it >= trainer.cfg.iterations and (trainer.run_dir / "model" / "scene.xml").exists():
        return {"iterations": trainer.it, "train_s": trainer.elapsed}
    return trainer.train(progress=False)
