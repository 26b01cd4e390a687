"""Writing frames as a movie: MP4 (H.264) through imageio-ffmpeg, GIF through Pillow.

imageio-ffmpeg ships its own ffmpeg binary in its wheel, so an MP4 needs nothing installed by
hand; frames are piped to it as raw RGB. Both writers write into a temporary file beside the
output and rename it onto the output only when the last frame is in: an interrupted or failed
render leaves the output path as it was (absent, or the old movie).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

__all__ = ["FORMATS", "FRAME_SIZE", "GIF_CENTISECOND", "movie_format", "write_movie"]

#: Output suffix -> format.
FORMATS = {".mp4": "mp4", ".gif": "gif"}
#: Frame size (width, height) per format. MP4 sides are multiples of 16 (H.264's macroblock) so
#: ffmpeg never rescales; a GIF is smaller because it is stored uncompressed-per-pixel palettes
#: (960x720 made a 3.5 MB GIF of 120 frames, 640x480 about 40% of it).
FRAME_SIZE = {"mp4": (960, 720), "gif": (640, 480)}
#: GIF stores each frame's delay in hundredths of a second: 24 fps (41.7 ms) plays at 40 ms.
GIF_CENTISECOND = 10.0
#: Colours of a GIF frame's palette: the figure's few line colours, text and antialiasing fit.
GIF_COLORS = 128


def movie_format(path: str | os.PathLike) -> str:
    """``"mp4"`` or ``"gif"`` from the suffix; ValueError naming the fix otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        shown = f"a {suffix} file" if suffix else "a name without a suffix"
        raise ValueError(f"{os.fspath(path)}: cannot write {shown}; give a .mp4 or .gif name, e.g. movie.mp4")
    return FORMATS[suffix]


@contextlib.contextmanager
def _atomic(target: Path) -> Iterator[Path]:
    """A temporary path beside ``target`` (same file system, so the rename is atomic), renamed onto
    ``target`` on success and removed on any failure, Ctrl-C included."""
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=target.suffix, dir=target.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        # mkstemp makes the file private (0600); a movie gets the permissions any new file would.
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o666 & ~umask)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def write_movie(frames: Iterable[np.ndarray], target: Path, fps: float, size: tuple[int, int]) -> None:
    """Write (height, width, 3) uint8 ``frames`` of ``size`` (width, height) to ``target`` at ``fps``."""
    kind = movie_format(target)
    with _atomic(Path(target)) as tmp:
        if kind == "mp4":
            _write_mp4(frames, tmp, fps, size)
        else:
            _write_gif(frames, tmp, fps)


def _write_mp4(frames: Iterable[np.ndarray], path: Path, fps: float, size: tuple[int, int]) -> None:
    import imageio_ffmpeg  # noqa: PLC0415 -- lazy: loads imageio_ffmpeg

    # yuv420p is what every player decodes; it needs even sides, and macro_block_size=16 would
    # silently rescale a size that is not a multiple of 16, so the drawer's sizes are (960x720).
    writer = imageio_ffmpeg.write_frames(str(path), size, fps=fps, codec="libx264", pix_fmt_in="rgb24",
                                         pix_fmt_out="yuv420p", quality=7, macro_block_size=16,
                                         ffmpeg_log_level="error")
    writer.send(None)  # start ffmpeg
    try:
        for frame in frames:
            writer.send(np.ascontiguousarray(frame, dtype=np.uint8))
    finally:
        writer.close()  # waits for ffmpeg to finish the file (or stops it on an error)


def _write_gif(frames: Iterable[np.ndarray], path: Path, fps: float) -> None:
    from PIL import Image  # noqa: PLC0415 -- lazy: loads PIL

    images = [Image.fromarray(frame).convert("P", palette=Image.Palette.ADAPTIVE, colors=GIF_COLORS)
              for frame in frames]
    if not images:
        raise ValueError("no frames to write")
    delay = max(GIF_CENTISECOND, round(1000.0 / fps / GIF_CENTISECOND) * GIF_CENTISECOND)
    # Pillow folds identical consecutive frames into one; the overlay's frame counter keeps every
    # frame distinct, so the GIF has exactly as many frames as the MP4.
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=delay, loop=0,
                   optimize=False)
