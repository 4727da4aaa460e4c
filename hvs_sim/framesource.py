"""Footage as frames: a video file OpenCV can read, or a folder of images, as one stream of RGB frames.

Apart from `video.py` (tracking footage and writing its outputs) because reading frames is what the footage benchmark
(`bench/footage.py`) needs too, without the tracking run's outputs.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.errors import ConfigError, InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
FOLDER_FPS = 30.0  # frame rate of the annotated video when the source is a folder (or a video without one)


@dataclass
class FrameSource:
    """A stream of RGB frames: the first is read up front (to check the ROI), the rest on demand."""

    path: Path
    first: np.ndarray
    rest: Iterator[np.ndarray]
    fps: float
    count: int | None  # frames in all, when known (for the progress bar)
    start: int = 0  # the clip's number of `first` (--start)

    def close(self) -> None:
        self.rest.close()  # runs the generator's finally: releases a VideoCapture

    @property
    def size(self) -> tuple[int, int]:
        return self.first.shape[1], self.first.shape[0]


def open_frames(path, start: int = 0, end: int | None = None) -> FrameSource:
    """The frames start..end-1 of a video file or a folder of images (end None: to the clip's end)."""
    path = Path(path)
    if start < 0 or (end is not None and end <= start):
        raise ConfigError(f"--start {start} --end {end}: the range is frames start..end-1, so give 0 <= start < end")
    source = _open_any(path)
    return source if start == 0 and end is None else _frame_range(source, start, end)


def _frame_range(source: FrameSource, start: int, end: int | None) -> FrameSource:
    """The frames start..end-1 of `source` (the skipped ones are read, as a video can only be read in order)."""
    import itertools

    frames = itertools.chain([source.first], source.rest)
    try:
        for _ in range(start):
            next(frames)
        first = next(frames)
    except StopIteration:
        source.close()
        raise InputError(f"--start {start} is past the end of {source.path}: it has "
                         f"{source.count if source.count is not None else 'fewer'} frames (numbered from 0)") from None

    def rest() -> Iterator[np.ndarray]:
        try:
            yield from itertools.islice(frames, None if end is None else end - start - 1)
        finally:
            source.close()

    count = None if source.count is None else max(0, min(source.count, end or source.count) - start)
    return FrameSource(source.path, first, rest(), source.fps, count, start)


def _open_any(path: Path) -> FrameSource:
    if not path.exists():
        raise InputError(f"{path} does not exist; give a video file OpenCV can read or a folder of images "
                         f"({' '.join(IMAGE_SUFFIXES)})")
    if path.is_dir():
        return _open_folder(path)
    if not path.is_file():  # a FIFO or a device would block or never end
        raise InputError(f"{path} is not a regular file or a folder; give a video file or a folder of images")
    return _open_video(path)


def _open_folder(folder: Path) -> FrameSource:
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError(f"folder {folder} has no images; accepted: {' '.join(IMAGE_SUFFIXES)} files, "
                         f"read in file-name order")
    first = _read_image(files[0])
    return FrameSource(folder, first, _folder_frames(files[1:], first.shape), FOLDER_FPS, len(files))


def _read_image(path: Path, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """A frame of a folder, read as scene.images.read_rgb reads images (size from the header, EXIF, 16 bit, alpha)."""
    from hvs_sim.scene.images import read_rgb

    rgb = read_rgb(path, "image")
    if shape is not None and rgb.shape != shape:
        raise InputError(f"image {path} is {rgb.shape[1]}×{rgb.shape[0]} but the first image is "
                         f"{shape[1]}×{shape[0]}; every image in the folder must have the same size")
    return rgb


def _folder_frames(files: list[Path], shape: tuple[int, ...]) -> Iterator[np.ndarray]:
    for path in files:
        yield _read_image(path, shape)


def _open_video(path: Path) -> FrameSource:
    cap = cv2.VideoCapture(str(path))
    ok, bgr = cap.read() if cap.isOpened() else (False, None)
    if not ok:
        cap.release()
        raise InputError(f"cannot read a video frame from {path}; accepted: a video file OpenCV can decode "
                         f"(e.g. .mp4, .avi, .mov) or a folder of images ({' '.join(IMAGE_SUFFIXES)})")
    fps = cap.get(cv2.CAP_PROP_FPS)
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    return FrameSource(path, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), _video_frames(cap),
                       fps if np.isfinite(fps) and fps > 0 else FOLDER_FPS, count if count > 0 else None)


def _video_frames(cap: cv2.VideoCapture) -> Iterator[np.ndarray]:
    try:
        while True:
            ok, bgr = cap.read()
            if not ok:
                return
            yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()
