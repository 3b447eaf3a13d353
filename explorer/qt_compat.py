"""A workaround for a reference-counting bug of PySide6 6.12 on Python 3.11.

On Python 3.11 PySide6 6.12 releases one reference to ``None`` on every call of a C++
method that returns void (``QLabel.setText``, ``QTimer.start``...) and one to ``True`` or
``False`` on every signal emission. A live GUI makes thousands of such calls a second, so
within seconds the singleton's count reaches zero and the interpreter aborts with
``Fatal Python error: none_dealloc: deallocating None``. Python 3.12 made these
singletons immortal, which makes the bug harmless there; here we do the same by hand,
giving them a reference count no program can exhaust. Remove once the binding is fixed.
"""

from __future__ import annotations

import ctypes
import sys

_RESERVE = 1 << 40
_applied = False


def protect_singletons() -> bool:
    """Make None, True and False effectively immortal on Python < 3.12; True if applied."""
    global _applied
    if _applied or sys.version_info >= (3, 12) or hasattr(sys, "gettotalrefcount"):
        return False
    for singleton in (None, True, False):
        ctypes.c_ssize_t.from_address(id(singleton)).value += _RESERVE
    _applied = True
    return True
