"""ifslab from Python: the fractal inverse problem with NumPy in and out.

Everything here calls the Rust library through its extension module (``ifslab._ifslab``):
runs go through the run API the ``ifslab`` command line and the sweeps call (one config, one
run folder), renders through the evaluation renderer as ``ifslab render`` configures it, and
the differentiable splat through its renderer. Errors are :class:`IfslabError` (or
``FileNotFoundError`` / ``KeyboardInterrupt``) carrying the library's own words.

>>> import ifslab
>>> image = ifslab.render("sierpinski", size=256, points=1_000_000)
>>> image.shape
(256, 256)
"""

from ._ifslab import IfslabError
from ._code import builtin_codes, code, load_code, save_code
from ._render import render, render_with_stats
from ._images import load_image, save_image
from ._runs import Result, fit_points, invert, load_run, resolve_config, run, sdf_fit
from ._sweep import Collected, collect, sweep
from . import flame, splat, suite

__all__ = [
    "Collected",
    "IfslabError",
    "Result",
    "builtin_codes",
    "code",
    "collect",
    "fit_points",
    "flame",
    "invert",
    "load_code",
    "load_image",
    "load_run",
    "render",
    "render_with_stats",
    "resolve_config",
    "run",
    "save_code",
    "save_image",
    "sdf_fit",
    "splat",
    "suite",
    "sweep",
]
