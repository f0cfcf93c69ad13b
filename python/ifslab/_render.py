"""The evaluation renderer: a code to a NumPy image, at any zoom."""

from __future__ import annotations

import json
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _ifslab
from ._code import CodeLike, code_arg
from ._progress import reporting

Size = Union[int, Tuple[int, int]]


def _size(size: Size) -> Tuple[int, int]:
    if isinstance(size, (int, np.integer)):
        return int(size), int(size)
    width, height = size
    return int(width), int(height)


def render_with_stats(
    code: CodeLike,
    size: Size = 1024,
    *,
    zoom: Optional[float] = None,
    center: Optional[Sequence[float]] = None,
    points: int = 50_000_000,
    supersample: int = 1,
    density: bool = False,
    seed: int = 0,
    min_hits: int = 0,
    max_points: int = 0,
    time_limit: Optional[float] = None,
    plain_zoom: bool = False,
    allow_empty: bool = False,
    progress: Any = None,
) -> Tuple[np.ndarray, Dict[str, Any]]:
    """:func:`render`, and what the render did (its window, points generated and in the
    window, seconds) as a dict."""
    text, is_json = code_arg(code)
    width, height = _size(size)
    with reporting(progress) as callback:
        image, stats = _ifslab.render(
            text,
            is_json,
            width,
            height,
            int(points),
            int(supersample),
            bool(density),
            None if zoom is None else float(zoom),
            None if center is None else [float(center[0]), float(center[1])],
            int(seed),
            int(min_hits),
            int(max_points),
            None if time_limit is None else float(time_limit),
            bool(plain_zoom),
            bool(allow_empty),
            callback,
        )
    return image, json.loads(stats)


def render(code: CodeLike, size: Size = 1024, **options: Any) -> np.ndarray:
    """Renders ``code`` (a dict in the ``ifslab-code/1`` format, a ``.json`` file, a
    built-in name or a :class:`~ifslab.Result`) with the evaluation renderer, as
    ``ifslab render CODE --size SIZE`` draws it: float32 ``(height, width)`` in [0, 1],
    1 on the attractor, row 0 at the top. The defaults are the command line's (50 M points,
    binary coverage, seed 0); ``size`` is a side or ``(width, height)``.

    ``zoom`` (a factor of the fitted window) and ``center`` (``(x, y)`` in the code's
    coordinates) zoom in as ``--zoom`` and ``--center`` do: through the code's words
    (deep zoom, to about 2^43) unless ``plain_zoom``. Other options: ``points``,
    ``supersample`` (per side: 16 is the papers' ground truth), ``density`` (log density
    instead of coverage), ``seed``, ``min_hits``, ``max_points``, ``time_limit``,
    ``allow_empty`` (an image where no point landed instead of an error), ``progress``
    (a callable ``(event, value)``, or True for tqdm).

    The 8-bit PNG the command line writes is ``np.round(image * 255)``.
    """
    return render_with_stats(code, size, **options)[0]
