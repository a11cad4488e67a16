"""The sample photographs as the page loads them: a pyramid of halved copies cut into JPEG tiles.

A 16 MP photograph is never sent whole: the page draws the tiles of the
level that matches its zoom (level 0 is full resolution, each next level
half the size), so panning and zooming touch a few hundred kilopixels at a
time. Pyramids are built with OpenCV on first use and kept for the few most
recent images (:class:`PyramidCache`); the neighbours of the image being
looked at are built ahead in a background thread.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from .. import io

__all__ = ["Pyramid", "PyramidCache"]

#: Side of a tile [px].
TILE = 512
#: JPEG quality of tiles and thumbnails (looked at, never measured).
JPEG_QUALITY = 88


def _to8(img: np.ndarray) -> np.ndarray:
    """An 8-bit copy for display (16-bit and float images scaled to their range)."""
    if img.dtype == np.uint8:
        return img
    a = img.astype(np.float32)
    hi = float(np.nanmax(a)) if a.size else 1.0
    return np.clip(a * (255.0 / (hi if hi > 0 else 1.0)), 0, 255).astype(np.uint8)


class Pyramid:
    """Halved copies of one image down to a level whose longer side fits one tile.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C)
    tile : int
        Tile side [px].
    """

    def __init__(self, image: np.ndarray, *, tile: int = TILE, quality: int = JPEG_QUALITY):
        import cv2  # slow optional dependency (OpenCV), loaded when an image is first shown

        self._cv2 = cv2
        img = _to8(image)
        if img.ndim == 3 and img.shape[2] == 4:
            img = img[..., :3]
        self.tile, self.quality = int(tile), int(quality)
        self.levels = [img]
        while max(self.levels[-1].shape[:2]) > self.tile:
            h, w = self.levels[-1].shape[:2]
            self.levels.append(cv2.resize(self.levels[-1], ((w + 1) // 2, (h + 1) // 2),
                                          interpolation=cv2.INTER_AREA))
        self._tiles: dict = {}
        self._lock = threading.Lock()

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the full image [px]."""
        return int(self.levels[0].shape[1]), int(self.levels[0].shape[0])

    def info(self) -> dict:
        """What the page needs to ask for tiles."""
        return {"width": self.size[0], "height": self.size[1], "tile": self.tile,
                "levels": [[int(a.shape[1]), int(a.shape[0])] for a in self.levels]}

    def _jpeg(self, a: np.ndarray) -> bytes:
        ok, buf = self._cv2.imencode(".jpg", a, [self._cv2.IMWRITE_JPEG_QUALITY, self.quality])
        if not ok:
            raise ValueError("JPEG encoding failed")
        return buf.tobytes()

    def tile_jpeg(self, level: int, tx: int, ty: int) -> bytes:
        """Tile ``(tx, ty)`` of ``level`` as JPEG bytes (cached)."""
        key = (int(level), int(tx), int(ty))
        with self._lock:
            hit = self._tiles.get(key)
        if hit is not None:
            return hit
        if not 0 <= key[0] < len(self.levels):
            raise KeyError(f"no level {level}")
        a = self.levels[key[0]]
        t = self.tile
        part = a[key[2] * t:(key[2] + 1) * t, key[1] * t:(key[1] + 1) * t]
        if part.size == 0:
            raise KeyError(f"no tile {tx},{ty} at level {level}")
        data = self._jpeg(part)
        with self._lock:
            self._tiles[key] = data
        return data

    def thumbnail(self, side: int = 160) -> bytes:
        """The whole image, its longer side ``side`` px, as JPEG bytes."""
        a = next((lv for lv in self.levels if max(lv.shape[:2]) <= 2 * side), self.levels[-1])
        h, w = a.shape[:2]
        f = side / max(h, w)
        small = self._cv2.resize(a, (max(1, round(w * f)), max(1, round(h * f))),
                                 interpolation=self._cv2.INTER_AREA)
        return self._jpeg(small)


class PyramidCache:
    """The pyramids of the most recent ``capacity`` images, built once per path (thread safe).

    ``prefetch(paths)`` builds the given images' pyramids in one background
    thread, so that switching to the next sample finds it ready.
    """

    def __init__(self, capacity: int = 4):
        self.capacity = int(capacity)
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self._building: dict = {}
        self._thumbs: dict = {}

    def get(self, path) -> Pyramid:
        """The pyramid of the image at ``path`` (built here if no thread is building it)."""
        key = str(path)
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
            event = self._building.get(key)
            if event is None:
                event = self._building[key] = threading.Event()
                mine = True
            else:
                mine = False
        if not mine:
            event.wait()
            with self._lock:
                if key in self._items:
                    return self._items[key]
            return self.get(path)
        try:
            pyr = Pyramid(io.load_image(path))
            with self._lock:
                self._items[key] = pyr
                while len(self._items) > self.capacity:
                    self._items.popitem(last=False)
            return pyr
        finally:
            with self._lock:
                self._building.pop(key, None)
            event.set()

    def thumbnail(self, path) -> bytes:
        """The thumbnail of the image at ``path`` (kept for every image: a few kB each)."""
        key = str(path)
        with self._lock:
            hit = self._thumbs.get(key)
        if hit is None:
            with self._lock:
                cached = self._items.get(key)
            if cached is None:
                import cv2  # slow optional dependency (OpenCV)
                # a reduced decode: a JPEG is decoded at a quarter of its size, far faster
                cached = Pyramid(io.load_image(path, cv2.IMREAD_REDUCED_COLOR_4))
            hit = cached.thumbnail()
            with self._lock:
                self._thumbs[key] = hit
        return hit

    def prefetch(self, paths) -> None:
        """Build the pyramids of ``paths`` in a background (daemon) thread; errors are left for ``get``."""
        todo = [p for p in paths if p is not None]

        def work():
            for p in todo:
                try:
                    self.get(p)
                except (OSError, ValueError):
                    pass

        if todo:
            threading.Thread(target=work, name="review-prefetch", daemon=True).start()
