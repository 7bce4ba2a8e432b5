"""The exceptions inkwarp raises. Every core error maps to one of these."""

from __future__ import annotations

import os
import sys

import numpy as np


class InkwarpError(Exception):
    """Base class of every error inkwarp raises on purpose."""


class InputError(InkwarpError, ValueError):
    """An argument or an input inkwarp refuses (a value, shape, file name or format it
    cannot use): the message names it and the fix. A ``ValueError`` too, as Python's own
    argument errors are, so ``except ValueError`` goes on catching it."""


class MissingFileError(InkwarpError, FileNotFoundError):
    """A file or folder inkwarp was given (a scene, a picture, a drawing, a video, an output's
    folder) does not exist; ``filename`` names it. A ``FileNotFoundError`` too, as Python's
    own ``open`` raises, so ``except FileNotFoundError`` goes on catching it."""


class SceneError(InkwarpError, ValueError):
    """A scene file (or dict) is invalid.

    Attributes
    ----------
    file : str or None
        The scene file, when the scene came from one.
    path : str
        Where in the scene the problem is, as a JSON path such as
        ``features[3].keys[1].points`` (empty for the whole document).
    problems : list of tuple(str, str)
        Every ``(path, message)`` found, the first of which is ``path``/the message.
    """

    def __init__(self, message: str, *, file: str | None = None, path: str = "",
                 problems: list[tuple[str, str]] | None = None) -> None:
        super().__init__(message)
        self.file = file
        self.path = path
        self.problems = problems if problems is not None else [(path, message)]


class InternalError(InkwarpError):
    """A bug in inkwarp (such as a panic in the engine), caught before it could crash the
    program. The message asks for a report; the command line exits with status 1."""


class OutputWriteError(InkwarpError, OSError):
    """An output could not be written for a reason of the machine's, not of the input: a
    full disk, a quota, a file-size limit, a failing device, or ffmpeg failing. The message
    names the output, the reason and what to do; whatever was written of it is removed.
    ``errno`` is the reason's error number where there is one. The command line exits
    with status 1."""


class WorkerLostError(InkwarpError, OSError):
    """A render farm's worker died (killed for memory, its node lost) more often than a
    chunk is rendered again: not the user's input and not a bug. The message names the
    frames, the reason Ray gives and how to resume; the command line exits with status 1."""


class InkwarpWarning(UserWarning):
    """Something inkwarp did works but is probably not what was meant (for example a
    transfer map that folds the drawing over)."""


class PastEndWarning(InkwarpWarning):
    """A frame or field was asked of a scene at a time past its end (``Scene.duration``), or
    before 0 and every key: it shows the poses held after the last keys (or before the
    first), which may not be what was meant (a time in milliseconds, say, or a sign slip). ``inkwarp render``, ``field`` and ``compare`` say the same of
    ``--time`` as a warning line on stderr."""


class ConvergenceWarning(InkwarpWarning):
    """A thin-plate solve stopped before it converged (its cycles ran out, a budget was
    spent, parts were left unsettled: see :attr:`SolveReport.stop`), so its field may be off
    by more than the accuracy contract, 5 times ``solver.tolerance`` (0.05 px at the default).
    The message names the layer and the frame, and what to change; ``inkwarp render`` prints
    it as one line on stderr."""


class ArrayValuesError(InputError):
    """Values :func:`real_array` refuses, its message naming the array."""


class ComplexValuesError(ArrayValuesError):
    """Complex numbers where real ones are needed (raised by :func:`real_array`)."""


def real_array(name: str, value: object, dtype: type = float) -> np.ndarray:
    """``value`` as an array of ``dtype``. Complex values are a :class:`ComplexValuesError`
    (numpy would drop their imaginary parts with only a warning), an integer too large for
    any float an :class:`ArrayValuesError`; other failures are numpy's."""
    arr = np.asarray(value)
    if arr.dtype.kind == "c":
        raise ComplexValuesError(f"{name} holds complex numbers; pass real values (np.real({name}) if "
                         "the imaginary parts are zero).")
    try:
        with np.errstate(over="ignore"):  # values past the dtype become inf, which the callers refuse
            return arr.astype(dtype, copy=False)
    except OverflowError:  # a Python int past 1.8e308
        raise ArrayValuesError(f"{name} holds a number too large for a float; every value must be a "
                               "finite number of pixels.") from None


def caller_outside() -> int:
    """The ``stacklevel`` for :func:`warnings.warn`, called where this is called, that names
    the first caller outside the inkwarp package (the user's line, not inkwarp's)."""
    package, frame, level = os.path.dirname(os.path.abspath(__file__)), sys._getframe(1), 1
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(package + os.sep):
        frame, level = frame.f_back, level + 1
    return level
