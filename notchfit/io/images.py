"""Image files: read one, or summarise it, with the reason when it cannot be used; write one.

Every problem is an :class:`~notchfit.io.errors.InputFileError` naming the
file: a missing file, a folder, no permission, zero bytes, a truncated or
corrupt file, a format OpenCV does not decode, or dimensions above
:data:`MAX_IMAGE_PIXELS` (checked from the PNG or JPEG header before
decoding, so a forged header cannot exhaust the memory). OpenCV's own log
lines are silenced while decoding: the error message is the one line.

A photograph's EXIF orientation tag (a phone or a DSLR held upright) is
applied on load, so the pixels are those a photo viewer shows: ``base =
"top"`` in experiment.toml and every pixel coordinate written refer to
the picture as it is seen, not to the sensor's rows. :func:`image_orientation`
says what was done (the detect log and ``detect_run.json`` report it).
"""

from __future__ import annotations

import io as _io
import struct
from pathlib import Path

import cv2
import numpy as np
from PIL import Image, UnidentifiedImageError

from .errors import InputFileError, InputFileNotFoundError, read_input_bytes
from .outputs import atomic_write

__all__ = ["EXIF_ORIENTATIONS", "MAX_IMAGE_PIXELS", "exif_orientation", "image_info", "image_orientation",
           "load_image", "orient", "write_image"]

#: Largest image accepted [pixels] (100 Mpx: above any camera of a bench set-up).
MAX_IMAGE_PIXELS = 100_000_000


def _header_size(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG or JPEG header, None for other formats or a damaged header."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24 and data[12:16] == b"IHDR":
        return struct.unpack(">II", data[16:24])
    if data[:2] == b"\xff\xd8":
        i = 2
        while i + 9 <= len(data) and data[i] == 0xFF:
            marker, length = data[i + 1], struct.unpack(">H", data[i + 2:i + 4])[0]
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                h, w = struct.unpack(">HH", data[i + 5:i + 9])
                return w, h
            i += 2 + length
    return None


#: What each EXIF orientation tag value (TIFF tag 0x0112) asks a viewer to do to the stored pixels.
EXIF_ORIENTATIONS = {1: "", 2: "mirrored left-right", 3: "turned 180 degrees", 4: "mirrored top-bottom",
                     5: "transposed", 6: "turned 90 degrees clockwise", 7: "transversed",
                     8: "turned 90 degrees anticlockwise"}
_EXIF_ORIENTATION_TAG = 0x0112


def exif_orientation(data: bytes) -> int:
    """The EXIF orientation tag (1..8) of an encoded image, 1 when it has none or it cannot be read.

    Read by Pillow from the file's header (the pixels are not decoded).
    """
    try:
        with Image.open(_io.BytesIO(data)) as im:
            value = im.getexif().get(_EXIF_ORIENTATION_TAG, 1)
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, struct.error, Image.DecompressionBombError,
            KeyError, IndexError, TypeError):
        return 1                          # a damaged or unknown header: no tag (the decoder says the rest)
    return int(value) if value in EXIF_ORIENTATIONS else 1


def orient(image: np.ndarray, orientation: int) -> np.ndarray:
    """Stored pixels -> the picture a viewer shows for an EXIF ``orientation`` (1..8), as Pillow's
    ``ImageOps.exif_transpose`` does it (a view of ``image``; 1 and unknown values: unchanged).

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C)
    orientation : int

    Returns
    -------
    ndarray (H, W, ...) or (W, H, ...) for 5..8
    """
    ops = {2: lambda a: a[:, ::-1], 3: lambda a: a[::-1, ::-1], 4: lambda a: a[::-1],
           5: lambda a: np.swapaxes(a, 0, 1), 6: lambda a: np.rot90(a, -1),
           7: lambda a: np.swapaxes(a, 0, 1)[::-1, ::-1], 8: lambda a: np.rot90(a, 1)}
    op = ops.get(int(orientation))
    return image if op is None else op(image)


def image_orientation(path) -> str:
    """What :func:`load_image` did to ``path`` for its EXIF orientation tag, in words (empty: nothing)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 17)       # the EXIF block is at the start (at most 64 KiB in JPEG)
    except OSError:
        return ""
    return EXIF_ORIENTATIONS[exif_orientation(head)]


def _decode(path: Path, data: np.ndarray, flags: int) -> np.ndarray | None:
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        return cv2.imdecode(data, flags)
    except cv2.error as exc:
        text = str(exc).strip().splitlines()
        why = "too many pixels" if "MAX_IMAGE_PIXELS" in str(exc) else (text[-1] if text else "decode error")
        raise InputFileError(f"corrupt or unreadable image (OpenCV: {why}): {path}", path=path) from None
    finally:
        cv2.utils.logging.setLogLevel(level)


def load_image(path, flags=None) -> np.ndarray:
    """Read an image, raising with the reason when it cannot be used.

    Parameters
    ----------
    path : path
    flags : int, optional
        ``cv2.imdecode`` flags (default ``cv2.IMREAD_UNCHANGED``: gray stays
        2-D, colour is BGR, 16-bit stays 16-bit).

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C)
        Upright as a photo viewer shows it: an EXIF orientation tag is applied
        (:func:`orient`; :func:`image_orientation` says what was done).

    Raises
    ------
    InputFileNotFoundError
        ``image missing: <path>`` (also a ``FileNotFoundError``).
    InputFileError
        ``corrupt or unreadable image (...): <path>``: OpenCV cannot decode
        it, an empty file, a folder, no permission, too many pixels.
    """
    path = Path(path)
    try:
        raw = read_input_bytes(path, what="image")
    except InputFileNotFoundError:
        raise InputFileNotFoundError(f"image missing: {path}", path=path) from None
    if not raw:
        raise InputFileError(f"corrupt or unreadable image (empty file): {path}", path=path)
    size = _header_size(raw)
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise InputFileError(f"image too large ({size[0]} x {size[1]} pixels, at most {MAX_IMAGE_PIXELS:,} "
                             f"accepted): {path}", path=path)
    img = _decode(path, np.frombuffer(raw, dtype=np.uint8), cv2.IMREAD_UNCHANGED if flags is None else flags)
    if img is None or img.size == 0:
        raise InputFileError(f"corrupt or unreadable image (OpenCV cannot decode it): {path}", path=path)
    if img.shape[0] * img.shape[1] > MAX_IMAGE_PIXELS:
        raise InputFileError(f"image too large ({img.shape[1]} x {img.shape[0]} pixels): {path}", path=path)
    turn = exif_orientation(raw)
    return img if turn == 1 else np.ascontiguousarray(orient(img, turn))


def image_info(path) -> dict:
    """Shape, dtype and intensity range of an image (a cheap check of a batch of images).

    Returns
    -------
    dict
        ``path, height, width, channels, dtype, min, max``.
    """
    img = load_image(path)
    return {"path": str(path), "height": int(img.shape[0]), "width": int(img.shape[1]),
            "channels": int(img.shape[2]) if img.ndim == 3 else 1, "dtype": str(img.dtype),
            "min": float(img.min()), "max": float(img.max())}


#: PNG encoder settings: ``"noisy"`` for images whose low bits are sensor noise (photographs,
#: renders), where deflate's string matching finds nothing and Huffman coding alone is the smallest
#: and the fastest; ``"graphics"`` for drawings with flat areas. Measured in docs/history.md.
PNG_SETTINGS = {
    "noisy": (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY),
    "graphics": (cv2.IMWRITE_PNG_COMPRESSION, 6),
}


def write_image(path, image, *, png: str = "noisy", jpeg_quality: int = 85, make_folder: bool = True) -> Path:
    """Write an image atomically, the format chosen by the extension.

    Parameters
    ----------
    path : path
        ``.png`` (lossless: study images, anything measured again later) or
        ``.jpg``/``.jpeg`` (lossy: images only looked at, e.g. detection overlays).
    image : ndarray, shape (H, W) or (H, W, 3)
        uint8 or uint16 (PNG), uint8 (JPEG); colour is BGR.
    png : str
        ``"noisy"`` or ``"graphics"`` (:data:`PNG_SETTINGS`).
    jpeg_quality : int
        JPEG quality, 0-100.
    make_folder : bool
        Create the folder when absent (:func:`notchfit.io.atomic_write`).

    Returns
    -------
    Path
    """
    path = Path(path)
    data = encode_image(image, path.suffix, png=png, jpeg_quality=jpeg_quality, name=path)
    return atomic_write(path, lambda tmp: Path(tmp).write_bytes(data), make_folder=make_folder)


def encode_image(image, ext: str, *, png: str = "noisy", jpeg_quality: int = 85, name=None) -> bytes:
    """The bytes of an image file in the format of extension ``ext`` (what :func:`write_image` writes).

    A batch worker encodes its overlay here and hands the bytes to the
    process that writes the run's files (``notchfit detect``).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
    ext : str
        ``".png"``, ``".jpg"`` or ``".jpeg"``.
    png, jpeg_quality
        As for :func:`write_image`.
    name : path, optional
        The file the bytes are meant for, for the error messages.
    """
    ext = ext.lower()
    what = f"{name}: " if name is not None else ""
    if ext == ".png":
        params = list(PNG_SETTINGS[png])
    elif ext in (".jpg", ".jpeg"):
        params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
    else:
        raise ValueError(f"{what}write_image writes .png or .jpg, not {ext or 'no extension'}")
    ok, buf = cv2.imencode(ext, np.asarray(image), params)
    if not ok:
        raise OSError(f"could not encode {name or 'an image'} as {ext}")
    return buf.tobytes()
