"""The differentiable splat from NumPy: affine maps (or θ) → image, and the
vector–Jacobian product of that image back to the maps (or θ).

A map is a row ``[a, b, c, d, e, f]``: ``x ↦ [[a, b], [c, d]]·x + [e, f]``; ``maps`` is
``(n, 6)``. θ is a parameterisation's flat vector (``param="svd"``, the image problem's
default; ``"naive"`` is the six numbers; ``"rsr"`` Learning Fractals' maps).

>>> image, tape = forward(maps, size=64, supersample=2, sigma=1.0, trajectories=200, length=60)
>>> grad_maps = vjp(tape, np.ones_like(image))      # ∂(Σ image)/∂maps, (n, 6)

The chaos game of a call is stream ``draw`` of ``seed`` (as a run's iteration ``draw``
does), fixed for the forward call and its reverse pass, so ``vjp`` is the exact derivative
of that call's image — which is what a finite-difference check at a fixed seed sees.
"""

from __future__ import annotations

import json
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _ifslab

__all__ = ["decode", "defaults", "encode", "forward", "vjp", "Tape"]

Tape = _ifslab.SplatForward


def defaults() -> Dict[str, Any]:
    """The splat's default settings (the paper's: 256², 2000 × 250 points, 5× supersampling,
    σ 2.5, coverage blending, fitted framing) as the nested dict :func:`forward` merges
    its keywords into."""
    return json.loads(_ifslab.splat_defaults())


def _settings(
    size: Union[int, Tuple[int, int], None],
    supersample: Optional[int],
    sigma: Optional[float],
    trajectories: Optional[int],
    length: Optional[int],
    warmup: Optional[int],
    blend: Optional[str],
    window: Optional[Sequence[float]],
    fill: Optional[float],
    extra: Dict[str, Any],
) -> str:
    cfg = defaults()
    if size is not None:
        width, height = (size, size) if isinstance(size, (int, np.integer)) else size
        cfg["width"], cfg["height"] = int(width), int(height)
    if supersample is not None:
        cfg["supersample"] = int(supersample)
    if sigma is not None:
        cfg["sigma"] = float(sigma)
    if blend is not None:
        cfg["blend"] = blend
    for key, value in (("trajectories", trajectories), ("length", length), ("warmup", warmup)):
        if value is not None:
            cfg["game"][key] = int(value)
    if window is not None:
        x0, y0, x1, y1 = (float(v) for v in window)
        cfg["framing"] = {"window": {"min": [x0, y0], "max": [x1, y1]}}
    elif fill is not None:
        cfg["framing"] = {"fit": {"fill": float(fill)}}
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(cfg.get(key), dict):
            cfg[key].update(value)
        else:
            cfg[key] = value
    return json.dumps(cfg)


def forward(
    maps: Optional[np.ndarray] = None,
    *,
    theta: Optional[np.ndarray] = None,
    param: str = "svd",
    size: Union[int, Tuple[int, int], None] = None,
    supersample: Optional[int] = None,
    sigma: Optional[float] = None,
    trajectories: Optional[int] = None,
    length: Optional[int] = None,
    warmup: Optional[int] = None,
    blend: Optional[str] = None,
    window: Optional[Sequence[float]] = None,
    fill: Optional[float] = None,
    probabilities: Optional[Sequence[float]] = None,
    seed: int = 0,
    draw: int = 0,
    **settings: Any,
) -> Tuple[np.ndarray, "Tape"]:
    """Splats ``maps`` ``(n, 6)`` — or ``theta`` of ``param`` — into a grey float64 image
    ``(height, width)``; returns it with the tape :func:`vjp` needs.

    Settings left out keep :func:`defaults`: ``size`` (side or ``(width, height)``),
    ``supersample``, ``sigma`` (in supersampled pixels), ``trajectories``, ``length``,
    ``warmup``, ``blend`` (``"coverage"`` or ``"additive"``), ``window=(x0, y0, x1, y1)``
    (a fixed window instead of framing the points, ``fill`` of the frame). Map ``i`` is
    drawn with ``probabilities[i]`` (uniform by default; not differentiated).
    """
    image, tape = _ifslab.splat_forward(
        _settings(size, supersample, sigma, trajectories, length, warmup, blend, window, fill, settings),
        None if maps is None else np.ascontiguousarray(np.atleast_2d(maps), dtype=np.float64),
        None if theta is None else np.ascontiguousarray(theta, dtype=np.float64).reshape(-1),
        param,
        None if probabilities is None else [float(p) for p in probabilities],
        int(seed),
        int(draw),
    )
    return image, tape


def vjp(tape: "Tape", grad_image: np.ndarray) -> np.ndarray:
    """The vector–Jacobian product of the forward call that made ``tape``: given
    ``∂L/∂image`` ``(height, width)``, returns ``∂L/∂maps`` ``(n, 6)`` — or ``∂L/∂θ`` when
    that call took ``theta``."""
    return _ifslab.splat_backward(tape, np.ascontiguousarray(grad_image, dtype=np.float64))


def encode(maps: np.ndarray, param: str = "svd") -> np.ndarray:
    """θ of ``param`` that decodes to ``maps`` ``(n, 6)``."""
    return _ifslab.encode_maps(np.ascontiguousarray(np.atleast_2d(maps), dtype=np.float64), param)


def decode(theta: np.ndarray, param: str = "svd") -> np.ndarray:
    """The maps ``(n, 6)`` θ of ``param`` decodes to."""
    return _ifslab.decode_theta(np.ascontiguousarray(theta, dtype=np.float64).reshape(-1), param)
