"""Nothing lost, nothing ignored (the audit of 2026-11-28): one source for every setting, one process on a run
folder at a time, poses and image sizes checked, an error naming the file and the fix for every bad file, and
interruptions that leave nothing half-made. Each test failed on the code before the fix (what happened is in its
docstring)."""
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import glint_mi

glint_mi.set_variant()

from glint_mi.config import ConfigError, TrainConfig  # noqa: E402
from glint_mi.data import DatasetError, load_dataset  # noqa: E402
from glint_mi.data.priors import check_priors  # noqa: E402
from glint_mi.runs import hold_run  # noqa: E402
from glint_mi.scene import SceneError, read_scene, scene_xml  # noqa: E402

from conftest import ROOT, cli, copy_tree, files_of  # noqa: E402

FAST = ("--preset", "tiny", "--iterations", "3", "--no-progress")


def one_error(r, errors, *needles):
    """Exit code 2, exactly one 'error:' line holding every needle, and no traceback."""
    assert r.returncode == 2 and len(errors) == 1, r.stdout[-2000:] + r.stderr[-3000:]
    assert "Traceback" not in r.stderr, r.stderr
    for n in needles:
        assert n in errors[0], errors[0]


@pytest.fixture(scope="module")
def xml(tiny):
    """The tiny room's optimisation scene as `python -m glint_mi.scene` writes it."""
    path = tiny.parent / "scene.xml"
    r, errors = cli("glint_mi.scene", tiny)
    assert r.returncode == 0, r.stderr
    path.write_text(r.stdout)
    return path


@pytest.fixture(scope="module")
def trained(xml, tmp_path_factory):
    """A finished, evaluated run of the tiny room (3 iterations)."""
    run = tmp_path_factory.mktemp("runs") / "run"
    r, _ = cli("glint_mi.optimize", xml, *FAST, "--out", run)
    assert r.returncode == 0, r.stderr[-3000:]
    return run


def copy_run(trained, dst):
    shutil.copytree(trained, dst, ignore=shutil.ignore_patterns(".lock"))
    return dst


def consistent(run: Path):
    """A complete evaluation: metrics.json's views each with their per_view JSON and EXR, nothing else."""
    m = json.loads((run / "metrics.json").read_text())
    assert m["views_done"] == m["views_total"] == len(m["views"]) and "interrupted" not in m
    assert sorted(p.stem for p in (run / "per_view").glob("*.json")) == sorted(m["views"])
    assert sorted(p.stem for p in (run / "renders").glob("*.exr")) == sorted(m["views"])
    assert not (run / "evaluation_partial").exists()


# ------------------------------------------------------------------ data lost
def test_evaluate_takes_the_run_lock(trained, tmp_path):
    """Two `evaluate` processes on one run (before: both exited 0, metrics.json said 2 views done while per_view/
    and renders/ held 1 - each moved its renders over the other's). Now the run's lock is held: a second process is
    refused with the holder named, and two started together leave one complete, consistent evaluation."""
    run = copy_run(trained, tmp_path / "run")
    lock = hold_run(run)  # another process (this one) works on the run
    try:
        r, errors = cli("glint_mi.evaluate", run, "--no-progress")
        one_error(r, errors, "another process", f"pid {os.getpid()}")
    finally:
        lock.close()
    procs = [subprocess.Popen([sys.executable, "-m", "glint_mi.evaluate", str(run), "--no-progress"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [(p.wait(timeout=600), p.stderr.read()) for p in procs]
    assert all(rc == 0 or (rc == 2 and "another process" in err) for rc, err in outs), outs
    assert any(rc == 0 for rc, _ in outs)
    consistent(run)


def test_resume_of_a_busy_run_names_the_other_process(xml, tmp_path):
    """--resume while another process sets the run up (before: 'no checkpoint to resume', as if it had died)."""
    run = tmp_path / "run"
    run.mkdir()
    TrainConfig.for_preset("tiny").save(run / "config.json")
    lock = hold_run(run)
    try:
        r, errors = cli("glint_mi.optimize", "--resume", run)
        one_error(r, errors, "another process")
    finally:
        lock.close()
    r, errors = cli("glint_mi.optimize", "--resume", run)  # nobody holds it: now the missing checkpoint is named
    one_error(r, errors, "checkpoint.npz: no checkpoint to resume")


# ------------------------------------------------------------ one source a setting
def _config(run: Path) -> dict:
    return TrainConfig.load(run / "config.json").flat()


def test_the_kernel_of_the_scene_xml_is_trained(tiny, tmp_path):
    """`scene --kernel ellipsoid` (before: written into the XML, and training built surfels)."""
    r, _ = cli("glint_mi.scene", tiny, "--kernel", "ellipsoid")
    assert r.returncode == 0 and r.stdout.count('name="kernel" value="ellipsoid"') == 3, r.stderr
    (tmp_path / "e.xml").write_text(r.stdout)
    r, _ = cli("glint_mi.optimize", tmp_path / "e.xml", *FAST, "--no-eval", "--out", tmp_path / "run")
    assert r.returncode == 0, r.stderr[-3000:]
    assert _config(tmp_path / "run")["kernel"] == "ellipsoid"
    # a method whose paper fixes the other kernel is refused, naming both, before any work
    r, errors = cli("glint_mi.optimize", xml_with(tiny, tmp_path, kernel="surfel"), *FAST, "--method", "3dgs",
                    "--out", tmp_path / "r2")
    one_error(r, errors, "kernel = 'surfel'", "method 3dgs gives 'ellipsoid'")
    assert not (tmp_path / "r2").exists()


def xml_with(tiny, tmp_path, **settings) -> Path:
    path = tmp_path / f"s{len(list(tmp_path.glob('s*.xml')))}.xml"
    path.write_text(scene_xml(tiny, **settings))
    return path


def test_a_setting_given_in_the_xml_and_the_config_must_agree(tiny, tmp_path):
    """A --config file's `components: all` against the XML's `auto` (before: the XML's won, silently; the XML always
    carried `auto`). Now `scene` writes a setting only when asked, the config's is then used, and two sources that
    disagree are refused naming both; --set over the --config file is said."""
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"components": "all", "w_trans": 0.02}))
    plain = xml_with(tiny, tmp_path)
    assert read_scene(plain).settings == {}
    r, _ = cli("glint_mi.optimize", plain, *FAST, "--no-eval", "--config", cfg, "--set", "w_trans=0.03",
               "--out", tmp_path / "run")
    assert r.returncode == 0, r.stderr[-3000:]
    assert _config(tmp_path / "run")["components"] == "all" and _config(tmp_path / "run")["w_trans"] == 0.03
    preset = TrainConfig.for_preset("tiny", iterations=3).flat()  # nothing else moved (no old run's migrations)
    assert {k for k, v in _config(tmp_path / "run").items() if preset[k] != v} == {"components", "w_trans"}
    assert f"note: the command line sets w_trans = 0.03 over --config {cfg}'s 0.02" in r.stderr
    stated = xml_with(tiny, tmp_path, components="auto")
    for extra, other in ((("--config", cfg), f"--config {cfg} gives 'all'"),
                         (("--set", "components=all"), "the command line gives 'all'")):
        r, errors = cli("glint_mi.optimize", stated, *FAST, *extra, "--out", tmp_path / "r2")
        one_error(r, errors, "components = 'auto'", other)
        assert not (tmp_path / "r2").exists()
    # the library road: a Trainer given a config that disagrees with the XML refuses it too
    from glint_mi.training.trainer import Trainer

    with pytest.raises(ConfigError, match=r"states components = 'auto' but the training config has components = "
                                          r"'all'"):
        Trainer(tmp_path / "r3", TrainConfig.for_preset("tiny", components="all"), scene=read_scene(stated),
                log=lambda *a: None)
    assert not (tmp_path / "r3").exists()


def test_preset_flag_and_config_file_must_agree(tiny, tmp_path):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"preset": "bench"}))
    r, errors = cli("glint_mi.optimize", xml_with(tiny, tmp_path), "--config", cfg, "--preset", "tiny",
                    "--out", tmp_path / "run")
    one_error(r, errors, "--preset tiny", "preset 'bench'")


@pytest.mark.parametrize("line, match", [
    ('<int name="max_order" value="2"/>', r"holds <int name=\"max_order\">, which is not read \(did you mean "
                                           r"<integer>\?\)"),
    ('<sting name="components" value="all"/>', r"<sting name=\"components\">, which is not read \(did you mean "
                                                r"<string>\?\)"),
    ('<integer name="components" value="2"/>', r"'components' is given as <integer>; write it as <string"),
    ('<string name="max_order" value="2"/>', r"'max_order' is given as <string>; write it as <integer"),
    ('<integer name="max_order" value="two"/>', r"'max_order' = 'two' is not an integer"),
    ('<integer name="max_order" value="3"/>', r"max_order = 3; use 1 .* or 2"),
    ('<string name="components" value="all"/><string name="components" value="auto"/>',
     r"gives 'components' twice"),
])
def test_xml_elements_of_the_wrong_type_are_refused(tiny, tmp_path, line, match):
    """Wrong tag types (before: `<int name="max_order">`, `<sting ...>` left the default in place)."""
    text = scene_xml(tiny).replace('<shape type="glint_gaussians" name="interface">',
                                   line + '\n        <shape type="glint_gaussians" name="interface">', 1)
    (tmp_path / "s.xml").write_text(text)
    with pytest.raises(SceneError, match=match):
        read_scene(tmp_path / "s.xml")


@pytest.mark.parametrize("change, match", [
    (lambda t: t.replace('value="grid"/>', 'value="grid"/>\n<integer name="grid_n" value="0"/>'),
     r"grid_n = 0; give at least 1"),
    (lambda t: t.replace('value="sfm"/>', 'value="sfm"/>\n<integer name="grid_k" value="3"/>', 1),
     r"shape 'interface': grid_k applies to init=grid only"),
    (lambda t: t.replace('name="transmission"', 'name="interface"'), r"two shapes for the interface set"),
    (lambda t: t.replace('value="sfm"/>', 'value="sfm"/>\n<string name="kernel" value="ellipsoid"/>', 1).replace(
        'value="grid"/>', 'value="grid"/>\n<string name="kernel" value="surfel"/>'),
     r"every set of a run has one kernel"),
])
def test_shape_settings_are_checked(tiny, tmp_path, change, match):
    """A zero grid (before: `grid_n 0` used the preset's grid), grid settings on a set not on the grid and a second
    shape for one set (before: ignored, the last one won), one kernel for every set (before: ignored per shape)."""
    (tmp_path / "s.xml").write_text(change(scene_xml(tiny)))
    with pytest.raises(SceneError, match=match):
        read_scene(tmp_path / "s.xml")


def test_zero_counts_are_refused_not_replaced(tiny, xml, tmp_path):
    """`--iterations 0` (before: trained the preset's budget) and `scene --grid-n 0` (before: the preset's grid)."""
    r, errors = cli("glint_mi.optimize", xml, "--iterations", "0", "--out", tmp_path / "run")
    one_error(r, errors, "--iterations 0: give a positive iteration count")
    assert not (tmp_path / "run").exists()
    r, errors = cli("glint_mi.scene", tiny, "--grid-n", "0")
    one_error(r, errors, "--grid-n 0: give at least 1")
    assert r.stdout == ""


def _transforms(cap: Path) -> dict:
    return json.loads((cap / "transforms.json").read_text())


@pytest.mark.parametrize("kind", ["scaled", "sheared", "mirrored", "zero", "last_row"])
def test_poses_that_are_not_rotations_are_refused(tiny, tmp_path, kind):
    """A scaled, sheared or mirrored (det -1) rotation (before: accepted by `scene` and by training, which traced
    rays of the wrong length or a mirrored image) and an all-zero one (before: passed `scene`, a traceback in
    training)."""
    cap = copy_tree(tiny, tmp_path / "cap")
    shutil.rmtree(cap / "sparse")  # the transforms.json is read
    tj = _transforms(cap)
    m = np.array(tj["frames"][2]["transform_matrix"], float)
    change = {"scaled": np.diag([2.0, 2.0, 2.0]), "sheared": np.array([[1, 0.3, 0], [0, 1, 0], [0, 0, 1.0]]),
              "mirrored": np.diag([-1.0, 1.0, 1.0]), "zero": np.zeros((3, 3)), "last_row": np.eye(3)}[kind]
    m[:3, :3] = m[:3, :3] @ change
    if kind == "last_row":
        m[3] = [0, 0, 0.5, 1]
    tj["frames"][2]["transform_matrix"] = m.tolist()
    (cap / "transforms.json").write_text(json.dumps(tj))
    match = {"scaled": "not orthonormal", "sheared": "not orthonormal", "mirrored": "mirrored (det -1)",
             "zero": "all zero", "last_row": "not [0, 0, 0, 1]"}[kind]
    with pytest.raises(DatasetError, match=r"frames\[2\]\.transform_matrix: .*" + re_escape(match)):
        load_dataset(cap)
    r, errors = cli("glint_mi.scene", cap)
    one_error(r, errors, "frames[2].transform_matrix", match)


def re_escape(s):
    import re
    return re.escape(s)


def test_a_broken_colmap_quaternion_is_refused(tiny, tmp_path):
    """A zero quaternion in images.txt (before: divided by its zero norm, NaN poses)."""
    cap = copy_tree(tiny, tmp_path / "cap")
    (cap / "transforms.json").unlink()
    images = cap / "sparse" / "0" / "images.txt"
    lines = images.read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line and not line.startswith("#"))
    parts = lines[i].split()
    parts[1:5] = ["0", "0", "0", "0"]
    lines[i] = " ".join(parts)
    images.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"the quaternion must be a finite unit quaternion \(\|q\| = 0\)"):
        load_dataset(cap)


def test_images_of_another_size_than_the_shared_intrinsics_are_refused(tiny, tmp_path):
    """A transforms.json with shared fl_x/cx/cy and no w/h, and one image of another size (before: trained with the
    shared focal length, no note)."""
    from PIL import Image

    cap = copy_tree(tiny, tmp_path / "cap")
    shutil.rmtree(cap / "sparse")
    tj = _transforms(cap)
    for k in ("w", "h"):
        tj.pop(k, None)
    (cap / "transforms.json").write_text(json.dumps(tj))
    load_dataset(cap)  # every image of one size: fine
    fp = tj["frames"][3]["file_path"]
    img = next(p for p in (cap / Path(fp).parent).glob(Path(fp).name + "*"))
    with Image.open(img) as im:
        im.resize((im.width * 2, im.height * 2)).save(img)
    with pytest.raises(DatasetError, match=r"frames\[3\] .* is 96 x 54 but frames\[0\] .* is 48 x 27, and both use "
                                           r"the shared fl_x"):
        load_dataset(cap)


def test_a_dataset_path_with_markup_characters_round_trips(tiny, tmp_path):
    """A dataset folder named `a&b` (before: `scene` wrote XML that `optimize` rejected as invalid)."""
    cap = copy_tree(tiny, tmp_path / "a&b <room>")
    r, _ = cli("glint_mi.scene", cap)
    assert r.returncode == 0, r.stderr
    (tmp_path / "s.xml").write_text(r.stdout)
    assert read_scene(tmp_path / "s.xml").dataset == cap.resolve()


# ------------------------------------------------------------ tracebacks -> errors
@pytest.mark.parametrize("ext", [".npy", ".exr"])
def test_truncated_prior_files_are_named(tiny, tmp_path, ext):
    """A truncated .npy (before: a ValueError traceback not naming the file) and a truncated .exr prior."""
    cap = copy_tree(tiny, tmp_path / "cap")
    ds = load_dataset(cap)
    v = ds.train_views[1]
    for f in (cap / "priors" / "depth").glob(f"{v.name}.*"):
        f.unlink()
    path = cap / "priors" / "depth" / f"{v.name}{ext}"
    if ext == ".npy":
        np.save(path, np.ones((v.height, v.width), np.float32))
    else:
        import OpenEXR

        with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Z": np.ones((v.height, v.width), np.float32)}) as f:
            f.write(str(path))
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])
    problems = check_priors(cap, ds.train_views)
    assert len(problems) == 1 and str(path) in problems[0] and "cannot read the depth prior" in problems[0], problems
    r, errors = cli("glint_mi.scene", cap)
    one_error(r, errors, str(path))


def test_a_patch_larger_than_the_downscaled_images_is_refused_before_the_run_folder(xml, tmp_path):
    """--set downscale=8 leaves 6 x 3 views for an 8 x 8 patch (before: found after set-up, leaving a run folder
    without a checkpoint)."""
    r, errors = cli("glint_mi.optimize", xml, *FAST, "--set", "downscale=8", "--out", tmp_path / "run")
    one_error(r, errors, "'patch' = 8", "downscale 8", "--set patch=")
    assert not (tmp_path / "run").exists()


def _immutable(folder: Path) -> bool:
    """Make ``folder`` unwritable even for root (chattr +i); False where the filesystem cannot."""
    if shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0


@pytest.mark.parametrize("command", ["evaluate", "resume"])
def test_a_read_only_run_folder_is_named(trained, tmp_path, command):
    """`evaluate` or `--resume` on a run folder nobody may write (before: a PermissionError traceback)."""
    run = copy_run(trained, tmp_path / "run")
    (run / ".lock").touch()
    if not _immutable(run):
        pytest.skip("cannot make a folder read-only for root here (chattr +i)")
    try:
        args = ("glint_mi.evaluate", run) if command == "evaluate" else ("glint_mi.optimize", "--resume", run)
        r, errors = cli(*args)
        one_error(r, errors, f"{run}: not writable", "chmod -R u+w")
    finally:
        subprocess.run(["chattr", "-i", str(run)])


@pytest.mark.parametrize("args, needles", [
    (("--seed", "-1"), ("'seed' = -1",)),
    (("--config", "LIST"), ("holds a JSON list, not an object",)),
    (("--set", "patch=2"), ("'patch' = 2: must be >= 3",)),
    (("--set", "w_trans=0", "--set", "w_trans=0.03"), ("'w_trans' is given twice (0 and 0.03); keep one",)),
])
def test_bad_values_are_refused_before_any_work(xml, tmp_path, args, needles):
    """--seed -1 (before: a numpy traceback after set-up), a --config JSON that is a list (before: an
    AttributeError traceback) and one field set twice with two values (before: the later --set won, silently)."""
    if "LIST" in args:
        (tmp_path / "list.json").write_text(json.dumps([{"components": "all"}]))
        args = ("--config", tmp_path / "list.json")
    r, errors = cli("glint_mi.optimize", xml, *FAST, *args, "--out", tmp_path / "run")
    one_error(r, errors, *needles)
    assert not (tmp_path / "run").exists()


def test_a_truncated_checkpoint_is_named(trained, tmp_path):
    """--resume of a run whose checkpoint.npz was cut short (before: a BadZipFile traceback)."""
    run = copy_run(trained, tmp_path / "run")
    ck = run / "checkpoint.npz"
    ck.write_bytes(ck.read_bytes()[:200])
    r, errors = cli("glint_mi.optimize", "--resume", run)
    one_error(r, errors, f"{ck}: damaged, cannot be resumed")
    r, errors = cli("glint_mi.evaluate", run)
    one_error(r, errors, f"{ck}: damaged")


def test_resume_refuses_settings_it_would_not_read(trained, tmp_path):
    """`--resume RUN --set ...` or `--iterations N` (before: silently ignored; the run went on as configured)."""
    run = copy_run(trained, tmp_path / "run")
    r, errors = cli("glint_mi.optimize", "--resume", run, "--iterations", "900", "--set", "w_trans=0")
    one_error(r, errors, "--iterations, --set would not be read")


def test_a_late_set_up_failure_leaves_no_run_folder(tiny, tmp_path):
    """TSGS on a room without glass masks is refused after the run folder was made (before: config.json and run.json
    were left, a folder that looked like a run)."""
    cap = copy_tree(tiny, tmp_path / "cap")
    shutil.rmtree(cap / "priors" / "glass")
    r, errors = cli("glint_mi.optimize", xml_with(cap, tmp_path), *FAST, "--method", "tsgs", "--out", tmp_path / "run")
    one_error(r, errors, "priors/glass")
    assert not (tmp_path / "run").exists()


def test_out_refuses_a_folder_that_is_not_a_run(xml, tiny, tmp_path):
    """--out naming the dataset itself (before: config.json, model/ and renders/ were written among its files)."""
    before = files_of(tiny)
    r, errors = cli("glint_mi.optimize", xml, *FAST, "--out", tiny)
    one_error(r, errors, "holds other files", "not a run")
    assert files_of(tiny) == before


def test_a_view_in_both_train_and_test_is_refused(tiny, tmp_path):
    cap = copy_tree(tiny, tmp_path / "cap")
    split = json.loads((cap / "split.json").read_text())
    split["test"].append(split["train"][0])
    (cap / "split.json").write_text(json.dumps(split))
    with pytest.raises(DatasetError, match=r"are in both 'train' and 'test'"):
        load_dataset(cap)


def test_a_stale_images_k_folder_is_refused(tiny, tmp_path):
    """images_4/ of another crop than the images (before: its size scaled the intrinsics anisotropically)."""
    from PIL import Image

    cap = copy_tree(tiny, tmp_path / "cap")
    ds = load_dataset(cap)
    v = ds.views[0]
    small = cap / v.image_path.parent.with_name(v.image_path.parent.name + "_2").name / v.image_path.name
    small.parent.mkdir()
    with Image.open(v.image_path) as im:
        im.resize((im.width // 2, im.height // 2 - 4)).save(small)
    with pytest.raises(DatasetError, match=r"but downscale 2 of the 48 x 27 image"):
        load_dataset(cap, downscale=2)


def test_a_bad_variant_is_named(xml, tmp_path):
    env = {**os.environ, "GLINT_VARIANT": "llvm_rgb"}
    r, errors = cli("glint_mi.optimize", xml, *FAST, "--out", tmp_path / "run", env=env)
    one_error(r, errors, "GLINT_VARIANT = 'llvm_rgb'", "llvm_ad_rgb")
    assert not (tmp_path / "run").exists()


def test_ctrl_c_early_in_evaluate_is_one_line(trained, tmp_path):
    """SIGINT in the first second of `evaluate` (before: a KeyboardInterrupt traceback from an import, or a
    SystemError from one in C, or SIGABRT when it came while Dr.Jit's extension loaded, 0.15-0.2 s in). The tiny
    run's evaluation takes ~0.6 s here; the signal is sent at 12 moments in it. Whatever the moment: no traceback,
    and the run holds its former evaluation or a complete new one. A signal that lands while CPython itself is still
    importing its ``site`` module (before any code of this project or its ``.pth`` hook runs; on a loaded machine the
    first moment can fall there) ends in CPython's own fatal error, which no program can catch: such a moment is
    skipped, and at most two of the twelve may be."""
    startup = 0
    for k, after in enumerate(np.arange(0.05, 0.65, 0.05)):
        run = copy_run(trained, tmp_path / f"run{k}")
        before = (run / "metrics.json").read_text()
        p = subprocess.Popen([sys.executable, "-m", "glint_mi.evaluate", str(run), "--no-progress"], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(after)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=300)
        if "init_import_site" in err and (run / "metrics.json").read_text() == before:
            startup += 1
            assert startup <= 2, (after, err)
            continue
        assert "Traceback" not in err, (after, err)
        assert p.returncode in (0, 130, -signal.SIGINT), (after, p.returncode, err)
        if p.returncode == 130:
            assert "interrupted" in err + out, (after, err)
        if (run / "metrics.json").read_text() != before:  # it finished first (SIGINT may end the process's exit)
            consistent(run)
        assert not (run / "evaluation_partial").exists() or p.returncode != 0


def test_ctrl_c_during_numpys_import_waits_for_its_end():
    """A Ctrl-C inside NumPy's import (before: 0.05 s into `evaluate` on a loaded CI machine, NumPy's extension turned
    it into an ImportError 'PyCapsule_Import could not import module "datetime"', printed as two tracebacks). Made
    certain here: a trace function raises SIGINT when NumPy's Python part of `multiarray` starts. The interrupt must
    come out as a KeyboardInterrupt after the extension has loaded (held back by glint_mi's import hook), not as an
    ImportError, and the command's top prints one line."""
    code = textwrap.dedent("""
        import signal, sys
        signal.signal(signal.SIGINT, signal.default_int_handler)  # a shell's background job starts with SIGINT ignored
        import glint_mi
        fired = []
        def tracer(frame, event, arg):
            if not fired and event == "call" and frame.f_code.co_filename.endswith("multiarray.py"):
                fired.append(1)
                signal.raise_signal(signal.SIGINT)
            return None
        sys.settrace(tracer)
        try:
            import numpy
        except KeyboardInterrupt:
            sys.settrace(None)
            print("loaded" if "numpy._core._multiarray_umath" in sys.modules else "not loaded", fired)
            raise
        print("no interrupt", fired)
    """)
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "loaded [1]", (r.stdout, r.stderr)
    assert r.returncode == 130 and "Traceback" not in r.stderr and "interrupted" in r.stderr, r.stderr


def test_threads_setting_reaches_drjit(xml, tmp_path):
    """`--set threads=1` is how a CLI run (and its --resume) becomes reproducible bit for bit on the LLVM backend
    (tests/test_train.py checks resume exactness on one thread); before, only a script could set Dr.Jit's threads."""
    import drjit as dr

    from glint_mi.training.trainer import Trainer

    threads = dr.thread_count()
    try:
        Trainer(tmp_path / "run", TrainConfig.for_preset("tiny", threads=1), scene=read_scene(xml), log=lambda *a: None)
        assert dr.thread_count() == 1
    finally:
        dr.set_thread_count(threads)
    with pytest.raises(ConfigError, match=r"'threads' = -1: must be >= 0"):
        TrainConfig.for_preset("tiny", threads=-1)
