"""MP4 files that browsers and GitHub play: H.264 (yuv420p) through PyAV, whose wheels carry FFmpeg with libx264.

OpenCV's VideoWriter offers only MPEG-4 Part 2 (`mp4v`) in its pip wheels, which browsers do not play; it is the
fallback when PyAV or its H.264 encoder is missing, and the writer says which codec it used (`codec`).
"""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

import numpy as np

from hvs_sim import outputs
from hvs_sim.errors import OutputError

log = logging.getLogger(__name__)
H264_CRF = 18  # x264 constant quality: near-lossless for rendered frames (mean error < 4 levels, tests)
H264_PRESET = "veryfast"  # encoding cost ~1–2 ms a 640×480 frame here


class Mp4Writer:
    """Frames (H×W×3 uint8 RGB) appended one at a time to an H.264 MP4 (or mp4v when H.264 is not available). Odd
    sizes are padded by one pixel of the last row/column (yuv420p needs even sizes)."""

    def __init__(self, path, fps: float, size: tuple[int, int], shown=None):
        self.path, self.size, self.frames = Path(path), (int(size[0]), int(size[1])), 0
        self.shown = Path(shown or path)  # the name an error gives: the final file, not its temporary
        self._av = self._cv = None
        try:
            import av

            self._av = av.open(str(self.path), mode="w")
            stream = self._av.add_stream("libx264", rate=_rate(fps))
            stream.width, stream.height = (self.size[0] + 1) // 2 * 2, (self.size[1] + 1) // 2 * 2
            stream.pix_fmt = "yuv420p"
            stream.options = {"crf": str(H264_CRF), "preset": H264_PRESET}
            self._stream = stream
            self.codec = "h264"
        except Exception as exc:  # noqa: BLE001 - no PyAV, or no libx264 in it: OpenCV's mp4v instead
            if self._av is not None:
                self._av.close()
            self._av = None
            import cv2

            self._cv = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"), fps, self.size)
            if not self._cv.isOpened():
                raise OutputError(f"cannot open a video writer at {self.path} (disk full or folder not writable?)") \
                    from None
            self.codec = "mp4v"
            log.warning("H.264 not available (%s): writing %s as mp4v, which browsers do not play", exc, self.path)

    def write(self, rgb: np.ndarray) -> None:
        """One frame; a full disk is an OutputError before FFmpeg is handed a chunk it cannot write (it may crash)."""
        with self._named_failures():
            outputs.ensure_space(self.path, rgb.nbytes)
            self._write(rgb)

    def _write(self, rgb: np.ndarray) -> None:
        if self._av is not None:
            import av

            h, w = self._stream.height, self._stream.width
            if rgb.shape[0] != h or rgb.shape[1] != w:
                rgb = np.pad(rgb, ((0, h - rgb.shape[0]), (0, w - rgb.shape[1]), (0, 0)), mode="edge")
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
            for packet in self._stream.encode(frame):
                self._av.mux(packet)
        else:
            import cv2

            self._cv.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        self.frames += 1

    def close(self) -> None:
        with self._named_failures():
            self._close()

    @contextlib.contextmanager
    def _named_failures(self):
        """A write the disk or FFmpeg could not finish, as an OutputError naming the video; other errors go on."""
        try:
            yield
        except OSError as exc:
            raise outputs.output_error(self.shown, exc) from None
        except Exception as exc:
            if _ffmpeg_error(exc):
                raise outputs.output_error(self.shown, exc) from None
            raise

    def _close(self) -> None:
        if self._av is not None:
            for packet in self._stream.encode():  # flush the encoder's delayed frames
                self._av.mux(packet)
            self._av.close()
            self._av = None
        elif self._cv is not None:
            self._cv.release()
            self._cv = None


def _ffmpeg_error(exc: BaseException) -> bool:
    """A failure of FFmpeg inside PyAV (a write it could not finish), as opposed to a bug in the caller."""
    try:
        import av
    except ImportError:
        return False
    return isinstance(exc, av.error.FFmpegError)


def _rate(fps: float):
    """The stream's frame rate as a fraction (PyAV wants one)."""
    from fractions import Fraction

    return Fraction(fps).limit_denominator(1001)
