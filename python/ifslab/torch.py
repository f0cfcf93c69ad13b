"""ifslab's splat inside a PyTorch model: a ``torch.autograd.Function`` over
:func:`ifslab.splat.forward` and :func:`ifslab.splat.vjp` (CPU, float64 inside; the image
comes back in the maps' dtype and device).

>>> import torch, ifslab.torch
>>> maps = torch.tensor([[0.5, 0, 0, 0.5, 0, 0], ...], requires_grad=True)
>>> image = ifslab.torch.splat(maps, seed=0, size=64, trajectories=200, length=60)
>>> loss = ((image - target) ** 2).mean(); loss.backward()      # maps.grad

Each call draws the chaos game of stream ``draw`` of ``seed``: pass a new ``draw`` per
optimisation step for fresh points, as ifslab's own runs do.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from . import splat as _splat

__all__ = ["Splat", "splat"]


class Splat(torch.autograd.Function):
    """``maps`` ``(n, 6)`` (or θ with ``theta=True``) → image; the reverse pass is the
    splat's own vector–Jacobian product."""

    @staticmethod
    def forward(ctx: Any, params: torch.Tensor, theta: bool, options: dict) -> torch.Tensor:
        x = params.detach().cpu().to(torch.float64).numpy()
        if theta:
            image, tape = _splat.forward(theta=x, **options)
        else:
            image, tape = _splat.forward(x, **options)
        ctx.tape = tape
        ctx.shape = params.shape
        return torch.from_numpy(np.ascontiguousarray(image)).to(dtype=params.dtype, device=params.device)

    @staticmethod
    def backward(ctx: Any, grad_image: torch.Tensor):
        g = _splat.vjp(ctx.tape, grad_image.detach().cpu().to(torch.float64).numpy())
        grad = torch.from_numpy(np.ascontiguousarray(g)).reshape(ctx.shape)
        return grad.to(dtype=grad_image.dtype, device=grad_image.device), None, None


def splat(params: torch.Tensor, *, theta: bool = False, **options: Any) -> torch.Tensor:
    """The splat of ``params`` (maps ``(n, 6)``, or θ when ``theta``) with the keywords of
    :func:`ifslab.splat.forward` (``size``, ``sigma``, ``seed``, ``draw``, …), as a
    differentiable tensor."""
    return Splat.apply(params, theta, options)
