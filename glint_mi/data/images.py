"""Image files of a dataset: found whatever their extension, decoded with any format Pillow reads (errors name the
file), and reduced by an area filter (``downscale``)."""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from glint_mi.data.errors import DatasetError

# tried, in this order, when a camera file names an image without its extension (COLMAP and NeRF files do both)
COMMON_EXTS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".exr")


def image_extensions() -> set[str]:
    """Every extension Pillow can open (lower case, with the dot)."""
    from PIL import Image

    Image.init()
    return {e for e, fmt in Image.registered_extensions().items() if fmt in Image.OPEN}


def find_image(folder: Path, name: str) -> Path | None:
    """``folder / name`` if it exists, else ``name`` with a common image extension (either case), else None."""
    p = Path(folder) / name
    if p.is_file():
        return p
    for ext in COMMON_EXTS:
        for e in (ext, ext.upper()):
            q = p.with_name(p.name + e)
            if q.is_file():
                return q
    return None


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) from the file header."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            return im.size
    except (OSError, SyntaxError, ValueError) as e:
        raise DatasetError(f"{path}: not an image Pillow can read ({e}).") from None


def decode(path: Path) -> np.ndarray:
    """[H, W, 3] float32 sRGB in [0, 1] (8- and 16-bit files; an alpha channel is dropped)."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                a = np.asarray(im, np.float32) / (65535.0 if im.mode != "I" else float(max(np.asarray(im).max(), 1)))
                return np.repeat(a[..., None], 3, axis=-1)
            if im.mode in ("F",):
                a = np.asarray(im, np.float32)
                return np.repeat(np.clip(a, 0, 1)[..., None], 3, axis=-1)
            return np.asarray(im.convert("RGB"), np.float32) / 255.0
    except (OSError, SyntaxError, ValueError) as e:
        raise DatasetError(f"{path}: cannot decode the image ({e}): the file is truncated or corrupt; export it "
                           f"again, or leave its frame out of the camera file.") from None


def check_decodable(paths: list[Path], threads: int = 2) -> None:
    """Decode every image once (Pillow releases the GIL while decoding); one error lists every bad file."""
    def bad(p):
        try:
            decode(p)
            return None
        except DatasetError as e:
            return str(e)

    with ThreadPoolExecutor(max_workers=threads) as pool:
        errors = [e for e in pool.map(bad, paths) if e]
    if errors:
        more = f"\n  ... and {len(errors) - 20} more" if len(errors) > 20 else ""
        raise DatasetError(f"{len(errors)} image(s) cannot be decoded:\n  " + "\n  ".join(errors[:20]) + more)


def block_mean(a: np.ndarray, k: int) -> np.ndarray:
    """[H, W, ...] -> [H // k, W // k, ...] by averaging k x k blocks (an area filter, like a lower-resolution
    sensor); trailing rows and columns that do not fill a block are dropped."""
    if k == 1:
        return a
    h, w = a.shape[0] // k, a.shape[1] // k
    a = a[:h * k, :w * k]
    return a.reshape(h, k, w, k, *a.shape[2:]).mean(axis=(1, 3))


def fit_to(a: np.ndarray, height: int, width: int, k: int, what: str) -> np.ndarray:
    """A map at a view's resolution: ``a`` as it is when it has the view's size, block-averaged by ``k`` when it
    has the full (k x larger) size, else a DatasetError naming ``what`` (the file) and both sizes."""
    h, w = a.shape[:2]
    if (h, w) == (height, width):
        return a
    if k > 1 and (h // k, w // k) == (height, width):
        return block_mean(a, k)
    full = f" or {height * k}x{width * k} (full size)" if k > 1 else ""
    raise DatasetError(f"{what}: {h}x{w} (HxW) but its view is {height}x{width}{full}; the file and the camera "
                       f"do not match: resize the file or fix the camera.")
