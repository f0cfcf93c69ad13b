"""Codes as plain dicts in the ``ifslab-code/1`` format, and the files the CLI writes."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Tuple, Union

from . import _ifslab

CodeLike = Union[Dict[str, Any], str, "os.PathLike[str]"]


def code_arg(code: CodeLike) -> Tuple[str, bool]:
    """``code`` as the extension takes it: (JSON text, True) for a dict (or a run
    :class:`~ifslab.Result`), (file or built-in name, False) otherwise."""
    if hasattr(code, "code") and isinstance(getattr(code, "code"), dict):
        code = code.code  # a Result
    if isinstance(code, dict):
        return json.dumps(code), True
    if isinstance(code, (str, os.PathLike)):
        return os.fspath(code), False
    raise TypeError(
        f"a code is a dict in the ifslab-code/1 format, a .json file or a built-in name, "
        f"not {type(code).__name__}"
    )


def code(spec: CodeLike) -> Dict[str, Any]:
    """The validated code document of ``spec``: a built-in name (``"fern"``), a code file,
    or a dict (checked: finite, shapes, probabilities, contractive maps)."""
    return json.loads(_ifslab.code_json(*code_arg(spec)))


def load_code(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Any]:
    """Reads and validates a code file (``code.json`` of a run, ``ifslab sample``'s files)."""
    return json.loads(_ifslab.load_code(os.fspath(path)))


def save_code(code: CodeLike, path: Union[str, "os.PathLike[str]"]) -> None:
    """Validates ``code`` and writes it as the command line writes codes: pretty JSON,
    numbers that read back to the same bits, atomically."""
    text, is_json = code_arg(code)
    if not is_json:
        text = _ifslab.code_json(text, False)
    _ifslab.save_code(text, os.fspath(path))


def builtin_codes() -> List[str]:
    """The names of the built-in codes (``ifslab codes``)."""
    return list(_ifslab.builtin_codes())
