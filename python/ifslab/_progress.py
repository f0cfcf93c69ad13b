"""Progress callbacks: the library reports ``(event, value)`` pairs to a Python callable.

Events: ``("start", (what, length))``, ``("length", n)``, ``("position", done)``,
``("message", text)`` and ``("finish", None)``; positions and messages come at most ten
times a second. ``progress=True`` draws a ``tqdm`` bar where tqdm is installed (and
nothing otherwise).
"""

from __future__ import annotations

import contextlib
from typing import Any, Callable, Iterator, Optional

Callback = Callable[[str, Any], None]


class _Tqdm:
    def __init__(self) -> None:
        from tqdm.auto import tqdm  # noqa: F401  (checked by the caller)

        self._tqdm = tqdm
        self._bar = None

    def __call__(self, event: str, value: Any) -> None:
        if event == "start":
            what, length = value
            if self._bar is not None:
                self._bar.close()
            self._bar = self._tqdm(total=length or None, unit=" " + what if what else "it")
        elif event == "length":
            # Some work announces its length only (a render's points).
            if self._bar is None:
                self._bar = self._tqdm(total=value)
            else:
                self._bar.total = value
                self._bar.refresh()
        elif self._bar is None:
            return
        elif event == "position":
            self._bar.update(value - self._bar.n)
        elif event == "message":
            self._bar.set_postfix_str(value)
        elif event == "finish":
            self.close()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def adapt(progress: Any) -> Optional[Callback]:
    """``progress`` as the callable the extension calls (``None`` for none)."""
    if progress is None or progress is False:
        return None
    if progress is True:
        try:
            import tqdm  # noqa: F401
        except ImportError:
            return None
        return _Tqdm()
    if callable(progress):
        return progress
    raise TypeError("progress is a callable(event, value), True (tqdm) or None")


@contextlib.contextmanager
def reporting(progress: Any) -> Iterator[Optional[Callback]]:
    """:func:`adapt`, with a tqdm bar closed when the work ends (some work announces no
    end of its own)."""
    callback = adapt(progress)
    try:
        yield callback
    finally:
        if isinstance(callback, _Tqdm):
            callback.close()
