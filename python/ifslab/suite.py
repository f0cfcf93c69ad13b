"""The chaotic-splatting paper's random test suite: a code scored against a suite's entry,
as ``ifslab suite score --json`` scores it (the same library function, ``score_code``).

>>> import ifslab
>>> ifslab.suite.score("sierpinski", "out/suite", index=0)["iou"]   # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Optional, Union

from . import _ifslab
from ._code import CodeLike, code_arg

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["score"]


def score(
    code: CodeLike, suite_dir: PathLike, index: Optional[int] = None
) -> Union[Dict[str, Any], List[Dict[str, Any]]]:
    """The scores of ``code`` (a dict, a ``.json`` file, a built-in name or a run's
    ``Result``) against entry ``index`` of the suite in ``suite_dir`` (made by ``ifslab
    suite make``): a dict as ``ifslab suite score --json`` prints it — the means over the
    views (``f1``, ``iou``, ``psnr``, ``ssim``, ``lpips`` where its weights are, …) and
    ``views``, each view's. With ``index=None``, a list: one score per entry of the suite.
    The GIL is released while the views are rendered."""
    text, is_json = code_arg(code)
    return json.loads(_ifslab.suite_score(os.fspath(suite_dir), text, is_json, index))
