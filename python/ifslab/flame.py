"""Fractal flames: ``.flame`` files rendered by flam3's algorithm, and colour flames learned
from a picture (``ifslab flame render`` and ``ifslab flame learn``)."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _ifslab
from ._progress import reporting
from ._runs import PathLike, Result, _Inputs, _merge, run

__all__ = ["learn", "render", "render_with_stats"]


def render_with_stats(
    flame: Union[str, "os.PathLike[str]"],
    *,
    name: Optional[str] = None,
    index: int = 0,
    size: Optional[Sequence[int]] = None,
    quality: Optional[float] = None,
    supersample: Optional[int] = None,
    seed: int = 0,
    transparent: bool = False,
    progress: Any = None,
) -> Tuple[np.ndarray, Dict[str, Any]]:
    """:func:`render`, and the render's statistics (samples, hits, bad values, seconds)."""
    source = os.fspath(flame)
    is_text = "<flame" in source
    with reporting(progress) as callback:
        image, stats = _ifslab.flame_render(
            source,
            is_text,
            name,
            int(index),
            None if size is None else [int(size[0]), int(size[1])],
            None if quality is None else float(quality),
            None if supersample is None else int(supersample),
            int(seed),
            bool(transparent),
            callback,
        )
    return image, json.loads(stats)


def render(flame: Union[str, "os.PathLike[str]"], **options: Any) -> np.ndarray:
    """Renders a flame — a ``.flame`` file (flam3, Apophysis, JWildfire) or its XML text —
    as ``ifslab flame render`` does: float32 ``(height, width, 4)`` on the library's
    scale — RGB in [0, 255], alpha in [0, 1]; the 8-bit PNG the command line writes is
    ``image[..., :3].astype(np.uint8)``. The
    flame's own size, quality and supersampling unless ``size=(width, height)``,
    ``quality`` or ``supersample`` say otherwise (the scale follows the height, as with
    ``--size``); ``name`` or ``index`` picks one flame of a file holding several;
    ``transparent`` keeps alpha instead of compositing onto the background."""
    return render_with_stats(flame, **options)[0]


def learn(
    image: Any,
    output: Optional[PathLike] = None,
    *,
    progress: Any = None,
    **config: Any,
) -> Result:
    """Learns a colour fractal flame from a picture (an ``(H, W, 3)`` array, a grey one, or
    a picture file), as ``ifslab flame learn`` does; the keys are a flame config's
    (``iterations=150``, ``paper=True``, ``flames=[{"xforms": 8, "variations":
    ["linear"]}]``, ``sampler={"size": 100}``, …). The learned flame is
    ``result.file("learned.flame")`` (it renders with :func:`render` and in flam3)."""
    with _Inputs() as inputs:
        table = _merge({"problem": "flame", "target": inputs.picture(image)}, config)
        return run(table, output, progress=progress)
