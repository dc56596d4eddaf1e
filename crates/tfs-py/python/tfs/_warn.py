"""Warnings raised at the caller's line: the first frame outside the ``tfs`` package."""

import os
import sys
import warnings

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def _outside_level():
    """The ``stacklevel`` of ``warnings.warn`` (called from here) that names the first frame
    outside this package: the user's script, not tfs's own Python code."""
    frame = sys._getframe(1)
    level = 1
    while frame is not None:
        name = os.path.abspath(frame.f_code.co_filename)
        if not name.startswith(_PACKAGE_DIR + os.sep):
            return level
        frame = frame.f_back
        level += 1
    return level


def warn_all(messages, category=UserWarning):
    """Issues each message as a warning attributed to the caller's frame (its file and line),
    so that ``python script.py`` shows which call of the script warned."""
    for msg in messages:
        warnings.warn(msg, category, stacklevel=_outside_level())
