"""Exceptions raised by ffsr-gym.

Every error names what was wrong, the offending value and what is allowed, so a user can fix the
input without reading a stack trace from deep inside numpy or Pinocchio.
"""

from __future__ import annotations


class FFSRError(Exception):
    """Base class of every error raised on purpose by ffsr-gym."""


class ScenarioError(FFSRError, ValueError):
    """A scenario file is missing, malformed, or holds a value outside its allowed range."""


class RobotFileError(FFSRError, FileNotFoundError):
    """A robot description (URDF or collision file) is missing or malformed."""


class InvalidInputError(FFSRError, ValueError):
    """A function argument (state, action, parameter) is non-finite, wrongly shaped or out of range."""


class UserFileError(InvalidInputError):
    """A file that cannot be read safely: not a regular file, too large, nested too deep, unreadable or not UTF-8."""


class WriteError(FFSRError, OSError):
    """A result file that could not be written (a full disk, no permission); the previous file is unchanged."""


class MissingDependencyError(FFSRError, ImportError):
    """An optional dependency is needed for the requested feature but is not installed."""


class UnknownArgumentError(InvalidInputError, TypeError):
    """A keyword argument that the function or environment does not take (never silently ignored)."""


def require(module: str, extra: str, packages: str, what: str):
    """Import an optional ``module``, or raise :class:`MissingDependencyError` naming the extra that installs it.

    ``what`` says what needs it ("the aggregates need"), ``packages`` what the extra brings.
    """
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(f'{what}: pip install "ffsr-gym[{extra}]" ({packages})') from exc
