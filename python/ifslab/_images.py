"""Pictures in and out as NumPy arrays, read and written by the library."""

from __future__ import annotations

import os
from typing import Union

import numpy as np

from . import _ifslab

PathLike = Union[str, "os.PathLike[str]"]


def as_float_image(image: np.ndarray) -> np.ndarray:
    """``image`` as float32 in [0, 1]: integers are scaled by their type's maximum (uint8
    by 255), floats are taken as they are."""
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (3, 4)):
        raise ValueError(
            f"an image is (height, width) grey or (height, width, 3 or 4) colour, got shape {a.shape}"
        )
    if np.issubdtype(a.dtype, np.integer):
        a = a.astype(np.float32) / np.float32(np.iinfo(a.dtype).max)
    elif a.dtype == np.bool_:
        a = a.astype(np.float32)
    return np.ascontiguousarray(a, dtype=np.float32)


def save_image(image: np.ndarray, path: PathLike) -> None:
    """Writes a grey ``(H, W)`` or colour ``(H, W, 3|4)`` array (floats in [0, 1], or
    integers) as a PNG; grey is written with 16 bits, so a float target keeps its levels."""
    _ifslab.save_png(as_float_image(image), os.fspath(path))


def load_image(path: PathLike, rgb: bool = False) -> np.ndarray:
    """Reads a picture as the library reads targets: grey float32 ``(H, W)`` in [0, 1]
    (alpha composited onto white), or with ``rgb`` ``(H, W, 3)``."""
    return _ifslab.load_image(os.fspath(path), rgb)
