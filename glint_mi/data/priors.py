"""Per-view priors as estimators write them: ``priors/{depth,normal,albedo,glass}/<view>.<ext>`` (glass: a
segmentation model's glass mask, what TSGS trains with).

Files: ``.npy`` (float arrays), ``.exr`` (float; depth in Z, Y or R; normals in N.X N.Y N.Z, X Y Z or R G B; albedo
in R G B), ``.png`` / ``.tif`` (8- or 16-bit; normals and albedo [0, 1]-encoded). ``priors/PRIORS.json`` names the
conventions (every key optional; defaults in brackets):

    {"depth":  {"type": "depth" | "disparity"},      # [depth]: metric or affine-invariant depth (any scale and
                                                     #  shift: the loss fits them); disparity: affine-invariant
                                                     #  inverse depth, as MiDaS / Depth Anything write it
     "normal": {"frame": "opencv" | "opengl"},       # [opencv]: camera axes x right, y down, z forward;
                                                     #  opengl: x right, y up, z backward. Facing the camera.
     "albedo": {"space": "linear" | "srgb"}}         # [linear for float files, srgb for 8/16-bit images]

A map at the view's size is used as it is; at the dataset's full size it is block-averaged to a downscaled view;
any other size is refused, naming the file. 0 marks an invalid depth or normal pixel.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from glint_mi.data.errors import DatasetError
from glint_mi.data.images import fit_to

KINDS = ("depth", "normal", "albedo", "glass")  # glass: a segmentation model's glass mask in [0, 1] (TSGS's masks)
EXTS = (".npy", ".exr", ".png", ".tif", ".tiff")
DEPTH_TYPES = ("depth", "disparity")
NORMAL_FRAMES = ("opencv", "opengl")


class PriorError(DatasetError):
    """Bad prior file or PRIORS.json; the message names the file and the fix."""


CONVENTION_KEYS = {"depth": ("type",), "normal": ("frame",), "albedo": ("space",), "glass": ()}
# what a PRIORS.json may hold besides the conventions: the record glint_mi's generator writes, and free notes
PRIORS_KEYS = (*CONVENTION_KEYS, "derived_from_ground_truth", "model", "seed", "kinds", "corruption", "views",
               "measured", "drawn", "notes")


def prior_conventions(root: Path) -> dict:
    """The conventions of ``root``/priors/PRIORS.json, validated: {'depth': 'depth'|'disparity', 'normal':
    'opencv'|'opengl', 'albedo': 'linear'|'srgb'|None (by file type)}, plus the file's own record."""
    p = Path(root) / "priors" / "PRIORS.json"
    record = {}
    if p.exists():
        try:
            record = json.loads(p.read_text())
        except json.JSONDecodeError as e:
            raise PriorError(f"{p}: not valid JSON ({e}).") from None
    if not isinstance(record, dict):
        raise PriorError(f"{p}: must hold a JSON object, e.g. {{\"depth\": {{\"type\": \"disparity\"}}}}.")
    unknown = sorted(set(record) - set(PRIORS_KEYS))
    if unknown:
        raise PriorError(f"{p}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}; the "
                         f"keys are {', '.join(CONVENTION_KEYS)} (conventions) and "
                         f"{', '.join(k for k in PRIORS_KEYS if k not in CONVENTION_KEYS)} (the record a generator "
                         f"or you keep; 'notes' for anything else).")
    for kind, keys in CONVENTION_KEYS.items():
        section = record.get(kind)
        if section is None:
            continue
        if not isinstance(section, dict):
            raise PriorError(f"{p}: '{kind}' must be an object with {' / '.join(keys) or 'no keys'}, e.g. "
                             f"{{\"{kind}\": {{\"{keys[0]}\": ...}}}}." if keys else f"{p}: '{kind}' must be {{}}.")
        bad = sorted(set(section) - set(keys))
        if bad:
            raise PriorError(f"{p}: unknown key{'s' if len(bad) > 1 else ''} {', '.join(map(repr, bad))} in "
                             f"'{kind}'; {'its key is ' + repr(keys[0]) if keys else 'it takes no keys'}.")
    depth = str((record.get("depth") or {}).get("type", "depth"))
    frame = str((record.get("normal") or {}).get("frame", "opencv"))
    space = (record.get("albedo") or {}).get("space")
    if depth not in DEPTH_TYPES:
        raise PriorError(f"{p}: depth.type = {depth!r}; use 'depth' (metric or affine-invariant depth) or "
                         f"'disparity' (affine-invariant inverse depth, MiDaS / Depth Anything).")
    if frame not in NORMAL_FRAMES:
        raise PriorError(f"{p}: normal.frame = {frame!r}; use 'opencv' (x right, y down, z forward) or 'opengl' "
                         f"(x right, y up, z backward).")
    if space not in (None, "linear", "srgb"):
        raise PriorError(f"{p}: albedo.space = {space!r}; use 'linear' or 'srgb'.")
    return {"depth": depth, "normal": frame, "albedo": space, "record": record}


def _read_image(p: Path) -> np.ndarray:
    """An 8/16-bit image as floats in [0, 1] ([H,W] or [H,W,C])."""
    from PIL import Image

    try:
        with Image.open(p) as im:
            im.load()
            a = np.asarray(im)
    except (OSError, SyntaxError, ValueError) as e:
        raise PriorError(f"{p}: cannot decode ({e}); write the prior again.") from None
    if a.dtype == np.uint8:
        return a.astype(np.float32) / 255.0
    if a.dtype in (np.uint16, np.int32) or a.dtype.kind in "iu":
        return a.astype(np.float32) / 65535.0
    return a.astype(np.float32)


def _read_exr(p: Path, kind: str) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(str(p), separate_channels=True) as f:
        ch = {k: np.array(v.pixels) for k, v in f.channels().items()}
    names = {"depth": (("Z",), ("Y",), ("R",)), "glass": (("T",), ("Y",), ("R",)),
             "normal": (("N.X", "N.Y", "N.Z"), ("X", "Y", "Z"), ("R", "G", "B")), "albedo": (("R", "G", "B"),)}[kind]
    found = next((n for n in names if all(c in ch for c in n)), None)
    if found is None:
        raise PriorError(f"{p}: channels {sorted(ch)}; a {kind} prior needs one of {list(names)}.")
    return ch[found[0]] if kind == "depth" else np.stack([ch[c] for c in found], -1)


def prior_file(root: Path, view, kind: str) -> Path | None:
    folder = Path(root) / "priors" / kind
    for ext in EXTS:
        p = folder / f"{view.name}{ext}"
        if p.exists():
            return p
    return None


def load_prior(root: Path, view, kind: str, conventions: dict | None = None) -> np.ndarray | None:
    """The ``kind`` prior of ``view`` at the view's resolution in glint_mi's conventions, or None when absent:
    depth [H,W] (as the file's type says: depth or disparity; 0 = invalid), normal [H,W,3] unit vectors in OpenCV
    camera axes facing the camera (0 = invalid), albedo [H,W,3] linear RGB, glass [H,W] in [0, 1]."""
    if kind not in KINDS:
        raise PriorError(f"unknown prior kind '{kind}'; use one of {KINDS}.")
    p = prior_file(root, view, kind)
    if p is None:
        return None
    conv = conventions or prior_conventions(root)
    encoded = p.suffix.lower() in (".png", ".tif", ".tiff")
    try:
        arr = np.load(p, allow_pickle=False) if p.suffix == ".npy" else (
            _read_exr(p, kind) if p.suffix == ".exr" else _read_image(p))
        arr = np.asarray(arr, np.float32)
    except PriorError:
        raise
    except Exception as e:  # numpy and OpenEXR raise ValueError, OSError, EOFError, RuntimeError... on a broken file
        why = str(e).splitlines()[0] if str(e) else "truncated?"
        raise PriorError(f"{p}: cannot read the {kind} prior ({type(e).__name__}: {why}); write it again (a float "
                         f"array: .npy / .exr / .png / .tif).") from None
    if arr.ndim not in (2, 3):
        raise PriorError(f"{p}: shape {arr.shape}; a {kind} prior is an [H, W] or [H, W, C] map.")
    if kind in ("depth", "glass") and arr.ndim == 3:
        arr = arr[..., 0]
    if kind not in ("depth", "glass"):
        if arr.ndim != 3 or arr.shape[-1] < 3:
            raise PriorError(f"{p}: shape {arr.shape}; a {kind} prior needs 3 channels.")
        arr = arr[..., :3]
        if kind == "normal" and encoded:  # [0, 1]-encoded
            arr = np.where(np.any(arr > 0, axis=-1, keepdims=True), arr * 2 - 1, 0.0)
        if kind == "albedo" and (conv["albedo"] == "srgb" or (conv["albedo"] is None and encoded)):
            arr = np.where(arr <= 0.04045, arr / 12.92, ((arr + 0.055) / 1.055) ** 2.4)
    if not np.isfinite(arr).all():
        raise PriorError(f"{p}: contains NaN/Inf; mark invalid pixels with 0 instead.")
    try:
        arr = fit_to(arr, view.height, view.width, getattr(view, "downscale", 1), str(p))
    except DatasetError as e:
        raise PriorError(str(e)) from None
    if kind == "normal":
        if conv["normal"] == "opengl":
            arr = arr * np.array([1.0, -1.0, -1.0], np.float32)
        n = np.linalg.norm(arr, axis=-1, keepdims=True)
        arr = np.where(n > 0.5, arr / np.maximum(n, 1e-12), 0.0).astype(np.float32)
    return np.asarray(arr, np.float32)


def check_priors(root: Path, views) -> list[str]:
    """Every problem of ``root``'s priors for ``views`` (the training views), one line each: PRIORS.json's keys and
    conventions, each file's decoding, channels, size and finiteness, and a kind present for some views only. Empty
    when they can be trained on; reads every map once."""
    try:
        conv = prior_conventions(root)
    except PriorError as e:
        return [str(e)]
    problems = []
    for kind in KINDS:
        lack = []
        for v in views:
            try:
                if load_prior(root, v, kind, conv) is None:
                    lack.append(v.name)
            except PriorError as e:
                problems.append(str(e))
        if lack and len(lack) < len(views):
            problems.append(partial_kind(root, kind, lack, len(views)))
    return problems


def partial_kind(root, kind: str, lack: list[str], n_views: int) -> str:
    """The message for a prior kind that some training views (``lack``) do not have."""
    return (f"{Path(root)}/priors/{kind}: {len(lack)} of {n_views} training views have no {kind} map "
            f"({', '.join(lack[:8])}{', ...' if len(lack) > 8 else ''}); write one for every training view, or "
            f"remove the folder (or train with --set priors=none).")


def priors_are_derived(root: Path) -> bool:
    """True when the dataset's priors were derived from ground truth (results must say so)."""
    return bool(prior_conventions(root)["record"].get("derived_from_ground_truth"))
