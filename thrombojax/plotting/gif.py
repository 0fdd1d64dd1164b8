"""Animated GIFs of a figure whose frames change only a few artists.

Matplotlib's ``Animation.save`` redraws the whole figure for every frame, whatever ``blit``
says. In a rollout's 3-D panels most of that work never changes: the axes, their tick labels,
panes and grid, the vessel wall, the legend and the colour bars (text layout alone was about
a third of a frame). :func:`render_frames` draws those once, keeps the picture, and per frame
restores it and draws only the artists that change (the clot scatters, the titles), on top, in
the order given. The frames equal full redraws wherever the changing artists are drawn last in
a full redraw too (3-D axes with ``computed_zorder = False`` and the changing artists added
after the static ones, as :func:`thrombojax.eval.plots.rollout_figure` builds them);
``tests/test_viz.py`` compares them pixel by pixel. The frames and :func:`write_gif` follow
matplotlib's ``PillowWriter`` (opaque frames as RGB, ``duration = 1000 / fps`` ms, looping),
so the GIF is the one it wrote, byte for byte on the rollout figures tried.
"""

from __future__ import annotations

import pathlib
from collections.abc import Callable, Sequence

__all__ = ["render_frames", "write_gif"]


def render_frames(fig, update: Callable[[int], object], n_frames: int,
                  changing: Sequence) -> list:
    """Every frame of ``fig`` as a PIL image (``RGB``, or ``RGBA`` where it is transparent).

    Args:
        fig: a figure on the Agg canvas.
        update: ``update(t)`` sets the figure to frame ``t``.
        n_frames: how many frames.
        changing: every artist ``update`` changes (the others must stay as they are); they are
            drawn in this order, after the rest.
    """
    from PIL import Image

    canvas = fig.canvas
    previous = [a.get_animated() for a in changing]
    for artist in changing:
        artist.set_animated(True)  # left out of canvas.draw()
    try:
        update(0)
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        renderer = canvas.get_renderer()
        size = canvas.get_width_height()
        frames = []
        for t in range(n_frames):
            update(t)
            canvas.restore_region(background)
            for artist in changing:
                if hasattr(artist, "do_3d_projection"):  # a 3-D collection: project the frame
                    artist.do_3d_projection()
                artist.draw(renderer)
            pixels = bytes(canvas.buffer_rgba())  # one copy: the canvas is drawn over next
            image = Image.frombuffer("RGBA", size, pixels, "raw", "RGBA", 0, 1)
            # as PillowWriter: an opaque frame as RGB (it converts to a GIF palette better)
            frames.append(image if image.getextrema()[3][0] < 255 else image.convert("RGB"))
        return frames
    finally:
        for artist, was in zip(changing, previous, strict=True):
            artist.set_animated(was)


def write_gif(frames: Sequence, path: str | pathlib.Path, fps: int) -> pathlib.Path:
    """Write PIL ``frames`` to ``path`` as a looping GIF at ``fps`` frames per second."""
    if not frames:
        raise ValueError(f"{path}: no frames to write")
    path = pathlib.Path(path)
    frames[0].save(path, format="GIF", save_all=True, append_images=list(frames[1:]),
                   duration=int(1000 / fps), loop=0)
    return path
