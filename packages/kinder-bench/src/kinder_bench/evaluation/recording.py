"""Writing episode videos (GIF, or MP4 when an ffmpeg backend for imageio is installed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

VIDEO_FORMATS = ("gif", "mp4")


def write_video(path: Path | str, frames: Sequence[NDArray[np.uint8]], fps: int = 20) -> Path:
    """Write RGB frames to ``path``; the format follows the suffix (``.gif`` or ``.mp4``)."""
    import imageio.v2 as imageio  # imported here: only recording runs need it

    path = Path(path)
    if not frames:
        raise ValueError(f"No frames to write to {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix.lower().lstrip(".")
    if suffix == "gif":
        _write_gif(path, frames, fps)
    elif suffix == "mp4":
        try:
            imageio.mimsave(path, list(frames), fps=fps, macro_block_size=1)
        except (ImportError, ValueError, RuntimeError) as e:
            raise RuntimeError(
                f"Writing {path} needs an ffmpeg backend for imageio: `pip install imageio-ffmpeg` "
                f"(or record GIFs) ({e})"
            ) from e
    else:
        raise ValueError(f"Unknown video format {suffix!r} for {path}; expected {VIDEO_FORMATS}")
    return path


def _write_gif(path: Path, frames: Sequence[NDArray[np.uint8]], fps: int) -> None:
    # One palette for the whole episode (from a few spread-out frames) and no dithering: an
    # order of magnitude faster than a palette per frame, and renders use few colours anyway.
    from PIL import Image

    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    picks = sorted({round(i * (len(images) - 1) / 3) for i in range(4)})
    sample = np.concatenate([np.asarray(images[i])[::2, ::2] for i in picks], axis=0)
    palette = Image.fromarray(sample).quantize(colors=255, method=Image.Quantize.FASTOCTREE)
    quantized = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    quantized[0].save(
        path,
        save_all=True,
        append_images=quantized[1:],
        duration=round(1000 / fps),
        loop=0,
        optimize=False,
    )
