"""An episode as an animated GIF (``ffsr-gym render``), written atomically."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError


def check_gif_path(out: str | Path) -> Path:
    """``out`` as a writable ``.gif`` path, checked before the episode runs.

    Raises:
        InvalidInputError: another suffix, a folder in the way, or a parent that cannot be written.
    """
    out = Path(out)
    if out.suffix.lower() != ".gif":
        raise InvalidInputError(f"--out {str(out)!r}; allowed: a .gif file")
    if out.is_dir():
        raise InvalidInputError(f"--out {str(out)!r} is a folder; allowed: a .gif file")
    existing = out.parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise InvalidInputError(f"--out {str(out)!r}: {str(existing)!r} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InvalidInputError(f"--out {str(out)!r}: {str(existing)!r} is not writable")
    return out


#: A GIF frame's delay is stored in hundredths of a second, in 16 bits.
GIF_DELAY_MS = (10.0, 655_350.0)


def frame_interval_ms(every: int, decision_s: float, speed: float) -> float:
    """The delay between frames [ms] of one frame every ``every`` decisions of ``decision_s`` [s] played ``speed``
    times faster than real time, checked before the episode runs.

    Raises:
        InvalidInputError: a delay a GIF cannot store (naming the options and the range).
    """
    interval = 1000.0 * every * decision_s / speed
    low, high = GIF_DELAY_MS
    if not low <= interval <= high:
        raise InvalidInputError(f"--every {every} and --speed {speed:g} give frames {interval:.3g} ms apart; allowed: "
                                f"{low:g} to {high:g} ms (a GIF's frame delay)")
    return interval


def record_episode(env: Any, step: Callable[[Any], tuple], *, seed: int, every: int,
                   options: dict | None = None) -> tuple[list, int, dict]:
    """Frames of one episode (the first, every ``every``-th decision and the last), decisions taken, last info."""
    obs, _ = env.reset(seed=seed, options=options)
    frames, decisions, done, info = [env.render()], 0, False, {}
    while not done:
        obs, _, terminated, truncated, info = step(obs)
        decisions, done = decisions + 1, terminated or truncated
        if decisions % every == 0 or done:
            frames.append(env.render())
    return frames, decisions, info


def write_gif(frames: list, out: Path, interval_ms: float) -> None:
    """Write ``frames`` (H, W, 3 arrays) as a looping GIF through a temporary file and an atomic rename."""
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.{os.getpid()}.", suffix=".tmp")
    os.close(fd)
    try:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(interval_ms), loop=0)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
